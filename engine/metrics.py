"""Errors of a coarse run against its reference (PHYSICS.md section 5).

The confined curves are compared on a common axis, the top-platen stress: along the loading
branch (consolidation stage) and the unloading branch, the strain, porosity and coordination
number each run has at the same stress levels. Each error is a normalised RMS difference

.. math:: e = \\sqrt{\\langle (x_c - x_r)^2 \\rangle} / (\\max x_r - \\min x_r)

over those levels (dimensionless; 0.1 means "off by 10 % of the reference's range": a porosity
that moves from 0.50 to 0.45 under load is judged against that 0.05, not against 0.5). The
unconfined strength error is
:math:`|\\sigma_c - \\sigma_r| / \\max(\\sigma_r, 0.05\\,\\sigma_{cons})`: relative to the reference
strength, or to 5 % of the consolidation stress when the reference is
(near) cohesionless and a relative error would divide by almost nothing.
"""

from __future__ import annotations

import numpy as np

#: Error names, in table order.
ERROR_NAMES = ("err_stress_strain", "err_stress_porosity", "err_coordination", "err_strength")

#: Stress levels per branch on which the curves are compared.
LEVELS = 40

#: Floor of the strength error's denominator, as a fraction of the consolidation stress.
STRENGTH_FLOOR = 0.05


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


def _monotone(stress: np.ndarray, loading: bool) -> np.ndarray:
    """Indices where the running max (loading) or min (unloading) of the stress is reached
    for the first time: a strictly monotone stress sequence to interpolate along."""
    env = np.maximum.accumulate(stress) if loading else np.minimum.accumulate(stress)
    keep = np.ones(len(stress), dtype=bool)
    keep[1:] = env[1:] != env[:-1]
    return np.flatnonzero(keep)


def branch_on_levels(curves: dict, levels: np.ndarray, loading: bool,
                     names=("strain", "porosity", "coordination")) -> dict[str, np.ndarray]:
    """``names`` of one branch's curves interpolated at the stress ``levels`` [Pa]."""
    stress = np.asarray(curves["stress_top"], dtype=float)
    idx = _monotone(stress, loading)
    s = stress[idx]
    order = np.argsort(s)
    return {n: np.interp(levels, s[order], np.asarray(curves[n], dtype=float)[idx][order])
            for n in names}


def _common_levels(a: np.ndarray, b: np.ndarray, loading: bool) -> np.ndarray:
    ia, ib = _monotone(a, loading), _monotone(b, loading)
    lo = max(a[ia].min(), b[ib].min())
    hi = min(a[ia].max(), b[ib].max())
    if not hi > lo:
        raise ValueError(f"the {'loading' if loading else 'unloading'} branches share no "
                         f"stress range ({lo:g} to {hi:g} Pa)")
    return np.linspace(lo, hi, LEVELS)


def run_errors(run, ref) -> dict[str, float]:
    """Errors of ``run`` against ``ref`` (both :class:`engine.uniaxial.UniaxialResult`)."""
    out = {}
    parts_run: dict[str, list] = {"strain": [], "porosity": [], "coordination": []}
    parts_ref: dict[str, list] = {"strain": [], "porosity": [], "coordination": []}
    for stage, loading in (("consolidation", True), ("unloading", False)):
        c_run, c_ref = run.stages[stage].curves, ref.stages[stage].curves
        levels = _common_levels(np.asarray(c_run["stress_top"]), np.asarray(c_ref["stress_top"]),
                                loading)
        a = branch_on_levels(c_run, levels, loading)
        b = branch_on_levels(c_ref, levels, loading)
        for n in parts_run:
            parts_run[n].append(a[n])
            parts_ref[n].append(b[n])
    for name, curve in (("err_stress_strain", "strain"), ("err_stress_porosity", "porosity"),
                        ("err_coordination", "coordination")):
        out[name] = nrmse(np.concatenate(parts_run[curve]), np.concatenate(parts_ref[curve]))
    if "unconfined_strength" in run.scalars and "unconfined_strength" in ref.scalars:
        out["err_strength"] = strength_error(run.scalars["unconfined_strength"],
                                             ref.scalars["unconfined_strength"],
                                             ref.test.consolidation_stress)
    return out


def strength_error(strength: float, reference: float, consolidation_stress: float) -> float:
    """|strength - reference| / max(reference, 5 % of the consolidation stress) [-]."""
    return abs(strength - reference) / max(reference, STRENGTH_FLOOR * consolidation_stress)
