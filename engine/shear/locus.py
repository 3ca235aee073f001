"""The yield locus of a shear test and its Mohr circles (docs/SHEAR.md, "Construction").

Plain functions of the shear points, recomputable from stored results:

- the yield locus: the least-squares line tau = c + sigma tan(phi) through the points of
  incipient failure (sigma_n, tau) (not the pre-shear point), c the cohesion [Pa] and phi
  the (linearised) angle of internal friction;
- sigma_c, the unconfined yield strength: the major principal stress of the Mohr circle
  through the origin tangent to the locus, sigma_c = 2 c (1 + sin phi) / cos phi (0 where
  c <= 0: no circle through the origin touches a locus that passes below it);
- sigma_1, the major consolidation stress: the larger principal stress of the Mohr circle
  through the pre-shear point (sigma_pre, tau_pre) tangent to the locus, with its tangent
  point at or left of the pre-shear point (the locus ends there: of the two circles, the
  smaller one). Centre p and radius r solve (sigma_pre - p)^2 + tau_pre^2 = r^2,
  r = c cos phi + p sin phi. A pre-shear point above the locus lies on no such circle: the
  circle is then the one tangent at the pre-shear point to the locus moved parallel through
  it (p = sigma_pre + tau_pre tan phi, r = tau_pre / cos phi), which is the limit of the
  first as the point reaches the locus (sigma_1 is continuous in the data); how far above
  is reported (``preshear_above``);
- ffc = sigma_1 / sigma_c (inf where sigma_c = 0), the effective angle of internal
  friction phi_e = asin(r / p) of the consolidation circle (the line through the origin
  tangent to it).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class YieldLocus:
    """A linearised yield locus and its Mohr-circle construction (units in the fields).

    Attributes:
        cohesion: c, the locus's intercept at sigma = 0 [Pa].
        slope: tan(phi) [-].
        friction_angle: phi, the angle of internal friction [deg].
        cohesion_se, slope_se: their standard errors from the fit's residuals [Pa], [-]
            (0 with two points: no residual degrees of freedom).
        sigma_c: unconfined yield strength [Pa].
        sigma_1: major consolidation stress [Pa].
        sigma_2: minor principal stress of the consolidation circle [Pa].
        ffc: flowability sigma_1 / sigma_c [-] (inf where sigma_c = 0).
        effective_friction_angle: phi_e [deg].
        preshear_above: how far the pre-shear point lies above the locus at sigma_pre [Pa]
            (0 when on or below it; see the module).
    """

    cohesion: float
    slope: float
    friction_angle: float
    cohesion_se: float
    slope_se: float
    sigma_c: float
    sigma_1: float
    sigma_2: float
    ffc: float
    effective_friction_angle: float
    preshear_above: float

    def to_dict(self) -> dict:
        """The fields as a plain dict."""
        return asdict(self)


def fit_line(sigma, tau) -> tuple[float, float, float, float]:
    """Least-squares line tau = c + m sigma through points ``sigma``, ``tau`` [Pa]: (c [Pa],
    m [-], standard error of c [Pa], of m [-]). Needs two different sigma."""
    x = np.asarray(sigma, dtype=float)
    y = np.asarray(tau, dtype=float)
    n = len(x)
    if n < 2 or np.ptp(x) <= 0:
        raise ValueError("a yield locus needs shear points at two different normal stresses")
    xm, ym = x.mean(), y.mean()
    sxx = float(np.sum((x - xm) ** 2))
    m = float(np.sum((x - xm) * (y - ym)) / sxx)
    c = float(ym - m * xm)
    if n > 2:
        s2 = float(np.sum((y - c - m * x) ** 2)) / (n - 2)
        se_m = math.sqrt(s2 / sxx)
        se_c = math.sqrt(s2 * (1.0 / n + xm * xm / sxx))
    else:
        se_m = se_c = 0.0
    return c, m, se_c, se_m


def unconfined_yield_strength(cohesion: float, slope: float) -> float:
    """sigma_c = 2 c (1 + sin phi) / cos phi [Pa] for the locus tau = c + sigma tan(phi)
    (``cohesion`` c [Pa], ``slope`` tan(phi) [-]); 0 where c <= 0."""
    if cohesion <= 0:
        return 0.0
    phi = math.atan(slope)
    return 2.0 * cohesion * (1.0 + math.sin(phi)) / math.cos(phi)


def consolidation_circle(
    cohesion: float, slope: float, sigma_pre: float, tau_pre: float
) -> tuple[float, float, float]:
    """(centre p [Pa], radius r [Pa], how far the pre-shear point lies above the locus [Pa])
    of the Mohr circle through the pre-shear point (``sigma_pre``, ``tau_pre``) [Pa] tangent
    to the locus tau = c + sigma tan(phi) (the module's construction)."""
    phi = math.atan(slope)
    a, b = math.sin(phi), cohesion * math.cos(phi)
    above = tau_pre - (cohesion + slope * sigma_pre)
    if above > 0:
        return sigma_pre + tau_pre * slope, tau_pre / math.cos(phi), above
    s = sigma_pre + a * b
    disc = s * s - (1.0 - a * a) * (sigma_pre**2 + tau_pre**2 - b * b)
    p = (s - math.sqrt(max(disc, 0.0))) / (1.0 - a * a)
    return p, b + a * p, 0.0


def yield_locus(sigma, tau, sigma_pre: float, tau_pre: float) -> YieldLocus:
    """The yield locus through the shear points (``sigma``, ``tau``) [Pa] and its Mohr
    circles with the pre-shear point (``sigma_pre``, ``tau_pre``) [Pa] (the module's
    construction). Raises ValueError for a locus that does not rise with the normal
    stress (phi <= 0: no Mohr construction), naming its slope, and for a pre-shear point so
    far below the locus that its consolidation circle would be centred at p <= 0."""
    c, m, se_c, se_m = fit_line(sigma, tau)
    if not m > 0:
        points = ", ".join(f"({float(s):.1f}, {float(t):.1f})" for s, t in zip(sigma, tau))
        raise ValueError(
            f"the yield locus's slope tan(phi) = {m:.4g} is not > 0: the shear points "
            f"(sigma_n, tau) = {points} Pa do not "
            "rise with the normal stress (noise larger than the locus's rise: a larger cell "
            "or normal stresses further apart)"
        )
    sc = unconfined_yield_strength(c, m)
    p, r, above = consolidation_circle(c, m, sigma_pre, tau_pre)
    if not p > 0:
        below = c + m * sigma_pre - tau_pre
        raise ValueError(
            f"no consolidation circle: the pre-shear point (sigma_pre, tau_pre) = "
            f"({sigma_pre:.1f}, {tau_pre:.1f}) Pa lies {below:.1f} Pa below the yield locus "
            f"tau = {c:.1f} Pa + {m:.4g} sigma, so far that the Mohr circle through it tangent "
            f"to the locus is centred at p = {p:.1f} Pa <= 0 (a pre-shear short of steady "
            "flow, or a locus whose cohesion its pre-shear stress cannot carry)"
        )
    s1, s2 = p + r, p - r
    return YieldLocus(
        cohesion=c,
        slope=m,
        friction_angle=math.degrees(math.atan(m)),
        cohesion_se=se_c,
        slope_se=se_m,
        sigma_c=sc,
        sigma_1=s1,
        sigma_2=s2,
        ffc=s1 / sc if sc > 0 else math.inf,
        effective_friction_angle=math.degrees(math.asin(min(1.0, r / p))),
        preshear_above=above,
    )
