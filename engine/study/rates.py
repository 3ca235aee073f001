"""The error-rate policy of a study's verdicts (docs/PHYSICS.md sections 7.1 and 7.2): how
much of alpha = 1 - confidence each test, each metric and each look may spend. The numbers
here are spent by :mod:`engine.study.comparison` (one comparison) and
:mod:`engine.study.judge` (a group's verdict); nothing here looks at data."""

from __future__ import annotations

#: Default confidence of a verdict: 1 - the largest rate of a wrong ``equivalent`` or of a
#: wrong ``differs`` [-].
CONFIDENCE = 0.95

VERDICTS = ("equivalent", "differs", "undecided")

#: Share of the ``differs`` error rate an adaptive study spends at its pilot look (the
#: planned runs); the later looks share the rest equally (docs/PHYSICS.md section 7.2).
PILOT_SHARE = 0.2

#: The nominal one-sided rate of each end of an equivalence interval, as a fraction of
#: alpha = 1 - confidence: one half, so that ``equivalent`` means the two-sided
#: 1 - alpha interval lies inside the tolerance. The plain form (alpha per end) covers less
#: than it states for skewed values with three reference seeds against many coarse ones
#: (simulated, alpha = 5 %: up to 7.3 % wrong ``equivalent`` for normal values, 8.5 % with
#: one seed in ten from a second mode 30 % away), for an adaptive second stage sized from a
#: pilot (7.8 %), and with pooled spreads where one variant's spread is twice the others'
#: (9 to 11 %): docs/PHYSICS.md section 7.1, tests/engine/test_coverage.py.
EQUIVALENCE_LEVEL = 0.5


def look_alpha(confidence: float, look: int = 1, looks: int = 1) -> float:
    """The ``differs`` error rate spent at look ``look`` of ``looks``: all of
    alpha = 1 - confidence when judged once; else :data:`PILOT_SHARE` of it at the pilot and
    the rest split equally over the later looks (Bonferroni over the looks)."""
    if not 0.5 < confidence < 1.0:
        raise ValueError(f"confidence {confidence} outside (0.5, 1)")
    if not 1 <= look <= looks:
        raise ValueError(f"look {look} outside 1 to {looks}")
    alpha = 1.0 - confidence
    if looks == 1:
        return alpha
    if look == 1:
        return PILOT_SHARE * alpha
    return (1.0 - PILOT_SHARE) * alpha / (looks - 1)


def error_rates(
    confidence: float, metrics_judged: int, look: int = 1, looks: int = 1
) -> tuple[float, float]:
    """Nominal one-sided rates per end of one metric's two tests: equivalence
    :data:`EQUIVALENCE_LEVEL` x alpha (claimed at the final look only; an intersection-union
    test needs no split), differs :func:`look_alpha` / (2 metrics)."""
    a = look_alpha(confidence, look, looks)
    return EQUIVALENCE_LEVEL * (1.0 - confidence), a / (2 * max(metrics_judged, 1))


__all__ = [
    "CONFIDENCE",
    "EQUIVALENCE_LEVEL",
    "PILOT_SHARE",
    "VERDICTS",
    "error_rates",
    "look_alpha",
]
