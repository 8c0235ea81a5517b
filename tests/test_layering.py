"""The package's layers: core <- envs <- learn <- experiments, claims <- cli. A module imports
only from its own layer and those below it, so each layer can be read (and reused) without the
ones above it. Imports inside functions count too."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "repro"
LAYER = {"core": 0, "envs": 1, "learn": 2, "experiments": 3, "claims": 3, "cli": 4,
         "__main__": 4}


def layer(module: str) -> int:
    """The layer of ``repro.<part>...`` (the package ``repro`` itself counts as the top)."""
    parts = module.split(".")
    return LAYER[parts[1]] if len(parts) > 1 else LAYER["cli"]


def imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append(node.module)
        elif isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
    return [m for m in found if m == "repro" or m.startswith("repro.")]


def test_no_module_imports_from_a_layer_above_its_own():
    upward = []
    for path in sorted(ROOT.rglob("*.py")):
        module = "repro." + ".".join(path.relative_to(ROOT).with_suffix("").parts)
        module = module.removesuffix(".__init__")
        for target in imports(path):
            if layer(target) > layer(module):
                upward.append(f"{module} imports {target}")
    assert upward == []


def test_the_check_sees_an_upward_import(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from repro.experiments.race import RaceConfig\n")
    assert imports(bad) == ["repro.experiments.race"]
    assert layer("repro.experiments.race") > layer("repro.envs.renewal.engine")


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
