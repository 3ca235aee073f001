"""Bulk measures of a uniaxial test, from its curves and particles: the interior slab's
porosity and coordination, secant stiffnesses, failure of the unconfined sample and its
strength (docs/PHYSICS.md sections 4 and 6). Plain numpy: recomputable from stored curves."""

from __future__ import annotations

import math

import numpy as np


class FailureDetector:
    """Tells, sample by sample, when an unconfined sample has failed: its stress has fallen
    ``drop`` (a fraction) below the peak so far and stayed there for ``strain`` more axial
    strain [-]. A single noisy sample, or the first grains touching the platen, is not a
    failure."""

    def __init__(self, drop: float, strain: float):
        self.drop = drop
        self.strain = strain
        self.peak = 0.0
        self.below_since = math.inf  # strain at which the stress last fell below the line

    def update(self, strain: float, stress: float) -> bool:
        """Feed one sample (strain [-], stress [Pa]); True once the sample has failed."""
        self.peak = max(self.peak, stress)
        if self.peak > 0 and stress < (1 - self.drop) * self.peak:
            self.below_since = min(self.below_since, strain)
        else:
            self.below_since = math.inf
        return strain - self.below_since >= self.strain


#: Softening that marks failure: the smoothed stress at the end of the unconfined stage this
#: fraction below its peak [-] (docs/PHYSICS.md section 6).
SOFTENING = 0.02


def smoothed(strain: np.ndarray, stress: np.ndarray, window: float) -> np.ndarray:
    """Centred moving average of ``stress`` over a ``window`` of strain [-] (truncated at
    the ends of the curve)."""
    e = np.asarray(strain, dtype=float)
    s = np.asarray(stress, dtype=float)
    c = np.concatenate([[0.0], np.cumsum(s)])
    lo = np.searchsorted(e, e - 0.5 * window)
    hi = np.searchsorted(e, e + 0.5 * window, side="right")
    return (c[hi] - c[lo]) / np.maximum(hi - lo, 1)


def failed_by_curve(
    strain: np.ndarray, stress: np.ndarray, window: float, softening: float = SOFTENING
) -> bool:
    """Whether an unconfined curve shows a peak followed by sustained softening (failure),
    as opposed to hardening to the strain limit. On the stress smoothed over ``window`` of
    strain [-] (the test's ``failure_strain``): the peak lies at least two windows before the
    end of the curve, and the stress at the end is more than ``softening`` [-] below the peak
    (2 %: over five times the smoothed stress's fluctuation in every stored run, whose raw
    samples scatter by 1-3 % of the peak). A curve that recovers to within ``softening`` of
    its peak, or whose maximum comes in the last two windows, hardens."""
    e = np.asarray(strain, dtype=float)
    s = np.asarray(stress, dtype=float)
    if len(e) < 3 or not np.all(np.isfinite(s)):
        return False
    w = max(float(window), 1e-3)
    sm = smoothed(e, s, w)
    k = int(np.argmax(sm))
    peak = float(sm[k])
    return bool(peak > 0 and e[-1] - e[k] >= 2 * w and sm[-1] < (1 - softening) * peak)


def unconfined_strength(
    strain: np.ndarray, stress: np.ndarray, failed: bool
) -> tuple[float, float, bool]:
    """The unconfined strength [Pa], the strain at it [-] and whether the sample failed.

    A sample that failed (its stress fell ``failure_drop`` below the peak and stayed there for
    ``failure_strain``, which ends the stage, or the curve shows a peak followed by sustained
    softening, :func:`failed_by_curve`) has the peak stress as its strength. One that did not
    fail within ``max_unconfined_strain`` (it hardens, or flows plastically) has the
    documented fallback:
    the largest stress reached up to that strain, which for a hardening sample is the stress
    at the strain limit. Either way the value is the maximum of the curve; ``failed`` tells
    which definition it is, and a study compares like with like (see engine.study.metrics).
    """
    stress = np.asarray(stress, dtype=float)
    k = int(np.argmax(stress))
    return max(0.0, float(stress[k])), float(strain[k]), bool(failed)


def slab_volumes(z: np.ndarray, radii: np.ndarray, lo: float, hi: float) -> np.ndarray:
    r"""Volume of each sphere (centre height ``z`` [m], radius [m]) inside the slab
    lo <= z <= hi [m]: the integral of the disc area :math:`\pi (r^2 - u^2)` over the part of
    [-r, r] that lies in the slab, :math:`F(u) = \pi (r^2 u - u^3 / 3)` [m^3]."""
    z = np.asarray(z, dtype=float)
    r = np.asarray(radii, dtype=float)
    a = np.clip(lo - z, -r, r)
    b = np.clip(hi - z, -r, r)

    def f(u):
        return np.pi * (r * r * u - u**3 / 3.0)

    return np.maximum(f(b) - f(a), 0.0)


def interior_margin(margin: float, gap: float, rmax: float) -> float:
    """The platen layer [m] actually left out of a sample ``gap`` [m] tall: ``margin``, or
    less in a sample too short for it, so that one largest diameter (2 ``rmax``) remains."""
    return max(0.0, min(margin, 0.5 * gap - rmax))


def interior_measures(
    z: np.ndarray, radii: np.ndarray, counts: np.ndarray, gap: float, margin: float, area: float
) -> tuple[float, float]:
    """Porosity [-] and coordination number [-] of the interior slab of a sample between
    platens at heights 0 and ``gap`` [m] (``z`` measured from the bottom platen [m]).

    The slab leaves out ``margin`` [m] next to each platen, where a wall orders and loosens
    the packing over a layer that grows with the particle size; it keeps at least one largest
    diameter (the margin shrinks for a sample too short for it). Porosity: 1 - (the exact
    volume of the spheres' parts inside the slab) / (slab volume); coordination: the mean
    contact count (``counts``) of the particles whose centres lie in the slab.
    """
    m = interior_margin(margin, gap, float(np.max(radii)))
    lo, hi = m, gap - m
    solid = float(slab_volumes(z, radii, lo, hi).sum())
    porosity = 1.0 - solid / (area * (hi - lo))
    inside = (z >= lo) & (z <= hi)
    n_in = int(np.count_nonzero(inside))
    coordination = float(counts[inside].sum()) / n_in if n_in else 0.0
    return porosity, coordination


def overburden_ratio(result) -> float:
    """The sample's own weight at the bottom platen over the consolidation stress [-]:
    rho_p (1 - n_c) g H_c / sigma_c, with n_c the porosity and H_c the platen gap at the end
    of consolidation and g the test's gravity (0 with ``gravity_off_after_fill``). The top
    platen reads sigma_c, the base
    sigma_c (1 + this ratio) less wall friction: consolidation is not uniform, and strength
    is read at the top."""
    t = result.test
    if getattr(t, "gravity_off_after_fill", False):
        return 0.0
    cons = result.stages["consolidation"].curves
    h = float(cons["platen_gap"][-1])
    n = float(cons["porosity"][-1])
    return t.density * (1.0 - n) * t.gravity * h / t.consolidation_stress


def lateral_ratio(stress_top: np.ndarray, stress_lateral: np.ndarray) -> float:
    """K0, the lateral stress ratio on confined loading [-]: the mean of lateral / vertical
    stress over the samples of the loading branch whose top platen stress is in the upper
    half of its range (normally consolidated, where the ratio settles), the lateral stress
    from the contact virial (engine.Simulation.pair_stress). NaN without such a sample."""
    top = np.asarray(stress_top, dtype=float)
    lat = np.asarray(stress_lateral, dtype=float)
    hi = top.max() if top.size else 0.0
    sel = (top >= 0.5 * hi) & (top > 0)
    return float(np.mean(lat[sel] / top[sel])) if sel.any() else math.nan


def secant_slope(strain: np.ndarray, stress: np.ndarray, lo: float, hi: float) -> float:
    """Least-squares slope of stress against strain [Pa] over the samples whose stress lies
    between ``lo`` and ``hi`` times the largest stress of the curve."""
    smax = float(np.max(stress))
    sel = (stress >= lo * smax) & (stress <= hi * smax)
    if np.count_nonzero(sel) < 2 or np.ptp(strain[sel]) == 0:
        sel = np.ones(len(stress), dtype=bool)  # too few samples in the window: all of them
    if np.count_nonzero(sel) < 2 or np.ptp(strain[sel]) == 0:
        raise FloatingPointError("the platen did not move during the stage: no stiffness")
    return float(np.polyfit(strain[sel], stress[sel], 1)[0])
