"""Parameters of the simulated Jenike-type shear test (docs/SHEAR.md).

:class:`ShearTest` holds every parameter of one test, declared with its unit and bounds
(:mod:`engine.core.records`) and validated once on construction. The fill and the
consolidation under a flat lid are the uniaxial test's first two stages
(:meth:`ShearTest.consolidation_test`), so the packing, the time step and the law checks are
the uniaxial test's own; the shear stages are :mod:`engine.shear.driver`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.hertz import HertzMindlin
from ..contact.wall import WallMaterial
from ..core.errors import ParameterError
from ..core.records import Record, check_fields, param
from ..uniaxial.spec import UniaxialTest, fill_param

#: Most shear points (normal stresses) one test takes.
MAX_POINTS = 8


@dataclass(frozen=True)
class ShearTest(Record):
    """Parameters of one simulated Jenike-type shear test (SI units; docs/SHEAR.md).

    A bed is poured into the cuboid ``cell`` = (Lx, Ly, H), periodic in x and y, and
    consolidated to ``preshear_stress`` by a flat lid (the uniaxial test's fill and
    pre-compression, gravity switched off after the fill so that the stress is uniform in
    height). The grains within ``platen_layer`` diameters of the floor and of the lid are
    then glued (moved as rigid bodies, :meth:`engine.Simulation.set_driven`): the rough
    base, fixed, and the rough lid, moved along x at the shear speed and along z by a
    normal-stress servo. The bed is pre-sheared at ``preshear_stress`` to steady flow; from
    that stored state each shear point reverses the lid until the shear stress is zero, sets
    its normal stress ``normal_stresses[i]`` and shears to failure (the peak shear stress).

    Attributes:
        cell: (Lx, Ly, H) [m]: periodic cross-section (x the shear direction) and the
            height the bed fills at ``solid_fraction``; by default 10 x 5 x 15 diameters at
            R = 2.5 mm, about 860 grains: of the stored cells 10, 15 and 20 diameters tall
            none differs significantly from the next (six seeds), and halving the rate
            changed the 10 d cell's results significantly, the 15 d cell's not
            (docs/SHEAR.md, "Cell height and rate").
        radius, polydispersity, density, gravity, solid_fraction, pour_fraction,
        pour_speed, pair_law, wall_law, wall_material, settle_ke, seed, output_interval,
        dt, dt_fraction, max_stage_time: as :class:`engine.UniaxialTest` (gravity acts in
        the fill only).
        preshear_stress: normal stress of the pre-shear, sigma_pre [Pa].
        normal_stresses: normal stresses of the shear points, each < ``preshear_stress``
            [Pa]; at least two different ones (a yield locus is a line fitted through them).
        inertial_number: the shear rate as an inertial number over the whole gap,
            I = (v / h) d sqrt(rho / sigma) [-], with v the lid's speed, h the gap, d = 2R,
            rho the particle density and sigma the stage's normal stress; the same I in the
            lid's descent of the consolidation (the uniaxial test's ``inertial_number``).
        max_shear_speed: the lid's shear speed at most [m/s].
        platen_layer: grains whose centres lie within this many mean diameters of the floor
            (or of the lid) are glued to it [-].
        preshear_min_strain: the pre-shear runs at least this shear strain (lid
            displacement over the gap) [-]: in the stored long pre-shears the shear stress
            has levelled off by 0.1-0.2 (cohesionless) and 0.5-0.6 (cohesive) (docs/SHEAR.md,
            "Steady flow").
        preshear_strain: the pre-shear ends at this shear strain at the latest [-].
        steady_window: the pre-shear's steady-state check compares the mean shear stress
            over the last two windows of this much shear strain [-] ...
        steady_tolerance: ... which must differ by less than this fraction [-], and their
            mean lid heights by less than ``steady_height_tolerance`` [-] (a bed still
            compacting is not in steady flow: in the stored long pre-shears the
            window-to-window height changes reach about 1 % in steady flow, 2.6-3.6 % while
            a cohesive bed compacts at 0.2-0.4 strain); a pre-shear that has not reached
            both by ``preshear_strain`` fails the test (StageError).
        failure_strain: a shear to failure ends at this shear strain at the latest [-].
        failure_drop: a shear to failure ends once its shear stress (smoothed over 0.01
            shear strain) has fallen this fraction below its peak [-].
        servo_tolerance: the normal stress before a shear to failure is held within this
            fraction of its target [-].
    """

    cell: tuple[float, float, float] = param(
        (0.05, 0.025, 0.075),
        unit="m",
        kind="list",
        max_items=3,
        doc="(Lx, Ly, H): periodic cross-section (x the shear direction) and bed height",
    )
    radius: float = fill_param("radius")
    polydispersity: float = fill_param("polydispersity")
    density: float = fill_param("density")
    gravity: float = fill_param("gravity", doc="gravity of the fill")
    solid_fraction: float = fill_param(
        "solid_fraction", doc="solid fraction assumed for the settled bed"
    )
    pour_fraction: float = fill_param("pour_fraction")
    pour_speed: float | None = fill_param(
        "pour_speed", doc="largest particle speed during the fill (None: free fall)"
    )
    pair_law: BilinearAdhesive | EEPA | HertzMindlin = fill_param("pair_law")
    wall_law: HertzMindlin = fill_param(
        "wall_law", doc="law of the flat floor and of the flat lid of the consolidation"
    )
    wall_material: WallMaterial = fill_param("wall_material", doc="floor and lid material")
    preshear_stress: float = param(10e3, unit="Pa", gt=0, doc="normal stress of the pre-shear")
    normal_stresses: tuple[float, ...] = param(
        (2e3, 4e3, 6e3, 8e3),
        unit="Pa",
        kind="list",
        max_items=MAX_POINTS,
        doc="normal stresses of the shear points (each < preshear_stress)",
    )
    inertial_number: float = param(
        1e-3, unit="1", gt=0, le=0.05, doc="inertial number of the shear over the gap"
    )
    max_shear_speed: float = param(
        0.05, unit="m/s", gt=0, le=1.0, doc="largest shear speed of the lid"
    )
    platen_layer: float = param(
        1.0, unit="1", gt=0, le=3.0, doc="glued layer thickness in mean diameters"
    )
    preshear_min_strain: float = param(
        0.6, unit="1", ge=0, le=10.0, doc="shortest pre-shear, in shear strain"
    )
    preshear_strain: float = param(
        1.5, unit="1", gt=0, le=10.0, doc="longest pre-shear, in shear strain"
    )
    steady_window: float = param(
        0.2, unit="1", gt=0, le=1.0, doc="shear strain of each steady-state window"
    )
    steady_tolerance: float = param(
        0.1, unit="1", gt=0, lt=1, doc="steady: two windows' mean shear stresses this close"
    )
    failure_strain: float = param(
        0.3, unit="1", gt=0, le=5.0, doc="longest shear to failure, in shear strain"
    )
    failure_drop: float = param(
        0.05, unit="1", gt=0, lt=1, doc="drop below the peak that ends a shear to failure"
    )
    steady_height_tolerance: float = param(
        0.01, unit="1", gt=0, lt=1, doc="steady: two windows' mean lid heights this close"
    )
    servo_tolerance: float = param(
        0.02, unit="1", gt=0, lt=0.5, doc="normal stress held this close before shearing"
    )
    settle_ke: float = fill_param("settle_ke")
    seed: int = fill_param("seed")
    output_interval: float = fill_param("output_interval")
    dt: float | None = fill_param("dt")
    dt_fraction: float = fill_param("dt_fraction")
    max_stage_time: float = fill_param("max_stage_time")

    def __post_init__(self) -> None:
        o = "ShearTest"
        try:
            stresses = tuple(float(s) for s in self.normal_stresses)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{o}.normal_stresses", self.normal_stresses, "a list of stresses [Pa]"
            ) from None
        object.__setattr__(self, "normal_stresses", stresses)
        check_fields(self, o)
        if not 2 <= len(stresses) <= MAX_POINTS:
            raise ParameterError(
                f"{o}.normal_stresses",
                list(stresses),
                f"2 to {MAX_POINTS} stresses",
                "a yield locus is a line fitted through the shear points",
            )
        for k, s in enumerate(stresses):
            if not (math.isfinite(s) and 0 < s < self.preshear_stress):
                raise ParameterError(
                    f"{o}.normal_stresses[{k}]",
                    s,
                    f"> 0 and < preshear_stress = {self.preshear_stress:g} Pa",
                )
        if len(set(stresses)) < 2:
            raise ParameterError(
                f"{o}.normal_stresses", list(stresses), "at least two different stresses"
            )
        if self.preshear_min_strain > self.preshear_strain:
            raise ParameterError(
                f"{o}.preshear_min_strain",
                self.preshear_min_strain,
                f"<= preshear_strain = {self.preshear_strain:g}",
            )
        if self.steady_window * 2 > self.preshear_strain:
            raise ParameterError(
                f"{o}.steady_window",
                self.steady_window,
                f"<= preshear_strain / 2 = {self.preshear_strain / 2:g}",
                "the steady-state check compares two windows",
            )
        # the fill, the consolidation and the law checks are the uniaxial test's: its errors
        # are given back under this record's field names
        try:
            ut = self.consolidation_test()
        except ParameterError as e:
            name = e.field.split(".", 1)[1] if "." in e.field else e.field
            if name == "consolidation_stress":
                name = "preshear_stress"
            raise ParameterError(f"{o}.{name}", e.value, e.limit, e.why) from None
        object.__setattr__(self, "cell", ut.cell)
        if self.cell[2] < 4 * self.platen_layer * 2 * self.radius:
            raise ParameterError(
                f"{o}.cell",
                f"{self.cell[2]:g} m along z",
                f">= {8 * self.platen_layer * self.radius:.4g} m (four glued layers' "
                "thickness: two glued layers and a sheared bed between them)",
            )
        del ut

    def consolidation_test(self) -> UniaxialTest:
        """The uniaxial test whose fill and pre-compression (to ``preshear_stress``, gravity
        off after the fill) are this test's fill and consolidation; its other stages are
        not run."""
        shared = {
            f.name: getattr(self, f.name)
            for f in fields(UniaxialTest)
            if f.name in _SHARED and hasattr(self, f.name)
        }
        return UniaxialTest(
            **shared,
            gravity_off_after_fill=True,
            pre_stress=self.preshear_stress,
            consolidation_stress=2.0 * self.preshear_stress,
            inertial_number=self.inertial_number,
            max_platen_speed=self.max_shear_speed,
            unconfined=False,
        )

    @property
    def area(self) -> float:
        """The cell's cross-section Lx Ly [m^2]."""
        return self.cell[0] * self.cell[1]

    @property
    def consolidation_stress(self) -> float:
        """The normal stress the bed is consolidated and pre-sheared at, sigma_pre [Pa]: a
        scaling study's stress scale (the floor of a strength's error, engine.study)."""
        return self.preshear_stress

    @property
    def n_particles(self) -> int:
        """Number of particles: solid_fraction x cell volume / mean particle volume."""
        return self.consolidation_test().n_particles

    @property
    def thickness_diameters(self) -> float:
        """Thinnest side of the cell's periodic cross-section (Lx, Ly) in diameters of the
        largest particle [-] (as :attr:`engine.UniaxialTest.thickness_diameters`)."""
        return min(self.cell[:2]) / (2 * self.radius * (1 + self.polydispersity))

    def resolved_dt(self) -> float:
        """The time step a run of this test takes [s]: ``dt``, or ``dt_fraction`` of the
        critical time of the stiffest contact (its consolidation test's)."""
        return self.consolidation_test().resolved_dt()


def halved_protocol(test: ShearTest) -> ShearTest:
    """``test`` at half its shear rate and half its time step, everything else equal: the
    inertial number halved (the lid's descent and every shear stage), ``dt`` halved where
    given, else ``dt_fraction``, and ``max_stage_time`` doubled (the same strains take
    twice the time). A run of it against ``test``'s shows whether the shear is
    quasi-static and its step converged (docs/PHYSICS.md section 7.6)."""
    step = {"dt": test.dt / 2} if test.dt is not None else {"dt_fraction": test.dt_fraction / 2}
    return replace(
        test,
        inertial_number=test.inertial_number / 2,
        max_stage_time=test.max_stage_time * 2,
        **step,
    )


def control_test(reference: ShearTest, radius: float, reference_dt: float) -> ShearTest:
    """The resolution control of coarse radius ``radius`` [m] for a shear study
    (docs/PHYSICS.md sections 7.4 and 11.1): the ``reference`` law unscaled in the
    reference cell scaled by s = R_ref / radius (as many of its diameters across as a
    coarse run is of its own, the same particle count), gravity over s (the fill's
    overburden rho g H kept; gravity is off from the consolidation on), the inertial number,
    the law, the time step (``reference_dt`` [s] where the reference gives one) and the
    stage bounds kept. At the same inertial number a coarse run under K ~ R, f0 ~ R^2 is
    this test scaled by 1/s in length and 1/s^2 in force, its clock too (times scale as
    1/s, shear speeds are the same), but for the curve samples, fixed in seconds
    (``output_interval``)."""
    s = reference.radius / radius
    return replace(
        reference,
        cell=tuple(c * s for c in reference.cell),
        gravity=reference.gravity / s,
        dt=None if reference.dt is None else reference_dt,
    )


#: The fields a shear test passes on to its consolidation test as they are.
_SHARED = (
    "cell",
    "radius",
    "polydispersity",
    "density",
    "gravity",
    "solid_fraction",
    "pour_fraction",
    "pour_speed",
    "pair_law",
    "wall_law",
    "wall_material",
    "settle_ke",
    "seed",
    "output_interval",
    "dt",
    "dt_fraction",
    "max_stage_time",
)
