"""SQLModel classes of the job store, one family per resource (base, table, public).

The queue holds jobs of two kinds in one table (``study``), as procrastinate keeps every
task in one jobs table: a *study* is one submitted :class:`engine.StudySpec`, its runs the
planned runs of the spec (the reference of each seed, then every coarse radius x rule); a
*calibration* is one submitted :func:`engine.calibrate` request, its runs the parameter sets
it has run (a row each as it finishes). Both share the queue, its quotas, claims,
heartbeats, cancel and resume. A study a calibration submitted when it ended
(``then_study``) names it in ``parent_id``. Times are UTC.
"""

from __future__ import annotations

import uuid
from datetime import datetime, timezone
from enum import Enum

from pydantic import computed_field, field_validator
from sqlalchemy import JSON, Column, ForeignKey, Uuid
from sqlmodel import Field, SQLModel


class Status(str, Enum):
    """Status of a study or a run."""

    queued = "queued"
    running = "running"
    succeeded = "succeeded"
    failed = "failed"
    cancelled = "cancelled"


#: Statuses a study never leaves.
TERMINAL = frozenset({Status.succeeded, Status.failed, Status.cancelled})


class Kind(str, Enum):
    """What a job of the queue is."""

    study = "study"
    calibration = "calibration"


def _as_utc(value: datetime | None) -> datetime | None:
    """SQLite keeps no time zone: times come back naive, and are UTC."""
    if value is not None and value.tzinfo is None:
        return value.replace(tzinfo=timezone.utc)
    return value


def utcnow() -> datetime:
    """Now, UTC (time-zone aware)."""
    return datetime.now(timezone.utc)


# ------------------------------------------------------------------------------------ study
#: Longest study name [characters].
NAME_MAX_LENGTH = 100


class StudyBase(SQLModel):
    """Fields a client chooses."""

    name: str | None = Field(default=None, max_length=NAME_MAX_LENGTH, description="A label.")


class Study(StudyBase, table=True):
    """A study row: the spec, its status and the worker's bookkeeping."""

    id: uuid.UUID = Field(default_factory=uuid.uuid4, primary_key=True)
    kind: Kind = Field(default=Kind.study, index=True, description="A study or a calibration.")
    #: The calibration whose ``then_study`` submitted this study (None: submitted by a client).
    parent_id: uuid.UUID | None = Field(default=None, index=True)
    owner: str = Field(
        default="",
        index=True,
        max_length=16,
        description="Fingerprint of the token that submitted it (service.settings.fingerprint).",
    )
    #: A study's normalised spec (engine.StudySpec.to_dict); a calibration's normalised
    #: request (service.admission.admit_calibration).
    spec: dict = Field(sa_column=Column(JSON, nullable=False))
    #: The engine's plan of the spec (engine.StudyPlan.to_dict), made once at submission: the
    #: worker runs it as stored. None for a study stored before plans were (planned then).
    plan: dict | None = Field(default=None, sa_column=Column(JSON, nullable=True))
    status: Status = Field(default=Status.queued, index=True)
    progress: float = 0.0
    n_runs: int = 0
    run_index: int | None = None
    current_run: str | None = None
    current_stage: str | None = None
    attempts: int = 0
    worker_id: str | None = None
    heartbeat_at: datetime | None = None
    cancel_requested: bool = False
    created_at: datetime = Field(default_factory=utcnow, index=True)
    started_at: datetime | None = None
    finished_at: datetime | None = None
    run_time: float | None = None
    error: str | None = None
    max_particles: int = 0
    estimated_particle_steps: float = 0.0
    #: When the worker expects the job to end, at the rate of its progress so far (written
    #: with each heartbeat; None while unknown, reset by a claim).
    finishes_at: datetime | None = None


def _runs_done(runs) -> int:
    return sum(1 for r in runs if r.status in (Status.succeeded, Status.failed))


class StudyPublic(StudyBase):
    """A study as the API shows it."""

    id: uuid.UUID
    status: Status
    progress: float = Field(description="Fraction done, 0..1.")
    n_runs: int
    run_index: int | None = Field(description="Index of the current run (0-based).")
    current_run: str | None
    current_stage: str | None
    attempts: int = Field(description="Times a worker has claimed the study.")
    cancel_requested: bool
    created_at: datetime | None
    started_at: datetime | None
    finished_at: datetime | None
    heartbeat_at: datetime | None
    run_time: float | None = Field(description="Seconds the last attempt ran.")
    finishes_at: datetime | None = Field(
        None,
        description="While running: when the worker expects the job to end, at the rate its "
        "progress has moved since it was claimed (null while unknown).",
    )
    runs_added: int = Field(
        0, description="Runs a decide study has added to its plan so far (counted in n_runs)."
    )

    @field_validator("created_at", "started_at", "finished_at", "heartbeat_at", "finishes_at")
    @classmethod
    def _utc(cls, v: datetime | None) -> datetime | None:
        return _as_utc(v)

    @computed_field(
        description="While running: seconds the job has left at the rate of its progress so "
        "far (finishes_at less now); null while unknown or when not running."
    )
    @property
    def eta(self) -> float | None:
        if self.status is not Status.running or self.finishes_at is None:
            return None
        return max(0.0, (self.finishes_at - utcnow()).total_seconds())

    error: str | None
    max_particles: int
    estimated_particle_steps: float
    parent_id: uuid.UUID | None = Field(
        None, description="The calibration that queued this study (its then_study), if any."
    )
    links: dict[str, str] = {}


class StudiesPublic(SQLModel):
    """A page of studies, newest first."""

    data: list[StudyPublic]
    count: int


class StudySubmitted(SQLModel):
    """Answer of a submission."""

    id: uuid.UUID
    status: Status
    links: dict[str, str]


# ------------------------------------------------------------------------------------ run
class RunBase(SQLModel):
    """What a run is: key, radius, rule and seed (from the spec)."""

    key: str
    position: int = Field(description="Order of the run in the study.")
    radius: float = Field(description="Particle radius [m].")
    rule: str = Field(description="Scaling rule name, 'reference' for the reference.")
    seed: int
    particles: int


class Run(RunBase, table=True):
    """A run row; its results live in the study's HDF5 file."""

    id: int | None = Field(default=None, primary_key=True)
    study_id: uuid.UUID = Field(
        sa_column=Column(
            Uuid, ForeignKey("study.id", ondelete="CASCADE"), index=True, nullable=False
        )
    )
    status: Status = Status.queued
    started_at: datetime | None = None
    finished_at: datetime | None = None
    steps: int | None = None
    wall_time: float | None = None
    error: str | None = None


class RunPublic(RunBase):
    """A run as the API shows it."""

    status: Status
    started_at: datetime | None
    finished_at: datetime | None
    steps: int | None
    wall_time: float | None = Field(description="Wall-clock time of the run [s].")
    error: str | None

    @field_validator("started_at", "finished_at")
    @classmethod
    def _utc(cls, v: datetime | None) -> datetime | None:
        return _as_utc(v)


class StudyDetail(StudyPublic):
    """A study with its normalised spec (engine.StudySpec.to_dict()), its plot kinds and its
    runs."""

    spec: dict
    plot_kinds: list[str] = Field(
        [],
        description="The plots this study has (GET /studies/{id}/plots/{kind}.png): those of "
        "its kind of test (a uniaxial study's curves, a shear study's yield loci and "
        "pre-shear), the unconfined one only with that stage, the resolution one only with "
        "resolution controls; any other kind is a 404.",
    )
    runs: list[RunPublic] = []

    @computed_field(description="Runs with an outcome (succeeded or failed) of the n_runs.")
    @property
    def runs_done(self) -> int:
        return _runs_done(self.runs)


# ------------------------------------------------------------------------------ calibration
class CalibrationPublic(StudyPublic):
    """A calibration as the API shows it (progress: runs done of the most it runs)."""

    study_id: uuid.UUID | None = Field(
        None, description="The study of the calibrated law it submitted (then_study)."
    )
    all_targets_met: bool | None = Field(
        None,
        description="Once succeeded: whether the check run of the calibrated law met every "
        "laboratory target within 2 sd (false: the calibration finished, but its law misses "
        "a target: result.not_met says which and by how much); null before.",
    )
    all_free: bool | None = Field(
        None,
        description="Once succeeded: true when the data determine none of the calibrated "
        "parameters (each free: its 90 % interval spans most of its box), so that any law of "
        "the box meets the targets met; result.determination says which target would "
        "determine each. Null before.",
    )
    outcome: str | None = Field(
        None,
        description="Once succeeded, in words: 'all N targets met' or 'k of N targets NOT "
        "met: <target> (z = ...)', after 'the data determine none of its parameters (...)' "
        "where they are all free; null before.",
    )


class CalibrationsPublic(SQLModel):
    """A page of calibrations, newest first."""

    data: list[CalibrationPublic]
    count: int


class CalibrationDetail(CalibrationPublic):
    """A calibration with its normalised request, its runs and, once it has succeeded, its
    result (engine.Calibration.to_summary(): the calibrated law, each parameter's median,
    90 % interval and whether the data determine it, every target met or not, the Sobol
    indices, every run, the check run's curves)."""

    request: dict
    runs: list[RunPublic] = []
    result: dict | None = None

    @computed_field(description="Runs with an outcome (succeeded or failed) so far.")
    @property
    def runs_done(self) -> int:
        return _runs_done(self.runs)
