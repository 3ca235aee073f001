"""The hopper's stages (docs/HOPPER.md): the fill poured from a loose lattice and settled behind
the closed gate, then the gate moved away downwards and the discharge sampled every
``output_interval`` until the hopper is empty, the flow stops, or ``max_discharge_time``.

With a :class:`engine.Checkpoint` the run writes its state (a pickle of the
:class:`HopperRun` between two samples: the simulation with its contact history and moving gate,
the discharge's rows so far and its stop criterion's state) every ``interval`` of wall time and
once the fill has settled, and resumes from it: nothing is random after the fill is placed, so
a resumed run's record is bit-identical to an uninterrupted one's
(tests/engine/test_hopper_checkpoint.py).

Each sample counts the mass discharged (centres more than one largest diameter below the
outlet), still in the hopper, and anywhere else (a leak: none in a sound scene), and reads the
grains' downward speeds next to the wall and on the centre line in a band at half the fill's
current height, and the wall normal stress by height (:mod:`engine.hopper.measures`).

The sink. A discharged grain falls 2 B and more below the outlet, at up to
:func:`impact_speed`, onto a catch floor; on a heap there the soft loading spring lets two
grains overlap by half a radius and the run stops with an ``InstabilityError`` (issue 52). So
every grain whose centre crosses the sink (``HopperGeometry.sink``: 2 B + 10 d below the
outlet, :data:`engine.hopper.scene.SINK_DIAMETERS` largest diameters above the highest the
heap could reach) is parked (:meth:`engine.Simulation.park_below`): moved to its own site of
a lattice below the sink, at rest, out of every contact for good. The sink is applied
whenever a grain at the run's fastest speed could have moved :data:`SINK_REACH` of a
diameter, so no grain goes further below it than that. Nothing reaches the floor, and what
happens 2 B below the outlet cannot act on the flow through it: the grains there fall
freely, away from it. The floor, its depth and the time step (sized for a fall onto it,
:func:`resolved_dt`) are those of the runs made before the sink, so that a run's protocol
is theirs. (Until 2026-12-06 a drag slowed the grains below the sink's height instead, as
a viscous drag of time sqrt(d / (2 g)): a dilute stream settled onto the heap, but the dense
stream of an 80 d outlet, whose front the drag slowed while its rear still fell, jammed at
the zone's top: docs/HOPPER.md, "The sink".)
"""

from __future__ import annotations

import bisect
import math
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core.errors import StopRequested, WallTimeExceeded
from ..simulation.backend import check_backend, resolve_backend
from ..simulation.simulation import Simulation
from ..simulation.snapshot import Snapshot, capture
from ..simulation.timestep import critical_time_step
from ..uniaxial.checkpoint import (
    TRAJECTORY_PACKAGES,
    Checkpoint,
    check_interval,
    resume,
    this_code,
)
from ..uniaxial.driver import StageError
from ..uniaxial.results import RESUMED, Progress, ProgressCallback
from .measures import (
    MASS_FLOW_INDEX,
    arch_profile,
    binned_stress,
    flow_index,
    hertz_wall_force,
    steady_rate,
    stop_time,
)
from .results import HOPPER_CURVE_UNITS, HopperResult
from .scene import (
    HopperGeometry,
    build_hopper,
    wall_bin_areas,
    wall_radius,
)
from .spec import CONE_SIDES, HopperTest

#: Grains whose centres lie within this many largest diameters of the wall (normal to it)
#: are the wall's in the mass-flow index; those within this many of the centre line the
#: centre's [-] (about the first layer of grains at the wall).
BAND_REACH = 1.0
#: Half-thickness of the band in which the mass-flow index reads speeds, in largest
#: diameters [-].
BAND_HALF = 1.0
#: The sink is applied at least every time a grain at :func:`impact_speed` moves this many
#: largest diameters [-] (module docstring).
SINK_REACH = 0.25
#: The share of the overall progress taken by the settling [-].
_SETTLE_SHARE = 0.3
#: The engine's packages a hopper run steps through (its checkpoint is resumed only by the
#: same sources of these: :class:`engine.Checkpoint`).
HOPPER_TRAJECTORY = (*TRAJECTORY_PACKAGES, "hopper")


def impact_speed(test: HopperTest, geometry: HopperGeometry) -> float:
    """Fastest impact the time step is sized for [m/s]: a free fall from the walls' top onto
    the catch floor, sqrt(2 g (top + catch depth)). (The opened gate moves away from the
    grains, faster than they fall: it strikes none.)"""
    return math.sqrt(2.0 * test.gravity * (geometry.wall_top + geometry.catch_depth))


def resolved_dt(test: HopperTest, geometry: HopperGeometry | None = None) -> float:
    """The time step of a run of ``test`` [s]: ``dt``, or ``dt_fraction`` of the stable limit
    of its scene (:func:`engine.critical_time_step`) at :func:`impact_speed`."""
    if test.dt is not None:
        return test.dt
    geometry = geometry or build_hopper(test)
    lim = critical_time_step(geometry.scene, impact_speed(test, geometry))
    return test.dt_fraction * lim.dt


class HopperRun:
    """One hopper discharge on one :class:`engine.Simulation`: :meth:`settle`, then
    :meth:`hold` (the gate kept closed) or :meth:`discharge`; :meth:`run` does the whole."""

    def __init__(
        self,
        test: HopperTest,
        progress: ProgressCallback | None = None,
        max_wall_time: float | None = None,
        wall_time_setting: str | None = None,
        threads: int | None = None,
        backend: str | None = None,
    ) -> None:
        if not isinstance(test, HopperTest):
            raise TypeError(f"a hopper run takes an engine.HopperTest, not {type(test).__name__}")
        self.test = test
        self.progress = progress
        #: called with a :class:`engine.simulation.snapshot.Snapshot` at the gate's opening,
        #: every ``snapshot_interval`` [s] of the discharge and at its end (run_hopper)
        self.on_snapshot: Callable[[Snapshot], Any] | None = None
        self.snapshot_interval: float | None = None
        self.max_wall_time = max_wall_time
        self.wall_time_setting = wall_time_setting or "max_wall_time"
        self.geo = build_hopper(test)
        self.dt = resolved_dt(test, self.geo)
        t = time.perf_counter()
        self.sim = Simulation(
            self.geo.scene,
            self.dt,
            max_speed=impact_speed(test, self.geo),
            threads=threads,
            backend=backend,
        )
        sim = self.sim
        self.d = test.max_diameter
        self.masses = sim.masses.copy()
        self.total = float(self.masses.sum())
        self.sample_steps = max(1, round(test.output_interval / self.dt))
        #: the most steps between two applications of the sink (module docstring)
        reach = SINK_REACH * self.d / (impact_speed(test, self.geo) * self.dt)
        self.sink_steps = max(1, int(reach))
        sim.run(1)  # compiles the kernels (or loads them): set-up, not the run's wall time
        self.setup = time.perf_counter() - t
        self.t0 = time.perf_counter()
        self.settle_time = math.nan
        self.fill_height = math.nan
        self.bulk_density = math.nan
        self.edges = np.zeros(2)
        self.stress_fill = np.zeros(1)
        self.checkpoint: Checkpoint | None = None
        self.stage = "settle"  # then "discharge", once the fill has settled
        self.flow: dict | None = None  # the discharge loop's state, once the gate opens
        self.last_progress = ("settle", 0.0, 0.0)  # (stage, fraction, stage fraction)

    # ------------------------------------------------------------------ checkpoints
    trajectory_packages = HOPPER_TRAJECTORY

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["progress"] = state["checkpoint"] = state["on_snapshot"] = None
        # wall time so far instead of the start of a clock that does not survive the process
        state["t0"] = time.perf_counter() - self.t0
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.t0 = time.perf_counter() - state["t0"]

    def _due(self) -> None:
        """Between two samples: write the checkpoint if its interval has passed."""
        if self.checkpoint is not None:
            self.checkpoint.due(self)

    # ------------------------------------------------------------------ helpers
    def _tick(self, stage: str, fraction: float, stage_fraction: float, msg: str = "") -> None:
        self.last_progress = (stage, fraction, stage_fraction)
        if self.max_wall_time is not None:
            elapsed = time.perf_counter() - self.t0
            if elapsed > self.max_wall_time:
                raise WallTimeExceeded(self.max_wall_time, elapsed, self.wall_time_setting)
        if self.progress is not None:
            p = Progress(
                min(1.0, fraction),
                stage,
                min(1.0, stage_fraction),
                self.sim.time,
                self.sim.steps,
                msg,
            )
            if self.progress(p) is False:
                raise StopRequested(f"stopped by the progress callback in stage {stage}")

    def regions(self) -> tuple[np.ndarray, np.ndarray]:
        """(discharged, inside) masks of the particles now: discharged, centres more than one
        largest diameter below the outlet; inside, the rest that lie within the hopper's
        walls (within one radius of them)."""
        p = self.sim.positions
        r = self.sim.radii
        z = p[:, 2]
        out = z < -self.d
        across = self._across(p)
        inside = ~out & (across <= wall_radius(self.test, z) + r)
        return out, inside

    def _across(self, p: np.ndarray) -> np.ndarray:
        """Distance of each centre from the mid-plane (slot) or the axis (cone) [m]."""
        if self.test.shape == "slot":
            return np.abs(p[:, 0])
        return np.hypot(p[:, 0], p[:, 1])

    def wall_stress(self, edges: np.ndarray) -> np.ndarray:
        """The wall normal stress by height bin of ``edges`` [Pa] at the last force
        evaluation: each wall contact's elastic Hertz normal force
        (:func:`engine.hopper.measures.hertz_wall_force`) at its contact point's height."""
        c = self.sim.mesh_contacts()
        on = np.isin(c.meshes, self.geo.wall_meshes)
        e_star, _ = self.test.wall_law.wall_moduli(self.test.wall_material)
        f = hertz_wall_force(c.overlaps[on], self.sim.radii[c.particles[on]], e_star)
        return binned_stress(c.points[on, 2], f, edges, wall_bin_areas(self.test, edges))

    def _advance(self, steps: int) -> None:
        """``steps`` steps of the discharge, the sink applied every ``sink_steps`` at most
        (module docstring)."""
        while steps > 0:
            n = min(steps, self.sink_steps)
            self.sim.run(n)
            steps -= n
            self.sim.park_below(self.geo.sink, self.geo.parking)

    def kinetic_scale(self) -> float:
        """N m g R [J]: the scale of the settling criterion."""
        return self.total * self.test.gravity * self.test.radius

    # ------------------------------------------------------------------ stages
    def settle(self) -> None:
        """Let the poured fill settle behind the closed gate: at least two free-fall times
        from the walls' top, then until its kinetic energy is below ``settle_ke`` N m g R
        (StageError past ``max_settle_time``). Then the settled fill's bulk density (its lower
        half's), the height it fills at that density under a level surface, and the wall
        normal stress of the fill at rest."""
        t = self.test
        sim = self.sim
        t_min = 2.0 * math.sqrt(2.0 * self.geo.wall_top / t.gravity)
        bound = t.settle_ke * self.kinetic_scale()
        while True:
            sim.run(self.sample_steps)
            ke = sim.kinetic_energy()
            self._tick("settle", _SETTLE_SHARE * sim.time / t.max_settle_time, sim.time / t_min)
            if sim.time >= t_min and ke < bound:
                break
            if sim.time > t.max_settle_time:
                raise StageError(
                    f"the fill did not settle within {t.max_settle_time:g} s "
                    f"(max_settle_time): kinetic energy {ke / self.kinetic_scale():.3g} "
                    f"N m g R, settle_ke {t.settle_ke:g}",
                    "settle",
                    sim.steps,
                )
            self._due()  # a resumed settling re-enters the loop here: it reads only sim
        self.settle_time = sim.time
        z = sim.positions[:, 2]
        half = 0.5 * float((z + sim.radii).max())
        # bulk density in the fill's lower half, its mass counted by centres: exact at the
        # walls and the gate (no grain crosses them), at the open face z = half on average
        self.bulk_density = float(self.masses[z < half].sum()) / t.volume_below(half)
        self.fill_height = t.height_holding(self.total / self.bulk_density)
        self.edges = np.linspace(0.0, self.fill_height, t.wall_bins + 1)
        self.stress_fill = self.wall_stress(self.edges)
        self.stage = "discharge"
        if self.checkpoint is not None and self.checkpoint.after_fill:
            self.checkpoint.save(self)  # the settled fill: never poured again

    def hold(self, seconds: float) -> float:
        """Run ``seconds`` [s] more with the gate closed; returns the mass discharged [kg]."""
        self.sim.run(max(1, round(seconds / self.dt)))
        out, _ = self.regions()
        return float(self.masses[out].sum())

    def discharge(self) -> HopperResult:
        """Open the gate (moved down at ``gate_speed`` until it lies below the catch floor) and
        sample the discharge until the hopper is empty, the flow has stopped
        (:func:`engine.hopper.measures.stop_time`'s criterion, read as it goes), or
        ``max_discharge_time``; then the measures. Resumed from a checkpoint, it goes on with
        the loop where it was (its state lives in ``self.flow``)."""
        t = self.test
        sim = self.sim
        geo = self.geo
        if self.flow is None:
            sim.set_mesh_velocity(geo.gate_mesh, (0.0, 0.0, -t.resolved_gate_speed))
            self.flow = {
                "gate_steps": math.ceil(abs(geo.gate_stop) / (t.resolved_gate_speed * self.dt)),
                "t_open": sim.time,
                "step_open": sim.steps,
                "rows": [],
                "times": [],  # the rows' times, for the stop criterion's look-back
                "stresses": [],
                "fastest": 0.0,
                "stopped": False,
                # the start of the window in which the flow was seen stopped
                "detected": math.nan,
            }
        f = self.flow
        gate_steps, t_open, step_open = f["gate_steps"], f["t_open"], f["step_open"]
        rows: list[tuple] = f["rows"]
        times: list[float] = f["times"]
        stresses: list[np.ndarray] = f["stresses"]
        wait = t.arch_wait * t.free_fall_time
        pm = float(self.masses.min())
        cos = math.cos(math.radians(t.half_angle))
        polygon = math.cos(math.pi / CONE_SIDES) if t.shape == "cone" else 1.0
        while True:
            moving = sim.steps - step_open < gate_steps
            steps = self.sample_steps
            if moving:
                steps = min(steps, gate_steps - (sim.steps - step_open))
            if rows:  # the first sample is the opening itself (t = 0)
                self._advance(steps)
            if moving and sim.steps - step_open >= gate_steps:
                sim.set_mesh_velocity(geo.gate_mesh, (0.0, 0.0, 0.0))
            out, inside = self.regions()
            m_out = float(self.masses[out].sum())
            m_in = float(self.masses[inside].sum())
            p, v = sim.positions, sim.velocities
            z = p[:, 2]
            top = float(z[inside].max()) if inside.any() else 0.0
            band = inside & (np.abs(z - 0.5 * top) <= BAND_HALF * self.d)
            across = self._across(p)
            gap = (wall_radius(t, z) * polygon - across) * cos
            wall = band & (gap <= BAND_REACH * self.d)
            centre = band & (across <= BAND_REACH * self.d)
            vz = -v[:, 2]
            rows.append(
                (
                    sim.time - t_open,
                    m_out,
                    m_in,
                    float(self.masses[~out & ~inside].sum()),
                    float(vz[wall].mean()) if wall.any() else math.nan,
                    float(wall.sum()),
                    float(vz[centre].mean()) if centre.any() else math.nan,
                    float(centre.sum()),
                    sim.kinetic_energy(),
                )
            )
            stresses.append(self.wall_stress(self.edges))
            now = rows[-1][0]
            times.append(now)
            self._snapshot(now)
            self._tick(
                "discharge",
                _SETTLE_SHARE + (1 - _SETTLE_SHARE) * m_out / self.total,
                m_out / self.total,
            )
            if m_in == 0.0:
                break
            # the stop criterion as it goes: the mass of the last window of `wait`
            if now >= wait:
                i = bisect.bisect_right(times, now - wait) - 1
                moved = m_out - rows[i][1]
                if moved < max(pm, t.arch_fraction * f["fastest"] * wait):
                    f["stopped"] = True
                    f["detected"] = rows[i][0]
                    break
                f["fastest"] = max(f["fastest"], moved / (now - rows[i][0]))
            if now >= t.max_discharge_time:
                break
            # between two samples, the criterion read: a resumed run re-enters the loop here
            self._due()
        if self.on_snapshot is not None:  # the end (SnapshotWriter merges it with a
            self.on_snapshot(capture(sim, "discharged"))  # snapshot of the same step)
        return self._result(rows, stresses, f["stopped"], wait, pm, f["detected"])

    def _snapshot(self, now: float) -> None:
        """A snapshot of the discharge (stage ``discharge``) when ``now`` [s since the gate
        opened] has reached the next one due: the opening itself, then every
        ``snapshot_interval``; where it is due lives in the run's state, so a resumed run
        goes on with the same times."""
        if self.on_snapshot is None:
            return
        f = self.flow
        due = f.get("next_snapshot", 0.0)
        if now < due:
            return
        self.on_snapshot(capture(self.sim, "discharge"))
        if self.snapshot_interval:
            while due <= now:
                due += self.snapshot_interval
        else:
            due = math.inf  # the opening and the end only
        f["next_snapshot"] = due

    def _result(
        self, rows, stresses, stopped: bool, wait: float, pm: float, detected: float
    ) -> HopperResult:
        t = self.test
        sim = self.sim
        a = np.array(rows, dtype=float)
        curves = {k: a[:, i].copy() for i, k in enumerate(HOPPER_CURVE_UNITS)}
        tt, m = curves["time"], curves["discharged_mass"]
        steady = steady_rate(tt, m, self.total, t.window_start, t.window_end)
        arched = False
        arch_time = arch_span = arch_height = math.nan
        if stopped:
            when = stop_time(tt, m, wait, t.arch_fraction, pm)
            # an arch: grains rest above the outlet's central half, within B above it
            p = sim.positions
            _, inside = self.regions()
            over = inside & (self._across(p) <= 0.25 * t.outlet_width)
            over &= p[:, 2] <= t.outlet_width
            arched = bool(over.any())
            if arched:
                # the criterion read over the whole curve, else where it was read as it went
                arch_time = when if when is not None else detected
                # the arch's crown and feet over the outlet (measures.arch_profile); its span
                # the walls' distance apart at its feet, its height the crown over the feet
                crown, feet = arch_profile(
                    self._across(p)[inside],
                    p[inside, 2] - sim.radii[inside],
                    self.geo.half_width,
                    self.d,
                )
                if math.isfinite(feet):
                    arch_span = 2.0 * float(wall_radius(t, feet))
                arch_height = crown - feet
        win = np.zeros(len(tt), dtype=bool)
        if math.isfinite(steady.rate):
            win = (tt >= steady.start) & (tt <= steady.end)
        if win.any():
            index = flow_index(
                curves["wall_speed"][win],
                curves["wall_count"][win],
                curves["centre_speed"][win],
                curves["centre_count"][win],
            )
            flow_stress = np.mean(np.array(stresses)[win], axis=0)
        else:
            index = math.nan
            flow_stress = np.full(t.wall_bins, math.nan)
        per_depth = steady.rate / t.depth if t.shape == "slot" else math.nan
        scale = t.rate_scale
        s = {
            "particles": float(sim.n),
            "total_mass": self.total,
            "discharged_mass": float(m[-1]),
            "remaining_mass": float(curves["remaining_mass"][-1]),
            "escaped_mass": float(curves["escaped_mass"][-1]),
            "discharge_rate": steady.rate,
            "discharge_rate_se": steady.se,
            "discharge_rate_per_depth": per_depth,
            "discharge_number": steady.rate / scale,
            "discharge_number_se": steady.se / scale,
            "window_start": steady.start,
            "window_end": steady.end,
            "window_samples": float(steady.samples),
            "stopped": float(stopped),
            "arched": float(arched),
            "arch_time": arch_time,
            "arch_span": arch_span,
            "arch_height": arch_height,
            "mass_flow_index": index,
            "mass_flow": float(index >= MASS_FLOW_INDEX) if math.isfinite(index) else 0.0,
            "fill_height": self.fill_height,
            "bulk_density": self.bulk_density,
            "outlet_diameters": t.outlet_diameters,
            "thickness_diameters": t.thickness_diameters,
            "height_diameters": self.fill_height / (2.0 * t.radius),
            "free_fall_time": t.free_fall_time,
            "settle_time": self.settle_time,
            "discharge_time": float(tt[-1]),
            "steps": float(sim.steps),
            "particle_steps": float(sim.n) * float(sim.steps),
            "dt": self.dt,
            "wall_time": time.perf_counter() - self.t0,
        }
        return HopperResult(t, curves, self.edges, self.stress_fill, flow_stress, s)

    def run(self) -> HopperResult:
        """Settle, then discharge (resumed from a checkpoint: go on with the stage it was
        in)."""
        if self.stage == "settle":
            self.settle()
        return self.discharge()


def run_hopper(
    test: HopperTest,
    progress: ProgressCallback | None = None,
    *,
    max_wall_time: float | None = None,
    wall_time_setting: str | None = None,
    threads: int | None = None,
    checkpoint: Checkpoint | str | os.PathLike | None = None,
    on_snapshot: Callable[[Snapshot], Any] | None = None,
    snapshot_interval: float | None = None,
    backend: str | None = None,
) -> HopperResult:
    """Run the hopper discharge (docs/HOPPER.md): the fill settled behind the closed gate, the
    gate opened, the discharge sampled and measured.

    Args:
        test: the parameters (:class:`engine.HopperTest`).
        progress: called after every sample with a :class:`engine.Progress`; returning
            ``False`` stops the run with :class:`engine.StopRequested`.
        max_wall_time: stop with :class:`engine.WallTimeExceeded` past this many seconds of
            wall time (the kernels' compilation left out) [s]; ``wall_time_setting`` names
            the knob in its message.
        threads: threads of the simulation on the CPU backend (None: numba's).
        checkpoint: a :class:`engine.Checkpoint` (or its path, written every
            ``CHECKPOINT_INTERVAL`` s): the run resumes from it when it holds this test's
            state (written by the same sources of :data:`HOPPER_TRAJECTORY`), and writes it
            between samples as it goes and once the fill has settled; the result is
            bit-identical to that of an uninterrupted run (its ``wall_time`` aside). The file
            is left for the caller to remove once the result is stored
            (:meth:`engine.Checkpoint.remove`).
        on_snapshot: called with a :class:`engine.simulation.snapshot.Snapshot` of the
            particles and their contacts at the gate's opening, every ``snapshot_interval``
            [s] of the discharge (None: none between) and at its end, e.g.
            ``engine.io.vtkhdf.SnapshotWriter(dir).add`` for a ParaView animation.
        backend: ``"cpu"``, ``"cuda"`` or ``"auto"`` (see :class:`engine.Simulation`; None:
            ``DEMSCALE_BACKEND``, else the CPU). On the CUDA backend the steps, the sink
            (its parking) and the kinetic energy are made on the device; each discharge sample
            copies the particles' arrays (the regions) and the walls' rows (the mesh
            contacts, the wall stress) to the host, not the pair list.
    Raises: :class:`engine.StageError` when the fill does not settle within
        ``max_settle_time``; :class:`engine.InstabilityError` when the integration blows up.
    """
    this_code()  # the code this run is made by, taken before it runs (engine.io.store)
    if max_wall_time is not None:
        check_interval(max_wall_time, "run_hopper.max_wall_time")
    if snapshot_interval is not None:
        check_interval(snapshot_interval, "run_hopper.snapshot_interval")
    # resolved once, naming this function's field (not Simulation's) where CUDA cannot run
    backend = resolve_backend(check_backend(backend, "run_hopper.backend"), "run_hopper.backend")

    def refuse(state) -> str | None:
        if not isinstance(state, HopperRun):
            return "holds no hopper run"
        if state.sim.backend != backend:
            return f"was written on the {state.sim.backend} backend, not the one asked for"
        return None

    checkpoint, run, load = resume(checkpoint, test, refuse, HOPPER_TRAJECTORY)
    if run is not None:
        run.setup += load
        run.t0 += load
        run.progress = progress
    else:
        run = HopperRun(test, progress, max_wall_time, wall_time_setting, threads, backend)
    run.checkpoint = checkpoint
    run.on_snapshot = on_snapshot
    run.snapshot_interval = snapshot_interval
    run.max_wall_time = max_wall_time
    run.wall_time_setting = wall_time_setting or "max_wall_time"
    if checkpoint is not None:
        checkpoint.start()
        if checkpoint.resumed_steps is not None:
            run._tick(*run.last_progress, f"{RESUMED} at step {checkpoint.resumed_steps}")
    return run.run()
