"""The figures read at a paper's column width and name what they draw: the bus panels two by
two, one column wide, the legend inside a panel, the buses drawn said; the race figure's betas
beside the paper's; every error bar named. ``--replot`` draws a driver's figure again from its
committed CSVs, and refuses (one line, exit 2, nothing written) without them."""

from __future__ import annotations

from pathlib import Path

import pytest

from repro.claims.race import PAPER_BETA
from repro.core.io import read_result
from repro.experiments import (beyond_mgae, beyond_order, fig_bus_arrivals, fig_bus_load,
                               learner_ablation, race, transfer)
from tests.conftest import run_cli, tree_snapshot

PAPER = Path(__file__).resolve().parents[1] / "results" / "paper"


@pytest.fixture
def drawn(monkeypatch):
    """The figures a plot function draws, kept open instead of saved."""
    figures = []

    def keep(fig, stem):
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
    module.plot(table, "unused", all_buses)
    fig = drawn[0]
    assert fig.get_figwidth() == fig_bus_arrivals.COLUMN_WIDTH
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == table.policy.nunique() == 4
    corners = {(round(ax.get_position().x0, 2), round(ax.get_position().y0, 2)) for ax in axes}
    assert len(corners) == 4 and len({x for x, _ in corners}) == 2  # two by two
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
    race.plot({n: read_result(PAPER / f"{n}.csv") for n in names}, Path("unused"))
    labels = [t.get_text() for t in drawn[0].axes[0].get_legend().get_texts()]
    ours = read_result(PAPER / "table_race.csv")
    for name, (beta, se) in PAPER_BETA.items():
        row = ours[ours.distribution == name].iloc[0]
        label = next(label for label in labels if label.startswith(name))
        assert f"{row.beta:.3f} ({row.beta_se:.3f})" in label
        assert f"paper {beta:.3f} ({se:.3f})" in label
    assert "standard error" in drawn[0].axes[0].get_title()


@pytest.mark.parametrize("draw, named", [
    (lambda: transfer.plot(read_result(PAPER / "transfer.csv"),
                           read_result(PAPER / "transfer_summary.csv"), "unused", "t"),
     "error bars: standard error"),
    (lambda: learner_ablation.plot(read_result(PAPER / "learner_ablation_summary.csv"),
                                   "unused", "t"), "error bars: standard error"),
    (lambda: beyond_order.plot(read_result(PAPER / "order_reversal.csv"),
                               read_result(PAPER / "order_reversal_summary.csv"), "unused", "t"),
     "error bars: 95% bootstrap CI"),
    (lambda: beyond_mgae.plot(read_result(PAPER / "beyond_mgae.csv"),
                              read_result(PAPER / "beyond_mgae_summary.csv"), "unused", "t"),
     "error bars: 95% bootstrap CI"),
], ids=["transfer", "learner-ablation", "beyond-order", "beyond-mgae"])
def test_error_bars_are_named(drawn, draw, named):
    draw()
    assert all(named in ax.get_ylabel() for ax in drawn[0].axes)


@pytest.mark.parametrize("command, extra, figure", [
    ("fig-bus-load", [], "bus_load"), ("fig-bus-arrivals", [], "bus_arrivals"),
    ("race", [], "race_dt_vs_n"), ("fig-transfer", ["--learner", "suite", "--corrected"],
                                   "transfer_corrected_suite"),
    ("beyond-mgae", [], "beyond_mgae"), ("learner-ablation", [], "learner_ablation"),
    ("beyond-order", [], "order_reversal")])
def test_replot_draws_from_the_csvs_and_writes_only_the_figure(tmp_path, command, extra, figure):
    before = tree_snapshot(PAPER)
    done = run_cli(command, "--scale", "paper", "--replot", "--figures-dir", str(tmp_path),
                   *extra)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{figure}.pdf", f"{figure}.png"]
    assert tree_snapshot(PAPER) == before
    empty = tmp_path / "empty"
    empty.mkdir()
    done = run_cli(command, "--scale", "paper", "--replot", "--results-dir", str(empty),
                   "--figures-dir", str(tmp_path / "figures"), *extra)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--replot: must be the results of an earlier run" \
        in done.stderr, done.stderr
    assert not (tmp_path / "figures").exists() and not list(empty.iterdir())
