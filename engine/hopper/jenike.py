"""Jenike's critical outlet width of a mass-flow hopper: the outlet below which a cohesive
bulk solid's arch carries itself (Jenike, A. W., "Storage and flow of solids", Bulletin 123,
Utah Engineering Experiment Station, 1964).

The method, as used here:

1. **The flow factor** ff = sigma_1 / sigma_1' of the hopper: sigma_1 the major consolidation
   stress the flowing solid carries at the outlet, sigma_1' the major stress in an arch
   spanning it. sigma_1 comes from Jenike's **radial stress field** of converging flow,
   solved numerically here (:func:`radial_stress_field`), not read from a chart or an
   approximation: the mean stress sigma = rho_b g r s(theta) (r from the hopper's apex, theta
   from its axis), the solid at yield on its effective yield locus (Mohr circles of radius
   sigma sin(delta)), the hoop stress of a cone the major principal stress (Jenike's
   converging-flow assumption), symmetry on the axis (the major principal stress normal to
   it), the wall at its friction angle phi_w (the major principal stress at
   beta = (phi_w + asin(sin phi_w / sin delta)) / 2 from the wall's normal). Two ordinary
   differential equations in theta for s and psi (the major principal direction's angle
   from the radius), shot from the axis for the one s(0) that meets the wall condition.
   Then, with the outlet at r = B / (2 sin theta_w) and sigma_1 = (1 + sin delta) sigma at the
   wall, ff = (1 + sin delta) s_w H(theta) / (2 sin theta_w). Check: at delta = 30 deg,
   phi_w = 19 deg, a cone of 27.5 deg, this gives ff = 1.85; a worked example of Rhodes
   (Introduction to Particle Technology, 2nd ed., Wiley 2008, ch. 10, as a public slide set
   quotes it: the book itself not checked) reads ff = 1.8 off Jenike's chart for the same
   point and the mass-flow limit at 30.5 deg; the field here ends between 31 and 32.5 deg
   (tests/engine/test_jenike.py).
   Why numerical: the closed-form approximations (Arnold & McLean 1976, Enstad 1975) replace
   the field by an average over the section and were not available here to check to the
   digit; the field itself is two ODEs and a root.
   Validity: delta below 90 deg, phi_w below delta, theta_w inside the mass-flow region (where
   no radial field meets the wall condition, :class:`engine.ParameterError` says so).
   Jenike's charts stop at delta = 70 deg; above it the method is extrapolated.
2. **H(theta)**, the arch's shape function: sigma_1' = rho_b g B / H(theta). Conical
   (circular outlet): H = 2 + theta/60 (theta in degrees), the linear fit to Jenike's chart
   used by Rhodes (2008, same example: H(27.5 deg) = 2.46). Plane flow (slot outlet):
   H = 1 + theta/120, half the conical value (Jenike's H at theta = 0 is 2 for a circle and 1
   for a slot, the ratio of a circular and a plane arch's weight to abutment; the plane
   chart's slope is assumed to keep that ratio). **The plane-flow H is an assumption, not
   checked against Jenike's chart** (no copy of it was at hand): it enters B_crit linearly.
3. **The critical point**: where the flow function sigma_c(sigma_1) (the unconfined yield
   strength against the major consolidation stress, from shear tests) crosses sigma_1 / ff
   from above (:func:`critical_point`), and **B_crit = H(theta) sigma_c* / (rho_b g)**
   (:func:`critical_outlet_width`). Outlets narrower than B_crit arch.

SI units: stresses in Pa, densities in kg/m^3, gravity in m/s^2, widths in m; angles in
degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import ParameterError

SHAPES = ("slot", "cone")


def _check_angles(delta: float, phi_w: float, theta: float, shape: str) -> tuple[float, ...]:
    delta, phi_w, theta = float(delta), float(phi_w), float(theta)
    if not (math.isfinite(delta) and 0.0 < delta < 90.0):
        raise ParameterError("jenike.delta", delta, "in (0, 90) deg")
    if not (math.isfinite(phi_w) and 0.0 <= phi_w < delta):
        raise ParameterError(
            "jenike.phi_w",
            phi_w,
            f"in [0, delta = {delta:g}) deg",
            "a rougher wall: the solid shears within itself",
        )
    if not (math.isfinite(theta) and 0.0 < theta < 90.0):
        raise ParameterError("jenike.theta", theta, "in (0, 90) deg")
    if shape not in SHAPES:
        raise ParameterError("jenike.shape", shape, f"one of {SHAPES}")
    return delta, phi_w, theta


def wall_stress_angle(delta: float, phi_w: float) -> float:
    """beta [deg]: the angle between the major principal stress at a wall and the wall's
    normal, (phi_w + asin(sin phi_w / sin delta)) / 2, for a solid at yield on its effective
    locus (angle delta) sliding on a wall at friction angle phi_w."""
    d, w = math.radians(delta), math.radians(phi_w)
    return math.degrees(0.5 * (w + math.asin(math.sin(w) / math.sin(d))))


def _rhs(theta: float, y, k: float, m: int):
    """d(s, psi)/dtheta of the radial stress field (module docstring): equilibrium in polar
    (m = 0) or spherical (m = 1) coordinates, compressive stresses, sigma_ij = rho g r f_ij,
    f_rr = s (1 + k cos 2psi), f_tt = s (1 - k cos 2psi), f_rt = s k sin 2psi, f_pp = s (1 + k)."""
    s, psi = y
    c2, s2 = math.cos(2.0 * psi), math.sin(2.0 * psi)
    frr, ftt, frt, fpp = s * (1 + k * c2), s * (1 - k * c2), s * k * s2, s * (1 + k)
    cot = math.cos(theta) / math.sin(theta)
    r1 = -math.cos(theta) - ((2 + m) * frr - ftt - m * fpp + m * frt * cot)
    r2 = math.sin(theta) - ((3 + m) * frt + m * (ftt - fpp) * cot)
    a11, a12, a21, a22 = k * s2, 2.0 * s * k * c2, 1.0 - k * c2, 2.0 * s * k * s2
    det = a11 * a22 - a12 * a21
    return [(r1 * a22 - a12 * r2) / det, (a11 * r2 - a21 * r1) / det]


def _breakdown(theta: float, y, k: float, m: int) -> float:
    """Zero where the field breaks down: the equations' determinant 2 s k (k - cos 2psi)
    vanishes (a characteristic direction) or s reaches zero."""
    return min(k - math.cos(2.0 * y[1]), y[0]) - 1e-6


_breakdown.terminal = True


def _shoot(s0: float, k: float, m: int, theta_w: float, rtol: float):
    """The field from the axis (psi = 90 deg, s = ``s0``) to the wall, or None where it
    breaks down first."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        _rhs,
        (1e-6, theta_w),
        [s0, 0.5 * math.pi],
        args=(k, m),
        rtol=rtol,
        atol=rtol * 1e-2,
        events=_breakdown,
    )
    if sol.status != 0 or not np.all(np.isfinite(sol.y[:, -1])):
        return None
    return sol


@dataclass(frozen=True)
class RadialField:
    """Jenike's radial stress field in a hopper (:func:`radial_stress_field`).

    Attributes:
        s_axis: s on the axis [-] (the mean stress there over rho_b g r).
        s_wall: s at the wall [-].
        psi_wall: the major principal stress's angle from the radius at the wall [deg].
    """

    s_axis: float
    s_wall: float
    psi_wall: float


def radial_stress_field(delta: float, phi_w: float, theta: float, shape: str) -> RadialField:
    """Jenike's radial stress field of converging flow in a ``shape`` ("slot": plane flow;
    "cone") hopper of half-angle ``theta`` [deg], a solid of effective angle of internal
    friction ``delta`` [deg] on walls of friction angle ``phi_w`` [deg] (module docstring).
    :class:`engine.ParameterError` where no field meets the wall condition (beyond the
    mass-flow limit)."""
    from scipy.optimize import brentq

    delta, phi_w, theta = _check_angles(delta, phi_w, theta, shape)
    k, m, tw = math.sin(math.radians(delta)), SHAPES.index(shape), math.radians(theta)
    target = math.radians(90.0 + wall_stress_angle(delta, phi_w))

    def miss(s0: float, rtol: float = 1e-7) -> float:
        sol = _shoot(s0, k, m, tw, rtol)
        # a field that breaks down before the wall has turned too far (small s0): +1
        return 1.0 if sol is None else float(sol.y[1, -1] - target)

    # psi at the wall falls as s(0) grows: the first sign change from small s(0) up,
    # refined by Brent's method on the accurate field; a root at a breakdown is not one
    grid = np.geomspace(1e-3, 100.0, 36)
    vals = [miss(g) for g in grid]
    for lo, hi, flo, fhi in zip(grid[:-1], grid[1:], vals[:-1], vals[1:], strict=True):
        if flo > 0.0 >= fhi:
            s0 = brentq(lambda x: miss(x, 1e-10), lo, hi, xtol=1e-13, rtol=1e-12)
            sol = _shoot(s0, k, m, tw, 1e-10)
            if sol is not None and abs(sol.y[1, -1] - target) < 1e-6:
                return RadialField(s0, float(sol.y[0, -1]), math.degrees(sol.y[1, -1]))
    raise ParameterError(
        "jenike.theta",
        theta,
        f"inside the mass-flow region for delta = {delta:g} deg, phi_w = {phi_w:g} deg ({shape})",
        "no radial stress field meets the wall condition",
    )


def h_function(theta: float, shape: str) -> float:
    """Jenike's H(theta) [-] (module docstring): 2 + theta/60 for a cone (the fit to his
    chart Rhodes 2008 uses), 1 + theta/120 for a slot (assumed: half the conical)."""
    theta = float(theta)
    if not (math.isfinite(theta) and 0.0 < theta < 90.0):
        raise ParameterError("jenike.theta", theta, "in (0, 90) deg")
    if shape not in SHAPES:
        raise ParameterError("jenike.shape", shape, f"one of {SHAPES}")
    return 2.0 + theta / 60.0 if shape == "cone" else 1.0 + theta / 120.0


def flow_factor(delta: float, phi_w: float, theta: float, shape: str) -> float:
    """Jenike's flow factor ff [-] = (1 + sin delta) s_w H(theta) / (2 sin theta) of a
    ``shape`` hopper of half-angle ``theta`` [deg], effective angle of internal friction
    ``delta`` [deg], wall friction angle ``phi_w`` [deg] (module docstring)."""
    field = radial_stress_field(delta, phi_w, theta, shape)
    k = math.sin(math.radians(delta))
    return (
        (1.0 + k) * field.s_wall * h_function(theta, shape) / (2.0 * math.sin(math.radians(theta)))
    )


def critical_point(sigma_1, sigma_c, ff: float) -> tuple[float, float]:
    """(sigma_1*, sigma_c*) [Pa]: where the flow function, the straight segments through the
    points (``sigma_1``, ``sigma_c``) [Pa] sorted by sigma_1, first crosses the line
    sigma_1 / ``ff`` from above (the strength an arch needs falls below what the solid has
    there). :class:`engine.ParameterError` where the flow function lies below the line at
    its first point (the critical point is below the stresses measured) or above it at its
    last (above them): no extrapolation."""
    x = np.asarray(sigma_1, dtype=float).ravel()
    y = np.asarray(sigma_c, dtype=float).ravel()
    if x.size < 2 or x.size != y.size:
        raise ParameterError(
            "jenike.flow_function", x.size, "at least two (sigma_1, sigma_c) points of equal count"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(x > 0) and np.all(y >= 0)):
        raise ParameterError(
            "jenike.flow_function", "values", "finite, sigma_1 > 0, sigma_c >= 0 Pa"
        )
    if not (math.isfinite(ff) and ff > 0):
        raise ParameterError("jenike.ff", ff, "finite and > 0")
    order = np.argsort(x)
    x, y = x[order], y[order]
    gap = y - x / ff
    if gap[0] <= 0.0:
        raise ParameterError(
            "jenike.flow_function",
            f"sigma_c = {y[0]:.4g} Pa at sigma_1 = {x[0]:.4g} Pa",
            f"above sigma_1 / ff = {x[0] / ff:.4g} Pa at the lowest consolidation",
            "the critical point lies below the stresses measured",
        )
    for i in range(x.size - 1):
        if gap[i] > 0.0 >= gap[i + 1]:
            t = gap[i] / (gap[i] - gap[i + 1])
            s1 = x[i] + t * (x[i + 1] - x[i])
            return float(s1), float(s1 / ff)
    raise ParameterError(
        "jenike.flow_function",
        f"sigma_c = {y[-1]:.4g} Pa at sigma_1 = {x[-1]:.4g} Pa",
        f"below sigma_1 / ff = {x[-1] / ff:.4g} Pa at the highest consolidation",
        "the critical point lies above the stresses measured",
    )


def critical_outlet_width(
    sigma_c_crit: float, bulk_density: float, gravity: float, theta: float, shape: str
) -> float:
    """B_crit [m] = H(theta) sigma_c* / (rho_b g): ``sigma_c_crit`` [Pa] the unconfined yield
    strength at the critical point, ``bulk_density`` [kg/m^3], ``gravity`` [m/s^2],
    ``theta`` [deg] the hopper's half-angle."""
    for name, v in (
        ("sigma_c_crit", sigma_c_crit),
        ("bulk_density", bulk_density),
        ("gravity", gravity),
    ):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"jenike.{name}", v, "finite and > 0")
    return h_function(theta, shape) * float(sigma_c_crit) / (float(bulk_density) * float(gravity))
