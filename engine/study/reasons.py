"""A verdict in words: each metric's error, interval, rate, spread and bias, what would
decide an undecided one, and the overall verdict with its reason (docs/PHYSICS.md section
7.1): a group's verdict record (:func:`judged`) from the per-metric dicts
:func:`engine.study.comparison.judge_metric` makes. Pure functions of those dicts."""

from __future__ import annotations

import math

#: Most seeds a "would need" estimate looks for (beyond it: "more than" this).
MAX_SEEDS_NEEDED = 100
#: Largest relative error a report prints as a number (+-1000 %): an interval end beyond
#: it says only that the spread has too few degrees of freedom (a two-seed study's 1-dof t
#: interval reaches +1e27 %), so such an interval is printed as :data:`UNBOUNDED_WORDS`.
UNBOUNDED = 10.0
#: How a report prints an interval with an end beyond +-1000 % or none at all.
UNBOUNDED_WORDS = "unbounded (too few seeds)"


def _pct(x: float) -> str:
    """A relative error in per cent with the figures a person reads: one decimal below
    100 %, whole per cent up to 1000 %, and beyond +-1000 % (no finite number there tells
    anything: the far end of a one-degree-of-freedom interval) "above +1000 %"."""
    if x is None or not math.isfinite(x):
        return "undefined"
    p = 100 * x
    if abs(p) > 100 * UNBOUNDED:
        return f"{'above +' if p > 0 else 'below -'}{100 * UNBOUNDED:.0f} %"
    return f"{p:+.1f} %" if abs(p) < 99.95 else f"{p:+.0f} %"


def pct(x: float | None) -> str:
    """:func:`_pct` for other modules: a relative error [-] in per cent, readable."""
    return _pct(x)


def bounded(interval) -> bool:
    """Whether ``interval`` (low, high) [-] has two finite ends within +-:data:`UNBOUNDED`."""
    if not interval:
        return False
    return all(x is not None and math.isfinite(x) and abs(x) <= UNBOUNDED for x in interval)


def interval_words(interval) -> str:
    """ "[-13.2 %, -1.1 %]", or :data:`UNBOUNDED_WORDS` for an interval with an end beyond
    +-1000 % or none."""
    if not bounded(interval):
        return UNBOUNDED_WORDS
    lo, hi = interval
    return f"[{_pct(lo)}, {_pct(hi)}]"


def bias_words(m: dict) -> str | None:
    """ "biased low by 27.0 [18.2, 34.9] %" where the metric's interval excludes zero."""
    b = m.get("bias")
    if not b or b["direction"] is None:
        return None
    lo, hi = b["interval"]
    if b["direction"] == "low":
        size, a, z = -b["error"], -hi, -lo
    else:
        size, a, z = b["error"], lo, hi
    what = "" if m["level"] is None else " (mean over levels)"
    if not bounded((a, z)):  # excludes zero, but its far end is beyond any use
        return (
            f"{m['metric']} biased {b['direction']} by {100 * size:.1f} %{what} (its "
            f"{b['confidence']:.0%} interval's far end {UNBOUNDED_WORDS})"
        )
    return (
        f"{m['metric']} biased {b['direction']} by {100 * size:.1f} "
        f"[{100 * a:.1f}, {100 * z:.1f}] %{what} ({b['confidence']:.0%} interval)"
    )


def describe(m: dict) -> str:
    """One metric's verdict in words: its error, interval, rate, spread and what would
    decide it."""
    tol = f"± {m['tolerance']:.0%}"
    left = ""
    if m.get("left_out"):
        left = f" ({m['left_out']} hardening runs left out)"
    if m["interval"] is None:
        err = "" if m.get("signed_error") is None else f" {_pct(m['signed_error'])}"
        why = "no failed run" if m["seeds"] == 0 or m["reference_seeds"] == 0 else "spread unknown"
        return f"{m['metric']}{err} ({why}{left}) against {tol}"
    conf = 1 - m["alpha_equivalent"]
    spread = f", {m['screen']}" if m.get("screen") else ""
    if m["verdict"] == "differs":
        what = "summed over levels " if m["level"] is not None else ""
        how = f"{1 - m['alpha_differs']:.1%} one-sided{spread}"
        return (
            f"{m['metric']} {what}{_pct(m['differs_error'])}"
            f"{_within(m['differs_interval'], how)} against {tol}{left}"
        )
    at = "" if m["level"] is None else f" at its worst level {m['level'] + 1}"
    how = f"{conf:.1%} one-sided per end, {_dof(m['df'])}{spread}"
    text = f"{m['metric']} {_pct(m['level_error'])}{at}{_within(m['interval'], how)}"
    text += f" against {tol}{left}"
    if m["verdict"] == "undecided":
        b = bias_words(m)
        if b:
            text += f"; {b}"
    need = m.get("needs")
    if need is not None:
        if need["coarse"] is not None:
            text += f"; about {need['coarse']} more coarse seeds would decide it"
        elif need["coarse_and_reference"] is not None:
            text += (
                f"; about {need['coarse_and_reference']} more coarse and "
                f"{m.get('against', 'reference')} seeds each would decide it"
            )
        else:
            text += f"; more than {MAX_SEEDS_NEEDED} more seeds would be needed"
    return text


def shown(m: dict) -> tuple[float | None, list | None, str]:
    """What a table shows of one metric's judgement, as :func:`describe` says it: (its
    error [-], its interval [-] or None, how the interval was made). A metric that
    differs: its error summed over levels and the one-sided interval that shows it; one
    without an interval: its signed error and why there is none."""
    if m.get("interval") is None:
        why = "no failed run" if m["seeds"] == 0 or m["reference_seeds"] == 0 else "spread unknown"
        return m.get("signed_error"), None, why
    if m["verdict"] == "differs":
        return m["differs_error"], m["differs_interval"], f"{1 - m['alpha_differs']:.1%} one-sided"
    at = "" if m["level"] is None else f", at its worst level {m['level'] + 1}"
    how = f"{1 - m['alpha_equivalent']:.1%} one-sided per end, {_dof(m['df'])}{at}"
    return m["level_error"], m["interval"], how


def _dof(df) -> str:
    """The degrees of freedom in words: infinite where both spreads are zero (stored as
    null in strict JSON, read back as None)."""
    if df is None or not math.isfinite(df):
        return "infinite dof (no spread)"
    return f"{df:.1f} dof"


def _within(interval, how: str) -> str:
    """ " in [a, b] (how)", or for an interval too wide to print ", interval unbounded
    (too few seeds: how)"."""
    if bounded(interval):
        return f" in {interval_words(interval)} ({how})"
    return f", interval {UNBOUNDED_WORDS.removesuffix(')')}: {how})"


def what_decides(metrics: list[dict]) -> str | None:
    """One line on what would decide an undecided (radius, rule), from its metrics'
    ``needs`` (as if their means and spreads stayed as observed); None when decided."""
    if any(m["verdict"] == "differs" for m in metrics):
        return None
    open_ = [m for m in metrics if m["verdict"] == "undecided"]
    if not open_:
        return None
    if any(m["interval"] is None for m in open_):
        return "two or more seeds on each side (three give the intervals more degrees of freedom)"
    other = open_[0].get("against", "reference")

    def cost(n: dict) -> tuple[int, str] | None:
        if n.get("coarse") is not None:
            return n["coarse"], "coarse"
        if n.get("coarse_and_reference") is not None:
            return n["coarse_and_reference"], f"coarse and {other}"
        return None

    def words(k: int, kind: str) -> str:
        return f"about {k} more {kind} seeds" + (" each" if kind != "coarse" else "")

    needs = {m["metric"]: m.get("needs") or {} for m in open_}
    to_differ = [
        (cost(n), name) for name, n in needs.items() if n.get("verdict") == "differs" and cost(n)
    ]
    if to_differ:
        (k, kind), name = min(to_differ, key=lambda x: (x[0][1] != "coarse", x[0][0]))
        return (
            f"{words(k, kind)} would show it differs in {name}, if the means and spreads "
            "stayed as observed"
        )
    costs = {name: cost(n) for name, n in needs.items()}
    hopeless = [name for name, c in costs.items() if c is None]
    if hopeless:
        return (
            f"no seed count within {MAX_SEEDS_NEEDED} more: {', '.join(hopeless)} sits at "
            "its tolerance (as observed); a looser tolerance, or a finer radius"
        )
    kind = "coarse" if all(c[1] == "coarse" for c in costs.values()) else f"coarse and {other}"
    k = max(c[0] for c in costs.values())
    return f"{words(k, kind)} would decide it, if the means and spreads stayed as observed"


def verdict(metrics: list[dict]) -> tuple[str, str]:
    """Overall verdict and its reason from the per-metric judgements."""
    if metrics and all(m["interval"] is None for m in metrics):
        if metrics[0]["reference_seeds"] < 2:
            return "undecided", (
                "one reference seed: the reference's own spread is unknown, so no error "
                "can be told apart from noise; run two or more reference seeds"
            )
        return "undecided", (
            "one seed of this variant and no pooled spread at its radius: its spread is "
            "unknown, so no interval holds; run two or more seeds: "
            + "; ".join(describe(m) for m in metrics)
        )
    differs = [m for m in metrics if m["verdict"] == "differs"]
    undecided = [m for m in metrics if m["verdict"] == "undecided"]
    if differs:
        reason = "differs beyond noise in " + "; ".join(describe(m) for m in differs)
        biased = [b for m in undecided if (b := bias_words(m))]
        if biased:
            reason += "; also " + "; ".join(biased)
        return "differs", reason
    if undecided:
        ok = [m["metric"] for m in metrics if m["verdict"] == "equivalent"]
        reason = "noise too large to tell for " + "; ".join(describe(m) for m in undecided)
        if ok:
            reason += "; within tolerance: " + ", ".join(ok)
        return "undecided", reason
    return "equivalent", "within tolerance beyond noise: " + "; ".join(describe(m) for m in metrics)


def judged(radius: float, rule: str, per_metric: list[dict], seeds: int) -> dict:
    """The verdict of group (``radius`` [m], ``rule``) from its metrics' judgements
    (``per_metric``, each as :func:`engine.study.comparison.judge_metric` makes it;
    ``seeds``: its seeds): the overall verdict and its reason (:func:`verdict`), what would
    decide it where undecided (:func:`what_decides`), its biased metrics and the metrics."""
    v, reason = verdict(per_metric)
    biased = [
        {
            "metric": m["metric"],
            "direction": m["bias"]["direction"],
            "error": m["bias"]["error"],
            "interval": m["bias"]["interval"],
        }
        for m in per_metric
        if m.get("bias") and m["bias"]["direction"] is not None
    ]
    return {
        "radius": radius,
        "rule": rule,
        "verdict": v,
        "reason": reason,
        "to_decide": what_decides(per_metric) if v == "undecided" else None,
        "seeds": seeds,
        "biased": biased,
        "metrics": per_metric,
    }


__all__ = [
    "MAX_SEEDS_NEEDED",
    "UNBOUNDED",
    "UNBOUNDED_WORDS",
    "bias_words",
    "bounded",
    "describe",
    "interval_words",
    "judged",
    "pct",
    "shown",
    "verdict",
    "what_decides",
]
