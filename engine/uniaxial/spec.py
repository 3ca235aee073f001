"""Parameters of the uniaxial test and its presets (docs/PHYSICS.md section 4).

:class:`UniaxialTest` holds every parameter of one test, declared with its unit and bounds
(:mod:`engine.core.records`) and validated once on construction; :func:`preset` gives the named
tests. The stage driver is :mod:`engine.uniaxial.driver`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.hertz import HertzMindlin
from ..contact.registry import law_names, pair_laws, wall_laws
from ..contact.wall import WallMaterial
from ..core.config import MAX_OVERLAP_FRACTION
from ..core.errors import ParameterError
from ..core.records import Record, check_fields, from_dict, param
from ..simulation.packing import draw_radii, loose_packing, sphere_volume
from ..simulation.scene import Plane, Scene
from ..simulation.timestep import adhesion_overlap, critical_time_step

GRAVITY = 9.81  # [m/s^2]

#: Thinnest side of the cell, in diameters of the largest particle, below which a bed is too
#: thin to be a bulk sample (the seed's criterion: "more than 5 diameters").
MIN_THICKNESS_DIAMETERS = 5.0


#: The seed's protocol: every field this project's protocol changed since the seed's
#: reproduction, at its seed value. The fixed time step dt = 1e-5 s, the constant platen speed
#: of 10 mm/s (``inertial_number`` None), the free-fall fill (``pour_speed`` None) and the
#: strength read from the top platen's stress; ``dt_fraction`` and ``max_platen_speed`` are
#: unused under it (stated so that a test made with it is one record). ``preset(name,
#: protocol="seed")`` is the seed's set-up; a stored run written before these fields existed
#: reads them from here (:meth:`UniaxialTest.from_stored`).
SEED_PROTOCOL = {
    "dt": 1e-5,
    "dt_fraction": 0.2,
    "platen_speed": 0.01,
    "inertial_number": None,
    "max_platen_speed": 0.1,
    "strength_from": "platen",
    "pour_speed": None,
}

#: The protocol of a new test: the defaults of its fields (docs/PROTOCOL.md, measured by
#: ``python -m benchmarks.protocol``): the time step 0.4 of the critical time of the stiffest
#: contact, each loading stage at the inertial number 5e-4 with the platen at most 0.05 m/s,
#: the pour capped at 2 m/s, the strength from the interior virial stress. Every field
#: of :data:`SEED_PROTOCOL`, so that a test is either.
DEFAULT_PROTOCOL = {
    "dt": None,
    "dt_fraction": 0.4,
    "platen_speed": 0.01,
    "inertial_number": 5e-4,
    "max_platen_speed": 0.05,
    "strength_from": "interior",
    "pour_speed": 2.0,
}

#: The fields a stored test may lack whose default has moved since (the protocol of issue
#: 40, and ``pour_speed``, stored since the capped pour): read at their seed values.
_ADDED_FIELDS = (
    "dt_fraction",
    "inertial_number",
    "max_platen_speed",
    "strength_from",
    "pour_speed",
)


def _cohesionless_law() -> BilinearAdhesive:
    return BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.5, mu_r=0.001, restitution=0.4)


def _platen_law() -> HertzMindlin:
    return HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.3)


def _law(types, default_factory, doc: str) -> dict:
    """The :func:`engine.core.records.param` arguments of a contact law field: a record of
    one of the law classes ``types()`` returns, by default ``default_factory()``."""
    return dict(unit="", kind="record", types=types, default_factory=default_factory, doc=doc)


#: The fill and material fields every test declares (:class:`UniaxialTest`,
#: :class:`engine.ShearTest`, :class:`engine.HopperTest`), declared once: each entry is the
#: arguments of :func:`engine.core.records.param` (default, unit, bounds, description). A test
#: lists the ones it takes with :func:`fill_param`, in the order of its own JSON form.
FILL_FIELDS: dict[str, dict] = {
    "radius": dict(default=2.5e-3, unit="m", doc="particle radius", gt=0, le=0.05),
    "polydispersity": dict(
        default=0.0, unit="1", doc="radii uniform in [R(1-p), R(1+p)]", ge=0, lt=0.5
    ),
    "density": dict(default=2000.0, unit="kg/m^3", doc="particle density", gt=0),
    "gravity": dict(
        default=GRAVITY, unit="m/s^2", gt=0, le=1e4, doc="acceleration of gravity, along -z"
    ),
    "solid_fraction": dict(
        default=0.6, unit="1", gt=0, le=0.74, doc="solid fraction assumed for the settled sample"
    ),
    "pour_fraction": dict(
        default=0.3, unit="1", gt=0, le=0.32, doc="solid fraction of the poured cloud"
    ),
    "pour_speed": dict(
        default=DEFAULT_PROTOCOL["pour_speed"],
        unit="m/s",
        gt=0,
        le=100.0,
        nullable=True,
        doc="largest particle speed during the fill (None: free fall from the pour column)",
    ),
    "pair_law": _law(pair_laws, _cohesionless_law, "particle-particle contact law"),
    "wall_law": _law(wall_laws, _platen_law, "platen contact law (Hertz-Mindlin)"),
    "wall_material": dict(
        unit="", kind="record", default_factory=WallMaterial, doc="platen material"
    ),
    "settle_ke": dict(
        default=1e-4, unit="1", gt=0, doc="settled below this kinetic energy / (N m g R)"
    ),
    "seed": dict(default=1, unit="", kind="int", ge=0, lt=2**31, doc="packing seed"),
    "output_interval": dict(default=1e-3, unit="s", gt=0, doc="time between curve samples"),
    "dt": dict(
        default=DEFAULT_PROTOCOL["dt"],
        unit="s",
        gt=0,
        nullable=True,
        doc="time step (None: dt_fraction of the critical time of the stiffest contact)",
    ),
    "dt_fraction": dict(
        default=DEFAULT_PROTOCOL["dt_fraction"],
        unit="1",
        gt=0,
        le=0.5,
        doc="with dt None: time step over the critical time of the stiffest contact",
    ),
    "max_stage_time": dict(default=5.0, unit="s", gt=0, doc="bound on any stage's time"),
}


def fill_param(name: str, doc: str | None = None) -> Any:
    """The field ``name`` of :data:`FILL_FIELDS` (a dataclass field, :func:`param`), with
    ``doc`` in place of its description where given (a test's own words for its walls)."""
    spec = FILL_FIELDS[name]
    return param(**(spec if doc is None else {**spec, "doc": doc}))


@dataclass(frozen=True)
class TimeStep:
    """A test's time step and where it comes from (:meth:`UniaxialTest.time_step`).

    Attributes: ``dt`` [s]; ``fraction`` (dt over the critical time) [-]; ``critical``, the
    smallest stability limit [s]; ``reason``, the contact that sets it; ``kind``, ``"pair"``
    or ``"wall"``; ``impact_speed``, the speed the Hertz limits assume [m/s].
    """

    dt: float
    fraction: float
    critical: float
    reason: str
    kind: str
    impact_speed: float


@dataclass(frozen=True)
class UniaxialTest(Record):
    """Parameters of one uniaxial test (SI units).

    The sample fills the cuboid ``cell`` = (Lx, Ly, H): the amount of material is what fills
    it at the solid fraction ``solid_fraction`` (N = solid_fraction Lx Ly H / particle
    volume). It is poured as a loose cloud of solid fraction ``pour_fraction`` from a column
    H solid_fraction / pour_fraction tall, settles under gravity on the bottom platen and is
    compressed by the top platen; x and y are periodic until the release.

    Attributes:
        cell: (Lx, Ly, H) [m]: periodic cross-section and the height the settled sample fills.
        radius: particle radius [m].
        polydispersity: radii uniform in [R (1 - p), R (1 + p)] [-].
        density: particle density [kg/m^3].
        gravity: acceleration of gravity, along -z [m/s^2] (a resolution control of a study
            runs the reference law in a cell scaled by s at g / s, so that its overburden
            rho g H is the coarse run's).
        gravity_off_after_fill: switch gravity off once the fill has settled, for every later
            stage (a diagnostic: compression without the sample's own weight, so that the
            consolidation is uniform; the sample still settles under gravity).
        solid_fraction: solid fraction the settled sample is assumed to have when the
            particles are counted [-].
        pour_fraction: solid fraction of the poured cloud [-] (random addition jams near 0.38).
        pour_speed: largest particle speed during the fill [m/s], as a fill that rains the
            cloud down through a sieve or a fluid would: 2 m/s by default (a free fall from
            20 cm), which settles in about the fewest steps and leaves the free fall's bed
            (docs/PROTOCOL.md); None: free fall from the pour column, which reaches
            sqrt(2 g H_pour), 3.4 m/s at the paper scale (the seed's). A soft,
            strongly adhesive law cannot absorb a cluster's impact at that speed within the
            overlap limit (experiment (b)'s b = 3 runs); the cap is applied between curve
            samples, to every particle faster than it.
        pair_law: particle-particle law (:class:`BilinearAdhesive`, :class:`EEPA` or
            :class:`HertzMindlin`).
        wall_law: platen law (:class:`HertzMindlin`; its E, nu are the particles').
        wall_material: platen material.
        pre_stress: pre-compression stress [Pa].
        consolidation_stress: consolidation stress [Pa], > pre_stress.
        platen_speed: top platen speed [m/s] of every loading stage when ``inertial_number``
            is None (the seed's constant 10 mm/s).
        inertial_number: the inertial number I* = (v / h) d sqrt(rho / p) every loading stage
            (pre-compression, consolidation, unloading, unconfined) holds [-]: its platen moves
            at the speed v that gives I* for the platen gap h, the mean diameter d, the
            particle density rho and the top platen stress p (floored at the weight of one
            layer of grains, rho g d), at most ``max_platen_speed`` (docs/PHYSICS.md section 4,
            "Loading rate"). None: the constant ``platen_speed``.
        max_platen_speed: the largest platen speed with ``inertial_number`` [m/s].
        unloading_inertial_number: the inertial number the unloading stage holds instead of
            ``inertial_number`` [-] (None: ``inertial_number``; needs ``inertial_number``):
            an unloading branch read more slowly than the loading, so that the sample's
            elastic response keeps up with its platen (docs/RESOLUTION.md, "Confounds"). Left
            out of the JSON form while None (a test made before the field keeps its form).
        hold_time: a hold stage between the consolidation and the unloading [s]: the top
            platen stopped where the consolidation left it for at least this long, then
            until the kinetic energy is below ``settle_ke`` x N m g R (at most
            ``max_stage_time``; < ``max_stage_time``), so that the unloading starts with the
            platen at rest rather than by reversing a moving one; the rest is judged on one
            curve sample's kinetic energy, which a still-ringing bed can pass at a turning
            point (docs/PHYSICS.md section 7.5). The stress wave of reversing a moving
            platen, rho_b c Delta v, grows with the sample's height at a held inertial
            number (same section). None: no hold stage (left out of the JSON form while
            None).
        hold_quiet: with ``hold_time``, the hold ends only once no curve sample's kinetic
            energy has been above ``settle_ke`` x N m g R for this long [s] (the stage's
            start counting as one that was): a window of samples, which a bed still ringing
            in its lowest mode does not pass at a turning point, as one sample can. None: one
            sample below it (left out of the JSON form while None).
        unloaded_stress: unloading ends when the top stress is below this fraction of the
            consolidation stress [-].
        unconfined: run the release and unconfined compression stages.
        failure_drop: the sample has failed when its stress has fallen this fraction below
            its peak [-] ...
        failure_strain: ... and has stayed there for this much further axial strain [-].
        max_unconfined_strain: unconfined compression also ends at this strain [-] (samples
            without a peak); their strength is the documented fallback (see
            :func:`engine.uniaxial.measures.unconfined_strength`).
        settle_ke: a settling stage ends when the kinetic energy is below this fraction of
            N m g R (the energy of lifting every particle by one radius) [-].
        release_time: the release stage also ends after this much simulated time [s].
        interior_margin: thickness of the layer next to each platen left out of the interior
            porosity and coordination number [m]; None: two diameters of the largest particle.
            In a sample too short for it the layer shrinks to leave one largest diameter
            (the scalar ``interior_margin`` of a result is the one used at consolidation).
        seed: random seed of the packing.
        output_interval: simulated time between curve samples [s].
        dt: time step [s]; None: ``dt_fraction`` of the critical time of the test's stiffest
            contact (:meth:`time_step`).
        dt_fraction: with ``dt`` None, the time step as a fraction of the critical time of the
            stiffest contact [-]: the smallest stability limit of the damped oscillator of the
            pair unloading stiffness K2 (lightest pair) and of the platen Hertz contact at the
            expected impact speed (:attr:`impact_speed`) (docs/PHYSICS.md section 6).
        strength_from: the curve the unconfined strength and failure are read from:
            ``"interior"``, the axial contact-virial stress of the particles whose centres lie
            in the interior window (the peak of its smoothed curve), or ``"platen"``, the top
            platen's stress (the largest value: the seed's estimator; runs stored before the
            interior curve existed were read so). Both are reported.
        max_stage_time: bound on the simulated time of any single stage [s].
    """

    cell: tuple[float, float, float] = param(
        (0.05, 0.05, 0.1),
        unit="m",
        kind="list",
        max_items=3,
        doc="(Lx, Ly, H): periodic cross-section and height the settled sample fills",
    )
    radius: float = fill_param("radius")
    polydispersity: float = fill_param("polydispersity")
    density: float = fill_param("density")
    gravity: float = fill_param("gravity")
    gravity_off_after_fill: bool = param(
        False,
        unit="",
        kind="bool",
        doc="switch gravity off once the fill has settled (a diagnostic: no overburden)",
    )
    solid_fraction: float = fill_param("solid_fraction")
    pour_fraction: float = fill_param("pour_fraction")
    pour_speed: float | None = fill_param("pour_speed")
    pair_law: BilinearAdhesive | EEPA | HertzMindlin = fill_param("pair_law")
    wall_law: HertzMindlin = fill_param("wall_law")
    wall_material: WallMaterial = fill_param("wall_material")
    pre_stress: float = param(5e3, unit="Pa", doc="pre-compression stress", gt=0)
    consolidation_stress: float = param(
        20e3, unit="Pa", gt=0, doc="consolidation stress (> pre_stress)"
    )
    platen_speed: float = param(
        DEFAULT_PROTOCOL["platen_speed"],
        unit="m/s",
        gt=0,
        doc="top platen speed when inertial_number is None",
    )
    inertial_number: float | None = param(
        DEFAULT_PROTOCOL["inertial_number"],
        unit="1",
        gt=0,
        le=0.01,
        nullable=True,
        doc="inertial number every loading stage holds (None: constant platen_speed; the "
        "unloading: unloading_inertial_number where set)",
    )
    max_platen_speed: float = param(
        DEFAULT_PROTOCOL["max_platen_speed"],
        unit="m/s",
        gt=0,
        le=1.0,
        doc="largest platen speed with inertial_number",
    )
    unloading_inertial_number: float | None = param(
        None,
        unit="1",
        gt=0,
        le=0.01,
        nullable=True,
        omit_default=True,
        doc="inertial number the unloading stage holds (None: inertial_number)",
    )
    hold_time: float | None = param(
        None,
        unit="s",
        gt=0,
        le=100.0,
        nullable=True,
        omit_default=True,
        doc="a hold stage between consolidation and unloading: the top platen still for at "
        "least this long, then until the kinetic energy is below settle_ke x N m g R "
        "(None: no hold)",
    )
    hold_quiet: float | None = param(
        None,
        unit="s",
        gt=0,
        le=100.0,
        nullable=True,
        omit_default=True,
        doc="with hold_time: the hold ends only once no curve sample's kinetic energy has "
        "been above settle_ke x N m g R for this long (None: one sample below it)",
    )
    unloaded_stress: float = param(
        0.01,
        unit="1",
        gt=0,
        lt=1,
        doc="unloading ends below this fraction of the consolidation stress",
    )
    unconfined: bool = param(
        True, unit="", kind="bool", doc="run the release and unconfined compression stages"
    )
    failure_drop: float = param(
        0.2, unit="1", gt=0, lt=1, doc="post-peak stress drop that marks failure"
    )
    failure_strain: float = param(
        0.005, unit="1", ge=0, lt=0.5, doc="strain the drop must persist for"
    )
    max_unconfined_strain: float = param(
        0.1, unit="1", gt=0, lt=0.8, doc="unconfined compression ends here at the latest"
    )
    settle_ke: float = fill_param("settle_ke")
    release_time: float = param(0.2, unit="s", gt=0, doc="longest release stage")
    interior_margin: float | None = param(
        None,
        unit="m",
        ge=0,
        nullable=True,
        doc="layer at each platen left out of interior measurements (None: 2 diameters)",
    )
    seed: int = fill_param("seed")
    output_interval: float = fill_param("output_interval")
    dt: float | None = fill_param("dt")
    dt_fraction: float = fill_param("dt_fraction")
    strength_from: str = param(
        DEFAULT_PROTOCOL["strength_from"],
        unit="",
        kind="str",
        choices=("interior", "platen"),
        doc="unconfined strength from the interior virial stress or the top platen",
    )
    max_stage_time: float = fill_param("max_stage_time")

    def __post_init__(self) -> None:
        o = "UniaxialTest"
        try:
            cell = tuple(float(c) for c in self.cell)
        except (TypeError, ValueError):
            cell = ()
        if len(cell) != 3 or not all(math.isfinite(c) and c > 0 for c in cell):
            raise ParameterError(f"{o}.cell", self.cell, "three lengths > 0 m")
        object.__setattr__(self, "cell", cell)
        check_fields(self, o)
        if self.unloading_inertial_number is not None and self.inertial_number is None:
            raise ParameterError(
                f"{o}.unloading_inertial_number",
                self.unloading_inertial_number,
                "None where inertial_number is None (the constant platen_speed)",
            )
        for name in ("hold_time", "hold_quiet"):
            value = getattr(self, name)
            if value is not None and value >= self.max_stage_time:
                raise ParameterError(
                    f"{o}.{name}",
                    value,
                    f"< max_stage_time = {self.max_stage_time:g} s",
                    "the hold also waits for the bed to come to rest, within the stage bound",
                )
        if self.hold_quiet is not None and self.hold_time is None:
            raise ParameterError(
                f"{o}.hold_quiet", self.hold_quiet, "None where hold_time is None (no hold)"
            )
        if self.consolidation_stress <= self.pre_stress:
            raise ParameterError(
                f"{o}.consolidation_stress",
                self.consolidation_stress,
                f"> pre_stress = {self.pre_stress:g} Pa",
            )
        if self.pour_fraction > self.solid_fraction:
            raise ParameterError(
                f"{o}.pour_fraction",
                self.pour_fraction,
                f"<= solid_fraction = {self.solid_fraction:g}",
                "the poured cloud cannot be denser than the settled bed",
            )
        if not isinstance(self.pair_law, pair_laws()):
            raise ParameterError(f"{o}.pair_law", self.pair_law, f"an {law_names(pair_laws())}")
        if not isinstance(self.wall_law, wall_laws()):
            raise ParameterError(f"{o}.wall_law", self.wall_law, f"an {law_names(wall_laws())}")
        if not isinstance(self.wall_material, WallMaterial):
            raise ParameterError(f"{o}.wall_material", self.wall_material, "an engine.WallMaterial")
        rmax = self.radius * (1 + self.polydispersity)
        for a, name in ((0, "x"), (1, "y")):
            if cell[a] < 2.4 * 2 * rmax:
                raise ParameterError(
                    f"{o}.cell",
                    f"{cell[a]:g} m along {name}",
                    f">= {4.8 * rmax:.4g} m (2.4 largest diameters) for the periodic minimum image",
                )
        if cell[2] < 4 * rmax:
            raise ParameterError(
                f"{o}.cell", f"{cell[2]:g} m along z", f">= {4 * rmax:.4g} m (2 largest diameters)"
            )
        self._check_runnable()

    def _check_runnable(self) -> None:
        """Refuse, before anything runs, what the engine would refuse in the middle of a run:
        an adhesion that pulls contacts too deep, a time step above the stable limit (checked
        on a two-particle stand-in scene). The fill is placed by the run that needs it
        (:meth:`initial_packing`), not here."""
        o = "UniaxialTest"
        rmin = self.radius * (1 - self.polydispersity)
        law = self.pair_law
        d_eq = adhesion_overlap(law, rmin, MAX_OVERLAP_FRACTION)
        if d_eq is not None:
            raise ParameterError(
                f"{o}.pair_law.f0",
                law.f0,
                f">= {-MAX_OVERLAP_FRACTION * rmin * law.k1:.4g} N",
                f"|f0|/k1 = {d_eq:.3g} m would pull contacts beyond "
                f"{MAX_OVERLAP_FRACTION:g} x the smallest radius",
            )
        # the law must carry the consolidation stress (and the sample's weight) within the
        # overlap the engine allows: a contact force of about sigma (2 R)^2
        rmax = self.radius * (1 + self.polydispersity)
        stress = self.consolidation_stress + self.density * self.solid_fraction * (
            self.gravity * self.cell[2]
        )
        force = stress * (2 * rmax) ** 2
        # (a registered law without load_overlap is not checked here: its run checks)
        load = getattr(law, "load_overlap", None)
        d_load, what = load(force, rmin) if load is not None else (0.0, "")
        if not (d_load <= MAX_OVERLAP_FRACTION * rmin):
            raise ParameterError(
                f"{o}.pair_law.{what}",
                getattr(law, what),
                "stiff enough to carry the consolidation stress within the overlap limit",
                f"a contact force of {force:.3g} N (consolidation stress and the sample's "
                f"weight over (2R)^2) needs an overlap of {d_load:.3g} m, beyond "
                f"{MAX_OVERLAP_FRACTION:g} x the smallest radius",
            )
        lim = self.time_step_limit()
        if self.dt is not None and self.dt > lim.dt:
            raise ParameterError(
                f"{o}.dt",
                self.dt,
                f"<= {lim.dt:.4g} s, the stable limit "
                f"set by {lim.reason} (recommended {lim.recommended:.4g} s)",
            )
        if self.dt is None and not math.isfinite(lim.dt):
            raise ParameterError(
                f"{o}.dt", None, "given explicitly", "no contact law limits the time step"
            )

    @classmethod
    def from_stored(cls, data: dict) -> UniaxialTest:
        """The test of a stored run's JSON (:mod:`engine.io.store`): a field it lacks because
        it was stored before the field existed takes its value in :data:`SEED_PROTOCOL`, the
        protocol every such run was made with; otherwise :meth:`from_dict`."""
        data = dict(data)
        for k in _ADDED_FIELDS:
            data.setdefault(k, SEED_PROTOCOL[k])
        return cls.from_dict(data)

    @property
    def margin(self) -> float:
        """The interior margin [m]: ``interior_margin`` or two largest diameters."""
        if self.interior_margin is not None:
            return self.interior_margin
        return 4.0 * self.radius * (1 + self.polydispersity)

    @property
    def pour_height(self) -> float:
        """Height of the column the loose cloud is poured from [m]."""
        return self.cell[2] * self.solid_fraction / self.pour_fraction

    @property
    def fall_time(self) -> float:
        """Time for the top of the poured cloud to reach the bottom platen [s]: the free fall
        sqrt(2 H_pour / g), or H_pour / pour_speed where the fill's speed is capped slower."""
        t = math.sqrt(2 * self.pour_height / self.gravity)
        return t if self.pour_speed is None else max(t, self.pour_height / self.pour_speed)

    @property
    def pour_region(self) -> tuple[float, float, float]:
        """(Lx, Ly, pour height) [m]: the box the loose cloud is placed in."""
        return (self.cell[0], self.cell[1], self.pour_height)

    @property
    def impact_speed(self) -> float:
        """The largest speed at which a particle is expected to meet a platen or another
        particle [m/s]: the free fall over the pour column, sqrt(2 g H_pour), or, with a
        capped pour, ``pour_speed`` plus what gravity adds within one curve sample (the cap
        is applied between samples), whichever is less; at least the platen's speed and
        0.1 m/s (as :func:`engine.simulation.timestep.expected_max_speed`)."""
        v = math.sqrt(2.0 * self.gravity * self.pour_height)
        if self.pour_speed is not None:
            v = min(v, self.pour_speed + self.gravity * self.output_interval)
        platen = self.platen_speed if self.inertial_number is None else self.max_platen_speed
        return max(v, platen, 0.1)

    def time_step_limit(self):
        """:func:`engine.critical_time_step` of this test's laws for its lightest particles
        at :attr:`impact_speed` (a two-particle stand-in for the packing)."""
        rmin = self.radius * (1 - self.polydispersity)
        lx, ly, lz = self.pour_region
        pos = np.array([(lx / 2, ly / 2, rmin), (lx / 2, ly / 2, lz - rmin)])
        return critical_time_step(self.scene(pos, np.full(2, rmin)), self.impact_speed)

    def time_step(self) -> TimeStep:
        """The time step a run of this test takes and where it comes from: ``dt`` when given,
        else ``dt_fraction`` of the critical time of the stiffest contact, the smallest
        stability limit of :meth:`time_step_limit` (docs/PHYSICS.md section 6)."""
        lim = self.time_step_limit()
        hard = min((c for c in lim.candidates if c.hard), key=lambda c: c.value)
        dt = self.dt if self.dt is not None else self.dt_fraction * lim.dt
        return TimeStep(dt, dt / lim.dt, lim.dt, lim.reason, hard.kind, self.impact_speed)

    def scene(self, positions: np.ndarray, radii: np.ndarray) -> Scene:
        """The test's scene for particles at ``positions`` [m] with ``radii`` [m]: periodic
        x and y, gravity, the bottom platen at z = 0 and the top one above the pour column."""
        lx, ly, lz = self.pour_region
        walls = [Plane((0, 0, 0), (0, 0, 1)), Plane((0, 0, lz + 4 * self.radius), (0, 0, -1))]
        return Scene(
            positions,
            radii,
            self.density,
            box=[(0, lx), (0, ly), (0, lz)],
            periodic=(True, True, False),
            walls=walls,
            gravity=(0, 0, -self.gravity),
            pair_law=self.pair_law,
            wall_law=self.wall_law,
            wall_material=self.wall_material,
        )

    def initial_packing(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and radii [m] of the poured fill: ``n_particles`` overlap-free
        spheres in the pour column (periodic x and y), from ``seed``."""
        try:
            pos, radii = _packing(
                self.n_particles, self.radius, self.polydispersity, self.seed, self.pour_region
            )
        except ParameterError as e:
            raise ParameterError(
                "UniaxialTest.pour_fraction",
                self.pour_fraction,
                "low enough for the fill to be placed without overlap",
                f"{e}; lower pour_fraction",
            ) from None
        return pos.copy(), radii.copy()

    def stage_inertial_number(self, stage: str) -> float | None:
        """The inertial number loading ``stage`` holds [-]: ``unloading_inertial_number`` in
        the unloading stage where it is set, else ``inertial_number`` (None: the constant
        ``platen_speed``)."""
        if stage == "unloading" and self.unloading_inertial_number is not None:
            return self.unloading_inertial_number
        return self.inertial_number

    @property
    def typical_platen_speed(self) -> float:
        """A typical speed of the top platen over the loading stages [m/s], for estimates of
        a run's cost: ``platen_speed``, or at ``inertial_number`` the speed that holds it in
        the cell's height at half the consolidation stress (the mean of the loading
        branch), I* (H / d) sqrt(sigma_c / (2 rho)), at most ``max_platen_speed``."""
        if self.inertial_number is None:
            return self.platen_speed
        v = (
            self.inertial_number
            * self.cell[2]
            / (2 * self.radius)
            * math.sqrt(0.5 * self.consolidation_stress / self.density)
        )
        return min(v, self.max_platen_speed)

    def resolved_dt(self) -> float:
        """The time step a run of this test takes [s]: ``dt``, or ``dt_fraction`` of the
        critical time of the stiffest contact (:meth:`time_step`)."""
        return self.dt if self.dt is not None else self.time_step().dt

    @property
    def n_particles(self) -> int:
        """Number of particles: solid_fraction x cell volume / mean particle volume."""
        return particle_count(self.cell, self.radius, self.solid_fraction, self.polydispersity)

    @property
    def thickness_diameters(self) -> float:
        """Thinnest side of the cell in diameters of the largest particle [-]."""
        return min(self.cell[:2]) / (2 * self.radius * (1 + self.polydispersity))


def particle_count(cell, radius: float, solid_fraction: float, polydispersity: float) -> int:
    """Particles of a test with ``cell`` (Lx, Ly, Lz) [m], mean ``radius`` [m] uniform within
    +-``polydispersity`` [-] and ``solid_fraction`` [-]: solid_fraction x cell volume / mean
    particle volume, at least 2. A pure function of the fields (the service counts a request's
    particles with it before any record is built); raises OverflowError when the count is
    infinite (a zero radius, or 1e-300 m) and ValueError when it is NaN."""
    mean_vol = sphere_volume(radius) * (1 + polydispersity**2)  # E[r^3] / R^3
    return max(2, round(solid_fraction * float(np.prod(cell)) / mean_vol))


@functools.lru_cache(maxsize=16)
def _packing(
    n: int, radius: float, polydispersity: float, seed: int, region: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """The poured fill, placed once per process for its parameters (a run's driver and, in
    tests, a second look at the same test share it)."""
    radii = draw_radii(n, radius, polydispersity, seed)
    lx, ly, lz = region
    return loose_packing(radii, [(0, lx), (0, ly), (0, lz)], seed=seed), radii


def halved_protocol(test: UniaxialTest) -> UniaxialTest:
    """``test`` at half its loading rate and half its time step, everything else equal: the
    inertial number (with ``max_platen_speed``, and ``unloading_inertial_number`` where set)
    halved, or the constant ``platen_speed``
    where it has none; ``dt`` halved where given, else ``dt_fraction``. A run of it against
    ``test``'s shows whether the protocol is quasi-static and its step converged (a study
    proves its own protocol, issue 40)."""
    if test.inertial_number is not None:
        rate = {
            "inertial_number": test.inertial_number / 2,
            "max_platen_speed": test.max_platen_speed / 2,
        }
        if test.unloading_inertial_number is not None:
            rate["unloading_inertial_number"] = test.unloading_inertial_number / 2
    else:
        rate = {"platen_speed": test.platen_speed / 2}
    step = {"dt": test.dt / 2} if test.dt is not None else {"dt_fraction": test.dt_fraction / 2}
    return replace(test, **rate, **step)


#: Named tests: their cells and what each stands for.
PRESETS = ("paper", "quick")
#: The cell (Lx, Ly, H) [m] of each preset at each protocol (:func:`preset`).
PRESET_CELLS = {
    "paper": {"default": (0.05, 0.15, 0.30), "seed": (0.05, 0.15, 0.30)},
    "quick": {"default": (0.05, 0.05, 0.30), "seed": (0.05, 0.05, 0.1)},
}
#: Protocols of :func:`preset`: the default, and the seed's (:data:`SEED_PROTOCOL`).
PROTOCOLS = ("default", "seed")


def preset(name: str, protocol: str = "default", **overrides) -> UniaxialTest:
    """A named test; keyword overrides replace fields.

    ``"paper"``: the set-up of Thakur et al. (2013): a 50 x 150 x 300 mm cuboid (periodic in
    x and y) filled with R = 2.5 mm spheres of density 2000 kg/m^3, K1 = 5e3 N/m,
    K2 = 2.5e4 N/m, Kt = 2/7 K1, mu_s = 0.5, mu_r = 0.001, Hertz-Mindlin platens with friction
    0.3. Assumed where the paper is silent: the cuboid is "filled" at solid fraction 0.6
    (about 20,600 particles; the poured cloud at 0.3 starts twice as tall and settles to
    about the cuboid's height), restitution 0.4 (the value of Thakur et al. 2014), particle
    E = 1e8 Pa and nu = 0.25, steel platens, pre-compression to 5 kPa and consolidation to
    20 kPa. At the default protocol (:data:`DEFAULT_PROTOCOL`); with ``protocol="seed"`` at
    the seed's (:data:`SEED_PROTOCOL`: platen at 10 mm/s, dt = 1e-5 s, free-fall fill, about
    1.2e10 particle-steps per reference run).

    ``"quick"``: the same law in a 50 x 50 x 300 mm cuboid (10 x 10 x 60 diameters, about
    6,900 particles at R = 2.5 mm): the seed's height, overburden and slenderness (height six
    times the thinnest side), without which a cohesive sample hardens instead of failing at a
    peak (docs/FAILURE.md), with a third of its cross-section. ``protocol="seed"``: the quick
    preset as the seed's experiments were reproduced, a 50 x 50 x 100 mm cuboid (about 2,300
    particles, whose cohesive samples harden) at the seed's protocol.
    """
    if protocol not in PROTOCOLS:
        raise ParameterError(
            "preset.protocol", protocol, "one of " + ", ".join(repr(p) for p in PROTOCOLS)
        )
    if name not in PRESETS:
        raise ParameterError("preset", name, "one of " + ", ".join(repr(p) for p in PRESETS))
    base = UniaxialTest(cell=PRESET_CELLS[name][protocol])
    if protocol == "seed":
        base = replace(base, **SEED_PROTOCOL)
    return replace(base, **overrides) if overrides else base


def uniaxial_from_json(raw: dict, owner: str = "UniaxialTest") -> UniaxialTest:
    """A test given as JSON: its fields, optionally on a named base, ``"preset": "quick"``
    (or ``"paper"``), and ``"protocol": "seed"`` (or ``"default"``) for the preset's (or,
    without a preset, the record's defaults') protocol fields; given fields override both.
    The one reader of a test's JSON for the command line, a study's reference and the
    service's cost estimate."""
    if not isinstance(raw, dict):
        raise ParameterError(owner, type(raw).__name__, "a JSON object of the test's fields")
    fields = dict(raw)
    name = fields.pop("preset", None)
    protocol = fields.pop("protocol", "default")
    if protocol not in PROTOCOLS:
        raise ParameterError(
            f"{owner}.protocol", protocol, "one of " + ", ".join(repr(p) for p in PROTOCOLS)
        )
    if name is not None:
        base = preset(name, protocol).to_dict()
    else:
        base = dict(SEED_PROTOCOL if protocol == "seed" else {})
    return from_dict(UniaxialTest, {**base, **fields}, owner)
