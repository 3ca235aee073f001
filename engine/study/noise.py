"""A study's groups of runs on the scale their verdicts compare, with their pooled spreads
(docs/PHYSICS.md section 7.1): the step between measuring (engine.study.metrics) and
judging (engine.study.judge).

Per metric the values of every run are mapped to the compared scale, per radius: the
logarithms where every value at that radius and every reference value is positive and the
metric is not a strength weaker than 5 % of the consolidation stress; else the values over
a constant scale (that floor, or the reference mean). The groups at each radius (the rules'
variants and the resolution controls) are then pooled (engine.study.pooling); the
references keep their own spread. A strength compares only the runs that failed at a peak
(engine.uniaxial.measures.failed_by_curve) where any run of the study failed: a hardening
sample's "strength" is the largest stress up to the strain limit, another quantity; the
counts of each kind are kept for the reasons.
"""

from __future__ import annotations

import numpy as np

from .comparison import Space
from .metrics import FLOORED, STRENGTH_FLOOR, metric_array, noise_floor, reference_scale
from .pooling import SCREEN_LEVEL, Spread, group_spreads, own_spread

#: The key of the references among a study's groups.
REFERENCE = "reference"


def _failed(values: dict) -> bool:
    return float(values.get("failed", 1.0)) == 1.0


def choose_space(name: str, arrays: list[np.ndarray], ref_mean: np.ndarray, cons: float) -> Space:
    """The :class:`Space` of metric ``name`` for the ``arrays`` compared (the references
    and every group at one radius)."""
    ref_mean = np.asarray(ref_mean, dtype=float)
    if name in FLOORED and ref_mean.size == 1:
        if abs(float(ref_mean[0])) < STRENGTH_FLOOR * cons:
            return Space("difference", STRENGTH_FLOOR * cons)
    if all(np.all(a > 0) for a in arrays if a.size):
        return Space("log")
    return Space("difference", reference_scale(name, ref_mean, cons))


class StudyNoise:
    """Every group of a study on its compared scale, with its spread, per metric.

    Args:
        ref_values: metric values per reference seed (engine.study.metrics.metric_values).
        groups: group key -> metric values per seed; a key is (radius [m], rule name or
            ``"control"``): the groups of one radius are pooled.
        names: the verdict metrics.
        consolidation_stress: [Pa] (the strength floor).
        level: the pooling screen's rate (None: pool without a screen; ``pool=False``:
            every group keeps its own spread, as before issue 39).
    """

    def __init__(
        self,
        ref_values: list[dict],
        groups: dict,
        names,
        consolidation_stress: float,
        level: float | None = SCREEN_LEVEL,
        pool: bool = True,
    ):
        self.names = tuple(names)
        self.cons = consolidation_stress
        self.pool = pool
        radii = sorted({k[0] for k in groups})
        strength_failures = any(_failed(v) for v in ref_values) or any(
            _failed(v) for vals in groups.values() for v in vals
        )
        self.kept: dict = {}  # (name, key) -> (kept values, left-out count)
        self.space: dict = {}  # (name, radius) -> Space
        self.values: dict = {}  # (name, key) -> compared values (seeds x levels)
        self.spread: dict = {}  # (name, key) -> Spread
        self.raw: dict = {}  # (name, key) -> raw values kept (seeds x levels)
        for name in self.names:
            only_failed = name == "strength" and strength_failures
            refs = [v for v in ref_values if not only_failed or _failed(v)]
            self.kept[name, REFERENCE] = (len(refs), len(ref_values) - len(refs))
            r = metric_array(refs, name)
            self.raw[name, REFERENCE] = r
            ref_mean = r.mean(axis=0) if len(r) else np.ones(1)
            for radius in radii:
                keys = [k for k in groups if k[0] == radius]
                kept = {}
                for k in keys:
                    vals = [v for v in groups[k] if not only_failed or _failed(v)]
                    self.kept[name, k] = (len(vals), len(groups[k]) - len(vals))
                    kept[k] = metric_array(vals, name)
                    self.raw[name, k] = kept[k]
                sp = choose_space(name, [r, *kept.values()], ref_mean, consolidation_stress)
                self.space[name, radius] = sp
                mapped = {k: sp.map(a) for k, a in kept.items() if len(a)}
                self.values[name, (radius, REFERENCE)] = sp.map(r) if len(r) else r
                self.spread[name, (radius, REFERENCE)] = own_spread(
                    self.values[name, (radius, REFERENCE)]
                )
                for k, a in kept.items():
                    self.values[name, k] = mapped.get(k, a)
                if mapped:
                    if pool:
                        spreads = group_spreads(mapped, level)
                    else:
                        spreads = {k: own_spread(a, k) for k, a in mapped.items()}
                    for k in keys:
                        self.spread[name, k] = spreads.get(k, _no_spread(k))
                else:
                    for k in keys:
                        self.spread[name, k] = _no_spread(k)

    def reference(self, name: str, radius: float) -> tuple[np.ndarray, Spread]:
        """The references' compared values and spread in the space of ``radius``."""
        return self.values[name, (radius, REFERENCE)], self.spread[name, (radius, REFERENCE)]

    def group(self, name: str, key) -> tuple[np.ndarray, Spread]:
        return self.values[name, key], self.spread[name, key]


def _no_spread(key) -> Spread:
    return Spread(np.zeros(1), 0.0, 0.0, False, (key,))


# noise_floor: the references' relative spread, beside the reference scale it is taken on
# (engine.study.metrics), importable from here as before
__all__ = ["REFERENCE", "Space", "StudyNoise", "choose_space", "noise_floor"]
