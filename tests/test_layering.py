"""The package's layers: core, paper <- envs, runs <- learn <- studies <- claims <- cli <-
reproduce (which runs the other commands through the command line) <- __main__. A module imports
only from its own package and the layers below it, so each layer can be read (and reused) without
the ones above it: never from a layer above, never from a sibling package of its own layer (the
environments never import the run bookkeeping, nor it them), and no module imports, through
others, itself. Imports inside functions count too."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "repro"
LAYER = {"core": 0, "paper": 0, "envs": 1, "runs": 1, "learn": 2, "studies": 3, "claims": 4,
         "cli": 5, "reproduce": 6, "__main__": 7}


def layer(module: str) -> int:
    """The layer of ``repro.<part>...`` (the package ``repro`` itself counts as the top)."""
    parts = module.split(".")
    return LAYER[parts[1]] if len(parts) > 1 else LAYER["cli"]


def package(module: str) -> str:
    """``repro.<part>`` of a module: the package of its layer."""
    return ".".join(module.split(".")[:2])


def imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # ``from repro.x import y``: y may be a module (then that module is what is imported)
            modules = [f"{node.module}.{alias.name}" for alias in node.names
                       if _is_module(f"{node.module}.{alias.name}")]
            found += modules if len(modules) == len(node.names) else [node.module, *modules]
        elif isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
    return [m for m in found if m == "repro" or m.startswith("repro.")]


def _is_module(name: str) -> bool:
    rel = Path(*name.split(".")[1:])
    return (ROOT / rel).with_suffix(".py").exists() or (ROOT / rel / "__init__.py").exists()


def module_name(path: Path) -> str:
    return ("repro." + ".".join(path.relative_to(ROOT).with_suffix("").parts)).removesuffix(
        ".__init__")


def graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the modules (of those under ``root``) it imports, a package's ``__init__`` being
    the package."""
    modules = {module_name(p): p for p in sorted(root.rglob("*.py"))}
    out = {}
    for module, path in modules.items():
        targets = set()
        for target in imports(path):
            while target not in modules and "." in target:  # a name in a module: the module
                target = target.rsplit(".", 1)[0]
            if target in modules and target != module:
                targets.add(target)
        out[module] = targets
    return out


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of ``edges``: each strongly connected set of more than one module
    (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_no_module_imports_from_a_layer_above_its_own():
    upward = []
    for path in sorted(ROOT.rglob("*.py")):
        module = module_name(path)
        for target in imports(path):
            if layer(target) > layer(module):
                upward.append(f"{module} imports {target}")
    assert upward == []


def test_no_module_imports_from_a_sibling_package_of_its_layer():
    """core and paper, envs and runs: each stands without the other."""
    sideways = []
    for path in sorted(ROOT.rglob("*.py")):
        module = module_name(path)
        for target in imports(path):
            if (layer(target) == layer(module) and package(target) != package(module)
                    and module != "repro"):
                sideways.append(f"{module} imports {target}")
    assert sideways == []


def test_no_import_circles():
    assert circles(graph()) == []


def test_the_checks_see_an_upward_import_a_sideways_one_and_a_circle(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from repro.studies.races.race import RaceConfig\n")
    assert imports(bad) == ["repro.studies.races.race"]
    assert layer("repro.studies.races.race") > layer("repro.envs.renewal.engine")
    assert layer("repro.runs.results") == layer("repro.envs.bus")
    assert package("repro.runs.results") != package("repro.envs.bus")
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_each_simpy_reference_stands_apart_from_its_fast_engine():
    """A SimPy reference is the oracle its engine is checked against: of its own package it imports
    only the parameters (``params.py``), never the engine's code."""
    references = sorted(ROOT.glob("envs/*/reference.py"))
    assert references  # the glob finds the models
    borrowed = []
    for path in references:
        package = f"repro.envs.{path.parent.name}"
        for target in imports(path):
            if target.startswith(package) and target != f"{package}.params":
                borrowed.append(f"{package}.reference imports {target}")
    assert borrowed == []


def test_no_module_imports_a_commands_module():
    """A study's module is its command: what several commands share lives in a module of their
    group (``repro.studies.<group>.study``, ...) or in ``repro.studies.kit``, never in another
    command, so a command can change without its neighbours (the CLI imports commands by name;
    the claims, above the studies, read what a command writes)."""
    from repro.cli import COMMANDS

    commands = {module for module, _ in COMMANDS.values()}
    borrowed = sorted(f"{module} imports {target}" for module, targets in graph().items()
                      for target in targets if target in commands
                      and module.startswith("repro.studies."))
    assert borrowed == []


PARSED_OPTIONS_READERS = {
    "add_arguments", "extend_arguments", "configure", "config_from_args", "study_config",
    "behaviour_config", "learner_overrides", "given_fields", "check_panel_options", "of",
    "scale_departures", "note_scale_departures", "check_sizes", "parse_arguments", "main",
    "spelled_as_given",
}
"""The functions that may read a command's parsed options: the command line's own, and each
command's ``configure`` with the helpers it calls to make its settings."""


def _takes_parsed_options(fn: ast.FunctionDef) -> bool:
    params = [*fn.args.posonlyargs, *fn.args.args, *fn.args.kwonlyargs]
    return any(p.arg == "args" or "Namespace" in ast.unparse(p.annotation or ast.Constant(""))
               for p in params)


def test_nothing_below_configure_reads_the_parsed_options():
    """The parsed options are read once, by a command's ``configure``, into its frozen settings;
    ``run`` and everything it calls take those (and the folders), never the Namespace."""
    readers = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and _takes_parsed_options(node):
                readers.append((module_name(path), node.name))
    assert readers, "the check found no reader at all: it would pass whatever the code did"
    assert [r for r in readers if r[1] not in PARSED_OPTIONS_READERS] == []


def test_every_command_reads_its_options_in_configure():
    import importlib
    import inspect

    from repro.cli import COMMANDS

    for name, (module_path, _) in COMMANDS.items():
        module = importlib.import_module(module_path)
        assert callable(getattr(module, "configure", None)), name
        first = next(iter(inspect.signature(module.run).parameters))
        assert first != "args", f"{name}: run reads the parsed options"
