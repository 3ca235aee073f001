r"""What a coarse run is judged by: the bulk quantities a calibration uses, and curve shapes
(docs/PHYSICS.md section 7).

**Verdict metrics** (:data:`METRICS`), each a relative error with a default tolerance fixed
for a stated physical reason before any study was run:

- ``density``: bulk solid fraction of the sample interior at common stress levels on the
  loading and unloading branches;
- ``loading_stiffness`` / ``unloading_stiffness``: the confined (constrained) tangent modulus
  of the loading and unloading branches, d(stress)/d(strain) averaged by least squares over
  the upper half of each branch's stress range [Pa];
- ``coordination``: coordination number of the sample interior at the same stress levels;
- ``strength``: unconfined strength [Pa] (the peak when the sample fails; the largest stress
  up to the strain limit when it does not, see
  :func:`engine.uniaxial.measures.unconfined_strength`).

A metric's *values* are a vector (one entry per stress level) or a single number; the error
of values :math:`x` against reference values :math:`r` is the relative RMS difference

.. math:: e = \sqrt{\langle ((x - r) / r)^2 \rangle}

so a density 2 % above the reference at every level is an error of exactly 0.02. The strength
is divided by max(r, 5 % of the consolidation stress) instead, so that a cohesionless
reference (strength near 0) does not divide by almost nothing.

**Shape measures** (:data:`SHAPE_NAMES`, reported, not used in verdicts): normalised RMS
differences of the strain, whole-sample porosity and coordination number against stress,
divided by the range the reference curve covers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Metric:
    """A verdict metric: ``name``, the ``unit`` of its values, its default ``tolerance``
    (largest accepted relative error) [-] and the physical ``reason`` for that tolerance."""

    name: str
    unit: str
    tolerance: float
    reason: str


METRICS = {
    m.name: m
    for m in (
        Metric(
            "density",
            "1",
            0.03,
            "bulk density sets the mass a hopper or die holds and a calibration matches it "
            "first; laboratory bulk densities of one powder differ by a few per cent "
            "between fill methods, so 3 % is as close as a calibration target is known",
        ),
        Metric(
            "loading_stiffness",
            "Pa",
            0.15,
            "confined compressibility of powders repeats to 10-20 % between samples in "
            "the laboratory; 15 % is the usual calibration tolerance for compressibility",
        ),
        Metric(
            "unloading_stiffness",
            "Pa",
            0.15,
            "the elastic recovery on unloading is measured with the same test and "
            "repeatability as the loading modulus",
        ),
        Metric(
            "coordination",
            "1",
            0.10,
            "the contact count carries cohesion and conduction through the bed; "
            "0.1 relative is about 0.4 contacts per particle in a consolidated bed",
        ),
        Metric(
            "strength",
            "Pa",
            0.15,
            "unconfined and shear-cell strengths of cohesive powders repeat to 10-20 % "
            "between laboratory samples; 15 % is the usual flowability tolerance",
        ),
    )
}

#: The shear test's verdict metrics (engine.ShearTest; docs/PHYSICS.md section 11.1): each
#: quantity gets the tolerance of the uniaxial quantity of its kind, so that one rule is
#: judged by one yardstick on both tests. Fixed before any coarse shear run was made.
SHEAR_METRICS = {
    m.name: m
    for m in (
        Metric(
            "yield_locus",
            "Pa",
            0.15,
            "the shear stress of incipient failure at each of the test's normal stresses "
            "(the fitted locus c + sigma_n tan(phi)) is the strength a silo or hopper design "
            "reads off a shear tester; shear-cell strengths of cohesive powders repeat to "
            "10-20 % between laboratory samples, the reason of the uniaxial strength's 15 %",
        ),
        Metric(
            "sigma_1",
            "Pa",
            0.15,
            "the major consolidation stress places a flow function's point along its axis; "
            "it is read from the same shear-cell measurements as the strengths, with their "
            "repeatability",
        ),
        Metric(
            "sigma_c",
            "Pa",
            0.15,
            "the unconfined yield strength sets the critical outlet width of a hopper "
            "(proportional to it); shear-cell strengths repeat to 10-20 % between laboratory "
            "samples, as the uniaxial strength's",
        ),
        Metric(
            "ffc",
            "1",
            0.15,
            "the flowability sigma_1 / sigma_c is what a user classes a powder by (Jenike's "
            "classes change at ffc 1, 2, 4, 10, factors of 2 to 2.5 apart); 15 % keeps a "
            "powder in its class but within 15 % of a boundary, the strengths' tolerance",
        ),
        Metric(
            "bulk_density",
            "kg/m^3",
            0.03,
            "the bulk density of the pre-sheared bed is what a shear tester reports beside "
            "its locus and a calibration matches first; laboratory bulk densities of one "
            "powder differ by a few per cent between fill methods (the uniaxial density's 3 %)",
        ),
    )
}

#: Default tolerance per shear verdict metric [-].
SHEAR_TOLERANCES = {k: m.tolerance for k, m in SHEAR_METRICS.items()}

#: Column of each shear verdict metric's per-run error in a study table.
SHEAR_METRIC_COLUMNS = {k: f"err_{k}" for k in SHEAR_METRICS}

#: Metrics whose difference is divided by max(reference, STRENGTH_FLOOR x the consolidation
#: stress): strengths, which a cohesionless bed has near 0.
FLOORED = frozenset({"strength", "sigma_c"})

#: Column of each verdict metric's per-run error in a study table.
METRIC_COLUMNS = {
    "density": "err_density",
    "loading_stiffness": "err_loading_stiffness",
    "unloading_stiffness": "err_unloading_stiffness",
    "coordination": "err_coordination_interior",
    "strength": "err_strength",
}

#: Default tolerance per verdict metric [-].
DEFAULT_TOLERANCES = {k: m.tolerance for k, m in METRICS.items()}

#: Shape measures (normalised curve RMS), in table order.
SHAPE_NAMES = ("err_stress_strain", "err_stress_porosity", "err_coordination")

#: Stress levels per branch at which density and coordination are compared.
LEVELS = 16

#: Floor of the strength error's denominator, as a fraction of the consolidation stress.
STRENGTH_FLOOR = 0.05


def metric_names(unconfined: bool) -> tuple[str, ...]:
    """The verdict metrics a study of tests with (or without) the unconfined stage has."""
    return tuple(k for k in METRICS if unconfined or k != "strength")


def _kind(obj):
    from .kinds import kind_of  # the registry of test kinds (engine.study.kinds)

    return kind_of(obj)


def metrics_of(test) -> dict[str, Metric]:
    """The verdict metrics of a study whose reference is ``test``: its kind's
    (:mod:`engine.study.kinds`: :data:`METRICS`, or :data:`SHEAR_METRICS`)."""
    return dict(_kind(test).metrics)


def metric_names_of(test) -> tuple[str, ...]:
    """The verdict metrics a study of ``test`` judges (its kind's: the uniaxial test's with
    or without the unconfined stage, :func:`metric_names`; the shear test's)."""
    return _kind(test).metric_names(test)


def shape_names_of(test) -> tuple[str, ...]:
    """The shape measures of a study of ``test`` (its kind's: :data:`SHAPE_NAMES`, none for
    a shear test)."""
    return _kind(test).shape_names


def metric_column(name: str) -> str:
    """The table column of a verdict metric's per-run error (``err_<name>`` for a kind's
    metric named in neither table: the hopper's, engine/study/kinds.py)."""
    return METRIC_COLUMNS.get(name) or SHEAR_METRIC_COLUMNS.get(name) or f"err_{name}"


def shear_metric_values(result) -> dict[str, np.ndarray]:
    """Values of every shear verdict metric of one :class:`engine.ShearResult`:
    ``yield_locus``, the fitted locus's shear stress c + sigma_n tan(phi) at each of the
    test's normal stresses sigma_n [Pa] (every run of a study is read at the same stresses,
    whatever its servo measured); ``sigma_1``, ``sigma_c`` [Pa]; ``ffc`` as
    sigma_1 / max(sigma_c, STRENGTH_FLOOR x sigma_pre) [-] (the flowability wherever it is
    below sigma_1 / (0.05 sigma_pre), about 30 here, far into "free flowing"; finite for a
    cohesionless bed); ``bulk_density``, the pre-shear's [kg/m^3]."""
    t, s = result.test, result.scalars
    sigma_n = np.asarray(t.normal_stresses, dtype=float)
    slope = math.tan(math.radians(s["friction_angle"]))
    floor = STRENGTH_FLOOR * t.preshear_stress
    return {
        "yield_locus": s["cohesion"] + slope * sigma_n,
        "sigma_1": np.array([s["sigma_1"]]),
        "sigma_c": np.array([s["sigma_c"]]),
        "ffc": np.array([s["sigma_1"] / max(s["sigma_c"], floor)]),
        "bulk_density": np.array([s["bulk_density"]]),
    }


def stress_levels(test) -> tuple[np.ndarray, np.ndarray]:
    """The stress levels [Pa] at which runs are compared: on the loading branch from 10 %
    of the way between the pre-compression and consolidation stresses to 95 % of the latter;
    on the unloading branch from 90 % down to 20 % of the consolidation stress. Fixed by
    the test, so every run of a study is read at the same levels."""
    pre, cons = test.pre_stress, test.consolidation_stress
    loading = np.linspace(pre + 0.1 * (cons - pre), 0.95 * cons, LEVELS)
    unloading = np.linspace(0.9 * cons, 0.2 * cons, LEVELS)
    return loading, unloading


def _monotone(stress: np.ndarray, loading: bool) -> np.ndarray:
    """Indices where the running max (loading) or min (unloading) of the stress is reached
    for the first time: a strictly monotone stress sequence to interpolate along."""
    env = np.maximum.accumulate(stress) if loading else np.minimum.accumulate(stress)
    keep = np.ones(len(stress), dtype=bool)
    keep[1:] = env[1:] != env[:-1]
    return np.flatnonzero(keep)


def branch_on_levels(
    curves: dict, levels: np.ndarray, loading: bool, names=("strain", "porosity", "coordination")
) -> dict[str, np.ndarray]:
    """``names`` of one branch's curves interpolated at the stress ``levels`` [Pa] (held at
    the end values outside the branch's stress range)."""
    stress = np.asarray(curves["stress_top"], dtype=float)
    idx = _monotone(stress, loading)
    s = stress[idx]
    order = np.argsort(s)
    return {
        n: np.interp(levels, s[order], np.asarray(curves[n], dtype=float)[idx][order])
        for n in names
    }


def metric_values(result) -> dict[str, np.ndarray]:
    """Values of every verdict metric of one run's result, as its kind reads them
    (:mod:`engine.study.kinds`: :func:`uniaxial_metric_values`, :func:`shear_metric_values`)."""
    return _kind(result).metric_values(result)


def uniaxial_metric_values(result) -> dict[str, np.ndarray]:
    """Values of every verdict metric of one :class:`engine.UniaxialResult` (see the module
    docstring), plus ``density_whole`` and ``coordination_whole`` (whole-sample values at the
    same levels, reported next to the interior ones) and, with a strength, ``failed`` (1.0
    when the sample failed at a peak, 0.0 when it hardened)."""
    test = result.test
    names = ("porosity_interior", "coordination_interior", "porosity", "coordination")
    parts: dict[str, list] = {n: [] for n in names}
    for stage, levels, loading in (
        ("consolidation", stress_levels(test)[0], True),
        ("unloading", stress_levels(test)[1], False),
    ):
        b = branch_on_levels(result.stages[stage].curves, levels, loading, names)
        for n in names:
            parts[n].append(b[n])
    s = result.scalars
    out = {
        "density": 1.0 - np.concatenate(parts["porosity_interior"]),
        "loading_stiffness": np.array([s["loading_stiffness"]]),
        "unloading_stiffness": np.array([s["unloading_stiffness"]]),
        "coordination": np.concatenate(parts["coordination_interior"]),
        "density_whole": 1.0 - np.concatenate(parts["porosity"]),
        "coordination_whole": np.concatenate(parts["coordination"]),
    }
    if "unconfined_strength" in s:
        out["strength"] = np.array([s["unconfined_strength"]])
        # whether the sample failed at a peak: a strength compares failed runs only
        # (engine.study.noise); a hardening sample's is the largest stress reached
        out["failed"] = float(s.get("unconfined_failure", 1.0))
    return out


def reference_scale(name: str, ref: np.ndarray, consolidation_stress: float) -> np.ndarray:
    """What a metric's difference is divided by: the reference values, or for a strength
    (:data:`FLOORED`) max(reference, 5 % of the consolidation stress)."""
    ref = np.abs(np.asarray(ref, dtype=float))
    if name in FLOORED:
        return np.maximum(ref, STRENGTH_FLOOR * consolidation_stress)
    return np.where(ref > 0, ref, 1.0)


def metric_array(values: list[dict], name: str) -> np.ndarray:
    """Metric ``name`` of runs' metric ``values`` as one array (runs x levels; one empty
    row of one level for no run)."""
    if not values:
        return np.zeros((0, 1))
    return np.array([np.atleast_1d(v[name]) for v in values], dtype=float)


def noise_floor(ref_values: list[dict], names, consolidation_stress: float) -> dict:
    """Per metric, the reference seeds' ``values`` (seeds x levels), mean values, spread
    (per level) and the relative noise floor [-] (RMS over levels of spread / the
    :func:`reference_scale`; ``consolidation_stress`` [Pa]); the floor is None with one
    seed."""
    out = {}
    for n in names:
        a = metric_array(ref_values, n)
        mean = a.mean(axis=0)
        sd = a.std(axis=0, ddof=1) if len(a) > 1 else None
        scale = reference_scale(n, mean, consolidation_stress)
        floor = None if sd is None else float(np.sqrt(np.mean((sd / scale) ** 2)))
        out[n] = {"values": a, "mean": mean, "sd": sd, "noise": floor, "seeds": len(a)}
    return out


def relative_error(name: str, values, ref, consolidation_stress: float) -> float:
    """Relative RMS error of ``values`` against ``ref`` [-] (module docstring)."""
    values = np.asarray(values, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if values.shape != ref.shape or values.size == 0:
        raise ValueError(f"{name}: values and reference differ in shape")
    rel = (values - ref) / reference_scale(name, ref, consolidation_stress)
    return float(np.sqrt(np.mean(rel**2)))


def signed_error(name: str, values, ref, consolidation_stress: float) -> float:
    """Mean relative difference (values - ref) / scale [-]: > 0 over-, < 0 under-predicts."""
    ref = np.asarray(ref, dtype=float)
    rel = (np.asarray(values, dtype=float) - ref) / reference_scale(name, ref, consolidation_stress)
    return float(np.mean(rel))


def nrmse(x: np.ndarray, ref: np.ndarray) -> float:
    """Normalised RMS difference sqrt(mean((x - ref)^2)) / (max ref - min ref) [-]; a flat
    reference is judged against max|ref| instead."""
    x = np.asarray(x, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if x.shape != ref.shape or x.size == 0:
        raise ValueError("nrmse needs two curves of equal, non-zero length")
    scale = float(np.ptp(ref)) or float(np.max(np.abs(ref)))
    if not scale > 0:
        raise ValueError("nrmse needs a reference curve that is not identically zero")
    return float(np.sqrt(np.mean((x - ref) ** 2)) / scale)


def _common_levels(a: np.ndarray, b: np.ndarray, loading: bool, n: int = 40) -> np.ndarray:
    ia, ib = _monotone(a, loading), _monotone(b, loading)
    lo = max(a[ia].min(), b[ib].min())
    hi = min(a[ia].max(), b[ib].max())
    if not hi > lo:
        raise ValueError(
            f"the {'loading' if loading else 'unloading'} branches share no "
            f"stress range ({lo:g} to {hi:g} Pa)"
        )
    return np.linspace(lo, hi, n)


def shape_errors(run, ref) -> dict[str, float]:
    """Shape measures of ``run`` against ``ref``, as their kind has them (none for shear
    tests: their curves are against shear strain, and every run's stress path differs in
    its own steps)."""
    return _kind(run).shape_errors(run, ref)


def uniaxial_shape_errors(run, ref) -> dict[str, float]:
    """Shape measures of ``run`` against ``ref`` (both :class:`engine.UniaxialResult`): the
    normalised RMS of strain, porosity and coordination on the common stress range of each
    branch, divided by the reference curve's range."""
    parts_run: dict[str, list] = {"strain": [], "porosity": [], "coordination": []}
    parts_ref: dict[str, list] = {"strain": [], "porosity": [], "coordination": []}
    for stage, loading in (("consolidation", True), ("unloading", False)):
        c_run, c_ref = run.stages[stage].curves, ref.stages[stage].curves
        levels = _common_levels(
            np.asarray(c_run["stress_top"]), np.asarray(c_ref["stress_top"]), loading
        )
        a = branch_on_levels(c_run, levels, loading)
        b = branch_on_levels(c_ref, levels, loading)
        for n in parts_run:
            parts_run[n].append(a[n])
            parts_ref[n].append(b[n])
    return {
        name: nrmse(np.concatenate(parts_run[c]), np.concatenate(parts_ref[c]))
        for name, c in zip(SHAPE_NAMES, ("strain", "porosity", "coordination"))
    }
