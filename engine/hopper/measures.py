"""The hopper's measures (docs/HOPPER.md), functions of the sampled discharge:

- :func:`steady_rate`: the mass discharge rate in the steady window with its batch-means
  standard error;
- :func:`stop_time`: whether (and when) the flow stopped;
- :func:`flow_index`: the mass-flow index, the grains' downward speed at the wall over that
  on the centre line;
- :func:`wall_normal_forces`: each wall contact's normal force and height, for the wall
  normal stress binned by height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Batches of the steady window whose rates give the rate's standard error [-].
BATCHES = 4
#: Samples each batch needs at least (a slope through fewer is noise) [-].
MIN_BATCH_SAMPLES = 3
#: Mass-flow index at and above which the discharge is called mass flow [-]. The index is
#: the ratio of the mean downward speed of the grains next to the wall to that of the grains
#: on the centre line; Ketterhagen et al. (Powder Technol. 195, 2009, 1-10) classified DEM
#: hopper discharges with such an index and a threshold of 0.3 (quoted from memory: check
#: the paper before relying on the figure). In funnel flow the grains at the wall are
#: stagnant (index about 0); in mass flow everything moves (index of order 1).
MASS_FLOW_INDEX = 0.3


@dataclass(frozen=True)
class SteadyRate:
    """The steady discharge (:func:`steady_rate`).

    Attributes: ``rate`` (the least-squares slope of the discharged mass against time over
    the window) [kg/s]; ``se`` (its batch-means standard error) [kg/s]; ``start``, ``end``
    (the window's first and last sample times) [s]; ``samples`` in the window; ``batches``
    used for ``se``. ``rate`` and ``se`` are NaN where the window was not reached (the flow
    stopped or the run ended before ``end_fraction`` of the mass was discharged) or holds
    fewer than ``BATCHES x MIN_BATCH_SAMPLES`` samples."""

    rate: float
    se: float
    start: float
    end: float
    samples: int
    batches: int


def _slope(t: np.ndarray, m: np.ndarray) -> float:
    tc = t - t.mean()
    return float(np.dot(tc, m - m.mean()) / np.dot(tc, tc))


def steady_rate(
    time: np.ndarray,
    discharged: np.ndarray,
    total: float,
    start_fraction: float,
    end_fraction: float,
    batches: int = BATCHES,
) -> SteadyRate:
    """The mass discharge rate in its steady window.

    The window holds the samples whose discharged mass lies between ``start_fraction`` and
    ``end_fraction`` of the fill's mass ``total`` [kg]. Why: right after the gate opens the
    flow accelerates from rest (over a few free-fall times sqrt(B / g)); near the end the
    free surface reaches the outlet region, the converging flow field is no longer the one
    that carries a steady rate, and the rate falls. In between a hopper's rate does not
    depend on the head (it is set at the outlet: Beverloo et al. 1961), which is what the
    window measures. The rate is the least-squares slope of discharged mass against time
    [kg/s]; its standard error is that of the mean of the slopes of ``batches`` consecutive
    equal batches of the window (batch means): successive samples of a cumulative mass are
    strongly correlated, so the regression's own standard error would understate the
    spread. With four batches the standard error carries 3 degrees of freedom.

    Args: ``time`` [s] and ``discharged`` mass [kg] of the samples (ascending time, mass not
    decreasing), ``total`` [kg], the fractions [-], ``batches`` (>= 2).
    """
    t = np.asarray(time, dtype=float)
    m = np.asarray(discharged, dtype=float)
    if t.shape != m.shape or t.ndim != 1:
        raise ValueError("steady_rate: time and discharged must be 1-D arrays of one length")
    if not (0.0 <= start_fraction < end_fraction <= 1.0) or batches < 2 or total <= 0:
        raise ValueError("steady_rate: fractions 0 <= start < end <= 1, batches >= 2, total > 0")
    nan = SteadyRate(math.nan, math.nan, math.nan, math.nan, 0, 0)
    if not len(m) or m[-1] < end_fraction * total:
        return nan
    inside = (m >= start_fraction * total) & (m <= end_fraction * total)
    idx = np.flatnonzero(inside)
    if len(idx) < batches * MIN_BATCH_SAMPLES:
        return SteadyRate(math.nan, math.nan, float(t[idx[0]]), float(t[idx[-1]]), len(idx), 0)
    tw, mw = t[idx], m[idx]
    rate = _slope(tw, mw)
    parts = np.array_split(np.arange(len(idx)), batches)
    slopes = np.array([_slope(tw[p], mw[p]) for p in parts])
    se = float(slopes.std(ddof=1) / math.sqrt(batches))
    return SteadyRate(rate, se, float(tw[0]), float(tw[-1]), len(idx), batches)


def stop_time(
    time: np.ndarray,
    discharged: np.ndarray,
    wait: float,
    fraction: float,
    particle_mass: float,
    opened: float = 0.0,
) -> float | None:
    """When the flow stopped, or None.

    The flow has stopped at t if the mass discharged over [t, t + ``wait``] is below
    ``fraction`` of what the flow's fastest rate so far would discharge in ``wait`` (and
    below one ``particle_mass`` at least: counts are whole grains). The fastest rate is the
    largest mass discharged in any earlier window of ``wait`` over ``wait`` (zero if nothing
    flowed: then one grain in ``wait`` is flow). Physical reason: a grain released at the
    outlet falls through it in about sqrt(B / g); a flowing outlet passes grains at a
    steady rate. Waiting many free-fall times (``wait`` = arch_wait sqrt(B / g)) with
    next to nothing discharged means the grains above the outlet are held by contacts (an
    arch, or a hopper emptied down to its stagnant zones), not passing intermittently.
    Whether it is an arch is decided by what rests above the outlet (the driver).

    Args: ``time`` [s], ``discharged`` [kg] (cumulative), ``wait`` [s], ``fraction`` [-],
    ``particle_mass`` [kg], ``opened`` (the gate's opening time: no window starts before)
    [s]. Returns the start t of the first such window [s], or None: the flow's last
    grains passed at t or within about ``fraction`` x ``wait`` after it (those a window
    may hold).
    """
    t = np.asarray(time, dtype=float)
    m = np.asarray(discharged, dtype=float)
    fastest = 0.0
    j = 0
    for i in range(len(t)):
        if t[i] < opened:
            continue
        while j < len(t) and t[j] < t[i] + wait:
            j += 1
        if j >= len(t):
            return None  # the window reaches past the last sample
        moved = m[j] - m[i]
        if moved < max(particle_mass, fraction * fastest * wait):
            return float(t[i])
        fastest = max(fastest, moved / (t[j] - t[i]))
    return None


def flow_index(v_wall: np.ndarray, n_wall: np.ndarray, v_centre: np.ndarray, n_centre) -> float:
    """Mass-flow index over a set of samples [-]: the mean downward speed of the grains next
    to the wall over that of the grains on the centre line, each the mean over all grains
    of all samples (``v_*``: per-sample mean downward speeds [m/s], ``n_*``: grains in each
    sample). NaN where no grain was on the centre line or it did not move down."""
    nw, nc = np.asarray(n_wall, float), np.asarray(n_centre, float)
    if nc.sum() == 0 or nw.sum() == 0:
        return math.nan
    vw = float(np.dot(np.nan_to_num(v_wall), nw) / nw.sum())
    vc = float(np.dot(np.nan_to_num(v_centre), nc) / nc.sum())
    if not vc > 0:
        return math.nan
    return vw / vc


def hertz_wall_force(overlap: np.ndarray, radius: np.ndarray, e_star: float) -> np.ndarray:
    """Elastic Hertz normal force of a sphere on a wall [N]: 4/3 E* sqrt(R) d^1.5 (the
    wall's effective radius is the particle's ``radius`` [m]; ``overlap`` d [m]; ``e_star``
    the particle-wall effective modulus [Pa]). The damping force is left out: averaged over
    many samples of a slowly moving fill it is small against the elastic force."""
    d = np.maximum(np.asarray(overlap, dtype=float), 0.0)
    return 4.0 / 3.0 * e_star * np.sqrt(np.asarray(radius, dtype=float)) * d**1.5


def binned_stress(heights: np.ndarray, forces: np.ndarray, edges, areas) -> np.ndarray:
    """Normal stress [Pa] per height bin: the sum of the contact normal ``forces`` [N] whose
    contact points lie at ``heights`` [m] within each bin of ``edges`` [m], over the bin's
    wall area ``areas`` [m^2]."""
    edges = np.asarray(edges, dtype=float)
    k = np.searchsorted(edges, heights, side="right") - 1
    ok = (k >= 0) & (k < len(edges) - 1)
    s = np.bincount(k[ok], weights=np.asarray(forces)[ok], minlength=len(edges) - 1)
    return s / np.asarray(areas, dtype=float)


def arch_profile(
    across: np.ndarray, bottoms: np.ndarray, half_width: float, d: float
) -> tuple[float, float]:
    """The arch over an outlet of half-width ``half_width`` [m] from the grains that rest
    above it: ``across`` their centres' distances from the mid-plane (slot) or the axis
    (cone) [m], ``bottoms`` their lowest points, centre height minus radius, above the
    outlet plane [m]. The outlet's half-width is cut into bins one largest diameter ``d``
    [m] wide (at least one); in each, the arch's underside is its lowest grain's bottom.
    Returns (the apex, the highest underside [m]; the feet, the lowest underside [m]), both
    above the outlet plane; NaN where a bin holds no grain (no arch spans the outlet).
    Why this: an arch is the lowest layer of grains that carries the fill over the
    opening; its underside is free, so it is what the lowest grain of each column over the
    outlet shows, highest at the crown and lowest where it rests on the walls."""
    n = max(1, int(half_width // d))
    k = np.minimum((np.asarray(across) / half_width * n).astype(np.int64), n)
    low = np.full(n, np.inf)
    inner = k < n
    np.minimum.at(low, k[inner], np.asarray(bottoms)[inner])
    if not np.all(np.isfinite(low)):
        return math.nan, math.nan
    return float(low.max()), float(low.min())
