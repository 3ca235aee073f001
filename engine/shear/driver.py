"""The shear test's stages (docs/SHEAR.md): the uniaxial test's fill and consolidation under
a flat lid, the glued platens, the pre-shear to steady flow, then per shear point (each from
the stored pre-sheared state) the lid reversed to zero shear stress, the normal stress set,
and the shear to failure; the yield locus and its Mohr circles from the points.

The lid is a layer of glued grains moved as one rigid body (:meth:`Simulation.set_driven`):
along x at the stage's shear speed, along z by a normal-stress servo updated every
``SERVO_STEPS`` steps. Its normal and shear stresses are the summed contact forces on its
grains over the cross-section; the base's are read the same way (quasi-statically the two
shear stresses agree). Curves are sampled every ``output_interval`` of simulated time, each
sample the mean of the servo's readings within it.
"""

from __future__ import annotations

import math
import os
import pickle
import time
from dataclasses import replace

import numpy as np

from ..core.errors import StopRequested
from ..simulation.packing import sphere_volume
from ..uniaxial.checkpoint import TRAJECTORY_PACKAGES, Checkpoint, resume, this_code
from ..uniaxial.driver import StageError, _Driver
from ..uniaxial.measures import interior_measures, secant_slope
from ..uniaxial.results import RESUMED, Progress, ProgressCallback
from .locus import yield_locus
from .results import SHEAR_CURVE_UNITS, ShearPoint, ShearResult, ShearStage
from .spec import ShearTest

#: The engine's packages a shear run steps through (its checkpoint is resumed only by the
#: same code of these): the uniaxial run's, which fill and consolidate its bed, and its own.
SHEAR_TRAJECTORY = (*TRAJECTORY_PACKAGES, "shear")
#: Steps between two updates of the lid's servo (its force reading and its velocity).
SERVO_STEPS = 10
#: Shear strain over which a shear to failure's shear and normal stresses are smoothed
#: where its peak is sought [-]: small against the strain at which the points peak (a few
#: hundredths, docs/SHEAR.md), long enough to average the readings of tens of samples.
SMOOTHING_STRAIN = 0.01
#: Servo relaxation times from the start of a shear to failure before its peak is sought
#: [-]: the lid's start sends a shear wave through the bed, and until it has crossed it a
#: few times the shear stress rings (a rise and fall of a fifth of the yield stress within a
#: hundredth of strain, in a 20-diameter cell, size series shear/bond1/d20-s2, point 1),
#: which a drop criterion takes for failure. Three, as the normal stage holds its target
#: (six wave transits, SERVO_TRANSITS); the points' peaks come later (strains of 0.05 to 0.2
#: against about 0.02 for these three in that cell).
PEAK_SETTLE = 3.0
#: Servo relaxation time in bed wave-transit times h sqrt(rho_b / E) [-]: slower than the
#: bed's own response, so the lid does not chase its stress waves. Chosen on the tests'
#: 124-grain cell (a scan in development, not stored): at 1 transit the cohesive bed's
#: normal stress did not settle within 2 s, at 4 the lid lagged a dilating peak by 15 %,
#: at 2 every point's normal stress was within 1.5 % of its target.
SERVO_TRANSITS = 2.0
#: Integral time of the servo over its relaxation time [-] (removes the lag a steadily
#: dilating bed would otherwise keep).
SERVO_INTEGRAL = 5.0
#: Updates in a row with the lid at its speed limit, each the other way, after which the
#: servo's gain is halved (a period-2 oscillation: the bed stiffer than estimated; an EEPA
#: bed, n = 1.5, oscillated so after a reversal at 2 kPa, in development). A servo that
#: works never saturates both ways in a row.
SERVO_FLIPS = 4
#: The servo integrates its error only while it is below this fraction of the target [-]
#: (conditional integration: a large step of the target, 10 to 3 kPa, is taken by the
#: proportional term alone and leaves no integral to unwind).
SERVO_INTEGRATE_BELOW = 0.1
#: The share of the overall progress taken by the fill and the consolidation [-].
_CONSOLIDATION_SHARE = 0.3


class _Cell:
    """The shear cell on one :class:`Simulation`: glued base and lid, servo, curve rows."""

    def __init__(self, test: ShearTest, sim, base: np.ndarray, lid: np.ndarray, servo: dict):
        self.test = test
        self.sim = sim
        self.base = base
        self.lid = lid
        self.free = np.setdiff1d(np.arange(sim.n), np.concatenate([base, lid]))
        self.area = test.area
        self.servo = servo
        self.vx = 0.0
        self.vz = 0.0
        self.integral = 0.0
        self.flips = 0  # consecutive updates at the speed limit, each the other way
        self.last_sign = 0
        self.x = 0.0  # lid displacement along x since the start of the shear [m]
        self.relax = math.nan  # a point's servo relaxation time as its normal stage starts [s]
        m = sim.masses
        self.m_free = m[self.free]
        self.i_free = 0.4 * m[self.free] * sim.radii[self.free] ** 2
        self.solid_volume = float(sphere_volume(sim.radii).sum())

    # ------------------------------------------------------------------ readings
    def stresses(self) -> tuple[float, float, float, float]:
        """(tau, sigma) of the lid and of the base at the last force evaluation [Pa]: the
        contact forces of the bed on each glued layer (gravity is off) over the
        cross-section; tau positive against the lid's forward (+x) motion."""
        f = self.sim.forces
        fl = f[self.lid].sum(axis=0)
        fb = f[self.base].sum(axis=0)
        a = self.area
        return -fl[0] / a, fl[2] / a, fb[0] / a, -fb[2] / a

    def heights(self) -> tuple[float, float]:
        """(z of the base's plane, gap between the base's and the lid's planes) [m]: the
        mean centre heights of their glued grains."""
        z = self.sim.positions[:, 2]
        zb = float(z[self.base].mean())
        return zb, float(z[self.lid].mean()) - zb

    def bulk_density(self) -> float:
        """Bulk density of the bed between the glued layers [kg/m^3]: particle density times
        the solid fraction of the slab that leaves out 1.5 mean diameters next to each
        glued layer's plane (:func:`engine.uniaxial.measures.interior_measures`)."""
        zb, gap = self.heights()
        sim = self.sim
        por, _ = interior_measures(
            sim.positions[:, 2] - zb,
            sim.radii,
            np.zeros(sim.n),
            gap,
            3.0 * self.test.radius,
            self.area,
        )
        return self.test.density * (1.0 - por)

    def kinetic_energy(self) -> float:
        """Kinetic energy of the free grains, translation and rotation [J]."""
        v = self.sim.velocities[self.free]
        w = self.sim.angular_velocities[self.free]
        return 0.5 * float(
            np.sum(self.m_free * np.einsum("ij,ij->i", v, v))
            + np.sum(self.i_free * np.einsum("ij,ij->i", w, w))
        )

    # ------------------------------------------------------------------ motion
    def set_lid(self) -> None:
        self.sim.set_driven(self.lid, (self.vx, 0.0, self.vz))

    def advance(self, steps: int, target: float, stop=None) -> tuple[np.ndarray, bool]:
        """Run ``steps`` steps with the servo holding the lid's normal stress at ``target``
        [Pa]: every ``SERVO_STEPS`` steps the lid's stresses are read and its vertical speed
        set, vz = g (e + (1 / T_i) integral of e dt), e = sigma - target, at most the
        servo's speed limit (the integral taken while |e| < ``SERVO_INTEGRATE_BELOW``
        target). Returns the mean of the readings (tau, sigma, tau_base,
        sigma_base) and whether ``stop`` (a function of one reading) held at a reading (the
        run then stops there)."""
        g, ti, vmax = self.servo["gain"], self.servo["integral_time"], self.servo["max_speed"]
        dt = self.sim.dt
        acc = np.zeros(4)
        n = 0
        done = 0
        hit = False
        while done < steps:
            k = min(SERVO_STEPS, steps - done)
            self.sim.run(k)
            done += k
            self.x += self.vx * k * dt
            r = self.stresses()
            acc += r
            n += 1
            e = r[1] - target
            if abs(e) < SERVO_INTEGRATE_BELOW * target:
                self.integral += e * k * dt
            # anti-windup: the integral term alone never asks for more than the speed limit
            lim = vmax * ti / g
            self.integral = min(max(self.integral, -lim), lim)
            v = g * (e + self.integral / ti)
            self.vz = min(max(v, -vmax), vmax)
            # the guard: the lid at its speed limit, the other way at each update, for
            # SERVO_FLIPS updates in a row, is the period-2 oscillation of a gain too high
            # for this bed (its stiffness underestimated): halve the gain, start again
            sign = 0 if abs(v) < vmax else (1 if v > 0 else -1)
            self.flips = self.flips + 1 if sign != 0 and sign == -self.last_sign else 0
            self.last_sign = sign
            if self.flips >= SERVO_FLIPS:
                self.servo["gain"] *= 0.5
                self.servo["relaxation_time"] *= 2.0
                self.servo["integral_time"] *= 2.0
                self.servo["halvings"] += 1
                g, ti = self.servo["gain"], self.servo["integral_time"]
                self.integral = 0.0
                self.flips = 0
                self.vz = 0.0
            self.set_lid()
            if stop is not None and stop(r):
                hit = True
                break
        return acc / n, hit


class _Steady:
    """The pre-shear's end (:meth:`_Shear.preshear`): two consecutive windows of
    ``steady_window`` shear strain with mean shear stresses within ``steady_tolerance``,
    mean lid heights within ``steady_height_tolerance``, and the last window's mean normal
    stress within ``servo_tolerance`` of the target; StageError at ``preshear_strain``
    without it. Holds the last drifts it computed (a checkpoint keeps them)."""

    def __init__(self, test: ShearTest):
        self.test = test
        self.drift = math.inf
        self.height_drift = math.inf

    def windows(self, rows):
        w = self.test.steady_window
        a = np.array(rows)
        g = a[:, 2]
        last = g >= g[-1] - w
        prev = (g >= g[-1] - 2 * w) & ~last
        return a, last, prev

    def __call__(self, rows) -> bool:
        t = self.test
        g = rows[-1][2]
        if g < max(2 * t.steady_window, t.preshear_min_strain):
            return False
        a, last, prev = self.windows(rows)
        t1, t0 = a[last, 3].mean(), a[prev, 3].mean()
        h1, h0 = a[last, 7].mean(), a[prev, 7].mean()
        s1 = a[last, 5].mean()
        self.drift = abs(t1 - t0) / max(abs(t1), 1e-300)
        self.height_drift = abs(h1 - h0) / h1
        steady = (
            self.drift < t.steady_tolerance
            and self.height_drift < t.steady_height_tolerance
            and abs(s1 - t.preshear_stress) < t.servo_tolerance * t.preshear_stress
        )
        if steady:
            return True
        if g >= t.preshear_strain:
            raise StageError(
                f"the pre-shear did not reach steady flow within {t.preshear_strain:g} "
                f"shear strain: its mean shear stress changed by {self.drift:.1%} "
                f"over the last window of {t.steady_window:g} (steady_tolerance "
                f"{t.steady_tolerance:g}), its mean lid height by "
                f"{self.height_drift:.2%} (steady_height_tolerance "
                f"{t.steady_height_tolerance:g}), its mean normal stress is {s1:.4g} Pa "
                f"(target {t.preshear_stress:.4g} Pa)",
                "preshear",
                0,
            )
        return False

    def fraction(self, rows) -> float:
        return rows[-1][2] / self.test.preshear_strain


class _ZeroShear:
    """A point's reversal ends at the first servo reading of a lid shear stress <= 0."""

    def __call__(self, rows) -> bool:
        return False

    @staticmethod
    def instant(reading) -> bool:
        return reading[0] <= 0.0

    def fraction(self, rows) -> float:
        return 0.5


class _Held:
    """A point's normal stage ends once it has run ``3 relax`` [s] and its last two samples'
    normal stresses are within ``tol`` [Pa] of ``target`` [Pa]."""

    def __init__(self, target: float, tol: float, relax: float):
        self.target, self.tol, self.relax = target, tol, relax

    def __call__(self, rows) -> bool:
        return (
            rows[-1][0] - rows[0][0] >= 3 * self.relax
            and len(rows) >= 3
            and all(abs(r[5] - self.target) < self.tol for r in rows[-2:])
        )

    def fraction(self, rows) -> float:
        t = self.target
        return min(1.0, abs(rows[0][5] - t) / max(abs(rows[-1][5] - t), 1))


class _Failed:
    """A shear to failure ends at failure (:func:`_peak` on the smoothed shear stress,
    sought from ``settle`` [s] after the start) or at ``failure_strain``; ``peaked`` says
    which."""

    def __init__(self, test: ShearTest, settle: float):
        self.test, self.settle = test, settle
        self.peaked = False

    def __call__(self, rows) -> bool:
        a = np.array(rows)
        sm = _smoothed(a[:, 2], a[:, 3], SMOOTHING_STRAIN)
        _, dropped = _peak(a[:, 0], a[:, 2], sm, self.settle, self.test.failure_drop)
        if dropped:
            self.peaked = True
            return True
        return a[-1, 2] >= self.test.failure_strain

    def fraction(self, rows) -> float:
        return rows[-1][2] / self.test.failure_strain


class _Stage:
    """A shear stage in flight: what its loop needs to go on from its last sample (a
    checkpoint holds it)."""

    def __init__(self, name, target, vx, done, share, sample, max_steps, x0, h0, steps0):
        self.name, self.target, self.vx, self.done, self.share = name, target, vx, done, share
        self.sample, self.max_steps = sample, max_steps
        self.x0, self.h0, self.steps0 = x0, h0, steps0
        self.rows: list[tuple] = []


class _Forward:
    """Stands for the shear run's checkpoint in the consolidation's uniaxial driver: what
    that driver would write of itself, the shear run writes of itself (the driver within)."""

    def __init__(self, checkpoint, shear):
        self.checkpoint, self.shear = checkpoint, shear
        self.after_fill = checkpoint.after_fill

    def due(self, _driver) -> bool:
        return self.checkpoint.due(self.shear)

    def save(self, _driver) -> None:
        self.checkpoint.save(self.shear)


class _Shear:
    """Runs one shear test: the fill and consolidation, the glued platens, the pre-shear
    and the points, as a machine that a checkpoint (a pickle of it between two curve
    samples) re-enters where it was: ``cons`` (the consolidation's uniaxial driver, until
    the platens are glued), ``cell`` (the cell being sheared: the pre-sheared one, then each
    point's branch), ``current`` (the stage in flight), ``presheared`` (the pickled
    pre-sheared cell every point starts from) and ``points`` (the points done)."""

    trajectory_packages = SHEAR_TRAJECTORY

    def __init__(self, test: ShearTest, progress: ProgressCallback | None):
        self.test = test
        self.progress = progress
        self.checkpoint = None
        self.t_wall = time.perf_counter()
        self.setup_time = 0.0
        self.stages: dict[str, ShearStage] = {}
        self.criteria: dict = {}  # each finished stage's criterion as the stage left it
        self.d = 2.0 * test.radius
        self.last_fraction = 0.0
        self.cons = None
        self.cons_stages: dict | None = None
        self.cell: _Cell | None = None
        self.current: _Stage | None = None
        self.pre: dict | None = None
        self.presheared: bytes | None = None
        self.pre_steps = 0
        self.pre_servo: dict = {}
        self.points: list[ShearPoint] = []
        self.steps = 0
        self.halvings = 0

    # ------------------------------------------------------------------ checkpoints
    @property
    def sim(self):
        """The simulation now stepping (:class:`engine.uniaxial.checkpoint.Checkpoint`
        reads its step count)."""
        return self.cell.sim if self.cell is not None else self.cons.sim

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["progress"] = state["checkpoint"] = None
        # wall time so far instead of the start of a clock that does not survive the process
        state["t_wall"] = time.perf_counter() - self.t_wall
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.t_wall = time.perf_counter() - state["t_wall"]

    def _due(self) -> None:
        if self.checkpoint is not None:
            self.checkpoint.due(self)

    # ------------------------------------------------------------------ progress
    def report(
        self, stage: str, fraction: float, sim, share: tuple[float, float], msg="running"
    ) -> None:
        if self.progress is None:
            return
        f = min(max(fraction, 0.0), 1.0)
        lo, hi = share
        # stresses fluctuate: never report less progress than before
        self.last_fraction = max(self.last_fraction, lo + (hi - lo) * f)
        answer = self.progress(Progress(self.last_fraction, stage, f, sim.time, sim.steps, msg))
        if answer is False:
            raise StopRequested(f"stopped by the progress callback during {stage}")

    def _cons_progress(self, p: Progress):
        if self.progress is None:
            return None
        share = _CONSOLIDATION_SHARE / 0.5  # the two stages are half the uniaxial's weights
        return self.progress(replace(p, fraction=min(1.0, p.fraction) * share * 0.5))

    # ------------------------------------------------------------------ set-up
    def consolidate(self) -> _Driver:
        """The uniaxial test's fill and pre-compression (to the pre-shear stress, gravity off
        after the fill): the consolidated bed under a flat lid (resumed where a checkpoint
        left it); returns the uniaxial driver that holds it."""
        if self.cons is None:
            self.cons = _Driver(self.test.consolidation_test(), None)
            self.setup_time = self.cons.setup_time
        d = self.cons
        d.progress = self._cons_progress if self.progress is not None else None
        d.checkpoint = None if self.checkpoint is None else _Forward(self.checkpoint, self)
        for stage in ("fill", "pre_compression"):
            if stage in d.stages:
                continue
            if d.current is None or d.current.stage != stage:
                d.begin(stage)
            d.loop()
            d.end(stage)
            if stage == "fill" and d.checkpoint is not None and d.checkpoint.after_fill:
                d.checkpoint.save(d)  # the settled bed: never poured again
        # the uniaxial driver's reports between kernel calls end with its stages (the shear
        # stages report after every curve sample)
        d.sim.between_calls = None
        return d

    def glue(self, d) -> _Cell:
        """Glue the grains within ``platen_layer`` mean diameters of the floor and of the
        flat lid, move the flat walls out of reach (the floor a quarter radius below the
        base's lowest grain, the lid far above) and size the servo from the consolidation's
        loading curve."""
        t = self.test
        sim = d.sim
        z = sim.positions[:, 2]
        r = sim.radii
        floor = float(sim.wall_positions[0, 2])
        top = float(sim.wall_positions[1, 2])
        layer = t.platen_layer * self.d
        base = np.nonzero(z - floor < layer)[0]
        lid = np.nonzero(top - z < layer)[0]
        if base.size == 0 or lid.size == 0 or base.size + lid.size >= sim.n:
            raise StageError(
                f"gluing the platens: {base.size} base and {lid.size} lid grains of {sim.n}: "
                "the consolidated bed is too thin for its glued layers (a taller cell)",
                "glue",
                0,
            )
        sim.set_driven(base, (0.0, 0.0, 0.0))
        sim.set_driven(lid, (0.0, 0.0, 0.0))
        low = float(np.min(z[base] - r[base]))
        sim.set_wall_position(0, (0.0, 0.0, low - 0.25 * t.radius))
        sim.set_wall_position(1, (0.0, 0.0, top + 1e3 * t.radius))
        # the servo: the bed's stiffness E from the consolidation's loading curve (the secant
        # over its upper half), times the law's unloading stiffness over its loading secant
        # (unloading_ratio); its relaxation time SERVO_TRANSITS wave transits
        # h sqrt(rho_b / E), at least 4 servo updates
        cons = d.stages["pre_compression"].curves
        e_load = secant_slope(cons["strain"], cons["stress_top"], 0.5, 1.0)
        stiff = e_load * unloading_ratio(t.pair_law)
        cell = _Cell(t, sim, base, lid, {})
        _, gap = cell.heights()
        rho_b = cell.bulk_density()
        if not (math.isfinite(stiff) and stiff > 0):
            raise StageError(
                f"the consolidation's loading stiffness is {e_load:.4g} Pa: no servo gain",
                "glue",
                0,
            )
        transit = gap * math.sqrt(rho_b / stiff)
        relax = max(SERVO_TRANSITS * transit, 4 * SERVO_STEPS * sim.dt)
        cell.servo = {
            "gain": gap / (stiff * relax),
            "integral_time": SERVO_INTEGRAL * relax,
            "max_speed": t.max_shear_speed,
            "relaxation_time": relax,
            "halvings": 0,
        }
        return cell

    # ------------------------------------------------------------------ stages
    def shear_speed(self, gap: float, sigma: float) -> float:
        """The lid's shear speed [m/s] for the gap [m] at the normal stress [Pa]: the
        ``inertial_number`` over the gap, at most ``max_shear_speed``."""
        t = self.test
        v = t.inertial_number * gap / self.d * math.sqrt(sigma / t.density)
        return min(v, t.max_shear_speed)

    def started(self, name: str) -> bool:
        """Whether stage ``name`` is done or in flight (a resumed run does not set it up
        again)."""
        return name in self.stages or (self.current is not None and self.current.name == name)

    def _row(self, st: _Stage, means) -> tuple:
        cell, t, sim = self.cell, self.test, self.cell.sim
        _, gap = cell.heights()
        p = max(st.target, 1e-9)
        return (
            sim.time,
            cell.x - st.x0,
            (cell.x - st.x0) / st.h0,
            means[0],
            means[2],
            means[1],
            means[3],
            gap,
            cell.bulk_density(),
            cell.kinetic_energy(),
            abs(st.vx) / gap * self.d * math.sqrt(t.density / p),
        )

    def stage(self, name: str, target: float, vx: float, done, share) -> tuple[dict, object]:
        """Run one stage on ``self.cell`` (or go on with it where a checkpoint left it, or
        return its curves where it is done): the lid at shear speed ``vx`` [m/s] and its
        servo at ``target`` [Pa], a curve sample every ``output_interval`` until
        ``done(rows)`` holds (or, with an instant criterion, ``done.instant`` at a servo
        reading; ``done.fraction(rows)`` is the stage's progress); StageError past
        ``max_stage_time``. A checkpoint may be written after each sample that did not end
        the stage. Returns the curves and the criterion as the stage left it."""
        if name in self.stages:
            return self.stages[name].curves, self.criteria[name]
        t = self.test
        cell = self.cell
        sim = cell.sim
        st = self.current
        if st is None or st.name != name:
            cell.vx = vx
            cell.set_lid()
            _, h0 = cell.heights()
            st = _Stage(
                name,
                target,
                vx,
                done,
                share,
                SERVO_STEPS * max(1, round(t.output_interval / sim.dt / SERVO_STEPS)),
                round(t.max_stage_time / sim.dt),
                cell.x,
                h0,
                sim.steps,
            )
            st.rows.append(self._row(st, np.array(cell.stresses())))
            self.current = st
        rows = st.rows
        instant = getattr(st.done, "instant", None)
        while True:
            if sim.steps - st.steps0 >= st.max_steps:
                r = rows[-1]
                raise StageError(
                    f"stage {name} did not end within {sim.steps - st.steps0} steps "
                    f"({t.max_stage_time:g} s, max_stage_time); now: shear stress "
                    f"{r[3]:.4g} Pa, normal stress {r[5]:.4g} Pa (target {target:.4g} Pa), "
                    f"shear strain {r[2]:.4g}",
                    name,
                    sim.steps - st.steps0,
                )
            means, hit = cell.advance(st.sample, st.target, instant)
            rows.append(self._row(st, means))
            self.report(name, st.done.fraction(rows), sim, st.share)
            if hit or st.done(rows):
                break
            self._due()
        a = np.array(rows, dtype=float)
        curves = {k: a[:, i].copy() for i, k in enumerate(SHEAR_CURVE_UNITS)}
        for k, v in curves.items():
            if not np.all(np.isfinite(v)):
                raise FloatingPointError(f"stage {name}: non-finite values in the {k} curve")
        self.stages[name] = ShearStage(name, curves, sim.steps - st.steps0)
        self.criteria[name] = st.done
        self.current = None
        return curves, st.done

    def preshear(self, share) -> dict:
        """Shear at the pre-shear stress, at least ``preshear_min_strain``, until it is
        steady (:class:`_Steady`). The pre-shear point is the mean (sigma, tau) over the
        last window."""
        t = self.test
        v = 0.0  # resumed: the stage's own speed, set when it started
        if not self.started("preshear"):
            _, gap = self.cell.heights()
            v = self.shear_speed(gap, t.preshear_stress)
        c, steady = self.stage("preshear", t.preshear_stress, v, _Steady(t), share)
        last = c["shear_strain"] >= c["shear_strain"][-1] - t.steady_window
        return {
            "sigma": float(c["normal_stress"][last].mean()),
            "tau": float(c["shear_stress"][last].mean()),
            "strain": float(c["shear_strain"][-1]),
            "drift": steady.drift,
            "height_drift": steady.height_drift,
            "bulk_density": float(c["bulk_density"][last].mean()),
        }

    def point(self, k: int, target: float, share) -> ShearPoint:
        """One shear point on ``self.cell`` (a branch of the pre-sheared state): reverse the
        lid until the shear stress is zero, set the normal stress, shear to failure (each
        stage skipped or gone on with where a checkpoint left the point)."""
        t = self.test
        cell = self.cell
        lo, hi = share
        parts = [(lo, lo + 0.1 * (hi - lo)), (lo + 0.1 * (hi - lo), lo + 0.3 * (hi - lo))]
        parts.append((parts[1][1], hi))
        reverse, normal, shear = (f"point{k}_{s}" for s in ("reverse", "normal", "shear"))
        v = 0.0  # resumed: the stage's own speed, set when it started
        if not self.started(reverse):
            _, gap = cell.heights()
            v = -self.shear_speed(gap, t.preshear_stress)
        self.stage(reverse, t.preshear_stress, v, _ZeroShear(), parts[0])
        if not self.started(normal):
            cell.integral = 0.0  # a new target: the old integral is the old target's lag
            cell.relax = cell.servo["relaxation_time"]  # the point's, as its normal stage starts
        relax = cell.relax
        self.stage(normal, target, 0.0, _Held(target, t.servo_tolerance * target, relax), parts[1])
        settle = PEAK_SETTLE * relax
        v = 0.0
        if not self.started(shear):
            _, gap = cell.heights()
            v = self.shear_speed(gap, target)
        c, failed = self.stage(shear, target, v, _Failed(t, settle), parts[2])
        g = c["shear_strain"]
        tau = _smoothed(g, c["shear_stress"], SMOOTHING_STRAIN)
        sig = _smoothed(g, c["normal_stress"], SMOOTHING_STRAIN)
        i, _ = _peak(c["time"], g, tau, settle, t.failure_drop)
        return ShearPoint(target, float(sig[i]), float(tau[i]), float(g[i]), failed.peaked)

    def run(self) -> ShearResult:
        """Run (or, resumed from a checkpoint, go on with) the stages, then the locus."""
        t = self.test
        if self.cell is None:
            self.cell = self.glue(self.consolidate())
            self.cons_stages = dict(self.cons.stages)
            self.cons = None
        n = len(t.normal_stresses)
        span = 1.0 - _CONSOLIDATION_SHARE
        pre_share = (_CONSOLIDATION_SHARE, _CONSOLIDATION_SHARE + span / (n + 1))
        if self.pre is None:
            self.pre = self.preshear(pre_share)
            self.presheared = pickle.dumps(self.cell)
            self.pre_steps = self.cell.sim.steps
            # every step run: the fill, consolidation, pre-shear, each branch
            self.steps = self.pre_steps
            self.halvings = self.cell.servo["halvings"]
            self.pre_servo = dict(self.cell.servo)
        pre = self.pre
        for k in range(len(self.points), n):
            if not self.started(f"point{k}_reverse"):
                self.cell = pickle.loads(self.presheared)
            lo = pre_share[1] + span / (n + 1) * k
            self.points.append(self.point(k, t.normal_stresses[k], (lo, lo + span / (n + 1))))
            self.steps += self.cell.sim.steps - self.pre_steps
            self.halvings = max(self.halvings, self.cell.servo["halvings"])
        points, cell, steps, halvings = self.points, self.cell, self.steps, self.halvings
        sim = cell.sim
        try:
            locus = yield_locus(
                [p.sigma for p in points], [p.tau for p in points], pre["sigma"], pre["tau"]
            )
        except ValueError as e:
            raise StageError(f"the yield locus: {e}", "locus", 0) from None
        s = {
            "preshear_sigma": pre["sigma"],
            "preshear_tau": pre["tau"],
            "preshear_strain": pre["strain"],
            "preshear_drift": float(pre["drift"]),
            "preshear_height_drift": float(pre["height_drift"]),
            "cohesion": locus.cohesion,
            "cohesion_se": locus.cohesion_se,
            "friction_angle": locus.friction_angle,
            "effective_friction_angle": locus.effective_friction_angle,
            "sigma_c": locus.sigma_c,
            "sigma_1": locus.sigma_1,
            "sigma_2": locus.sigma_2,
            "ffc": locus.ffc,
            "preshear_above": locus.preshear_above,
            "bulk_density": pre["bulk_density"],
            "bulk_density_consolidated": float(self.stages["preshear"].curves["bulk_density"][0]),
            "height_diameters": float(self.stages["preshear"].curves["lid_height"][0]) / self.d,
            "glued_base": float(cell.base.size),
            "glued_lid": float(cell.lid.size),
            "particles": float(sim.n),
            "servo_time": self.pre_servo["relaxation_time"],
            "servo_gain": self.pre_servo["gain"],
            "servo_halvings": float(halvings),
            "steps": float(steps),
            "particle_steps": float(sim.n) * float(steps),
            "thickness_diameters": t.thickness_diameters,
            "dt": sim.dt,
            "wall_time": time.perf_counter() - self.t_wall - self.setup_time,
        }
        bad = [k for k, v in s.items() if math.isnan(v) or (math.isinf(v) and k != "ffc")]
        if bad:
            raise FloatingPointError(f"non-finite scalars {bad}: the shear test is not usable")
        return ShearResult(t, dict(self.cons_stages), self.stages, tuple(points), locus, s)


def unloading_ratio(law) -> float:
    """A contact's unloading tangent stiffness over its loading secant stiffness [-], the
    factor from the bed's loading secant to the stiffness the servo sizes its gain by: for
    a law f = K1 d^n on loading and K2 (d^n - d_p^n) on unloading (the bilinear law, n = 1;
    EEPA, its n), n K2 / K1; for Hertz (f ~ d^1.5, elastic), 1.5."""
    k1, k2 = getattr(law, "k1", None), getattr(law, "k2", None)
    if k1 is None or k2 is None:
        return 1.5
    return max(1.0, float(getattr(law, "n", 1.0)) * k2 / k1)


def _peak(
    time: np.ndarray, strain: np.ndarray, sm: np.ndarray, settle: float, drop: float
) -> tuple[int, bool]:
    """A shear to failure's peak: the index of the largest smoothed shear stress ``sm``
    [Pa] (:func:`_smoothed` over :data:`SMOOTHING_STRAIN` of ``strain`` [-]) among the
    samples at least ``settle`` [s] of ``time`` [s] after the first, and whether the curve
    has since fallen ``drop`` [-] below it over at least :data:`SMOOTHING_STRAIN` of strain
    (failure). A curve with no sample that late has not failed (its peak: the largest of
    all its samples)."""
    j0 = int(np.searchsorted(time, time[0] + settle))
    if j0 >= len(sm):
        return int(np.argmax(sm)), False
    i = j0 + int(np.argmax(sm[j0:]))
    return i, bool(sm[-1] < (1 - drop) * sm[i] and strain[-1] - strain[i] >= SMOOTHING_STRAIN)


def _smoothed(strain: np.ndarray, values: np.ndarray, window: float) -> np.ndarray:
    """Centred moving average of ``values`` over ``window`` of shear strain [-]
    (truncated at the ends)."""
    c = np.concatenate([[0.0], np.cumsum(values)])
    lo = np.searchsorted(strain, strain - 0.5 * window)
    hi = np.searchsorted(strain, strain + 0.5 * window, side="right")
    return (c[hi] - c[lo]) / np.maximum(hi - lo, 1)


def run_shear(
    test: ShearTest,
    progress: ProgressCallback | None = None,
    *,
    checkpoint: Checkpoint | str | os.PathLike | None = None,
) -> ShearResult:
    """Run the shear test (docs/SHEAR.md): fill, consolidation to ``preshear_stress`` under a
    flat lid, glued platens, pre-shear to steady flow, then each shear point from the
    stored pre-sheared state (lid reversed to zero shear stress, normal stress set, shear
    to failure), and the yield locus with its Mohr circles.

    Args:
        test: the parameters (:class:`engine.ShearTest`).
        progress: called after every curve sample with a :class:`engine.Progress`;
            returning ``False`` stops the run with :class:`engine.StopRequested`.
        checkpoint: a :class:`engine.Checkpoint` (or its path, written every
            ``CHECKPOINT_INTERVAL`` s): the run resumes from it when it holds this test's
            state (written by the same code of :data:`SHEAR_TRAJECTORY`), and writes it
            between curve samples as it goes and once the fill has settled; the result is
            bit-identical to that of an uninterrupted run
            (tests/engine/test_shear.py). The file is left for the caller to remove once
            the result is stored (:meth:`engine.Checkpoint.remove`).
    Raises: :class:`engine.StageError` when a stage misses its criterion within its bound
        (a pre-shear that does not reach steady flow, a normal stress not held), or when
        the shear points give no yield locus (a slope <= 0); FloatingPointError for a
        non-finite curve or scalar; :class:`engine.InstabilityError` when the integration
        blows up. The CPU backend.
    """
    if not isinstance(test, ShearTest):
        raise TypeError(f"run_shear takes an engine.ShearTest, not {type(test).__name__}")
    this_code()  # the code this run is made by, taken before it runs (engine.io.store)

    def refuse(state) -> str | None:
        return None if isinstance(state, _Shear) else "holds no shear run"

    checkpoint, run, load = resume(checkpoint, test, refuse, SHEAR_TRAJECTORY)
    if run is not None:
        run.setup_time += load
        run.t_wall -= load  # wall_time = now - t_wall - setup_time
        run.progress = progress
    else:
        run = _Shear(test, progress)
    run.checkpoint = checkpoint
    if checkpoint is not None:
        checkpoint.start()
        if checkpoint.resumed_steps is not None and run.progress is not None:
            msg = f"{RESUMED} at step {checkpoint.resumed_steps}"
            st = run.current
            if st is not None:  # within a shear stage
                run.report(st.name, st.done.fraction(st.rows), run.sim, st.share, msg)
            else:  # in the consolidation (within its stage, or its fill just ended)
                run.cons.progress = run._cons_progress
                run.cons.report(run.cons.stage_now, run.cons.stage_fraction, msg)
    return run.run()
