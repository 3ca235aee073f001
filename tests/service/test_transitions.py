"""The transitions module: legal changes happen once, illegal ones are refused."""

from __future__ import annotations

from datetime import timedelta

import pytest
from sqlmodel import Session, select

from service import transitions
from service.db import engine_for
from service.models import Run, Status, Study, utcnow
from service.transitions import IllegalTransition


@pytest.fixture
def session(settings):
    with Session(engine_for(settings)) as s:
        yield s


def new_study(session: Session, n_runs: int = 2) -> Study:
    runs = [
        Run(study_id=None, key=f"run{i}", position=i, radius=1e-3, rule="r", seed=1, particles=10)
        for i in range(n_runs)
    ]
    return transitions.submit(session, Study(spec={}, n_runs=n_runs), runs, 1000, 1000)


def status(session: Session, study: Study) -> Status:
    session.expire_all()
    return session.get(Study, study.id).status


def run_statuses(session: Session, study: Study) -> list[Status]:
    session.expire_all()
    return [
        r.status
        for r in session.exec(select(Run).where(Run.study_id == study.id).order_by(Run.position))
    ]


@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    "src,dst",
    [
        (Status.succeeded, Status.running),
        (Status.queued, Status.succeeded),
        (Status.queued, Status.failed),
        (Status.cancelled, Status.queued),
        (Status.failed, Status.running),
        (Status.running, Status.running),
    ],
)
def test_illegal_pairs_are_refused_before_the_database(session, src, dst):
    study = new_study(session)
    with pytest.raises(IllegalTransition):
        transitions.move(session, study.id, src, dst)
    assert status(session, study) is Status.queued


@pytest.mark.timeout(30)
def test_a_study_is_claimed_once_and_only_by_its_owner_finished(session):
    study = new_study(session)
    claimed = transitions.claim_next(session, "w1")
    assert claimed.id == study.id and claimed.attempts == 1 and claimed.worker_id == "w1"
    assert transitions.claim_next(session, "w2") is None
    # another worker cannot finish, fail or release it
    assert not transitions.succeed(session, study.id, "w2", 1.0, [])
    assert not transitions.fail(session, study.id, "w2", "boom")
    assert not transitions.release(session, study.id, "w2")
    assert not transitions.heartbeat(
        session, study.id, "w2", progress=0.5, run_index=0, current_run="run0", current_stage="fill"
    ).owned
    assert status(session, study) is Status.running
    transitions.run_started(session, study.id, "run0")
    transitions.run_finished(session, study.id, "run0", steps=5, wall_time=0.1)
    transitions.run_started(session, study.id, "run1")
    assert run_statuses(session, study) == [Status.succeeded, Status.running]
    table = [
        {"run": "run0", "steps": 5, "wall_time": 0.1},
        {"run": "run1", "steps": 7, "wall_time": 0.2},
    ]
    assert transitions.succeed(session, study.id, "w1", 2.0, table)
    assert status(session, study) is Status.succeeded
    assert run_statuses(session, study) == [Status.succeeded, Status.succeeded]
    # a finished study stays finished
    assert not transitions.succeed(session, study.id, "w1", 2.0, table)
    assert not transitions.fail(session, study.id, "w1", "late")
    assert not transitions.request_cancel(session, study.id)
    assert status(session, study) is Status.succeeded


@pytest.mark.timeout(30)
def test_runs_finish_one_by_one_and_a_failed_run_keeps_its_error(session):
    study = new_study(session)
    transitions.claim_next(session, "w1")
    # a run reported only when it ends (a task on a pool) goes queued -> running -> done
    transitions.run_finished(session, study.id, "run1", error="InstabilityError: boom")
    transitions.run_finished(session, study.id, "run0", steps=3, wall_time=0.5)
    assert run_statuses(session, study) == [Status.succeeded, Status.failed]
    assert transitions.succeed(session, study.id, "w1", 1.0, [])
    assert run_statuses(session, study) == [Status.succeeded, Status.failed]


@pytest.mark.timeout(30)
def test_cancel_queued_is_immediate_and_running_is_a_request(session):
    queued = new_study(session)
    assert transitions.request_cancel(session, queued.id)
    assert status(session, queued) is Status.cancelled
    assert run_statuses(session, queued) == [Status.cancelled] * 2
    assert transitions.claim_next(session, "w1") is None  # a cancelled study is never claimed
    running = new_study(session)
    assert transitions.claim_next(session, "w1").id == running.id
    assert transitions.request_cancel(session, running.id)
    assert status(session, running) is Status.running
    assert transitions.heartbeat(
        session,
        running.id,
        "w1",
        progress=0.1,
        run_index=0,
        current_run="run0",
        current_stage="fill",
    ).cancel_requested
    assert transitions.cancelled(session, running.id, "w1", 1.0)
    assert status(session, running) is Status.cancelled


@pytest.mark.timeout(30)
def test_release_requeues_without_counting_the_attempt(session):
    study = new_study(session)
    transitions.claim_next(session, "w1")
    transitions.run_started(session, study.id, "run1")
    assert transitions.release(session, study.id, "w1")
    session.expire_all()
    row = session.get(Study, study.id)
    assert row.status is Status.queued and row.attempts == 0 and row.worker_id is None
    assert run_statuses(session, study) == [Status.queued] * 2


@pytest.mark.timeout(30)
def test_stale_studies_are_requeued_then_failed_after_max_attempts(session):
    study = new_study(session)
    for attempt in (1, 2):
        assert transitions.claim_next(session, f"w{attempt}").attempts == attempt
        # fresh heartbeat: not stale
        assert transitions.recover_stale(session, utcnow() - timedelta(seconds=30), 2) == []
        assert transitions.recover_stale(session, utcnow() + timedelta(seconds=1), 2) == [
            (study.id, Status.queued if attempt == 1 else Status.failed)
        ]
    session.expire_all()
    row = session.get(Study, study.id)
    assert row.status is Status.failed and row.attempts == 2
    assert "gave up after 2 attempts" in row.error and "w2" in row.error
    # the dead worker cannot write its result afterwards
    assert not transitions.succeed(session, study.id, "w2", 1.0, [])


@pytest.mark.timeout(30)
def test_interruptions_that_finish_runs_are_not_failures_a_poison_run_is(session):
    study = new_study(session)
    later = timedelta(seconds=1)
    # the first attempt finishes run0, then its worker dies: requeued, the attempt not counted
    assert transitions.claim_next(session, "w1").attempts == 1
    transitions.run_started(session, study.id, "run0")
    transitions.run_finished(session, study.id, "run0", steps=1, wall_time=1.0)
    transitions.run_started(session, study.id, "run1")
    assert transitions.recover_stale(session, utcnow() + later, 1) == [(study.id, Status.queued)]
    # the stored run stays succeeded; the interrupted one is queued again
    assert run_statuses(session, study) == [Status.succeeded, Status.queued]
    assert transitions.claim_next(session, "w2").attempts == 1
    # the second attempt dies on run1 without finishing it: with max_attempts 1, run1 is a
    # poison run and the study is failed with that reason
    transitions.run_started(session, study.id, "run1")
    transitions.heartbeat(
        session, study.id, "w2", progress=0.6, run_index=1, current_run="run1", current_stage="fill"
    )
    assert transitions.recover_stale(session, utcnow() + later, 1) == [(study.id, Status.failed)]
    session.expire_all()
    row = session.get(Study, study.id)
    assert "finished no run" in row.error and "run run1 was interrupted" in row.error
    assert run_statuses(session, study) == [Status.succeeded, Status.cancelled]


@pytest.mark.timeout(30)
def test_remove_only_finished_studies(session):
    study = new_study(session)
    assert not transitions.remove(session, study.id)
    transitions.request_cancel(session, study.id)
    assert transitions.remove(session, study.id)
    session.expire_all()
    assert session.get(Study, study.id) is None
    assert session.exec(select(Run).where(Run.study_id == study.id)).all() == []


@pytest.mark.timeout(30)
def test_only_attempts_without_progress_count_towards_the_poison_rule(session):
    """An attempt that moved its run's checkpoint on is an interruption; one that died at
    the same point (no newer checkpoint, no finished run) counts; max_attempts of those in a
    row fail the study as a poison run."""
    study = new_study(session)
    later = timedelta(seconds=1)
    moved = {"value": True}
    seen = []

    def advanced(sid, since):
        seen.append((sid, since))
        return moved["value"]

    for attempt in range(5):  # killed from outside five times, progress each time
        assert transitions.claim_next(session, f"w{attempt}").attempts == 1
        transitions.run_started(session, study.id, "run0")
        assert transitions.recover_stale(session, utcnow() + later, 2, advanced) == [
            (study.id, Status.queued)
        ]
    assert seen and all(sid == study.id for sid, _ in seen)
    moved["value"] = False  # now it dies at the same point every time
    assert transitions.claim_next(session, "w5").attempts == 1
    assert transitions.recover_stale(session, utcnow() + later, 2, advanced) == [
        (study.id, Status.queued)
    ]
    assert transitions.claim_next(session, "w6").attempts == 2
    transitions.heartbeat(
        session,
        study.id,
        "w6",
        progress=0.3,
        run_index=0,
        current_run="run0",
        current_stage="consolidation",
    )
    assert transitions.recover_stale(session, utcnow() + later, 2, advanced) == [
        (study.id, Status.failed)
    ]
    session.expire_all()
    row = session.get(Study, study.id)
    assert "advanced no checkpoint" in row.error
    assert "run run0 was interrupted each time at the same point" in row.error
