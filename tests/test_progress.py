"""One progress display that only moves forward (issue 53 item 3): across a ``decide`` study
whose round adds runs, the engine's fraction and the display's never decrease, the added
runs are announced (with the runs done of the new total) before any of them runs, the time
left is shown; ``demscale job`` shows the service's progress the same way, a line per event
off a terminal; the embedded worker logs to a file under the data folder, not onto the
display. The study: tests/test_cli.py's two-run cohesive TINY with one round that adds
reference seeds (about 10 s)."""

from __future__ import annotations

import io
import itertools
import re
import time
from datetime import timedelta

import pytest

pytest.importorskip("rich")
from rich.console import Console

import engine
from demscale.commands.job import _follow
from demscale.progress import StudyBars
from engine.study.plan import most_added, plan_runs
from engine.study.run import ADDED, Eta, duration_words
from tests.test_cli import TINY

#: TINY judged in one round that adds seeds: no controls, no protocol check (two planned
#: runs; the round adds the two reference seeds a one-seed reference lacks).
DECIDE = {
    **TINY,
    # at the default protocol's inertial number: runs long enough (seconds) for the display
    # to have a time left to show before the study ends
    "reference": {**TINY["reference"], "inertial_number": 5e-4},
    "controls": False,
    "protocol_check": False,
    "decide": True,
    "max_seeds": 3,
    "max_reference_seeds": 3,
    "rounds": 1,
}
PERCENT = re.compile(r"^\[\s*([\d.]+) %\]")


def never_back(xs) -> bool:
    return all(b >= a for a, b in itertools.pairwise(xs))


def percents(lines: list[str]) -> list[float]:
    return [float(m[1]) for m in map(PERCENT.match, lines) if m]


def test_a_decide_study_s_progress_never_goes_back(tmp_path):
    spec = engine.StudySpec.from_dict(DECIDE)
    study = engine.plan(spec)
    out = io.StringIO()
    console = Console(file=out, width=200)  # not a terminal: a line per event
    assert not console.is_terminal
    reports = []
    with StudyBars(list(study.runs), console) as bars:

        def progress(p):
            reports.append(p)
            bars.update(p)

        result = engine.run_study(study, progress=progress, on_run=bars.finished)
    added = [a["run"] for a in result.report.adaptive.added_runs]
    assert added, "the round added no run: the case is not made"

    # the engine's fraction never goes back, and moves on through the added runs
    fractions = [p.fraction for p in reports]
    assert never_back(fractions), fractions
    (announce,) = [i for i, p in enumerate(reports) if p.stage == ADDED]
    at_added = reports[announce]
    assert at_added.n_runs == len(study.runs) + len(added) and at_added.added == len(added)
    assert at_added.runs_done == len(study.runs)
    assert all(a in at_added.message for a in added)
    # the reserve: the pilot never reaches the whole; the added runs move the bar on
    assert at_added.fraction < 0.95 and fractions[-1] - at_added.fraction > 0.1
    # nothing of an added run ran before its announcement
    assert not {p.run_key for p in reports[:announce]} & set(added)

    # the display: a line per event, percentages that never go back, the added runs said
    # before their first line, runs done of the total, the time left
    lines = out.getvalue().splitlines()
    shown = percents(lines)
    assert shown and never_back(shown), lines
    said = next(i for i, ln in enumerate(lines) if "adds" in ln and "until decided" in ln)
    assert (
        f"{len(study.runs)}/{len(study.runs) + len(added)} runs done ({len(added)} added)"
        in (lines[said])
    )
    first_run_line = min(i for i, ln in enumerate(lines) for k in added if f"{k} done" in ln)
    assert said < first_run_line, lines
    assert any(re.search(r"ETA \d", ln) for ln in lines), lines
    n_runs = len(study.runs) + len(added)
    assert len(lines) <= 2 * n_runs + 3, lines  # events, not a line per sample
    assert all(f"{k} done:" in out.getvalue() for k in added)


def test_the_reserve_of_a_decide_study_is_what_its_rounds_may_add():
    spec = engine.StudySpec.from_dict(DECIDE)
    study = engine.plan(spec)
    planned, added, stopped = plan_runs(study, {})
    reserve = most_added(spec, planned, added, stopped)
    known = sum(p.particle_steps for p in planned)
    assert study.estimated_particle_steps() == pytest.approx(known + reserve)
    # every variant and the reference filled to their caps (3 seeds of 1 each: 2 more)
    assert reserve == pytest.approx(2 * known)
    assert most_added(spec, planned, added, "every verdict decided") == 0.0
    undecided = engine.StudySpec.from_dict({**DECIDE, "decide": False})
    assert most_added(undecided, planned, [], None) == 0.0
    budget = engine.StudySpec.from_dict({**DECIDE, "budget": 0.5 * known})
    assert most_added(budget, planned, [], None) == pytest.approx(0.5 * known)


def test_the_time_left_and_its_words():
    now = [0.0]
    eta = Eta(lambda: now[0])
    assert eta(0.1) is None  # the first report starts the clock
    now[0] = 2.0
    assert eta(0.2) is None  # not yet min_seconds
    now[0] = 10.0
    assert eta(0.3) == pytest.approx(0.7 * 10.0 / 0.2)
    assert eta(1.0) == 0.0
    assert [duration_words(s) for s in (None, 4.6, 200, 4000)] == [
        "-",
        "5 s",
        "3 min 20 s",
        "1 h 06 min",
    ]


class FakeAPI:
    """GET /studies/{id} answers of a decide study, one per poll."""

    def __init__(self, answers):
        self.answers = list(answers)

    def get(self, url):
        answer = self.answers.pop(0) if len(self.answers) > 1 else self.answers[0]
        return type("R", (), {"raise_for_status": lambda self: self, "json": lambda self: answer})()


def api_state(progress, status, done, keys, added=0, run=None, eta=None):
    runs = [
        {"key": k, "status": "succeeded" if i < done else "queued", "error": None, "wall_time": 1.5}
        for i, k in enumerate(keys)
    ]
    return {
        "status": status,
        "progress": progress,
        "n_runs": len(keys),
        "runs_added": added,
        "runs_done": done,
        "current_run": run,
        "current_stage": "consolidation" if run else None,
        "eta": eta,
        "runs": runs,
    }


def test_demscale_job_shows_the_service_s_progress_a_line_per_event():
    pilot = ["ref-s1", "r3mm-paper-s1"]
    more = ["ref-s2", "ref-s3"]
    answers = [
        api_state(0.0, "queued", 0, pilot),
        api_state(0.2, "running", 0, pilot, run="ref-s1", eta=60.0),
        api_state(0.5, "running", 1, pilot, run="r3mm-paper-s1", eta=40.0),
        api_state(0.55, "running", 2, pilot + more, added=2, run="ref-s2", eta=30.0),
        api_state(0.54, "running", 2, pilot + more, added=2, run="ref-s2", eta=29.0),  # late
        api_state(0.8, "running", 3, pilot + more, added=2, run="ref-s3", eta=10.0),
        api_state(1.0, "succeeded", 4, pilot + more, added=2),
    ]
    out = io.StringIO()
    final = _follow(FakeAPI(answers), "x", Console(file=out, width=200), poll=0.0)
    assert final["status"] == "succeeded"
    lines = out.getvalue().splitlines()
    shown = percents(lines)
    assert never_back(shown), lines
    said = next(i for i, ln in enumerate(lines) if "2 runs added until decided" in ln)
    assert "ref-s2, ref-s3" in lines[said] and "2/4 runs done (2 added)" in lines[said]
    assert said < next(i for i, ln in enumerate(lines) if "ref-s2 done" in ln)
    assert any("ETA 40 s" in ln for ln in lines) and "succeeded · 4/4 runs done" in lines[-1]
    assert len(lines) == len(set(lines)) <= 12, lines


def test_the_api_says_the_time_left_and_the_runs_added():
    pytest.importorskip("fastapi")
    import uuid

    from service.models import Status, Study, utcnow
    from service.routes.studies import public

    row = Study(
        id=uuid.uuid4(),
        spec={"reference": {}},
        plan={"runs": [{}, {}]},
        status=Status.running,
        n_runs=4,
        finishes_at=utcnow() + timedelta(seconds=100),
    )
    made = public(row)
    assert made.runs_added == 2 and made.eta == pytest.approx(100.0, abs=2.0)
    assert made.model_dump()["eta"] == pytest.approx(100.0, abs=2.0)
    row.status = Status.succeeded
    assert public(row).eta is None


def test_the_embedded_worker_logs_to_a_file_under_the_data_folder(tmp_path):
    pytest.importorskip("fastapi")
    from service.embedded import EmbeddedWorker
    from service.settings import Settings

    settings = Settings(
        data_dir=tmp_path / "data",
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}",
        poll_interval=0.1,
        api_token="test-token-0123456789abcdef",
    )
    worker = EmbeddedWorker(settings)
    worker.start()
    try:
        log = settings.data_dir / "logs" / "worker.log"
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and "started" not in (
            log.read_text() if log.exists() else ""
        ):
            time.sleep(0.1)
        assert "started" in log.read_text()
    finally:
        worker.stop()
    assert Settings(data_dir=tmp_path, worker_log="-").worker_log_path is None
