"""A decide study's store (issue 51 item 1): a study stored before added runs were stored
with their round loads, reports and judges identically; runs stored now carry their round
and reason, and loading them reads the rounds instead of judging them again.

tests/data/studies/decide_v0.tar.xz was written by the code before this change (commit
a7ae8f6): a tiny decide study (three reference seeds, one coarse radius with its
resolution control, the protocol check; round 1 added two coarse seeds and their controls),
each run in its own ``<key>.h5`` (``save_run``, no particles), the study's file
``study.h5`` (``save_study``), ``spec.json`` and ``summary.json`` (``to_summary()`` of the
study as that code reported it, strict JSON)."""

from __future__ import annotations

import concurrent.futures as cf
import io
import json
import tarfile
from pathlib import Path

import pytest

import engine
import engine.study.loop as loop_module
from engine.io.store import (
    completed_runs,
    load_study,
    save_run,
    save_study,
    stored_additions,
    strict_json,
)
from engine.study.loop import StudyLoop, plan_runs
from tests.engine.helpers import assert_same_to_round_off

ARCHIVE = Path(__file__).resolve().parents[1] / "data" / "studies" / "decide_v0.tar.xz"


@pytest.fixture(scope="module")
def old_store(tmp_path_factory):
    folder = tmp_path_factory.mktemp("decide_v0")
    with tarfile.open(ARCHIVE) as tar:
        tar.extractall(folder, filter="data")
    spec = engine.StudySpec.from_dict(json.loads((folder / "spec.json").read_text()))
    return folder, spec, (folder / "summary.json").read_text()


def _same_report(summary: dict, want: str) -> None:
    """``summary`` as strict JSON is the stored ``want`` to round-off (another CPU's BLAS
    rounds a fit's sums otherwise)."""
    assert_same_to_round_off(json.loads(strict_json(summary)), json.loads(want))


def _no_allocator(*args, **kw):
    raise AssertionError("a round was judged again: its stored runs should have been read")


def test_a_study_stored_before_rounds_were_recorded_reports_identically(old_store):
    folder, spec, want = old_store
    assert stored_additions(folder) == []  # no round stored: they are replayed
    decided: list = ["stale entry"]
    done, stale = completed_runs(spec, folder, decided)
    assert stale == [] and decided == []
    assert len(done) == len(list(folder.glob("*-s*.h5"))) == 11
    # the runs its round added are found from the outcomes, as that code found them
    added = json.loads(want)["advisor"]["adaptive"]["added_runs"]
    assert plan_runs(spec, done)[1] == added
    _same_report(StudyLoop(spec, done).result().to_summary(), want)
    # the study's own file: the same report
    _same_report(load_study(folder / "study.h5").to_summary(), want)


class _StoredRuns(cf.Executor):
    """An executor that "runs" a test by handing back its stored outcome."""

    def __init__(self, outcomes):
        self.outcomes = list(outcomes)

    def submit(self, fn, test, *args, **kw):
        fut: cf.Future = cf.Future()
        fut.set_result(next(o for o in self.outcomes if o.test == test))
        return fut


def test_added_runs_are_stored_with_their_round_and_read_back(old_store, tmp_path, monkeypatch):
    folder, spec, want = old_store
    old, _ = completed_runs(spec, folder)
    heard: dict = {}

    def on_run(key, outcome, added=None):
        heard[key] = added
        save_run(tmp_path / f"{key}.h5", outcome, keep_particles=False, added=added)

    pilot = {p.key for p in engine.plan(spec).runs}
    res = engine.run_study(spec, executor=_StoredRuns(old.values()), on_run=on_run)
    # the same runs give the same report, the loop as the replay
    _same_report(res.to_summary(), want)
    added = list(res.report.adaptive.added_runs)
    assert {k for k, a in heard.items() if a is None} == pilot
    for a in added:
        assert a in heard[a["run"]] and {b["round"] for b in heard[a["run"]]} == {a["round"]}
    # each added run's file holds its round and reason; loading reads them, judging no round
    assert stored_additions(tmp_path) == added
    monkeypatch.setattr(loop_module, "allocate_round", _no_allocator)
    decided: list = []
    done, stale = completed_runs(spec, tmp_path, decided)
    assert decided == added and not stale and set(done) == set(old)
    again = StudyLoop(spec, done, decided)
    assert again.added == added
    _same_report(again.result().to_summary(), want)
    # the study's file keeps them too
    save_study(tmp_path / "study.h5", "s", res)
    _same_report(load_study(tmp_path / "study.h5").to_summary(), want)


def test_stored_rounds_are_taken_as_decided_and_others_are_not(old_store, tmp_path):
    _, spec, want = old_store
    # the rounds a store holds are the study's runs before any outcome is known
    added = json.loads(want)["advisor"]["adaptive"]["added_runs"]
    loop = StudyLoop(spec, {}, added)
    assert loop.added == added and loop.stopped is None
    assert [p.key for p in loop.ask()][-len(added) :] == [a["run"] for a in added]
    assert loop.round_of("ctl-r3.1mm-s4") == added and loop.round_of("ref-s1") is None
    # a store whose additions name no run of this study's plan, or skip a round: the
    # study's rounds are judged from its outcomes instead
    other = [{"run": "r9mm-paper-s4", "round": 1, "kind": "coarse", "reason": "x"}]
    assert StudyLoop(spec, {}, other).decided == {}
    gap = [{"run": "ref-s4", "round": 2, "kind": "reference", "reason": "x"}]
    assert StudyLoop(spec, {}, gap).decided == {}
    with pytest.raises(ValueError, match="ref-s9"):
        save_run(tmp_path / "ref-s9.h5", "failed", added=gap)


def test_the_stored_report_reads_back_typed_and_draws_the_same_figures(old_store):
    # the summary's "advisor" JSON, read as a StudyReport, writes the same JSON back, and
    # the report figures drawn from it are the live report's, byte for byte
    pytest.importorskip("matplotlib")
    from engine.io.figures import figure, study_plot_data
    from engine.study.report import StudyReport

    folder, _, want = old_store
    stored = StudyReport.from_dict(json.loads(want)["advisor"])
    assert strict_json(stored.to_dict()) == strict_json(json.loads(want)["advisor"])
    live = load_study(folder / "study.h5")
    # the same records but where strict JSON nulls a non-finite number (an infinite dof)
    assert_same_to_round_off(
        json.loads(strict_json(stored.to_dict())), json.loads(strict_json(live.report.to_dict()))
    )
    assert stored.rules == live.report.rules and stored.adaptive == live.report.adaptive
    runs, table, report = study_plot_data(live)

    def png(kind, rep):
        buf = io.BytesIO()
        figure(kind, runs, table, rep).savefig(buf, format="png", metadata={"Software": None})
        return buf.getvalue()

    for kind in ("error_vs_runtime", "resolution"):
        assert png(kind, stored) == png(kind, report), kind


def test_the_stored_verdicts_read_in_words_with_an_infinite_dof(old_store):
    # strict JSON stores an infinite dof (both spreads zero) as null: the words of every
    # stored metric read it (the study page raised TypeError on decide_v0's strength)
    from engine.study.reasons import describe, shown

    _, _, want = old_store
    metrics = [
        m
        for v in json.loads(want)["advisor"]["verdicts"]
        for m in v.get("metrics", [])
        if m.get("interval") is not None
    ]
    assert any(m["df"] is None for m in metrics)  # the case this test is for
    for m in metrics:
        text = describe(m)
        assert isinstance(text, str) and m["metric"] in text
        assert isinstance(shown(m)[2], str)
        if m["df"] is None and m["verdict"] != "differs":
            assert "infinite dof" in text
