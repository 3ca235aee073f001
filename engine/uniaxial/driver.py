"""The uniaxial test's stage driver: fill, pre-compression, confined consolidation and
unloading, release of the periodic confinement, unconfined compression to failure
(docs/PHYSICS.md section 4).

The parameters and presets are in :mod:`engine.uniaxial.spec`; :func:`run_uniaxial` runs the
stages in order. Every stage ends on a physical criterion and has a bound on its steps that
fails the run with :class:`StageError` rather than hanging. Curves are sampled every
``output_interval`` seconds of simulated time.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable

import numpy as np

from ..core.errors import StopRequested, WallTimeExceeded
from ..kernel.virial import platen_levers
from ..simulation.backend import check_backend, resolve_backend
from ..simulation.packing import sphere_volume
from ..simulation.simulation import Simulation
from ..simulation.snapshot import capture
from .checkpoint import Checkpoint, check_interval, resume, this_code
from .measures import (
    SOFTENING,
    FailureDetector,
    curve_failed,
    held_inertial_numbers,
    interior_axial_stress,
    interior_margin,
    interior_measures,
    lateral_ratio,
    loading_speed,
    peak_start,
    secant_slope,
    strength_scalars,
)
from .results import (
    CURVE_UNITS,
    RESUMED,
    Progress,
    ProgressCallback,
    SnapshotCallback,
    StageResult,
    UniaxialResult,
)
from .spec import UniaxialTest

STAGES = (
    "fill",
    "pre_compression",
    "consolidation",
    "hold",
    "unloading",
    "release",
    "unconfined",
)

#: The stages whose top platen moves: at ``inertial_number`` each holds it (the unloading its
#: own where ``unloading_inertial_number`` is set; docs/PHYSICS.md section 4, "Loading rate").
LOADING = ("pre_compression", "consolidation", "unloading", "unconfined")


#: Stage weights of the overall progress fraction.
_WEIGHTS = {
    "fill": 0.3,
    "pre_compression": 0.05,
    "consolidation": 0.25,
    "hold": 0.05,
    "unloading": 0.1,
    "release": 0.1,
    "unconfined": 0.2,
}


def stages_of(test: UniaxialTest) -> tuple[str, ...]:
    """The stages ``test`` runs, in order: :data:`STAGES` less the hold where ``hold_time``
    is None and less the release and unconfined compression where ``unconfined`` is False."""
    return tuple(
        s
        for s in STAGES
        if (s != "hold" or test.hold_time is not None)
        and (test.unconfined or s not in ("release", "unconfined"))
    )


class StageError(RuntimeError):
    """A stage did not reach its end criterion within its bound on steps.

    Attributes: ``stage`` (name), ``steps`` (steps spent in the stage).
    """

    def __init__(self, message: str, stage: str, steps: int):
        self.stage = stage
        self.steps = steps
        super().__init__(message)

    def __reduce__(self):  # pickles with its fields (see engine.core.errors)
        return type(self), (self.args[0], self.stage, self.steps)


def platen_virial(sim: Simulation, wall_forces: np.ndarray, n_walls: int) -> float:
    """The platens' part of the vertical contact virial [N m]: per platen its normal force
    (``wall_forces`` [N], rows bottom then top) times the mean lever (radius less overlap)
    of the particles touching it, whose branch vectors run from the contact point to the
    centre along the platen's normal (exact for equal radii and equal overlaps; the
    horizontal components get nothing). ``n_walls``: 1 (bottom only) or 2."""
    walls = sim.wall_positions
    top = float(walls[1, 2]) if n_walls > 1 else np.inf
    lever_b, lever_t = platen_levers(
        np.ascontiguousarray(sim.positions[:, 2]), sim.radii, float(walls[0, 2]), top
    )
    out = abs(float(wall_forces[0, 2])) * lever_b
    if n_walls > 1:
        out += abs(float(wall_forces[1, 2])) * lever_t
    return out


def cap_speed(sim: Simulation, cap: float, device: bool | None = None) -> bool:
    """Scale down the velocity of every particle of ``sim`` faster than ``cap`` [m/s] to
    ``cap``, the forces then evaluated again (``set_velocities``); whether any was.
    ``device``: on the CUDA backend (None: whenever ``sim`` is on it) on the device
    (:meth:`engine.cuda.CudaSimulation.cap_speed`), no state copied; else on the host."""
    if device is None:
        device = hasattr(sim, "cap_speed")
    if device:
        return sim.cap_speed(cap)
    v = sim.velocities
    speed = np.sqrt(np.einsum("ij,ij->i", v, v))
    fast = speed > cap
    if fast.any():
        v = v.copy()
        v[fast] *= (cap / speed[fast])[:, None]
        sim.set_velocities(v)
    return bool(fast.any())


def sample_measures(
    sim: Simulation,
    wall_forces: np.ndarray,
    gap: float,
    area: float,
    margin: float,
    n_walls: int,
    device: bool | None = None,
) -> dict[str, float]:
    """A curve sample's measures of the contacts and particles, at the last force
    evaluation of ``sim`` between platens ``gap`` [m] apart (``wall_forces`` [N] as
    ``sim.wall_forces``, cross-section ``area`` [m^2], interior ``margin`` [m], ``n_walls``
    1 or 2): ``coordination`` [-] (all particles), ``por_in`` and ``coord_in`` (the interior
    slab's porosity and coordination, :func:`interior_measures`), ``s_lat`` and ``s_ver``
    [Pa] (the lateral and vertical contact-virial stress of the sample's volume, the
    platens' part included in ``s_ver``), ``s_in`` [Pa] (:func:`interior_axial_stress`) and
    ``ke`` [J] (the kinetic energy).

    ``device``: on the CUDA backend (None: whenever ``sim`` is on it) the sums are made on
    the device (:meth:`engine.cuda.CudaSimulation.sample_sums`) and only they cross to the
    host; else from the host's state (on the CUDA backend a copy of the whole state). The
    two agree to round-off (tests/engine/test_cuda_measures.py)."""
    if device is None:
        device = hasattr(sim, "sample_sums")
    if device:
        return _device_measures(sim, wall_forces, gap, area, margin, n_walls)
    counts = sim.contact_counts()
    coordination = float(counts.sum()) / sim.n
    bottom = float(sim.wall_positions[0, 2])
    por_in, coord_in = interior_measures(
        sim.positions[:, 2] - bottom, sim.radii, counts, gap, margin, area
    )
    # lateral and vertical stress from the contact virial of the sample's volume (a
    # lambda tester's lateral sensor; K0 = lateral / vertical on loading)
    sig = sim.pair_stress(area * gap)
    s_lat = 0.5 * float(sig[0, 0] + sig[1, 1])
    s_ver = float(sig[2, 2]) + platen_virial(sim, wall_forces, n_walls) / (area * gap)
    # the axial contact-virial stress of the particles whose centres lie in the interior
    # window (the strength curve of the unconfined stage)
    c = sim.contacts()
    s_in = interior_axial_stress(
        sim.positions[:, 2] - bottom,
        sim.radii,
        c.pairs,
        c.forces,
        c.normals,
        c.overlaps,
        gap,
        margin,
        area,
    )
    ke = sim.kinetic_energy()
    return {
        "coordination": coordination,
        "por_in": por_in,
        "coord_in": coord_in,
        "s_lat": s_lat,
        "s_ver": s_ver,
        "s_in": s_in,
        "ke": ke,
    }


def _device_measures(sim, wall_forces, gap, area, margin, n_walls) -> dict[str, float]:
    """:func:`sample_measures` from the device's sums (engine.cuda.measures): the same
    formulas as the host's functions, on sums made in another order."""
    walls = sim.wall_positions
    bottom = float(walls[0, 2])
    top = float(walls[1, 2]) if n_walls > 1 else np.inf
    m = interior_margin(margin, gap, float(np.max(sim.radii)))
    lo, hi = m, gap - m
    s = sim.sample_sums(bottom, top, lo, hi)
    n_in = round(s.inside)
    volume = area * gap
    sig = s.virial / volume
    lever_b = s.lever_b / s.n_b if s.n_b else 0.0
    lever_t = s.lever_t / s.n_t if s.n_t else 0.0
    platen = abs(float(wall_forces[0, 2])) * lever_b
    if n_walls > 1:
        platen += abs(float(wall_forces[1, 2])) * lever_t
    return {
        "coordination": s.counts / sim.n,
        "por_in": 1.0 - s.solid / (area * (hi - lo)),
        "coord_in": s.counts_in / n_in if n_in else 0.0,
        "s_lat": 0.5 * float(sig[0, 0] + sig[1, 1]),
        "s_ver": float(sig[2, 2]) + platen / volume,
        "s_in": s.szz_in / (area * (hi - lo)) if hi > lo else 0.0,
        "ke": 0.5 * s.trans + 0.5 * s.rot,
    }


class _Recorder:
    """Samples the curves of one stage, and holds what a checkpoint needs to re-enter the
    stage's loop: its start height ``h0`` [m] and simulated time ``t0`` [s], the rows so far,
    the steps run in it, and the unconfined stage's failure detector."""

    def __init__(self, driver: _Driver, stage: str, h0: float):
        self.d = driver
        self.stage = stage
        self.h0 = h0
        self.t0 = driver.sim.time
        self.rows: list[tuple] = []
        self.steps0 = driver.sim.steps
        self.steps = 0
        self.failure: FailureDetector | None = None
        # unconfined, at inertial_number: the running peak of the strength curve smoothed
        # over the last failure_strain of strain, and whether it has turned (post-peak)
        self.smoothed_peak = 0.0
        self.post_peak = False

    def sample(self) -> tuple:
        d = self.d
        sim = d.sim
        f = sim.wall_forces
        area = d.area
        gap = d.gap()
        s_top = float(f[1, 2]) / area if d.n_walls > 1 else 0.0
        s_bot = -float(f[0, 2]) / area
        porosity = 1.0 - d.solid_volume / (area * gap)
        m = sample_measures(sim, f, gap, area, d.test.margin, d.n_walls)
        coordination, por_in, coord_in = m["coordination"], m["por_in"], m["coord_in"]
        s_lat, s_ver, s_in, ke = m["s_lat"], m["s_ver"], m["s_in"], m["ke"]
        speed = abs(float(sim.wall_velocities[1, 2])) if d.n_walls > 1 else 0.0
        # inertial number with the pressure floored at the weight of one particle layer
        p = max(abs(s_top), abs(s_bot), d.layer_stress)
        inertial = speed / gap * 2.0 * d.test.radius * math.sqrt(d.test.density / p)
        row = (
            sim.time,
            (self.h0 - gap) / self.h0,
            s_top,
            s_bot,
            porosity,
            coordination,
            ke,
            inertial,
            gap,
            por_in,
            coord_in,
            s_lat,
            s_ver,
            s_in,
        )
        self.rows.append(row)
        return row

    def turned(self) -> bool:
        """Whether the unconfined strength curve (``strength_from``), smoothed over the last
        ``failure_strain`` of strain, has fallen ``SOFTENING`` below its running peak: the
        peak is passed and the sample softens. The running peak counts smoothed values from
        one window past the stage's start (``peak_start``: the first window's mean holds the
        release's last settling, not the sample's strength). A smoothed value above the
        running peak is a new peak: a turn before it was a fluctuation on the way up, not
        the failure, and clears (the platen holds the inertial number over the whole sample
        again, not over a shear band, until the curve turns after its true peak)."""
        t = self.d.test
        col = STRENGTH_COLUMN[t.strength_from]
        w = max(t.failure_strain, 1e-3)
        e_now = self.rows[-1][1]
        total, n = 0.0, 0
        for r in reversed(self.rows):
            if r[1] < e_now - w:
                break
            total += r[col]
            n += 1
        sm = total / n
        if e_now - self.rows[0][1] >= max(peak_start(t), w) and sm > self.smoothed_peak:
            self.smoothed_peak = sm
            self.post_peak = False
        if not self.post_peak:
            self.post_peak = self.smoothed_peak > 0 and sm < (1 - SOFTENING) * self.smoothed_peak
        return self.post_peak

    def softened(self) -> bool:
        """Whether the unconfined curve so far shows the documented failure
        (:func:`engine.uniaxial.measures.curve_failed`: a peak, then ``SOFTENING`` below it
        two windows later), checked once the curve has turned."""
        if not self.post_peak:
            return False
        a = np.array(self.rows, dtype=float)
        curves = {k: a[:, i] for i, k in enumerate(CURVE_UNITS)}
        return curve_failed(self.d.test, curves)

    def result(self) -> StageResult:
        a = np.array(self.rows, dtype=float).reshape(-1, len(CURVE_UNITS))
        curves = {k: a[:, i].copy() for i, k in enumerate(CURVE_UNITS)}
        for k, v in curves.items():
            if not np.all(np.isfinite(v)):
                raise FloatingPointError(f"stage {self.stage}: non-finite values in the {k} curve")
        snap = capture(self.d.sim, self.stage)
        if self.d.on_snapshot is not None:
            self.d.on_snapshot(snap)
        return StageResult(
            self.stage, curves, snap.positions, snap.radii, self.d.sim.steps - self.steps0, snap
        )


#: The column of a curve row (:data:`CURVE_UNITS` order) each strength estimator reads.
STRENGTH_COLUMN = {"platen": 2, "interior": list(CURVE_UNITS).index("stress_interior")}


class _Driver:
    """Runs the stages on one :class:`Simulation`.

    A stage is begun (its platen and periodicity set-up, then its first curve sample), looped
    (run ``output_interval``, sample, report) until its criterion holds, and ended (its
    result kept, then its closing platen move). Everything the loop needs lives on the driver
    and its current :class:`_Recorder`, so a checkpoint taken between two samples (a pickle of
    the driver, see :class:`engine.uniaxial.checkpoint.Checkpoint`) re-enters the loop where it
    was."""

    def __init__(
        self,
        test: UniaxialTest,
        progress: ProgressCallback | None,
        on_snapshot: SnapshotCallback | None = None,
        snapshot_interval: float | None = None,
        backend: str | None = None,
    ):
        self.test = test
        self.progress = progress
        self.on_snapshot = on_snapshot
        self.snapshot_interval = snapshot_interval
        self.next_snapshot = snapshot_interval
        self.area = test.cell[0] * test.cell[1]
        self.stages: dict[str, StageResult] = {}
        self.current: _Recorder | None = None
        self.last_fraction = 0.0
        self.scalars: dict[str, float] = {}
        self.t_wall = time.perf_counter()
        pos, radii = test.initial_packing()
        self.solid_volume = float(sphere_volume(radii).sum())
        g = test.gravity
        self.layer_stress = test.density * g * 2 * test.radius
        m = float(test.density * sphere_volume(test.radius))
        self.settle_energy = test.settle_ke * len(radii) * m * g * test.radius
        self.unconfined_failed = False
        self.n_walls = 2  # bottom platen at z = 0; the top one starts above the cell
        scene = test.scene(pos, radii)
        # kernels are compiled (or loaded from the disk cache) when a Simulation is built and
        # when its periodicity changes: that time is kept out of the run's wall time
        t0 = time.perf_counter()
        self.time_step = test.time_step()
        self.sim = Simulation(
            scene, dt=self.time_step.dt, max_speed=self.time_step.impact_speed, backend=backend
        )
        self.setup_time = time.perf_counter() - t0
        self.sample_steps = max(1, round(test.output_interval / self.sim.dt))
        self.max_steps = max(1, round(test.max_stage_time / self.sim.dt))
        self.h_consolidation = math.nan
        self.checkpoint = None
        self.max_wall_time: float | None = None
        self.wall_time_setting = "max_wall_time"
        # within a long curve sample, a progress report (and so a stop request) at least
        # every engine.simulation.simulation.CALL_SECONDS of wall time
        self.stage_now, self.stage_fraction = "fill", 0.0
        self.sim.between_calls = self._between_calls

    # ------------------------------------------------------------------ checkpoints
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        for k in ("progress", "on_snapshot", "checkpoint"):
            state[k] = None
        # wall time so far instead of the start of a clock that does not survive the process
        state["t_wall"] = time.perf_counter() - self.t_wall
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.t_wall = time.perf_counter() - state["t_wall"]
        self.sim.between_calls = self._between_calls

    # ------------------------------------------------------------------ helpers
    def gap(self) -> float:
        """Distance between the platens [m]."""
        return float(self.sim.wall_positions[1, 2] - self.sim.wall_positions[0, 2])

    def bed_top(self) -> float:
        """Highest particle surface [m]."""
        return float(np.max(self.sim.positions[:, 2] + self.sim.radii))

    def wall_time(self) -> float:
        """Wall time of the run so far, set-up left out [s]."""
        return time.perf_counter() - self.t_wall - self.setup_time

    def report(self, stage: str, stage_fraction: float, message: str = "") -> None:
        if self.max_wall_time is not None:
            elapsed = self.wall_time()
            if elapsed > self.max_wall_time:
                raise WallTimeExceeded(self.max_wall_time, elapsed, self.wall_time_setting)
        if self.progress is None:
            return
        run = stages_of(self.test)
        done = sum(_WEIGHTS[s] for s in run[: run.index(stage)])
        total = sum(_WEIGHTS[s] for s in run)
        frac = min(1.0, (done + _WEIGHTS[stage] * min(max(stage_fraction, 0.0), 1.0)) / total)
        # stress fluctuates: never report less progress than before
        frac = self.last_fraction = max(frac, self.last_fraction)
        answer = self.progress(
            Progress(frac, stage, stage_fraction, self.sim.time, self.sim.steps, message)
        )
        if answer is False:
            raise StopRequested(f"stopped by the progress callback during {stage}")

    def _between_calls(self) -> None:
        """A report between two kernel calls of a curve sample: the stage's progress as of
        its last sample (so the fraction never goes back), the stop request heard."""
        self.report(self.stage_now, self.stage_fraction, "running")

    def settled(self, row, t_min: float, t0: float, quiet: float | None = None, rows=()) -> bool:
        """Whether a settling stage that began at ``t0`` [s] is over at sample ``row``: at
        least ``t_min`` [s] in, the kinetic energy below settle_ke N m g R, and with
        ``quiet`` [s] no sample of ``rows`` (the stage's so far) above it for that long, the
        stage's start counting as one that was."""
        if not (row[0] - t0 >= t_min and row[6] <= self.settle_energy):
            return False
        if quiet is None:
            return True
        loud = next((r[0] for r in reversed(rows) if r[6] > self.settle_energy), t0)
        return row[0] - loud >= quiet

    def platen_virial(self, wall_forces: np.ndarray) -> float:
        """The platens' part of the vertical contact virial [N m] (:func:`platen_virial`)."""
        return platen_virial(self.sim, wall_forces, self.n_walls)

    def cap_speed(self, cap: float) -> None:
        """Scale down the velocity of every particle faster than ``cap`` [m/s] to ``cap``
        (``UniaxialTest.pour_speed``, during the fill): :func:`cap_speed`."""
        cap_speed(self.sim, cap)

    def move_top(self, speed: float) -> None:
        self.sim.set_wall_velocity(1, (0.0, 0.0, speed))

    def drive(self, stage: str, gap: float, stress: float, post_peak: bool = False) -> None:
        """Set the top platen's speed for the next curve sample of a loading ``stage``: the
        constant ``platen_speed``, or at the stage's inertial number
        (:meth:`engine.UniaxialTest.stage_inertial_number`) the speed of
        :func:`engine.uniaxial.measures.loading_speed` for the platen ``gap`` [m] and the
        sample's mean axial ``stress`` [Pa] (down, or up while unloading)."""
        t = self.test
        if t.inertial_number is None:
            v = t.platen_speed
        else:
            v = loading_speed(
                t,
                gap,
                stress,
                h0=self.current.h0 if self.current is not None else gap,
                unconfined=stage == "unconfined",
                post_peak=post_peak,
                inertial_number=t.stage_inertial_number(stage),
            )
        self.move_top(v if stage == "unloading" else -v)

    # ------------------------------------------------------------------ the stage machine
    def run(self) -> UniaxialResult:
        """Run (or, resumed from a checkpoint, go on with) the stages, then the scalars."""
        for stage in stages_of(self.test):
            if stage in self.stages:
                continue
            if self.current is None or self.current.stage != stage:
                self.begin(stage)
            self.loop()
            self.end(stage)
            if stage == "fill" and self.checkpoint is not None and self.checkpoint.after_fill:
                self.checkpoint.save(self)  # the settled bed: never poured again
        return self.finish()

    def begin(self, stage: str) -> None:
        """The stage's set-up (platens, periodicity), then its first curve sample."""
        t = self.test
        h0 = None
        if stage == "pre_compression":
            if t.gravity_off_after_fill:
                self.sim.set_gravity((0.0, 0.0, 0.0))
            top = self.bed_top() + 0.05 * t.radius
            self.sim.set_wall_position(1, (0.0, 0.0, top))
            # the platen is placed above the bed: the stress is the floor until it touches
            self.drive(stage, self.gap(), 0.5 * self.bottom_stress())
        elif stage == "consolidation":
            self.h_consolidation = self.gap()
        elif stage == "hold":
            self.move_top(0.0)  # the platen stopped where the consolidation left it
        elif stage == "unloading":
            self.drive(stage, self.gap(), self.mean_stress())
            h0 = self.h_consolidation
        elif stage == "release":
            t_setup = time.perf_counter()
            self.sim.set_periodic((False, False, False))
            self.setup_time += time.perf_counter() - t_setup
        elif stage == "unconfined":
            # the platen starts where unloading left it, on top of the consolidated sample,
            # and strain is measured against that height: a sample that collapsed on release
            # is never reached within max_unconfined_strain and has exactly zero strength
            self.drive(stage, self.gap(), self.mean_stress())
        rec = _Recorder(self, stage, self.gap() if h0 is None else h0)
        if stage == "unconfined":
            rec.failure = FailureDetector(t.failure_drop, t.failure_strain)
        self.current = rec
        self.stage_now, self.stage_fraction = stage, 0.0
        rec.sample()

    def bottom_stress(self) -> float:
        """The bottom platen's stress at the last force evaluation [Pa]."""
        return -float(self.sim.wall_forces[0, 2]) / self.area

    def mean_stress(self) -> float:
        """The mean of the two platens' stresses at the last force evaluation [Pa]."""
        return 0.5 * (float(self.sim.wall_forces[1, 2]) / self.area + self.bottom_stress())

    def criterion(self, rec: _Recorder) -> tuple[Callable, Callable, str]:
        """The stage's end criterion, its progress fraction and what it waits for."""
        t, t0 = self.test, rec.t0
        stage = rec.stage
        if stage == "fill":
            t_fall = math.sqrt(2 * t.cell[2] / t.gravity)
            if t.pour_speed is not None:  # the capped cloud rains down no faster than this
                t_fall = max(t_fall, t.pour_height / t.pour_speed)
            return (
                lambda r: self.settled(r, t_fall, t0),
                lambda r: min(1.0, (r[0] - t0) / (2 * t_fall)),
                "settle (kinetic energy below settle_ke x N m g R)",
            )
        if stage in ("pre_compression", "consolidation"):
            target = t.pre_stress if stage == "pre_compression" else t.consolidation_stress
            return (
                lambda r: r[2] >= target,
                lambda r: r[2] / target,
                f"reach the {stage.replace('_', '-')} stress {target:g} Pa",
            )
        if stage == "unloading":
            target = t.consolidation_stress
            low = t.unloaded_stress * target
            return (
                lambda r: r[2] <= low,
                lambda r: 1.0 - r[2] / target,
                f"relax the stress below {low:g} Pa",
            )
        if stage == "hold":
            longest = max(t.hold_time, t.hold_quiet or 0.0)
            return (
                lambda r: self.settled(r, t.hold_time, t0, t.hold_quiet, rec.rows),
                lambda r: min(1.0, (r[0] - t0) / longest),
                "come to rest (hold_time, then kinetic energy below settle_ke x N m g R, "
                "at every sample for hold_quiet where set)",
            )
        if stage == "release":
            t_min = 5 * math.sqrt(2 * t.radius / t.gravity)  # a few particle fall times
            t_max = max(t_min, t.release_time)
            return (
                lambda r: self.settled(r, t_min, t0) or r[0] - t0 >= t_max,
                lambda r: min(1.0, (r[0] - t0) / t_max),
                "settle after the release (kinetic energy below settle_ke x N m g R)",
            )

        col = STRENGTH_COLUMN[t.strength_from]

        def failed(r) -> bool:
            # the in-run detector (a drop of failure_drop held for failure_strain), or, where
            # the strength is the interior's, the documented failure of that curve so far
            if rec.failure.update(r[1], r[col]) or (
                t.strength_from == "interior" and rec.softened()
            ):
                self.unconfined_failed = True
                return True
            return r[1] >= t.max_unconfined_strain

        return (
            failed,
            lambda r: r[1] / t.max_unconfined_strain,
            "fail (post-peak drop) or reach max_unconfined_strain",
        )

    def loop(self) -> None:
        """Run the current stage from its last sample until its criterion holds."""
        rec = self.current
        stage = rec.stage
        done, fraction, what = self.criterion(rec)
        row = rec.rows[-1]
        while not done(row):
            # the stage goes on (its end makes its own snapshot)
            if self.next_snapshot is not None and rec.steps and self.sim.time >= self.next_snapshot:
                self.on_snapshot(capture(self.sim, stage))
                while self.next_snapshot <= self.sim.time:
                    self.next_snapshot += self.snapshot_interval
            if rec.steps >= self.max_steps:
                raise StageError(
                    f"stage {stage} did not {what} within {rec.steps} steps "
                    f"({rec.steps * self.sim.dt:.3g} s, max_stage_time); now: top stress "
                    f"{row[2]:.4g} Pa, platen gap {row[8]:.4g} m, kinetic energy "
                    f"{row[6]:.3g} J",
                    stage,
                    rec.steps,
                )
            self.sim.run(self.sample_steps)
            rec.steps += self.sample_steps
            if stage == "fill" and self.test.pour_speed is not None:
                self.cap_speed(self.test.pour_speed)
            row = rec.sample()
            turned = stage == "unconfined" and rec.turned()
            if stage in LOADING and self.test.inertial_number is not None:
                self.drive(stage, row[8], 0.5 * (row[2] + row[3]), post_peak=turned)
            self.stage_fraction = fraction(row)
            self.report(stage, self.stage_fraction)
            if self.checkpoint is not None:
                # between two samples, before the criterion sees the new row: a resumed run
                # re-enters here and asks the criterion about that same row
                self.checkpoint.due(self)

    def end(self, stage: str) -> None:
        self.stages[stage] = self.current.result()
        self.current = None
        self.report(stage, 1.0, "done")
        if stage in ("unloading", "unconfined"):
            self.move_top(0.0)

    # ------------------------------------------------------------------ scalars
    def finish(self) -> UniaxialResult:
        s = self.scalars
        cons, unl = self.stages["consolidation"].curves, self.stages["unloading"].curves
        s["loading_stiffness"] = secant_slope(cons["strain"], cons["stress_top"], 0.5, 1.0)
        s["unloading_stiffness"] = secant_slope(
            unl["strain"][::-1], unl["stress_top"][::-1], 0.5, 1.0
        )
        s["k0"] = lateral_ratio(cons["stress_top"], cons["stress_lateral"])
        s["consolidated_porosity"] = float(cons["porosity"][-1])
        s["consolidated_porosity_interior"] = float(cons["porosity_interior"][-1])
        dmax = 2 * self.test.radius * (1 + self.test.polydispersity)
        s["thickness_diameters"] = self.test.thickness_diameters
        gap = float(cons["platen_gap"][-1])
        s["height_diameters"] = gap / dmax
        s["interior_margin"] = interior_margin(self.test.margin, gap, dmax / 2)
        if "unconfined" in self.stages:
            g = 0.0 if self.test.gravity_off_after_fill else self.test.gravity
            s.update(
                strength_scalars(
                    self.stages["unconfined"].curves,
                    self.test,
                    self.unconfined_failed,
                    self.test.density * self.solid_volume * g / (2.0 * self.area),
                )
            )
        s["particles"] = float(self.sim.n)
        s["steps"] = float(self.sim.steps)
        s["dt"] = self.sim.dt
        ts = self.time_step
        s["dt_fraction"] = self.sim.dt / ts.critical
        s["dt_critical"] = ts.critical
        s["dt_limited_by_wall"] = 1.0 if ts.kind == "wall" else 0.0
        s["impact_speed"] = ts.impact_speed
        t = self.test
        held = np.concatenate(
            [
                # the unloading at its own inertial number counts as its share of the target
                held_inertial_numbers(self.stages[k].curves, t)
                * (
                    t.inertial_number / t.unloading_inertial_number
                    if k == "unloading" and t.unloading_inertial_number is not None
                    else 1.0
                )
                for k in LOADING
                if k in self.stages
            ]
        )
        s["inertial_number_held"] = float(np.median(held))
        s["inertial_number_held_max"] = float(np.max(held))
        s["setup_time"] = self.setup_time
        s["wall_time"] = self.wall_time()
        s["particle_steps"] = float(self.sim.n) * self.sim.steps
        s["threads"] = float(self.sim.threads)  # wall time is per this many engine threads
        s["max_inertial_number"] = max(
            float(np.max(self.stages[k].curves["inertial_number"]))
            for k in ("pre_compression", "consolidation", "unloading", "unconfined")
            if k in self.stages
        )
        bad = [k for k, v in s.items() if not math.isfinite(v)]
        if bad:
            raise FloatingPointError(f"non-finite scalars {bad}: the run is not usable")
        return UniaxialResult(self.test, self.stages, s)


def run_uniaxial(
    test: UniaxialTest,
    progress: ProgressCallback | None = None,
    *,
    on_snapshot: SnapshotCallback | None = None,
    snapshot_interval: float | None = None,
    checkpoint: Checkpoint | str | os.PathLike | None = None,
    max_wall_time: float | None = None,
    wall_time_setting: str = "max_wall_time",
    backend: str | None = None,
) -> UniaxialResult:
    """Run the uniaxial test: fill, pre-compression, consolidation, unloading and (with
    ``test.unconfined``) release and unconfined compression.

    Args:
        test: the parameters.
        progress: called after every curve sample with a :class:`Progress`; returning
            ``False`` stops the run with :class:`engine.StopRequested`.
        on_snapshot: called with every :class:`engine.simulation.snapshot.Snapshot` as it is
            taken: at each stage's end (also kept in :attr:`StageResult.snapshot`) and, with
            ``snapshot_interval``, during the stages (not kept: e.g. pass
            ``engine.io.vtkhdf.SnapshotWriter(dir).add`` to write them as they come).
        snapshot_interval: simulated time between snapshots during the stages [s], at the
            first curve sample past each multiple (None: stage ends only).
        checkpoint: a :class:`engine.Checkpoint` (or its path, written every
            ``CHECKPOINT_INTERVAL`` s): the run resumes from it when it holds this test's
            state, and writes it between curve samples as it goes; the result is
            bit-identical to that of an uninterrupted run. The file is left for the caller to
            remove once the result is stored (:meth:`engine.Checkpoint.remove`).
        max_wall_time: stop the run with :class:`engine.WallTimeExceeded` once it has run
            this long [s] (set-up left out; checked after every curve sample and between
            kernel calls, at least every 0.2 s); ``wall_time_setting`` names the limit in
            the message.
        backend: ``"cpu"``, ``"cuda"`` or ``"auto"`` (see :class:`engine.Simulation`);
            None: ``DEMSCALE_BACKEND``, else the CPU.
    Raises: :class:`StageError` when a stage misses its criterion within its bound,
        :class:`engine.InstabilityError` when the integration blows up.
    """
    this_code()  # the code this run is made by, taken before it runs (engine.io.store)
    if snapshot_interval is not None:
        if on_snapshot is None:
            raise ValueError("snapshot_interval needs on_snapshot to receive the snapshots")
        if not (math.isfinite(snapshot_interval) and snapshot_interval > 0):
            raise ValueError(f"snapshot_interval must be a time > 0 s, not {snapshot_interval}")
    if max_wall_time is not None:
        check_interval(max_wall_time, "run_uniaxial.max_wall_time")
    # resolved once, naming this function's field (not Simulation's) where CUDA cannot run
    field = "run_uniaxial.backend"
    backend = resolve_backend(check_backend(backend, field), field)

    def refuse(state) -> str | None:
        if state.sim.backend == backend:
            return None
        return f"was written on the {state.sim.backend} backend, not the one asked for"

    checkpoint, d, load = resume(checkpoint, test, refuse)
    if d is not None:
        d.setup_time += load
        d.t_wall -= load  # wall_time = now - t_wall - setup_time
        d.progress, d.on_snapshot = progress, on_snapshot
    else:
        d = _Driver(test, progress, on_snapshot, snapshot_interval, backend)
    d.checkpoint = checkpoint
    d.max_wall_time, d.wall_time_setting = max_wall_time, wall_time_setting
    if checkpoint is not None:
        checkpoint.start()
        if checkpoint.resumed_steps is not None:
            d.report(d.stage_now, d.stage_fraction, f"{RESUMED} at step {checkpoint.resumed_steps}")
    return d.run()
