"""A sidecar is written once, by its run: a later correction is a dated note beside it, and the
reader shows both (repro.runs.results.write_correction, shown_provenance)."""

from __future__ import annotations

import hashlib
import json
import subprocess

import pandas as pd
import pytest

from repro.core.errors import UsageError
from repro.runs.results import (correction_paths, read_provenance, recreation_paths,
                                shown_provenance, source_records, write_correction,
                                write_result)
from tests.conftest import ROOT, tree_snapshot, write_result_csv


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout


def _as_run_wrote_it(side: str) -> dict | None:
    """The sidecar ``side`` (a path in the repository) as the commit that first held its run (its
    ``finished_utc``) recorded it; None where its history is not in this clone."""
    now = json.loads((ROOT / side).read_text())
    for commit in reversed(_git("log", "--format=%H", "--", side).split()):
        try:
            then = json.loads(_git("show", f"{commit}:{side}"))
        except subprocess.CalledProcessError:  # removed in that commit
            continue
        if then.get("finished_utc") == now.get("finished_utc"):
            return then
    return None


def test_every_committed_sidecar_is_as_its_run_wrote_it():
    """Every committed sidecar is as its run wrote it, but for a field an ``in_place`` correction
    note accounts for (six transfer sidecars had their git_commit rewritten by hand after the run,
    before provenance was written once): the sidecar holds the note's value, the run wrote the
    note's ``recorded``."""
    if _git("rev-parse", "--is-shallow-repository").strip() != "false":
        pytest.skip("a shallow clone has not the sidecars' history")
    sides = _git("ls-files", "results/*.provenance.json").split()
    compared = 0
    for side in sides:
        then = _as_run_wrote_it(side)
        if then is not None:
            now = json.loads((ROOT / side).read_text())
            for note in (json.loads(p.read_text()) for p in correction_paths(
                    ROOT / side.replace(".provenance.json", ".csv"))):
                if note.get("in_place"):
                    assert now[note["field"]] == note["value"], side
                    now[note["field"]] = note["recorded"]
            assert now == then, side
            compared += 1
    assert compared == len(sides) > 50


def test_every_committed_correction_names_a_sidecar_that_holds_its_value():
    """A dated correction note stays beside the sidecar it corrects, and goes with it: a result
    made again has no note of the one it replaced."""
    for path in sorted((ROOT / "results").rglob("*.correction-*.json")):
        note = json.loads(path.read_text())
        side = path.parent / note["corrects"]
        assert side.exists(), path
        assert path.name.startswith(side.name.removesuffix(".provenance.json") + ".correction-")
        if note.get("in_place"):
            assert json.loads(side.read_text())[note["field"]] == note["value"], path


def test_every_committed_recreation_made_its_results_bytes():
    """A re-creation note beside a committed result records a run that wrote the very bytes its
    sidecar describes (a sidecar written before sidecars kept the hash describes the CSV beside
    it), at its scale."""
    notes = sorted((ROOT / "results").rglob("*.recreated-*.json"))
    for path in notes:
        note = json.loads(path.read_text())
        side = json.loads((path.parent / note["recreates"]).read_text())
        csv = path.parent / note["recreates"].replace(".provenance.json", ".csv")
        want = side.get("csv_sha256", hashlib.sha256(csv.read_bytes()).hexdigest())
        assert note["csv_sha256"] == want and note["scale"] == side["scale"], path
        assert note["finished_utc"] != side["finished_utc"], path
    assert notes


def test_a_correction_is_a_note_of_its_own_written_once(tmp_path):
    result = tmp_path / "r.csv"
    write_result_csv(pd.DataFrame(dict(x=[1])), result, git_commit="aaa")
    side = (tmp_path / "r.provenance.json").read_bytes()
    note = write_correction(result, "git_commit", "bbb", "wrong checkout", date="2026-01-02")
    assert note.name == "r.correction-2026-01-02.json" and correction_paths(result) == [note]
    assert (tmp_path / "r.provenance.json").read_bytes() == side
    assert read_provenance(result)["git_commit"] == "aaa"
    assert shown_provenance(result)["corrections"][0]["value"] == "bbb"
    assert source_records([result])[0]["corrections"][0]["recorded"] == "aaa"
    before = tree_snapshot(tmp_path)
    with pytest.raises(UsageError, match="date"):
        write_correction(result, "git_commit", "ccc", "again", date="2026-01-02")
    with pytest.raises(UsageError, match="field"):
        write_correction(result, "no_such_field", "ccc", "none", date="2026-01-03")
    assert tree_snapshot(tmp_path) == before
    write_result(result, pd.DataFrame(dict(x=[2])), {"scale": "paper"})  # the result made again
    assert correction_paths(result) == [] and "corrections" not in shown_provenance(result)


def test_a_result_made_again_byte_for_byte_keeps_its_first_sidecar(tmp_path, monkeypatch):
    """A run that makes the same CSV bytes at the same scale leaves the first run's sidecar (and
    its notes) as they were and records itself in a dated re-creation note; other bytes, or
    another scale, replace the pair and its notes."""
    result, frame = tmp_path / "r.csv", pd.DataFrame(dict(x=[1.5, 2.0]))
    write_result(result, frame, {"scale": "paper", "git_commit": "first"})
    write_correction(result, "git_commit", "fixed", "wrong checkout", date="2026-01-02")
    side = (tmp_path / "r.provenance.json").read_bytes()
    monkeypatch.setattr("time.gmtime", lambda *a: __import__("time").struct_time(
        (2026, 11, 29, 9, 30, 0, 6, 333, 0)))
    write_result(result, frame, {"scale": "paper", "git_commit": "second"})
    assert (tmp_path / "r.provenance.json").read_bytes() == side
    [note] = recreation_paths(result)
    assert note.name == "r.recreated-2026-11-29T093000Z.json"
    shown = shown_provenance(result)
    assert shown["git_commit"] == "first" and shown["corrections"][0]["value"] == "fixed"
    assert [n["git_commit"] for n in shown["recreations"]] == ["second"]
    assert shown["recreations"][0]["recreates"] == "r.provenance.json"
    write_result(result, frame, {"scale": "quick", "git_commit": "third"}, overwrite=True)
    assert read_provenance(result)["git_commit"] == "third"
    assert recreation_paths(result) == correction_paths(result) == []
    write_result(result, frame.assign(x=[1.5, 2.5]), {"scale": "quick", "git_commit": "fourth"})
    assert read_provenance(result)["git_commit"] == "fourth" and recreation_paths(result) == []


def test_a_result_whose_sidecar_describes_other_bytes_is_replaced_not_noted(tmp_path):
    result, frame = tmp_path / "r.csv", pd.DataFrame(dict(x=[1]))
    write_result(result, frame, {"scale": "paper", "git_commit": "first"})
    side = tmp_path / "r.provenance.json"
    side.write_text(json.dumps({**json.loads(side.read_text()), "csv_sha256": "0" * 64}))
    write_result(result, frame, {"scale": "paper", "git_commit": "second"})
    assert read_provenance(result)["git_commit"] == "second" and recreation_paths(result) == []


def test_a_figure_drawn_again_byte_for_byte_keeps_its_first_sidecar(tmp_path):
    """As a result: the same files from the same sources keep the first sidecar and get a note;
    other files replace the sidecar and its notes."""
    from repro.runs.results import write_figure

    result = tmp_path / "r.csv"
    write_result(result, pd.DataFrame(dict(x=[1])), {"scale": "paper", "command": "c"})
    figs = tmp_path / "fig"
    figs.mkdir()
    stem, side = figs / "r", figs / "r.provenance.json"
    files = {figs / "r.png": b"png", figs / "r.pdf": b"pdf"}
    write_figure(stem, files, [result])
    first = side.read_bytes()
    write_figure(stem, files, [result], extra={"again": True})
    assert side.read_bytes() == first
    [note] = recreation_paths(side)
    assert json.loads(note.read_text())["again"] and note.name.startswith("r.recreated-")
    write_figure(stem, {**files, figs / "r.png": b"other"}, [result])
    assert side.read_bytes() != first and recreation_paths(side) == []
