"""Every status change of studies and runs, as conditional UPDATEs.

Each change names the status it leaves; the UPDATE matches only a row still in that status
(and, for a worker, still owned by that worker), so two workers cannot claim one study, a
cancelled study cannot be marked succeeded, and a worker whose study was taken over after a
missed heartbeat cannot overwrite the new owner's work. A pair not in :data:`ALLOWED` is
refused with :class:`IllegalTransition` before it reaches the database. A study's change and
its runs' changes commit together.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import delete, func, select, update
from sqlmodel import Session

from .models import TERMINAL, Run, Status, Study, utcnow

Q, R, S, F, C = Status.queued, Status.running, Status.succeeded, Status.failed, Status.cancelled

#: The legal (from, to) pairs of a study.
ALLOWED = frozenset({(Q, R), (Q, C), (R, S), (R, F), (R, C), (R, Q)})
#: Those of a run: also succeeded -> queued, for a stored run that must run again.
RUN_ALLOWED = ALLOWED | {(S, Q)}

#: What a claim resets: the progress and outcome of an earlier attempt.
_FRESH = {
    "finished_at": None,
    "progress": 0.0,
    "run_index": None,
    "current_run": None,
    "current_stage": None,
    "error": None,
    "finishes_at": None,
}


class IllegalTransition(ValueError):
    """A status change that no study (or run) may make, e.g. succeeded -> running."""


class QueueFull(RuntimeError):
    """A submission beyond the bound on queued or running studies (in all, or of its token)."""

    def __init__(self, active: int, limit: int, whose: str):
        self.active, self.limit, self.whose = active, limit, whose
        super().__init__(f"{active} studies {whose} are queued or running; the limit is {limit}")


def _check(src: Status, dst: Status, allowed: frozenset = ALLOWED, what: str = "study") -> None:
    if (src, dst) not in allowed:
        raise IllegalTransition(f"a {what} cannot go from {src.value} to {dst.value}")


def _move(session: Session, study_id: uuid.UUID, src: Status, dst: Status, *where, **values):
    _check(src, dst)
    stmt = update(Study).where(Study.id == study_id, Study.status == src, *where)
    return session.execute(stmt.values(status=dst, **values)).rowcount == 1


def _runs(session: Session, study_id: uuid.UUID, src: tuple, dst: Status, *where, **values):
    for s in src:
        _check(s, dst, RUN_ALLOWED, "run")
    stmt = update(Run).where(Run.study_id == study_id, Run.status.in_(src), *where)
    session.execute(stmt.values(status=dst, **values))


def move(session: Session, study_id: uuid.UUID, src: Status, dst: Status, *where, **values):
    """Change the study from ``src`` to ``dst`` if it is still in ``src`` (and matches the
    ``where`` conditions), setting ``values`` too. Returns whether the row changed."""
    changed = _move(session, study_id, src, dst, *where, **values)
    session.commit()
    return changed


# ---------------------------------------------------------------------------------- API side
def submit(
    session: Session,
    study: Study,
    runs: list[Run],
    max_active: int,
    max_active_per_owner: int,
    check: Callable[[Session], None] | None = None,
) -> Study:
    """Insert a new queued study and its queued runs, unless that makes more than
    ``max_active`` queued or running studies in all, or ``max_active_per_owner`` of the
    study's owner (:class:`QueueFull`, nothing stored), or ``check(session)`` raises (e.g.
    the storage quota; nothing stored, the exception goes on). The counts are taken after
    the insert, in its transaction: SQLite lets one writer in at a time, so two submissions
    cannot both slip under a bound."""
    study.status = Q
    session.add(study)
    session.flush()  # the study row first: the runs refer to it (and the write lock is ours)
    active = select(func.count()).select_from(Study).where(Study.status.in_((Q, R)))
    for count, limit, whose in (
        (session.execute(active).scalar_one(), max_active, "in all"),
        (
            session.execute(active.where(Study.owner == study.owner)).scalar_one(),
            max_active_per_owner,
            "of this token",
        ),
    ):
        if count > limit:
            session.rollback()
            raise QueueFull(count - 1, limit, whose)
    if check is not None:
        try:
            check(session)
        except BaseException:
            session.rollback()
            raise
    for run in runs:
        run.study_id, run.status = study.id, Q
    session.add_all(runs)
    session.commit()
    session.refresh(study)
    return study


def request_cancel(session: Session, study_id: uuid.UUID) -> bool:
    """Cancel a queued study at once, or ask the worker of a running one to stop. Returns
    False when the study is already finished (nothing to cancel)."""
    if _move(session, study_id, Q, C, finished_at=utcnow(), error="cancelled before it ran"):
        _runs(session, study_id, (Q,), C)
        session.commit()
        return True
    stmt = update(Study).where(Study.id == study_id, Study.status == R)
    asked = session.execute(stmt.values(cancel_requested=True)).rowcount == 1
    session.commit()
    return asked


def remove(session: Session, study_id: uuid.UUID) -> bool:
    """Delete a finished study and its runs. Returns False unless it was finished."""
    stmt = delete(Study).where(Study.id == study_id, Study.status.in_(TERMINAL))
    gone = session.execute(stmt).rowcount == 1
    if gone:
        session.execute(delete(Run).where(Run.study_id == study_id))
    session.commit()
    return gone


def child_of(session: Session, job_id: uuid.UUID) -> uuid.UUID | None:
    """The study a calibration queued when it ended (``parent_id``), if any."""
    stmt = select(Study.id).where(Study.parent_id == job_id).limit(1)
    return session.execute(stmt).scalar()


def owner_and_name(session: Session, job_id: uuid.UUID) -> tuple[str, str | None]:
    """The owner and name of a job."""
    row = session.execute(select(Study.owner, Study.name).where(Study.id == job_id)).one()
    return row[0], row[1]


# ------------------------------------------------------------------------------- worker side
def claim_next(session: Session, worker_id: str) -> Study | None:
    """Claim the oldest queued study for ``worker_id`` (attempts + 1); None if none is queued.
    When another worker takes the candidate first, the next one is tried."""
    while True:
        oldest = select(Study.id).where(Study.status == Q).order_by(Study.created_at).limit(1)
        candidate = session.execute(oldest).scalar()
        if candidate is None:
            return None
        now = utcnow()
        if move(
            session,
            candidate,
            Q,
            R,
            worker_id=worker_id,
            attempts=Study.attempts + 1,
            started_at=now,
            heartbeat_at=now,
            **_FRESH,
        ):
            return session.get(Study, candidate, populate_existing=True)


@dataclass(frozen=True)
class Beat:
    """What a heartbeat learns: does the worker still own the study, was a cancel asked."""

    owned: bool
    cancel_requested: bool


def heartbeat(session: Session, study_id: uuid.UUID, worker_id: str, **progress) -> Beat:
    """Record liveness and ``progress`` (progress, run_index, current_run, current_stage,
    finishes_at) of the study ``worker_id`` runs. Not a status change, but owner-checked the
    same way."""
    stmt = update(Study).where(
        Study.id == study_id, Study.status == R, Study.worker_id == worker_id
    )
    owned = session.execute(stmt.values(heartbeat_at=utcnow(), **progress)).rowcount == 1
    cancel = session.execute(select(Study.cancel_requested).where(Study.id == study_id)).scalar()
    session.commit()
    return Beat(owned, bool(cancel))


def add_runs(session: Session, study_id: uuid.UUID, runs: list[dict]) -> int:
    """Rows for runs a ``decide`` study added (each a dict of key, radius, rule, seed,
    particles), after the study's other runs; keys it already has are skipped. Returns how
    many were added; the study's ``n_runs`` follows."""
    have = set(session.execute(select(Run.key).where(Run.study_id == study_id)).scalars())
    position = len(have)
    new = [r for r in runs if r["key"] not in have]
    for r in new:
        session.add(Run(study_id=study_id, position=position, **r))
        position += 1
    if new:
        session.execute(update(Study).where(Study.id == study_id).values(n_runs=position))
    session.commit()
    return len(new)


def run_started(session: Session, study_id: uuid.UUID, key: str) -> None:
    """Mark run ``key`` running."""
    _runs(session, study_id, (Q,), R, Run.key == key, started_at=utcnow())
    session.commit()


def run_finished(
    session: Session,
    study_id: uuid.UUID,
    key: str,
    error: str | None = None,
    steps: int | None = None,
    wall_time: float | None = None,
) -> None:
    """Mark run ``key`` succeeded (its results are stored) or failed with ``error``."""
    dst = S if error is None else F
    _runs(session, study_id, (Q,), R, Run.key == key)  # a run reported only at its end
    _runs(
        session,
        study_id,
        (R,),
        dst,
        Run.key == key,
        finished_at=utcnow(),
        error=error,
        steps=steps,
        wall_time=wall_time,
    )
    session.commit()


def succeed(
    session: Session, study_id: uuid.UUID, worker_id: str, run_time: float, table: list[dict]
) -> bool:
    """Running -> succeeded, with each run's steps and wall time from the result table."""
    now = utcnow()
    if not _move(
        session,
        study_id,
        R,
        S,
        Study.worker_id == worker_id,
        progress=1.0,
        finished_at=now,
        run_time=run_time,
        current_stage=None,
    ):
        session.rollback()
        return False
    _runs(session, study_id, (Q,), R)  # a run the engine never reported on
    _runs(session, study_id, (R,), S, finished_at=now)
    for row in table:
        stmt = update(Run).where(Run.study_id == study_id, Run.key == row["run"])
        session.execute(stmt.values(steps=int(row["steps"]), wall_time=float(row["wall_time"])))
    session.commit()
    return True


def fail(
    session: Session,
    study_id: uuid.UUID,
    worker_id: str,
    error: str,
    run_time: float | None = None,
    run_key: str | None = None,
) -> bool:
    """Running -> failed with ``error``; the failing run (``run_key``) is marked failed and
    the runs that did not finish cancelled."""
    now = utcnow()
    if not _move(
        session,
        study_id,
        R,
        F,
        Study.worker_id == worker_id,
        error=error,
        finished_at=now,
        run_time=run_time,
    ):
        session.rollback()
        return False
    if run_key is not None:
        _runs(session, study_id, (Q,), R, Run.key == run_key)
        _runs(session, study_id, (R,), F, Run.key == run_key, error=error, finished_at=now)
    _runs(session, study_id, (Q, R), C)
    session.commit()
    return True


def cancelled(session: Session, study_id: uuid.UUID, worker_id: str, run_time: float) -> bool:
    """Running -> cancelled, after the worker stopped on a cancel request."""
    if not _move(
        session,
        study_id,
        R,
        C,
        Study.worker_id == worker_id,
        finished_at=utcnow(),
        run_time=run_time,
        error="cancelled while running",
    ):
        session.rollback()
        return False
    _runs(session, study_id, (Q, R), C)
    session.commit()
    return True


def release(session: Session, study_id: uuid.UUID, worker_id: str) -> bool:
    """Running -> queued when a worker shuts down cleanly; the attempt is not counted."""
    if not _move(
        session,
        study_id,
        R,
        Q,
        Study.worker_id == worker_id,
        worker_id=None,
        attempts=func.max(Study.attempts - 1, 0),
        heartbeat_at=None,
    ):
        session.rollback()
        return False
    _runs(session, study_id, (R,), Q, started_at=None, finished_at=None)
    session.commit()
    return True


def recover_stale(
    session: Session,
    stale_before: datetime,
    max_attempts: int,
    advanced: Callable[[uuid.UUID, datetime], bool] | None = None,
) -> list[tuple[uuid.UUID, Status]]:
    """Requeue every running study whose heartbeat is older than ``stale_before`` (its
    worker died); fail it once ``max_attempts`` claims in a row died without progress;
    cancel it if a cancel was requested. An attempt made progress when it finished a run,
    or when ``advanced(study_id, started_at)`` says it wrote a newer checkpoint of its run
    in flight: only a run that brings its worker down at the same point again and again
    (a poison run) uses up the attempts, not a worker killed from outside now and then.
    Returns (id, new status) of each study recovered."""
    cols = (Study.id, Study.worker_id, Study.attempts, Study.cancel_requested, Study.heartbeat_at)
    rows = session.execute(
        select(*cols).where(Study.status == R, Study.heartbeat_at < stale_before)
    ).all()
    out = []
    for sid, worker, attempts, cancel, beat in rows:
        last = f"worker {worker} stopped sending heartbeats (last {beat:%Y-%m-%d %H:%M:%S} UTC)"
        started = session.execute(select(Study.started_at).where(Study.id == sid)).scalar()
        finished = session.execute(
            select(func.count())
            .select_from(Run)
            .where(Run.study_id == sid, Run.status.in_((S, F)), Run.finished_at >= started)
        ).scalar()
        current = session.execute(select(Study.current_run).where(Study.id == sid)).scalar()
        if finished or (advanced is not None and started is not None and advanced(sid, started)):
            # an interruption, not a failure: this attempt finished runs, which are stored,
            # or moved its run's checkpoint on; only claims in a row that do neither count
            # towards max_attempts
            attempts = 0
        if cancel:
            dst, values = C, {"error": f"cancelled; {last}", "finished_at": utcnow()}
        elif attempts >= max_attempts:
            poison = (
                f"; run {current} was interrupted each time at the same point (a poison run)"
                if current
                else ""
            )
            dst, values = (
                F,
                {
                    "error": f"gave up after {attempts} attempts that finished no run and "
                    f"advanced no checkpoint: {last}"
                    f"{poison}",
                    "finished_at": utcnow(),
                },
            )
        else:
            dst, values = Q, {"worker_id": None, "heartbeat_at": None, "attempts": attempts}
        # the same worker and heartbeat as read: a worker that beat meanwhile keeps its study
        same = (Study.worker_id == worker, Study.heartbeat_at == beat)
        if _move(session, sid, R, dst, *same, **values):
            if dst is Q:  # stored runs stay succeeded: a resumed study runs only the others
                _runs(session, sid, (R,), Q, started_at=None, finished_at=None)
            else:
                _runs(session, sid, (Q, R), C)
            out.append((sid, dst))
        session.commit()
    return out
