"""The uniaxial test: fill, pre-compression, confined consolidation and unloading, release of
the periodic confinement, unconfined compression to failure (PHYSICS.md section 4).

:class:`UniaxialTest` holds every parameter (validated once); :func:`run_uniaxial` runs the
stages in order. Every stage ends on a physical criterion and has a bound on its steps that
fails the run with :class:`StageError` rather than hanging. Curves are sampled every
``output_interval`` seconds of simulated time.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from .config import MAX_OVERLAP_FRACTION
from .errors import ParameterError, StopRequested
from .materials import BilinearAdhesive, HertzMindlin, WallMaterial
from .packing import draw_radii, loose_packing, sphere_volume
from .scene import Plane, Scene
from .simulation import Simulation
from .stability import adhesion_overlap, critical_time_step

GRAVITY = 9.81  # [m/s^2]

STAGES = ("fill", "pre_compression", "consolidation", "unloading", "release", "unconfined")

#: Units of the curves of every stage.
CURVE_UNITS = {
    "time": "s",
    "strain": "1",
    "stress_top": "Pa",
    "stress_bottom": "Pa",
    "porosity": "1",
    "coordination": "1",
    "kinetic_energy": "J",
    "inertial_number": "1",
    "platen_gap": "m",
}

#: Stage weights of the overall progress fraction.
_WEIGHTS = {"fill": 0.3, "pre_compression": 0.05, "consolidation": 0.25, "unloading": 0.1,
            "release": 0.1, "unconfined": 0.2}


class StageError(RuntimeError):
    """A stage did not reach its end criterion within its bound on steps.

    Attributes: ``stage`` (name), ``steps`` (steps spent in the stage).
    """

    def __init__(self, message: str, stage: str, steps: int):
        self.stage = stage
        self.steps = steps
        super().__init__(message)


@dataclass(frozen=True)
class Progress:
    """What a progress callback receives.

    Attributes: ``fraction`` of the whole test in [0, 1], ``stage`` name, ``stage_fraction``
    in [0, 1], simulated ``time`` [s], ``steps`` so far, ``message``.
    """

    fraction: float
    stage: str
    stage_fraction: float
    time: float
    steps: int
    message: str = ""


ProgressCallback = Callable[[Progress], object]


@dataclass(frozen=True)
class UniaxialTest:
    """Parameters of one uniaxial test (SI units).

    Attributes:
        cell: (Lx, Ly, Lz) fill cell [m]; periodic in x and y during filling and
            consolidation, Lz is the height of the region the particles are poured from.
        radius: particle radius [m].
        polydispersity: radii uniform in [R (1 - p), R (1 + p)] [-], in [0, 0.5).
        density: particle density [kg/m^3].
        fill_fraction: solid fraction of the poured cloud [-], in (0, 0.32]; it sets the amount
            of material: N = fill_fraction * cell volume / particle volume.
        pair_law: particle-particle law (:class:`BilinearAdhesive` or :class:`HertzMindlin`).
        wall_law: platen law (:class:`HertzMindlin`; its E, nu are the particles').
        wall_material: platen material.
        pre_stress: pre-compression stress [Pa].
        consolidation_stress: consolidation stress [Pa], > pre_stress.
        platen_speed: top platen speed [m/s].
        unloaded_stress: unloading ends when the top stress is below this fraction of the
            consolidation stress [-].
        unconfined: run the release and unconfined compression stages.
        failure_drop: unconfined compression ends when the stress has fallen this fraction
            below its peak [-] ...
        failure_strain: ... and has stayed there for this much further axial strain [-].
        max_unconfined_strain: unconfined compression also ends at this strain [-] (samples
            without a peak, e.g. cohesionless ones).
        settle_ke: a settling stage ends when the kinetic energy is below this fraction of
            N m g R (the energy of lifting every particle by one radius) [-].
        release_time: the release stage also ends after this much simulated time [s]: a
            sample without cohesion collapses and its particles roll away on the unbounded
            bottom platen for a long time; by then the collapse is over.
        seed: random seed of the packing.
        output_interval: simulated time between curve samples [s].
        dt: time step [s]; None lets the engine choose from its stability limits.
        max_stage_time: bound on the simulated time of any single stage [s].
    """

    cell: tuple[float, float, float] = (0.05, 0.05, 0.1)
    radius: float = 2.5e-3
    polydispersity: float = 0.0
    density: float = 2000.0
    fill_fraction: float = 0.3
    pair_law: BilinearAdhesive | HertzMindlin = field(
        default_factory=lambda: BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.5,
                                                 mu_r=0.001, restitution=0.4))
    wall_law: HertzMindlin = field(
        default_factory=lambda: HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.3))
    wall_material: WallMaterial = field(default_factory=WallMaterial)
    pre_stress: float = 5e3
    consolidation_stress: float = 20e3
    platen_speed: float = 0.01
    unloaded_stress: float = 0.01
    unconfined: bool = True
    failure_drop: float = 0.2
    failure_strain: float = 0.005
    max_unconfined_strain: float = 0.1
    settle_ke: float = 1e-4
    release_time: float = 0.2
    seed: int = 1
    output_interval: float = 1e-3
    dt: float | None = 1e-5
    max_stage_time: float = 5.0

    def __post_init__(self) -> None:
        o = "UniaxialTest"
        cell = tuple(float(c) for c in self.cell)
        if len(cell) != 3 or not all(math.isfinite(c) and c > 0 for c in cell):
            raise ParameterError(f"{o}.cell", self.cell, "three lengths > 0 m")
        object.__setattr__(self, "cell", cell)

        def num(name, ok, limit):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParameterError(f"{o}.{name}", v, "a finite number")
            if not ok(v):
                raise ParameterError(f"{o}.{name}", v, limit)

        num("radius", lambda v: v > 0, "> 0 m")
        num("polydispersity", lambda v: 0 <= v < 0.5, "in [0, 0.5)")
        num("density", lambda v: v > 0, "> 0 kg/m^3")
        num("fill_fraction", lambda v: 0 < v <= 0.32, "in (0, 0.32] (random addition jams "
            "near 0.38)")
        num("pre_stress", lambda v: v > 0, "> 0 Pa")
        num("consolidation_stress", lambda v: v > self.pre_stress,
            f"> pre_stress = {self.pre_stress:g} Pa")
        num("platen_speed", lambda v: v > 0, "> 0 m/s")
        num("unloaded_stress", lambda v: 0 < v < 1, "in (0, 1)")
        num("failure_drop", lambda v: 0 < v < 1, "in (0, 1)")
        num("failure_strain", lambda v: 0 <= v < 0.5, "in [0, 0.5)")
        num("max_unconfined_strain", lambda v: 0 < v < 0.8, "in (0, 0.8)")
        num("settle_ke", lambda v: v > 0, "> 0")
        num("release_time", lambda v: v > 0, "> 0 s")
        num("output_interval", lambda v: v > 0, "> 0 s")
        num("max_stage_time", lambda v: v > 0, "> 0 s")
        if self.dt is not None:
            num("dt", lambda v: v > 0, "> 0 s or None (automatic)")
        if not isinstance(self.unconfined, bool):
            raise ParameterError(f"{o}.unconfined", self.unconfined, "true or false")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ParameterError(f"{o}.seed", self.seed, "an integer >= 0")
        if not isinstance(self.pair_law, (BilinearAdhesive, HertzMindlin)):
            raise ParameterError(f"{o}.pair_law", self.pair_law,
                                 "an engine.BilinearAdhesive or engine.HertzMindlin")
        if not isinstance(self.wall_law, HertzMindlin):
            raise ParameterError(f"{o}.wall_law", self.wall_law, "an engine.HertzMindlin")
        if not isinstance(self.wall_material, WallMaterial):
            raise ParameterError(f"{o}.wall_material", self.wall_material,
                                 "an engine.WallMaterial")
        rmax = self.radius * (1 + self.polydispersity)
        for a, name in ((0, "x"), (1, "y")):
            if cell[a] < 2.4 * 2 * rmax:
                raise ParameterError(f"{o}.cell", f"{cell[a]:g} m along {name}",
                                     f">= {4.8 * rmax:.4g} m (2.4 largest diameters) for the "
                                     "periodic minimum image")
        if cell[2] < 8 * rmax:
            raise ParameterError(f"{o}.cell", f"{cell[2]:g} m along z",
                                 f">= {8 * rmax:.4g} m (4 largest diameters)")
        self._check_runnable()

    def _check_runnable(self) -> None:
        """Refuse, before anything runs, what the engine would refuse in the middle of a run:
        a fill the packer cannot place, an adhesion that pulls contacts too deep, a time step
        above the stable limit."""
        o = "UniaxialTest"
        rmin = self.radius * (1 - self.polydispersity)
        law = self.pair_law
        d_eq = adhesion_overlap(law, rmin, MAX_OVERLAP_FRACTION)
        if d_eq is not None:
            raise ParameterError(f"{o}.pair_law.f0", law.f0,
                                 f">= {-MAX_OVERLAP_FRACTION * rmin * law.k1:.4g} N",
                                 f"|f0|/k1 = {d_eq:.3g} m would pull contacts beyond "
                                 f"{MAX_OVERLAP_FRACTION:g} x the smallest radius")
        if self.dt is not None:
            lim = self.time_step_limit()
            if self.dt > lim.dt:
                raise ParameterError(f"{o}.dt", self.dt, f"<= {lim.dt:.4g} s, the stable limit "
                                     f"set by {lim.reason} (recommended {lim.recommended:.4g} s)")
        # the packer is deterministic for a seed: place the fill now, exactly as the run will
        try:
            self.initial_packing()
        except ParameterError as e:
            raise ParameterError(f"{o}.fill_fraction", self.fill_fraction,
                                 "low enough for the fill to be placed without overlap",
                                 f"{e}; lower fill_fraction or raise cell[2]") from None

    def time_step_limit(self):
        """:func:`engine.critical_time_step` of this test's laws for its lightest particles
        and the free fall over its cell height (a two-particle stand-in for the packing)."""
        rmin = self.radius * (1 - self.polydispersity)
        lx, ly, lz = self.cell
        pos = np.array([(lx / 2, ly / 2, rmin), (lx / 2, ly / 2, lz - rmin)])
        return critical_time_step(self.scene(pos, np.full(2, rmin)))

    def scene(self, positions: np.ndarray, radii: np.ndarray) -> Scene:
        """The test's scene for particles at ``positions`` [m] with ``radii`` [m]: periodic
        x and y, gravity, the bottom platen at z = 0 and the top one above the cell."""
        lx, ly, lz = self.cell
        walls = [Plane((0, 0, 0), (0, 0, 1)), Plane((0, 0, lz + 4 * self.radius), (0, 0, -1))]
        return Scene(positions, radii, self.density, box=[(0, lx), (0, ly), (0, lz)],
                     periodic=(True, True, False), walls=walls, gravity=(0, 0, -GRAVITY),
                     pair_law=self.pair_law, wall_law=self.wall_law,
                     wall_material=self.wall_material)

    def initial_packing(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and radii [m] of the poured fill: ``n_particles`` overlap-free
        spheres in the cell (periodic x and y), from ``seed``."""
        pos, radii = _packing(self.n_particles, self.radius, self.polydispersity, self.seed,
                              self.cell)
        return pos.copy(), radii.copy()

    def resolved_dt(self) -> float:
        """The time step a run of this test takes [s]: ``dt``, or the recommended one."""
        return self.dt if self.dt is not None else self.time_step_limit().recommended

    @property
    def n_particles(self) -> int:
        """Number of particles: fill_fraction x cell volume / mean particle volume."""
        mean_vol = sphere_volume(self.radius) * (1 + self.polydispersity**2)  # E[r^3] / R^3
        return max(2, round(self.fill_fraction * np.prod(self.cell) / mean_vol))

    def to_dict(self) -> dict:
        """JSON-friendly parameters (laws as nested dicts with a ``type``)."""
        d = asdict(self)
        d["cell"] = list(self.cell)
        d["pair_law"] = {"type": type(self.pair_law).__name__, **asdict(self.pair_law)}
        d["wall_law"] = {"type": "HertzMindlin", **asdict(self.wall_law)}
        d["wall_material"] = asdict(self.wall_material)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> UniaxialTest:
        """Inverse of :meth:`to_dict`; unknown keys raise :class:`ParameterError`."""
        d = dict(d)
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ParameterError("UniaxialTest", sorted(unknown), f"fields among {sorted(known)}")
        if isinstance(d.get("pair_law"), dict):
            pl = dict(d["pair_law"])
            kind = pl.pop("type", "BilinearAdhesive")
            law_cls = {"BilinearAdhesive": BilinearAdhesive, "HertzMindlin": HertzMindlin}.get(kind)
            if law_cls is None:
                raise ParameterError("UniaxialTest.pair_law.type", kind,
                                     "BilinearAdhesive or HertzMindlin")
            d["pair_law"] = law_cls(**pl)
        if isinstance(d.get("wall_law"), dict):
            wl = dict(d["wall_law"])
            wl.pop("type", None)
            d["wall_law"] = HertzMindlin(**wl)
        if isinstance(d.get("wall_material"), dict):
            d["wall_material"] = WallMaterial(**d["wall_material"])
        if "cell" in d:
            if not isinstance(d["cell"], (list, tuple)):
                raise ParameterError("UniaxialTest.cell", d["cell"], "three lengths > 0 m")
            d["cell"] = tuple(d["cell"])
        return cls(**d)


@functools.lru_cache(maxsize=16)
def _packing(n: int, radius: float, polydispersity: float, seed: int,
             cell: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The poured fill, computed once: admission (every UniaxialTest places its fill when it
    is built) and the run use the same one."""
    radii = draw_radii(n, radius, polydispersity, seed)
    lx, ly, lz = cell
    return loose_packing(radii, [(0, lx), (0, ly), (0, lz)], seed=seed), radii


def preset(name: str, **overrides) -> UniaxialTest:
    """A named test: ``"paper"`` (Thakur et al. 2013: 50 x 150 x 300 mm cell, R = 2.5 mm,
    10 mm/s platen, dt = 1e-5 s) or ``"quick"`` (50 x 50 x 100 mm cell: a full reference run
    in about a minute on 2 cores, same law, speed and step). Keyword overrides replace fields.
    """
    if name == "paper":
        base = UniaxialTest(cell=(0.05, 0.15, 0.30))
    elif name == "quick":
        base = UniaxialTest(cell=(0.05, 0.05, 0.1))
    else:
        raise ParameterError("preset", name, "'paper' or 'quick'")
    return replace(base, **overrides) if overrides else base


@dataclass
class StageResult:
    """Curves of one stage (1-D arrays of equal length, units in :data:`CURVE_UNITS`) and the
    particle positions [m] and radii [m] at its end."""

    name: str
    curves: dict[str, np.ndarray]
    positions: np.ndarray
    radii: np.ndarray
    steps: int


@dataclass
class UniaxialResult:
    """Result of :func:`run_uniaxial`.

    Attributes: ``test`` (the parameters), ``stages`` (name -> :class:`StageResult`, in order),
    ``scalars`` (name -> value; see :data:`SCALAR_UNITS`).
    """

    test: UniaxialTest
    stages: dict[str, StageResult]
    scalars: dict[str, float]


#: Units of the scalars of a :class:`UniaxialResult`.
SCALAR_UNITS = {
    "unconfined_strength": "Pa",
    "strain_at_peak": "1",
    "loading_stiffness": "Pa",
    "unloading_stiffness": "Pa",
    "consolidated_porosity": "1",
    "particles": "1",
    "steps": "1",
    "dt": "s",
    "wall_time": "s",
    "setup_time": "s",
    "particle_steps": "1",
    "max_inertial_number": "1",
}


class _Recorder:
    """Samples the curves of one stage."""

    def __init__(self, driver: _Driver, stage: str, h0: float):
        self.d = driver
        self.stage = stage
        self.h0 = h0
        self.rows: list[tuple] = []
        self.steps0 = driver.sim.steps

    def sample(self) -> tuple:
        d = self.d
        sim = d.sim
        f = sim.wall_forces
        area = d.area
        gap = d.gap()
        s_top = float(f[1, 2]) / area if d.n_walls > 1 else 0.0
        s_bot = -float(f[0, 2]) / area
        porosity = 1.0 - d.solid_volume / (area * gap)
        coordination = 2.0 * sim.n_contacts() / sim.n
        ke = sim.kinetic_energy()
        speed = abs(float(sim.wall_velocities[1, 2])) if d.n_walls > 1 else 0.0
        # inertial number with the pressure floored at the weight of one particle layer
        p = max(abs(s_top), abs(s_bot), d.layer_stress)
        inertial = speed / gap * 2.0 * d.test.radius * math.sqrt(d.test.density / p)
        row = (sim.time, (self.h0 - gap) / self.h0, s_top, s_bot, porosity, coordination, ke,
               inertial, gap)
        self.rows.append(row)
        return row

    def result(self) -> StageResult:
        a = np.array(self.rows, dtype=float).reshape(-1, len(CURVE_UNITS))
        curves = {k: a[:, i].copy() for i, k in enumerate(CURVE_UNITS)}
        for k, v in curves.items():
            if not np.all(np.isfinite(v)):
                raise FloatingPointError(f"stage {self.stage}: non-finite values in the "
                                         f"{k} curve")
        return StageResult(self.stage, curves, self.d.sim.positions, self.d.sim.radii,
                           self.d.sim.steps - self.steps0)


class _Driver:
    """Runs the stages on one :class:`Simulation`."""

    def __init__(self, test: UniaxialTest, progress: ProgressCallback | None):
        self.test = test
        self.progress = progress
        self.area = test.cell[0] * test.cell[1]
        self.stages: dict[str, StageResult] = {}
        self.last_fraction = 0.0
        self.scalars: dict[str, float] = {}
        self.t_wall = time.perf_counter()
        pos, radii = test.initial_packing()
        self.solid_volume = float(sphere_volume(radii).sum())
        g = GRAVITY
        self.layer_stress = test.density * g * 2 * test.radius
        m = float(test.density * sphere_volume(test.radius))
        self.settle_energy = test.settle_ke * len(radii) * m * g * test.radius
        self.n_walls = 2  # bottom platen at z = 0; the top one starts above the cell
        scene = test.scene(pos, radii)
        # kernels are compiled (or loaded from the disk cache) when a Simulation is built and
        # when its periodicity changes: that time is kept out of the run's wall time
        t0 = time.perf_counter()
        self.sim = Simulation(scene, dt=test.dt)
        self.setup_time = time.perf_counter() - t0
        self.sample_steps = max(1, round(test.output_interval / self.sim.dt))
        self.max_steps = max(1, round(test.max_stage_time / self.sim.dt))

    # ------------------------------------------------------------------ helpers
    def gap(self) -> float:
        """Distance between the platens [m]."""
        return float(self.sim.wall_positions[1, 2] - self.sim.wall_positions[0, 2])

    def top_stress(self) -> float:
        """Compressive stress on the top platen [Pa]."""
        return float(self.sim.wall_forces[1, 2]) / self.area

    def bed_top(self) -> float:
        """Highest particle surface [m]."""
        return float(np.max(self.sim.positions[:, 2] + self.sim.radii))

    def report(self, stage: str, stage_fraction: float, message: str = "") -> None:
        if self.progress is None:
            return
        done = 0.0
        for s in STAGES:
            if s == stage:
                break
            done += _WEIGHTS[s]
        total = sum(_WEIGHTS[s] for s in STAGES if self.test.unconfined or s not in
                    ("release", "unconfined"))
        frac = min(1.0, (done + _WEIGHTS[stage] * min(max(stage_fraction, 0.0), 1.0)) / total)
        # stress fluctuates: never report less progress than before
        frac = self.last_fraction = max(frac, self.last_fraction)
        answer = self.progress(Progress(frac, stage, stage_fraction, self.sim.time,
                                        self.sim.steps, message))
        if answer is False:
            raise StopRequested(f"stopped by the progress callback during {stage}")

    def run_stage(self, stage: str, h0: float, done: Callable[[tuple], bool],
                  fraction: Callable[[tuple], float], what: str) -> None:
        rec = _Recorder(self, stage, h0)
        row = rec.sample()
        steps = 0
        while not done(row):
            if steps >= self.max_steps:
                raise StageError(
                    f"stage {stage} did not {what} within {steps} steps "
                    f"({steps * self.sim.dt:.3g} s, max_stage_time); now: top stress "
                    f"{row[2]:.4g} Pa, platen gap {row[8]:.4g} m, kinetic energy "
                    f"{row[6]:.3g} J", stage, steps)
            self.sim.run(self.sample_steps)
            steps += self.sample_steps
            row = rec.sample()
            self.report(stage, fraction(row))
        self.stages[stage] = rec.result()
        self.report(stage, 1.0, "done")

    def settled(self, row, t_min: float, t0: float) -> bool:
        return row[0] - t0 >= t_min and row[6] <= self.settle_energy

    def move_top(self, speed: float) -> None:
        self.sim.set_wall_velocity(1, (0.0, 0.0, speed))

    # ------------------------------------------------------------------ stages
    def fill(self) -> None:
        t0 = self.sim.time
        t_fall = math.sqrt(2 * self.test.cell[2] / GRAVITY)
        self.run_stage("fill", self.gap(), lambda r: self.settled(r, t_fall, t0),
                       lambda r: min(1.0, (r[0] - t0) / (2 * t_fall)),
                       "settle (kinetic energy below settle_ke x N m g R)")

    def pre_compression(self) -> None:
        top = self.bed_top() + 0.05 * self.test.radius
        self.sim.set_wall_position(1, (0.0, 0.0, top))
        self.move_top(-self.test.platen_speed)
        target = self.test.pre_stress
        self.run_stage("pre_compression", self.gap(), lambda r: r[2] >= target,
                       lambda r: r[2] / target, f"reach the pre-compression stress {target:g} Pa")

    def consolidation(self) -> None:
        h0 = self.gap()
        target = self.test.consolidation_stress
        self.h_consolidation = h0
        self.run_stage("consolidation", h0, lambda r: r[2] >= target,
                       lambda r: r[2] / target,
                       f"reach the consolidation stress {target:g} Pa")
        self.move_top(+self.test.platen_speed)
        low = self.test.unloaded_stress * target
        self.run_stage("unloading", h0, lambda r: r[2] <= low,
                       lambda r: 1.0 - r[2] / target, f"relax the stress below {low:g} Pa")
        self.move_top(0.0)

    def release(self) -> None:
        t_setup = time.perf_counter()
        self.sim.set_periodic((False, False, False))
        self.setup_time += time.perf_counter() - t_setup
        t0 = self.sim.time
        t_min = 5 * math.sqrt(2 * self.test.radius / GRAVITY)  # a few particle fall times
        t_max = max(t_min, self.test.release_time)
        self.run_stage("release", self.gap(),
                       lambda r: self.settled(r, t_min, t0) or r[0] - t0 >= t_max,
                       lambda r: min(1.0, (r[0] - t0) / t_max),
                       "settle after the release (kinetic energy below settle_ke x N m g R)")

    def unconfined(self) -> None:
        t = self.test
        # the platen starts where unloading left it, on top of the consolidated sample, and
        # strain is measured against that height: a sample that collapsed on release is never
        # reached within max_unconfined_strain and has exactly zero strength
        self.move_top(-t.platen_speed)
        h0 = self.gap()
        peak = 0.0
        below_since = math.inf  # strain at which the stress last fell below the failure line

        def done(r) -> bool:
            # failure: the stress stays failure_drop below its peak for failure_strain more
            # strain (a single noisy sample, or the first grains touching, is not a failure)
            nonlocal peak, below_since
            peak = max(peak, r[2])
            if peak > 0 and r[2] < (1 - t.failure_drop) * peak:
                below_since = min(below_since, r[1])
            else:
                below_since = math.inf
            return r[1] - below_since >= t.failure_strain or r[1] >= t.max_unconfined_strain

        self.run_stage("unconfined", h0, done, lambda r: r[1] / t.max_unconfined_strain,
                       "fail (post-peak drop) or reach max_unconfined_strain")
        self.move_top(0.0)

    # ------------------------------------------------------------------ scalars
    def finish(self) -> UniaxialResult:
        s = self.scalars
        cons, unl = self.stages["consolidation"].curves, self.stages["unloading"].curves
        s["loading_stiffness"] = _secant_slope(cons["strain"], cons["stress_top"], 0.5, 1.0)
        s["unloading_stiffness"] = _secant_slope(unl["strain"][::-1], unl["stress_top"][::-1],
                                                 0.5, 1.0)
        s["consolidated_porosity"] = float(cons["porosity"][-1])
        if "unconfined" in self.stages:
            u = self.stages["unconfined"].curves
            k = int(np.argmax(u["stress_top"]))
            s["unconfined_strength"] = max(0.0, float(u["stress_top"][k]))
            s["strain_at_peak"] = float(u["strain"][k])
        s["particles"] = float(self.sim.n)
        s["steps"] = float(self.sim.steps)
        s["dt"] = self.sim.dt
        s["setup_time"] = self.setup_time
        s["wall_time"] = time.perf_counter() - self.t_wall - self.setup_time
        s["particle_steps"] = float(self.sim.n) * self.sim.steps
        s["max_inertial_number"] = max(
            float(np.max(self.stages[k].curves["inertial_number"]))
            for k in ("pre_compression", "consolidation", "unloading", "unconfined")
            if k in self.stages)
        bad = [k for k, v in s.items() if not math.isfinite(v)]
        if bad:
            raise FloatingPointError(f"non-finite scalars {bad}: the run is not usable")
        return UniaxialResult(self.test, self.stages, s)


def _secant_slope(strain: np.ndarray, stress: np.ndarray, lo: float, hi: float) -> float:
    """Least-squares slope of stress against strain [Pa] over the samples whose stress lies
    between ``lo`` and ``hi`` times the largest stress of the curve."""
    smax = float(np.max(stress))
    sel = (stress >= lo * smax) & (stress <= hi * smax)
    if np.count_nonzero(sel) < 2 or np.ptp(strain[sel]) == 0:
        sel = np.ones(len(stress), dtype=bool)  # too few samples in the window: all of them
    if np.count_nonzero(sel) < 2 or np.ptp(strain[sel]) == 0:
        raise FloatingPointError("the platen did not move during the stage: no stiffness")
    return float(np.polyfit(strain[sel], stress[sel], 1)[0])


def run_uniaxial(test: UniaxialTest, progress: ProgressCallback | None = None
                 ) -> UniaxialResult:
    """Run the uniaxial test: fill, pre-compression, consolidation, unloading and (with
    ``test.unconfined``) release and unconfined compression.

    Args:
        test: the parameters.
        progress: called after every curve sample with a :class:`Progress`; returning
            ``False`` stops the run with :class:`engine.StopRequested`.
    Raises: :class:`StageError` when a stage misses its criterion within its bound,
        :class:`engine.InstabilityError` when the integration blows up.
    """
    d = _Driver(test, progress)
    d.fill()
    d.pre_compression()
    d.consolidation()
    if test.unconfined:
        d.release()
        d.unconfined()
    return d.finish()
