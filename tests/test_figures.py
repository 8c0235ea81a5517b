"""The figures read at a paper's column width and name what they draw: the bus panels two by
two, one column wide, the legend inside a panel, the buses drawn said; the race figure's betas
beside the paper's; every error bar named. ``--replot`` draws a driver's figure again from its
committed CSVs, and refuses (one line, exit 2, nothing written) without them. Every figure has a
sidecar naming its files' and its sources' hashes and its scale, and a run never replaces a
figure of a larger scale unless told to."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

import repro.runs.results as io_module
from repro.core.errors import UsageError
from repro.paper import RACE_BETA
from repro.runs.locks import folder_lock
from repro.runs.results import (CSV_HASH, FIGURES_LOCK, figure_sidecar, open_figures,
                                read_provenance, read_result, release_results, save_figure)
from repro.studies.advantage import estimators as beyond_mgae
from repro.studies.bus import arrivals as fig_bus_arrivals, loads as fig_bus_load, pictures
from repro.studies.races import race
from repro.studies.transfer import learner_ablation, order as beyond_order, transfer
from tests.conftest import ROOT, run_cli, tree_snapshot

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast

PAPER = Path(__file__).resolve().parents[1] / "results" / "paper"


@pytest.fixture
def drawn(monkeypatch):
    """The figures a plot function draws, kept open instead of saved."""
    figures = []

    def keep(fig, stem, sources):
        figures.append(fig)

    for module in (fig_bus_arrivals, fig_bus_load, race, transfer, beyond_mgae, beyond_order,
                   learner_ablation):
        monkeypatch.setattr(module, "save_figure", keep)
    return figures


def inside(inner, outer) -> bool:
    return (inner.x0 >= outer.x0 and inner.x1 <= outer.x1 and inner.y0 >= outer.y0
            and inner.y1 <= outer.y1)


@pytest.mark.parametrize("module, csv", [(fig_bus_load, "bus_load.csv"),
                                         (fig_bus_arrivals, "bus_arrivals.csv")])
@pytest.mark.parametrize("all_buses", [False, True])
def test_bus_panels_fit_a_column_with_the_legend_inside(drawn, module, csv, all_buses):
    table = read_result(PAPER / csv)
    module.plot(table, "unused", all_buses, [])
    fig = drawn[0]
    assert fig.get_figwidth() == pictures.COLUMN_WIDTH
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == table.policy.nunique() == 6  # the paper's four, the GRU's two
    corners = {(round(ax.get_position().x0, 2), round(ax.get_position().y0, 2)) for ax in axes}
    assert len(corners) == 6 and len({x for x, _ in corners}) == 2  # two to a row
    fig.tight_layout()  # as save_figure lays it out
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legend = axes[0].get_legend()
    assert inside(legend.get_window_extent(renderer), axes[0].get_window_extent(renderer))
    buses = [t.get_text() for t in legend.get_texts() if t.get_text().startswith("Bus")]
    assert buses == [f"Bus {b}" for b in range(1, 7 if all_buses else 6)]
    title = fig._suptitle.get_text()
    assert ("all six buses" in title) if all_buses else ("Bus 6 not drawn" in title)


def test_race_figure_draws_the_papers_betas_beside_ours(drawn):
    names = ("race_dt_vs_n", "table_race", "race_exact")
    race.plot({n: read_result(PAPER / f"{n}.csv") for n in names}, Path("unused"), [])
    labels = [t.get_text() for t in drawn[0].axes[0].get_legend().get_texts()]
    ours = read_result(PAPER / "table_race.csv")
    for name, (beta, se) in RACE_BETA.items():
        row = ours[ours.distribution == name].iloc[0]
        label = next(label for label in labels if label.startswith(name))
        assert f"{row.beta:.3f} ({row.beta_se:.3f})" in label
        assert f"paper {beta:.3f} ({se:.3f})" in label
    assert "standard error" in drawn[0].axes[0].get_title()


@pytest.mark.parametrize("draw, named", [
    (lambda: transfer.plot(read_result(PAPER / "transfer.csv"),
                           read_result(PAPER / "transfer_summary.csv"), "unused", "t", []),
     "error bars: standard error"),
    (lambda: learner_ablation.plot(read_result(PAPER / "learner_ablation_summary.csv"),
                                   "unused", "t", []), "error bars: standard error"),
    (lambda: beyond_order.plot(read_result(PAPER / "order_reversal.csv"),
                               read_result(PAPER / "order_reversal_summary.csv"), "unused", "t",
                               []),
     "error bars: 95% bootstrap CI"),
    (lambda: beyond_mgae.plot(read_result(PAPER / "beyond_mgae.csv"),
                              read_result(PAPER / "beyond_mgae_summary.csv"), "unused", "t",
                              []),
     "error bars: 95% bootstrap CI"),
], ids=["transfer", "learner-ablation", "beyond-order", "beyond-mgae"])
def test_error_bars_are_named(drawn, draw, named):
    draw()
    assert all(named in ax.get_ylabel() for ax in drawn[0].axes)


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def assert_sidecar_describes(stem: Path, sources: list[Path], scale: str,
                             check_paths: bool = True) -> dict:
    """The sidecar of the figure ``stem`` records its PNG's and PDF's hashes, the result CSVs
    ``sources`` (in order; at their paths unless ``check_paths`` is false) with their bytes'
    hashes, which their own sidecars record too where they record one (results older than the
    hash do not), and ``scale``; returns it. A committed figure's sidecar records where its CSVs
    were when it was drawn (written once, possibly another machine's folder), so its sources are
    checked by their bytes only."""
    prov = json.loads(figure_sidecar(stem).read_text())
    assert prov["figures"] == {f"{stem.name}{ext}": sha256(f"{stem}{ext}")
                               for ext in (".png", ".pdf")}
    assert len(prov["sources"]) == len(sources)
    if check_paths:
        assert [Path(s["csv"]).resolve() for s in prov["sources"]] == [s.resolve() for s in sources]
    for record, source in zip(prov["sources"], sources):
        assert record[CSV_HASH] == sha256(source)
        assert read_provenance(source).get(CSV_HASH, sha256(source)) == sha256(source)
        assert record["scale"] == scale
    assert prov["scale"] == scale and prov["git_commit"] and "matplotlib" in prov["versions"]
    return prov


@pytest.mark.parametrize("command, extra, figure, sources", [
    ("fig-bus-load", [], "bus_load", ["bus_load"]),
    ("fig-bus-arrivals", [], "bus_arrivals", ["bus_arrivals"]),
    ("race", [], "race_dt_vs_n", ["race_dt_vs_n", "table_race", "race_exact"]),
    ("fig-transfer", ["--learner", "suite", "--corrected"], "transfer_corrected_suite",
     ["transfer_corrected_suite", "transfer_corrected_suite_summary"]),
    ("beyond-mgae", [], "beyond_mgae", ["beyond_mgae", "beyond_mgae_summary"]),
    ("beyond-sb3", [], "beyond_sb3", ["beyond_sb3", "beyond_sb3_summary"]),
    ("learner-ablation", [], "learner_ablation", ["learner_ablation_summary"]),
    ("beyond-order", [], "order_reversal", ["order_reversal", "order_reversal_summary"]),
    ("beyond-transfer-dt", [], "transfer_dt_grid",
     ["transfer_dt_grid", "transfer_dt_grid_summary", "races"]),
    ("fig-bus-lambda", ["--learner", "suite"], "bus_lambda_suite",
     ["bus_lambda_suite", "bus_lambda_suite_summary"]),
    ("beyond-races", [], "races", ["races", "races_fit"]),
    ("scaling", [], "scaling", ["scaling", "scaling_wall", "scaling_fit"])])
def test_replot_draws_from_the_csvs_and_writes_only_the_figure(tmp_path, command, extra, figure,
                                                               sources):
    before = tree_snapshot(PAPER)
    done = run_cli(command, "--scale", "paper", "--replot", "--figures-dir", str(tmp_path),
                   *extra)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{figure}.pdf", f"{figure}.png",
                                                          f"{figure}.provenance.json"]
    assert_sidecar_describes(tmp_path / figure, [PAPER / f"{s}.csv" for s in sources], "paper")
    assert tree_snapshot(PAPER) == before
    empty = tmp_path / "empty"
    empty.mkdir()
    done = run_cli(command, "--scale", "paper", "--replot", "--results-dir", str(empty),
                   "--figures-dir", str(tmp_path / "figures"), *extra)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--replot: must be the results of an earlier run" \
        in done.stderr, done.stderr
    assert not (tmp_path / "figures").exists() and not list(empty.iterdir())


# --- the figures' provenance and the scale guard --------------------------------------------------

RACE = ("race", "--scale", "smoke", "--n-sets", "400", "--n-max", "5", "--distribution",
        "exponential")
RACE_SOURCES = ("race_dt_vs_n", "table_race", "race_exact")


def test_a_driver_writes_a_figure_with_a_sidecar_of_its_files_and_sources(cli, tmp_path):
    res, fig = tmp_path / "res", tmp_path / "fig"
    done = cli(*RACE, "--results-dir", str(res), "--figures-dir", str(fig))
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in fig.iterdir()) == ["race_dt_vs_n.pdf", "race_dt_vs_n.png",
                                                     "race_dt_vs_n.provenance.json"]
    prov = assert_sidecar_describes(fig / "race_dt_vs_n",
                                    [res / f"{name}.csv" for name in RACE_SOURCES], "smoke")
    assert prov["command"] == "race" and "--figures-dir" in prov["argv"]
    assert all(s["command"] == "race" for s in prov["sources"])


def paper_figure(folder: Path, stem: str = "race_dt_vs_n") -> None:
    """A hand-made paper-scale figure in ``folder``: its files and a sidecar saying so."""
    folder.mkdir(parents=True, exist_ok=True)
    for ext in (".png", ".pdf"):
        (folder / f"{stem}{ext}").write_bytes(b"a paper-scale figure")
    figure_sidecar(folder / stem).write_text(json.dumps({"scale": "paper"}))


def test_figures_of_a_larger_scale_are_replaced_only_when_told(cli, tmp_path):
    """A smoke run into a figures folder holding a paper-scale figure: refused before any work,
    one line naming --figures-dir, nothing written anywhere; --overwrite replaces it."""
    res, fig = tmp_path / "res", tmp_path / "anywhere"
    paper_figure(fig)
    before = tree_snapshot(fig)
    done = cli(*RACE, "--results-dir", str(res), "--figures-dir", str(fig))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--figures-dir" in lines[0], done.stderr
    assert "paper-scale race_dt_vs_n.png" in lines[0] and "--overwrite" in lines[0]
    assert tree_snapshot(fig) == before and not res.exists()
    done = cli(*RACE, "--results-dir", str(res), "--figures-dir", str(fig), "--overwrite")
    assert done.returncode == 0, done.stderr
    assert_sidecar_describes(fig / "race_dt_vs_n", [res / f"{n}.csv" for n in RACE_SOURCES],
                             "smoke")


def test_figures_without_a_sidecar_or_of_a_smaller_scale_are_replaced(cli, tmp_path):
    res, fig = tmp_path / "res", tmp_path / "fig"
    fig.mkdir()
    (fig / "race_dt_vs_n.png").write_bytes(b"an old figure")  # drawn before sidecars
    paper_figure(fig, "other")
    figure_sidecar(fig / "other").write_text(json.dumps({"scale": "smoke"}))
    done = cli(*RACE, "--results-dir", str(res), "--figures-dir", str(fig))
    assert done.returncode == 0, done.stderr
    assert (fig / "race_dt_vs_n.png").read_bytes() != b"an old figure"


def test_a_larger_figure_that_appears_during_the_run_is_not_replaced(tmp_path, monkeypatch,
                                                                      capsys):
    """The folder was checked before the work; a paper-scale figure written there meanwhile is
    still refused when the figure is saved (one line naming --figures-dir, exit 2)."""
    from repro.cli import main

    monkeypatch.setenv("REPRO_QUIET", "1")
    res, fig = tmp_path / "res", tmp_path / "fig"
    study = race.run_study

    def meanwhile(*args, **kwargs):
        paper_figure(fig)
        return study(*args, **kwargs)

    monkeypatch.setattr(race, "run_study", meanwhile)
    assert main([*RACE, "--results-dir", str(res), "--figures-dir", str(fig)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--figures-dir" in lines[0] and "paper-scale" in lines[0]
    assert (fig / "race_dt_vs_n.png").read_bytes() == b"a paper-scale figure"
    assert json.loads(figure_sidecar(fig / "race_dt_vs_n").read_text()) == {"scale": "paper"}


def test_save_figure_keeps_a_larger_figure_unless_its_folder_was_opened_to_replace_it(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    csv = tmp_path / "res" / "table_race.csv"
    csv.parent.mkdir()
    shutil.copy(PAPER / "table_race.csv", csv)
    shutil.copy(PAPER / "table_race.provenance.json", csv.parent)
    prov = json.loads((csv.parent / "table_race.provenance.json").read_text())
    prov["scale"] = "quick"
    (csv.parent / "table_race.provenance.json").write_text(json.dumps(prov))
    fig = tmp_path / "fig"
    paper_figure(fig)
    with pytest.raises(UsageError, match="--figures-dir"):
        save_figure(plt.figure(), fig / "race_dt_vs_n", [csv])
    assert (fig / "race_dt_vs_n.png").read_bytes() == b"a paper-scale figure"
    try:
        open_figures(fig, "--figures-dir", scale="quick", overwrite=True)
        save_figure(plt.figure(), fig / "race_dt_vs_n", [csv])
    finally:
        release_results()
    assert_sidecar_describes(fig / "race_dt_vs_n", [csv], "quick")


def test_a_second_writer_of_a_figures_folder_is_refused(tmp_path, capsys, monkeypatch):
    """A driver holds its figures folder from the start (one line naming --figures-dir and the
    holder's lock, nothing written); a figure saved outside a driver waits for the holder, then
    is refused too."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from repro.cli import main

    monkeypatch.setenv("REPRO_QUIET", "1")
    monkeypatch.setattr(io_module, "PAIR_WAIT", 0.1)
    res, fig = tmp_path / "res", tmp_path / "fig"
    with folder_lock(fig, FIGURES_LOCK, "--figures-dir", "a figures folder"):
        capsys.readouterr()
        assert main([*RACE, "--results-dir", str(res), "--figures-dir", str(fig)]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "--figures-dir" in lines[0] and FIGURES_LOCK in lines[0]
        with pytest.raises(UsageError, match="--figures-dir.*figures.lock"):
            save_figure(plt.figure(), fig / "race_dt_vs_n", [])
        assert [p.name for p in fig.iterdir()] == [FIGURES_LOCK] and not res.exists()
    assert main([*RACE, "--results-dir", str(res), "--figures-dir", str(fig)]) == 0
    assert not (fig / FIGURES_LOCK).exists()


def test_a_figures_folder_that_is_the_results_folder_is_refused(cli, tmp_path):
    """A figure's sidecar has the name of its result's (race_dt_vs_n.provenance.json), so one
    folder for both is refused before any work."""
    done = cli(*RACE, "--results-dir", str(tmp_path / "out"), "--figures-dir",
               f"{tmp_path}/out/.")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--figures-dir" in lines[0] and "--results-dir" in lines[0]
    assert not (tmp_path / "out").exists()


def test_the_committed_figures_sidecars_describe_them():
    """Every committed figure has a sidecar, and is the figure it describes, drawn from the
    committed results it names (the CSVs of its folder's counterpart under results/paper)."""
    figures = ROOT / "figures" / "paper"
    sidecars = sorted(figures.rglob("*.provenance.json"))
    drawn = {p.with_suffix("") for p in figures.rglob("*.png")}
    assert drawn and drawn == {side.with_name(side.name.removesuffix(".provenance.json"))
                               for side in sidecars}
    for side in sidecars:
        stem = side.with_name(side.name.removesuffix(".provenance.json"))
        prov = json.loads(side.read_text())
        results = PAPER / side.parent.relative_to(figures)
        sources = [results / Path(s["csv"]).name for s in prov["sources"]]
        assert_sidecar_describes(stem, sources, "paper", check_paths=False)
