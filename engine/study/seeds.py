"""How many seeds a comparison needs, and how its seeds are matched (docs/PHYSICS.md
sections 7.2 and 7.4): the seeds an undecided metric would need if its means and spreads
stayed as observed (:func:`seeds_needed`, the reasons' "needs"), the power added seeds are
sized for (:data:`PLANNED_POWER`, engine.study.allocate), and whether a rule's own error is
judged paired by seed (:func:`pairing_pays`). Counts and fixed numbers in, counts out."""

from __future__ import annotations

import math

from .intervals import interval_df, t_quantile
from .reasons import MAX_SEEDS_NEEDED

#: Power a variant's added seeds are sized for where the chance of deciding it is judged at
#: a true error of 0 (engine.study.allocate) [-].
PLANNED_POWER = 0.8
#: Variance of the per-seed difference of a coarse run and its resolution control, relative
#: to the sum of their variances, per metric (``python -m benchmarks.pairing``, 2026-12-03):
#: density and coordination keep the cloud's imprint, the stiffnesses and the strength
#: forget it. Fixed, so that whether a metric is paired depends on counts only.
PAIRING_VARIANCE_RATIO = {
    "density": 0.37,
    "loading_stiffness": 1.12,
    "unloading_stiffness": 1.06,
    "coordination": 0.51,
    "strength": 1.05,
}


def pairing_pays(
    name: str, pairs: int, nc: int, nr: int, alpha: float, df_unpaired: float | None = None
) -> bool:
    """Whether the rule's own error of metric ``name`` is judged paired by seed (the t
    interval of the ``pairs`` per-seed differences, pairs - 1 degrees of freedom) rather
    than unpaired (all ``nc`` coarse and ``nr`` control seeds with ``df_unpaired`` degrees
    of freedom, their pooled ones; default the own-spread bound): paired when its expected
    half-width at one-sided rate ``alpha``, with equal spreads and the measured
    :data:`PAIRING_VARIANCE_RATIO`, is the smaller. Depends on counts and fixed numbers
    alone, so either interval keeps its own coverage."""
    ratio = PAIRING_VARIANCE_RATIO.get(name, 1.0)
    if pairs < 2 or ratio >= 1.0:
        return False
    if df_unpaired is None:
        df_unpaired = float(interval_df(nc, nr, 1.0 / nc, 1.0 / nr))
    unpaired = t_quantile(1.0 - alpha, df_unpaired) * math.sqrt(1.0 / nc + 1.0 / nr)
    paired = t_quantile(1.0 - alpha, pairs - 1) * math.sqrt(2.0 * ratio / pairs)
    return paired < unpaired


def seeds_needed(comp, alpha_e: float, alpha_d: float) -> dict:
    """How many more seeds would decide an undecided metric if its means and spreads stayed
    as observed (``comp``: an :class:`engine.study.comparison.Comparison`): ``coarse`` (more
    of this group), or ``coarse_and_reference`` (the same number more of each side; paired:
    more pairs), each None beyond
    :data:`MAX_SEEDS_NEEDED`; ``verdict``: the one those seeds would give."""
    n0, m0 = comp.nc, comp.nr

    def first(pred):
        lo, hi = 1, MAX_SEEDS_NEEDED
        if not pred(hi):
            return None
        while lo < hi:
            mid = (lo + hi) // 2
            if pred(mid):
                hi = mid
            else:
                lo = mid + 1
        return lo

    def decides(n, m):
        return comp.projected(n, m, alpha_e, alpha_d) is not None

    coarse = None if comp.paired else first(lambda k: decides(n0 + k, m0))
    both = None if coarse is not None else first(lambda k: decides(n0 + k, m0 + k))
    verdict = None
    if coarse is not None:
        verdict = comp.projected(n0 + coarse, m0, alpha_e, alpha_d)
    elif both is not None:
        verdict = comp.projected(n0 + both, m0 + both, alpha_e, alpha_d)
    return {"coarse": coarse, "coarse_and_reference": both, "verdict": verdict}


__all__ = [
    "MAX_SEEDS_NEEDED",
    "PAIRING_VARIANCE_RATIO",
    "PLANNED_POWER",
    "pairing_pays",
    "seeds_needed",
]
