"""Parameters of the simulated hopper discharge (docs/HOPPER.md).

:class:`HopperTest` holds every parameter of one discharge, declared with its unit and bounds
(:mod:`engine.core.records`) and validated once on construction: an error names the field and
the limit (:class:`engine.ParameterError`). The scene is built by :mod:`engine.hopper.scene`,
run by :mod:`engine.hopper.driver` and read by :mod:`engine.hopper.measures`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.hertz import HertzMindlin
from ..contact.registry import pair_laws
from ..contact.wall import WallMaterial
from ..core.config import SKIN_FRACTION
from ..core.errors import ParameterError
from ..core.records import Record, check_fields, param
from ..uniaxial.spec import fill_param

#: The outlet is at least this many diameters of the largest particle wide [-]: below about
#: three diameters a few grains span any outlet and no flow, steady or not, is measured
#: (Beverloo's law holds from about six: docs/HOPPER.md).
MIN_OUTLET_DIAMETERS = 3.0
#: The fewest particles a fill holds: the steady window needs a flow of many particles.
MIN_PARTICLES = 50
#: The most particles a fill holds (a guard against a typo in fill_height) [-].
MAX_PARTICLES = 2_000_000
#: Sides of the polygon that stands for the cone's circular cross-section [-].
CONE_SIDES = 32


@dataclass(frozen=True)
class HopperTest(Record):
    """Parameters of one hopper discharge (SI units; docs/HOPPER.md).

    A ``"slot"`` hopper is a plane-flow wedge: two flat walls at ``half_angle`` from the
    vertical meet an outlet of width ``outlet_width`` (x across, z up) and the scene is
    periodic in its ``depth`` (y). A ``"cone"`` is a conical hopper of outlet diameter
    ``outlet_width``, its wall a triangle mesh of :data:`CONE_SIDES` sides (the outlet a
    regular polygon of that circumradius). The fill is poured from a loose lattice behind a
    closed flat gate at the outlet and settled; the gate is then moved away downwards at
    ``gate_speed`` (faster than anything falls behind it) and the discharge runs until the
    hopper is empty, the flow stops, or ``max_discharge_time``. Discharged particles fall
    onto a catch floor far below the outlet.

    Attributes:
        shape: ``"slot"`` or ``"cone"``.
        half_angle: the wall's angle from the vertical [deg], in (0, 90).
        outlet_width: B, the outlet's width (slot) or diameter (cone) [m], at least
            :data:`MIN_OUTLET_DIAMETERS` diameters of the largest particle.
        depth: the slot's periodic depth [m] (unused by a cone), at least twice the
            neighbour cut-off 2 (2 Rmax + skin).
        particles: number of particles of the fill; or None with ``fill_height`` given.
        fill_height: height of the settled fill above the outlet [m]: the fill is
            ``solid_fraction`` of the hopper's volume below it; or None with ``particles``.
        solid_fraction: solid fraction assumed for the settled fill (only to count particles
            from ``fill_height``) [-].
        radius, polydispersity, density, gravity, pair_law, wall_law, wall_material, seed,
        dt, dt_fraction: as :class:`engine.UniaxialTest` (the wall law and material are the
        hopper's walls' and the gate's; ``wall_law.mu`` is the wall friction).
        gate_speed: speed at which the gate moves away [m/s] (None: 5 sqrt(g B), five times
            the speed a grain reaches falling B/2).
        settle_ke: the fill is settled once its kinetic energy is below this fraction of
            N m g R [-] ...
        max_settle_time: ... within this time [s] (else StageError).
        window_start, window_end: the steady window is the stretch of the discharge between
            these fractions of the fill's mass discharged [-] (docs/HOPPER.md).
        arch_wait: the flow has stopped when, for this many free-fall times sqrt(B / g), the
            mass discharged is below ``arch_fraction`` of what the flow's fastest rate would
            discharge in that time (and below one particle's mass at least) [-].
        arch_fraction: see ``arch_wait`` [-].
        wall_bins: number of height bins of the wall normal stress [-].
        output_interval: time between samples of the discharge [s].
        max_discharge_time: bound on the discharge after the gate opens [s].
    """

    shape: str = param("slot", unit="", kind="str", choices=("slot", "cone"), doc="hopper shape")
    half_angle: float = param(30.0, unit="deg", gt=0.0, lt=90.0, doc="wall angle from the vertical")
    outlet_width: float = param(0.05, unit="m", gt=0.0, le=10.0, doc="outlet width B")
    depth: float = param(0.025, unit="m", gt=0.0, le=10.0, doc="periodic depth of a slot")
    particles: int | None = param(
        800,
        unit="1",
        kind="int",
        ge=MIN_PARTICLES,
        le=MAX_PARTICLES,
        nullable=True,
        doc="particles in the fill (None: from fill_height)",
    )
    fill_height: float | None = param(
        None, unit="m", gt=0.0, le=100.0, nullable=True, doc="settled fill height"
    )
    solid_fraction: float = fill_param(
        "solid_fraction", doc="settled solid fraction (fill_height to count)"
    )
    radius: float = fill_param("radius")
    polydispersity: float = fill_param("polydispersity")
    density: float = fill_param("density")
    gravity: float = fill_param("gravity", doc="gravity")
    pair_law: BilinearAdhesive | EEPA | HertzMindlin = fill_param("pair_law")
    wall_law: HertzMindlin = fill_param(
        "wall_law", doc="particle-wall law of the hopper's walls and gate (mu: the wall friction)"
    )
    wall_material: WallMaterial = fill_param("wall_material", doc="wall and gate material")
    gate_speed: float | None = param(
        None, unit="m/s", gt=0, le=1e3, nullable=True, doc="gate opening speed"
    )
    settle_ke: float = fill_param("settle_ke")
    max_settle_time: float = param(3.0, unit="s", gt=0, doc="bound on the settling")
    window_start: float = param(
        0.2, unit="1", gt=0, lt=1, doc="steady window from this discharged fraction"
    )
    window_end: float = param(
        0.6, unit="1", gt=0, lt=1, doc="steady window up to this discharged fraction"
    )
    arch_wait: float = param(
        20.0, unit="1", ge=2.0, le=1e4, doc="stopped: this many sqrt(B/g) without flow"
    )
    arch_fraction: float = param(
        0.01, unit="1", gt=0, lt=1, doc="stopped: rate below this fraction of the fastest"
    )
    wall_bins: int = param(5, unit="1", kind="int", ge=1, le=100, doc="wall stress bins")
    seed: int = fill_param("seed")
    output_interval: float = fill_param("output_interval", doc="time between samples")
    max_discharge_time: float = param(5.0, unit="s", gt=0, doc="bound on the discharge")
    dt: float | None = fill_param("dt")
    dt_fraction: float = fill_param(
        "dt_fraction", doc="with dt None: time step over the critical time"
    )

    def __post_init__(self) -> None:
        o = "HopperTest"
        check_fields(self, o)
        d = self.max_diameter
        if self.outlet_width < MIN_OUTLET_DIAMETERS * d:
            raise ParameterError(
                f"{o}.outlet_width",
                self.outlet_width,
                f">= {MIN_OUTLET_DIAMETERS:g} diameters of the largest particle "
                f"({MIN_OUTLET_DIAMETERS * d:.4g} m)",
                "a few grains span a narrower outlet: no flow to measure",
            )
        if self.shape == "slot":
            cut = 2.0 * (2.0 * self.radius * (1 + self.polydispersity)) + SKIN_FRACTION * (
                self.radius * (1 + self.polydispersity)
            )
            if self.depth < 2.0 * cut:
                raise ParameterError(
                    f"{o}.depth",
                    self.depth,
                    f">= {2 * cut:.4g} m (twice the neighbour cut-off 2 Rmax + skin)",
                    "the slot is periodic in its depth (minimum image)",
                )
        if (self.particles is None) == (self.fill_height is None):
            raise ParameterError(
                f"{o}.particles",
                self.particles,
                "given, or None with fill_height given (exactly one of the two)",
            )
        if self.fill_height is not None:
            n = self.n_particles
            if not MIN_PARTICLES <= n <= MAX_PARTICLES:
                raise ParameterError(
                    f"{o}.fill_height",
                    self.fill_height,
                    f"a fill of {MIN_PARTICLES} to {MAX_PARTICLES} particles (it gives {n})",
                )
        if self.window_start >= self.window_end:
            raise ParameterError(
                f"{o}.window_start",
                self.window_start,
                f"< window_end = {self.window_end:g}",
            )
        if not isinstance(self.pair_law, pair_laws()):
            raise ParameterError(f"{o}.pair_law", self.pair_law, "a pair law record")

    # ------------------------------------------------------------------ derived
    @property
    def max_diameter(self) -> float:
        """Diameter of the largest particle, 2 R (1 + p) [m]."""
        return 2.0 * self.radius * (1.0 + self.polydispersity)

    @property
    def mean_particle_volume(self) -> float:
        """Mean particle volume of radii uniform in [R(1-p), R(1+p)] [m^3]:
        4/3 pi E[r^3] = 4/3 pi R^3 (1 + p^2)."""
        return 4.0 / 3.0 * math.pi * self.radius**3 * (1.0 + self.polydispersity**2)

    def volume_below(self, h: float) -> float:
        """Volume of the hopper between the outlet and height ``h`` above it [m^3] (the cone:
        its polygonal cross-section, :data:`CONE_SIDES` sides)."""
        b = 0.5 * self.outlet_width
        t = math.tan(math.radians(self.half_angle))
        if self.shape == "slot":
            return self.depth * (2.0 * b * h + t * h * h)
        n = CONE_SIDES
        k = 0.5 * n * math.sin(2.0 * math.pi / n)  # polygon area / circumradius^2
        top = b + t * h
        return k * h * (b * b + b * top + top * top) / 3.0

    def height_holding(self, volume: float) -> float:
        """The height above the outlet below which the hopper holds ``volume`` [m^3] [m]
        (the inverse of :meth:`volume_below`, by bisection)."""
        lo, hi = 0.0, max(self.outlet_width, 1e-9)
        while self.volume_below(hi) < volume:
            hi *= 2.0
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.volume_below(mid) < volume else (lo, mid)
        return 0.5 * (lo + hi)

    @property
    def n_particles(self) -> int:
        """Particles in the fill: ``particles``, or ``solid_fraction`` of the hopper's volume
        below ``fill_height`` over the mean particle volume."""
        if self.particles is not None:
            return int(self.particles)
        v = self.volume_below(self.fill_height)
        return round(self.solid_fraction * v / self.mean_particle_volume)

    @property
    def free_fall_time(self) -> float:
        """sqrt(B / g) [s]: the time scale of a grain's fall through the outlet."""
        return math.sqrt(self.outlet_width / self.gravity)

    @property
    def resolved_gate_speed(self) -> float:
        """``gate_speed``, or 5 sqrt(g B) [m/s]."""
        if self.gate_speed is not None:
            return self.gate_speed
        return 5.0 * math.sqrt(self.gravity * self.outlet_width)

    @property
    def consolidation_stress(self) -> float:
        """The stress scale of the fill, rho_b g B with rho_b = density x solid_fraction [Pa]
        (a study's stress scale, as the other tests' consolidation stress)."""
        return self.density * self.solid_fraction * self.gravity * self.outlet_width

    @property
    def rate_scale(self) -> float:
        """The mass rate scale of the outlet [kg/s]: rho sqrt(g) B^(3/2) x depth for a slot,
        rho sqrt(g) B^(5/2) for a cone (rho the particle density): Beverloo's form without
        its constants. The rate over it, the discharge number, is the same for a hopper
        scaled in length by s with gravity over s (a study's resolution control) as for the
        hopper it stands for."""
        b = self.outlet_width
        root = self.density * math.sqrt(self.gravity)
        if self.shape == "slot":
            return root * b**1.5 * self.depth
        return root * b**2.5

    def resolved_dt(self) -> float:
        """The time step a run of this test takes [s]: ``dt``, or ``dt_fraction`` of the
        stable limit of its scene at its fastest impact
        (:func:`engine.hopper.driver.resolved_dt`; builds the scene, no simulation)."""
        from .driver import resolved_dt

        return resolved_dt(self)

    @property
    def thickness_diameters(self) -> float:
        """The outlet width in diameters of the largest particle [-]: the hopper's smallest
        feature (as :attr:`engine.UniaxialTest.thickness_diameters` is the cell's)."""
        return self.outlet_width / self.max_diameter

    @property
    def outlet_diameters(self) -> float:
        """B over the mean diameter 2R [-]."""
        return self.outlet_width / (2.0 * self.radius)


def halved_protocol(test: HopperTest) -> HopperTest:
    """``test`` at half its time step (``dt`` halved where given, else ``dt_fraction``),
    everything else equal: the discharge is driven by gravity, so its rate is the physics'
    and only the step can be halved; a run of it against ``test``'s shows whether the step
    is converged."""
    step = {"dt": test.dt / 2} if test.dt is not None else {"dt_fraction": test.dt_fraction / 2}
    return replace(test, **step)


def control_test(reference: HopperTest, radius: float, reference_dt: float) -> HopperTest:
    """The resolution control of coarse radius ``radius`` [m] for a hopper study: the
    ``reference`` law unscaled in the reference hopper scaled by s = R_ref / radius (outlet,
    depth and fill height: as many of its diameters as a coarse run is of its own, the same
    particle count), gravity over s (the stress level rho_b g B kept, as the uniaxial
    control keeps rho g H), the time step (``reference_dt`` [s] where the reference gives
    one) kept (docs/PHYSICS.md section 7.4)."""
    s = reference.radius / radius
    fill = None if reference.fill_height is None else reference.fill_height * s
    return replace(
        reference,
        outlet_width=reference.outlet_width * s,
        depth=reference.depth * s,
        fill_height=fill,
        gravity=reference.gravity / s,
        dt=None if reference.dt is None else reference_dt,
    )
