"""Bulk measures of a uniaxial test, from its curves and particles: the interior slab's
porosity, coordination and axial contact-virial stress, secant stiffnesses, failure of the
unconfined sample and its strength, the platen speed that holds a stated inertial number and
the inertial number a run held (docs/PHYSICS.md sections 4, 6 and 7.3). Plain numpy:
recomputable from stored curves."""

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
    strain: np.ndarray,
    stress: np.ndarray,
    window: float,
    softening: float = SOFTENING,
    start: float = 0.0,
) -> bool:
    """Whether an unconfined curve shows a peak followed by sustained softening (failure),
    as opposed to hardening to the strain limit. On the stress smoothed over ``window`` of
    strain [-] (the test's ``failure_strain``): the peak lies at least two windows before the
    end of the curve, and the stress at the end is more than ``softening`` [-] below the peak
    (2 %: over five times the smoothed stress's fluctuation in every stored run, whose raw
    samples scatter by 1-3 % of the peak). A curve that recovers to within ``softening`` of
    its peak, or whose maximum comes in the last two windows, hardens. The peak is sought
    from ``start`` [-] of strain past the curve's first sample (:func:`peak_start`)."""
    e = np.asarray(strain, dtype=float)
    s = np.asarray(stress, dtype=float)
    if len(e) < 3 or not np.all(np.isfinite(s)):
        return False
    w = max(float(window), 1e-3)
    sm = smoothed(e, s, w)
    after = np.nonzero(e >= e[0] + start)[0]
    if after.size == 0:
        return False
    k = int(after[np.argmax(sm[after])])
    peak = float(sm[k])
    return bool(peak > 0 and e[-1] - e[k] >= 2 * w and sm[-1] < (1 - softening) * peak)


def peak_start(test) -> float:
    """Strain [-] past the unconfined stage's start before which no peak of the strength
    curve is sought: one smoothing window (``failure_strain``, at least 1e-3) for the
    interior virial stress, which starts at about the sample's self-weight stress and holds
    the release's last settling there (the smoothed value of that first window is not a
    peak of the sample's strength); 0 for the top platen's stress, which starts near 0."""
    if getattr(test, "strength_from", "platen") == "interior":
        return max(test.failure_strain, 1e-3)
    return 0.0


def curve_failed(test, curves: dict) -> bool:
    """:func:`failed_by_curve` on the curve the test reads its strength from
    (:func:`strength_curve`), the peak sought past :func:`peak_start`."""
    return failed_by_curve(
        curves["strain"], strength_curve(test, curves), test.failure_strain, start=peak_start(test)
    )


#: Thickness of a shear band in particle diameters [-]: localised shear bands in granular
#: samples are about ten grains thick (Muhlhaus and Vardoulakis 1987: 16 d in sand; Oda and
#: Kazama 1998: 7-8 d; DEM of biaxial tests, Iwashita and Oda 1998: about 10 d). Past the
#: unconfined peak the deformation gathers in such a band, whose strain rate is the sample's
#: times h / (band thickness): the platen slows by that ratio so that the band holds the
#: stated inertial number (:func:`loading_speed`).
SHEAR_BAND_DIAMETERS = 10.0

#: Curve samples within one ``failure_strain`` of unconfined strain, at least [-]: the window
#: the strength curve is smoothed over and the failure detector's persistence, each then
#: resolved by ten samples or more (:func:`loading_speed`).
SAMPLES_PER_WINDOW = 10


def stress_floor(test) -> float:
    """The weight of one layer of grains, rho g d [Pa] (``test``'s particle density, gravity
    and mean diameter 2R): the pressure below which grains rearrange at their free-fall time
    over a diameter, sqrt(d / g), whatever the platen stress. The floor of the pressure in
    the inertial number (recorded curve and platen speed alike)."""
    return test.density * test.gravity * 2.0 * test.radius


def loading_speed(
    test,
    gap: float,
    stress: float,
    h0: float,
    unconfined: bool = False,
    post_peak: bool = False,
    inertial_number: float | None = None,
) -> float:
    """The top platen's speed [m/s] that holds ``test.inertial_number`` I* in a loading stage
    (``inertial_number`` instead where given: the stage's,
    :meth:`engine.UniaxialTest.stage_inertial_number`) (docs/PHYSICS.md section 4, "Loading
    rate"):

        v = I* (h / d) sqrt(max(p, rho g d) / rho),   at most ``max_platen_speed``,

    with h the platen ``gap`` [m], d = 2R, rho the particle density and p the sample's mean
    axial ``stress`` [Pa], the mean of the two platens' stresses (the top's plus half the
    sample's weight over its cross-section), floored (:func:`stress_floor`). In the
    unconfined stage (``unconfined``) the platen also moves at most ``failure_strain`` h0 /
    ``SAMPLES_PER_WINDOW`` per curve sample (h0 [m]: the gap at the stage's start), and
    ``post_peak`` (the smoothed strength curve has turned, see the stage driver) it holds I*
    over a shear band instead of the sample: v times min(1, ``SHEAR_BAND_DIAMETERS`` d / h)."""
    d = 2.0 * test.radius
    p = max(float(stress), stress_floor(test))
    i_star = test.inertial_number if inertial_number is None else inertial_number
    v = i_star * gap / d * math.sqrt(p / test.density)
    if post_peak:
        v *= min(1.0, SHEAR_BAND_DIAMETERS * d / gap)
    if unconfined:
        window = max(test.failure_strain, 1e-3)  # as failed_by_curve's smoothing window
        v = min(v, window * h0 / (SAMPLES_PER_WINDOW * test.output_interval))
    return min(v, test.max_platen_speed)


def held_inertial_numbers(curves: dict, test) -> np.ndarray:
    """The inertial number a loading stage held between consecutive curve samples [-]:
    (v / h) d sqrt(rho / max(p, rho g d)) with v the platen's mean speed over the interval
    (from ``platen_gap`` and ``time``), h the gap and p the mean of the two platens'
    stresses at its end, d = 2R: the quantity :func:`loading_speed` holds (empty for a stage
    of one sample)."""
    t = np.asarray(curves["time"], dtype=float)
    gap = np.asarray(curves["platen_gap"], dtype=float)
    mean = 0.5 * (np.asarray(curves["stress_top"]) + np.asarray(curves["stress_bottom"]))
    if len(t) < 2:
        return np.zeros(0)
    dt = np.diff(t)
    ok = dt > 0
    v = np.abs(np.diff(gap))[ok] / dt[ok]
    p = np.maximum(mean[1:][ok], stress_floor(test))
    return v / gap[1:][ok] * 2.0 * test.radius * np.sqrt(test.density / p)


def interior_axial_stress(
    z: np.ndarray,
    radii: np.ndarray,
    pairs: np.ndarray,
    forces: np.ndarray,
    normals: np.ndarray,
    overlaps: np.ndarray,
    gap: float,
    margin: float,
    area: float,
) -> float:
    r"""The axial (zz) contact-virial stress of the particles whose centres lie in the
    interior window [Pa] (compression positive): the Love-Weber sum over those particles of
    their contacts' lever times force,

    .. math:: \sigma_{zz} = \frac{1}{A (h - 2m)} \sum_{i \in W} \sum_{c \in i}
              a_{ic}\, n_z f_z, \qquad a_{ic} = r_i - \delta_c / 2,

    over particle-particle contacts (``pairs`` (M, 2) ids into ``z`` and ``radii``, ``forces``
    on the first particle [N], unit ``normals`` from the second to the first, ``overlaps``
    delta [m]: :class:`engine.Contacts`), W the particles with centre heights ``z`` [m] (from
    the bottom platen) in [m, gap - m], m the interior margin (:func:`interior_margin` of
    ``margin`` [m]) and A the cross-section ``area`` [m^2]. A contact with both particles in
    W counts whole (f l, as :meth:`engine.Simulation.pair_stress`), one with a single
    particle in W by that particle's lever. Quasi-statically it is the mean over the window
    of the axial force through a horizontal section over A: the top platen's stress plus
    the weight above the window's middle (the mean of the two platens' stresses for a
    centred window); no platen contact lies in the window when m is at least a diameter."""
    z = np.asarray(z, dtype=float)
    r = np.asarray(radii, dtype=float)
    m = interior_margin(margin, gap, float(np.max(r)))
    lo, hi = m, gap - m
    inside = ((z >= lo) & (z <= hi)).astype(float)
    if len(pairs) == 0 or hi <= lo:
        return 0.0
    i, j = pairs[:, 0], pairs[:, 1]
    half = 0.5 * np.asarray(overlaps, dtype=float)
    lever = (r[i] - half) * inside[i] + (r[j] - half) * inside[j]
    szz = float(np.sum(lever * normals[:, 2] * forces[:, 2]))
    return szz / (area * (hi - lo))


def strength_scalars(curves: dict, test, detector_fired: bool, self_weight: float) -> dict:
    """The unconfined stage's scalars from its ``curves``: ``unconfined_strength`` [Pa],
    ``strain_at_peak`` [-] and ``unconfined_failure`` (1 or 0) read from the test's
    ``strength_from`` curve, the interior virial stress (the peak of the curve smoothed over
    ``failure_strain``) or the top platen's (its largest value, the seed's estimator), a
    failure being the in-run detector's (``detector_fired``, on that curve) or
    :func:`failed_by_curve`'s on that curve; beside them ``unconfined_strength_platen``,
    ``unconfined_strength_interior`` (where the curve exists), ``self_weight_stress``
    (``self_weight`` [Pa]: the sample's weight over its cross-section, halved) and
    ``strength_from_interior`` (1 where the strength is the interior's)."""
    e = np.asarray(curves["strain"], dtype=float)
    w = test.failure_strain
    platen = np.asarray(curves["stress_top"], dtype=float)
    strength_p, strain_p, _ = unconfined_strength(e, platen, False)
    out = {"unconfined_strength_platen": strength_p, "self_weight_stress": float(self_weight)}
    interior = curves.get("stress_interior")
    if interior is not None:
        start = max(w, 1e-3)  # peak_start of the interior curve
        strength_i, strain_i = smoothed_peak(e, interior, w, start)
        out["unconfined_strength_interior"] = strength_i
    if test.strength_from == "interior" and interior is not None:
        strength, strain = strength_i, strain_i
    else:
        strength, strain = strength_p, strain_p
    failed = detector_fired or curve_failed(test, curves)
    out.update(
        unconfined_strength=strength,
        strain_at_peak=strain,
        unconfined_failure=1.0 if failed else 0.0,
        strength_from_interior=1.0 if strength_curve(test, curves) is interior else 0.0,
    )
    return out


def smoothed_peak(
    strain: np.ndarray, stress: np.ndarray, window: float, start: float = 0.0
) -> tuple[float, float]:
    """The peak of ``stress`` smoothed over ``window`` of strain [-] (as
    :func:`failed_by_curve` smooths it; at least 1e-3) [Pa], not below 0, sought from
    ``start`` [-] past the first sample (the whole curve where it is shorter), and the
    strain at it [-]."""
    e = np.asarray(strain, dtype=float)
    sm = smoothed(e, stress, max(float(window), 1e-3))
    after = np.nonzero(e >= e[0] + start)[0]
    if after.size == 0:
        after = np.arange(len(e))
    k = int(after[np.argmax(sm[after])])
    return max(0.0, float(sm[k])), float(e[k])


def strength_curve(test, curves: dict) -> np.ndarray:
    """The unconfined curve a run's strength and failure are read from [Pa]: the interior
    virial stress where the test reads it (``strength_from``) and the run recorded it, else
    the top platen's stress (runs stored before the interior curve existed)."""
    if getattr(test, "strength_from", "platen") == "interior" and "stress_interior" in curves:
        return curves["stress_interior"]
    return curves["stress_top"]


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


def section_profile(
    positions: np.ndarray,
    radii: np.ndarray,
    pairs: np.ndarray,
    normal_forces: np.ndarray,
    branches: np.ndarray,
    section: tuple[float, float],
    window: tuple[float, float],
    bin_width: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The axial stress across the section of a released column, binned by distance from
    its nearest free face (the skin measure of docs/PHYSICS.md section 7.5).

    Each particle whose centre height lies in ``window`` = (z_lo, z_hi) [m] gets the normal
    part of its Love-Weber axial stress, :math:`s_i = \sum_{c \in i} a_{c} f_{n,c}
    n_{z,c}^2` [N m] with the lever :math:`a_c = |b_c| / 2` (the half branch: the particle's
    radius less half the overlap for equal radii), :math:`f_n` the normal force (> 0
    compressive) and :math:`n = b / |b|`; the tangential forces' part is left out (a
    :class:`engine.simulation.snapshot.Snapshot` keeps normal forces only). Its distance
    from the nearest face of the section ``section`` = (Lx, Ly) [m], the cell the column
    filled before its release, is :math:`\delta = \min(x, L_x - x, y, L_y - y)` (at least
    0: a grain bulged out of the section counts in the first bin). Bins of ``bin_width`` [m]
    run from the face to the centre (the last one ends at min(Lx, Ly) / 2).

    Args: ``positions`` (N, 3) [m], ``radii`` (N,) [m], ``pairs`` (M, 2), ``normal_forces``
    (M,) [N], ``branches`` (M, 3) x_i - x_j [m].

    Returns ``(edges, sums, areas)``: bin edges (K + 1,) [m] from 0, the sum of s_i over the
    bin's particles (K,) [N m] and the bin's area in the section (K,) [m^2]: the ring
    between distances a and b from the faces of an Lx x Ly rectangle, (Lx - 2a)(Ly - 2a)
    - (Lx - 2b)(Ly - 2b). The bin's mean axial stress is ``sums / (areas (z_hi - z_lo))``
    [Pa]; over all bins it is the window's stress, normal part (:func:`skin_thickness`).
    """
    lx, ly = (float(section[0]), float(section[1]))
    half = 0.5 * min(lx, ly)
    nb = max(1, math.ceil(half / bin_width - 1e-9))
    edges = np.minimum(np.arange(nb + 1) * bin_width, half)
    x = np.asarray(positions, dtype=float)
    n = len(x)
    s = np.zeros(n)
    if len(pairs):
        b = np.asarray(branches, dtype=float)
        length = np.sqrt(np.einsum("ij,ij->i", b, b))
        ok = length > 0
        fn = np.asarray(normal_forces, dtype=float)
        share = np.zeros(len(b))
        share[ok] = 0.5 * fn[ok] * b[ok, 2] ** 2 / length[ok]  # a f_n n_z^2, a = |b| / 2
        np.add.at(s, pairs[:, 0], share)
        np.add.at(s, pairs[:, 1], share)
    z = x[:, 2]
    inside = (z >= window[0]) & (z <= window[1])
    delta = np.minimum.reduce([x[:, 0], lx - x[:, 0], x[:, 1], ly - x[:, 1]])
    delta = np.clip(delta, 0.0, half)
    k = np.clip(np.searchsorted(edges, delta, side="right") - 1, 0, nb - 1)
    sums = np.bincount(k[inside], weights=s[inside], minlength=nb).astype(float)
    a, b2 = edges[:-1], edges[1:]
    areas = (lx - 2 * a) * (ly - 2 * a) - (lx - 2 * b2) * (ly - 2 * b2)
    return edges, sums, areas


def skin_thickness(
    edges: np.ndarray, sums: np.ndarray, areas: np.ndarray, core_from: float
) -> tuple[float, float]:
    r"""The load-free skin of a :func:`section_profile`: with :math:`\sigma(\delta)` the
    bins' mean stress and :math:`\sigma_c` the mean over the core (distances from the face
    of at least ``core_from`` [m]), the skin thickness [m]

    .. math:: t = \int_0^{\delta_c} \left(1 - \frac{\sigma(\delta)}{\sigma_c}\right)
              d\delta,

    the depth of a stress-free layer that would carry the same deficit (a face that carries
    no load over t and the core's stress beyond it). Returns ``(t, sigma_c)`` (NaN where no
    bin lies in the core or the core carries no stress). The section's mean stress is then
    :math:`\sigma_c (1 - t P / A)` to first order, P the perimeter and A the area: for a
    square section of side L, :math:`1 - 4 t / L`."""
    edges = np.asarray(edges, dtype=float)
    sums = np.asarray(sums, dtype=float)
    areas = np.asarray(areas, dtype=float)
    core = edges[:-1] >= core_from - 1e-12
    if not core.any() or areas[core].sum() <= 0:
        return math.nan, math.nan
    sigma_c = float(sums[core].sum() / areas[core].sum())
    if not sigma_c > 0:
        return math.nan, math.nan
    skin = ~core
    stress = np.divide(sums, areas, out=np.zeros_like(sums), where=areas > 0)
    width = np.diff(edges)
    t = float(np.sum((1.0 - stress[skin] / sigma_c) * width[skin]))
    return t, sigma_c
