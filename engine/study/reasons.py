"""A verdict in words: each metric's error, interval, rate, spread and bias, what would
decide an undecided one, and the overall verdict with its reason (docs/PHYSICS.md section
7.1). Pure functions of the per-metric dicts :func:`engine.study.judge.judge_metric`
makes."""

from __future__ import annotations

#: Most seeds a "would need" estimate looks for (beyond it: "more than" this).
MAX_SEEDS_NEEDED = 100


def _pct(x: float) -> str:
    """A relative error in per cent, one decimal; in powers of ten beyond +-10,000 % (the far
    end of a one-degree-of-freedom interval) so that no end runs to thirty digits."""
    p = 100 * x
    return f"{p:+.1f} %" if abs(p) < 1e4 else f"{p:+.2g} %"


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
        lo, hi = m["differs_interval"]
        what = "summed over levels " if m["level"] is not None else ""
        return (
            f"{m['metric']} {what}{_pct(m['differs_error'])} in [{_pct(lo)}, {_pct(hi)}] "
            f"({1 - m['alpha_differs']:.1%} one-sided{spread}) against {tol}{left}"
        )
    lo, hi = m["interval"]
    at = "" if m["level"] is None else f" at its worst level {m['level'] + 1}"
    text = (
        f"{m['metric']} {_pct(m['level_error'])}{at} in [{_pct(lo)}, {_pct(hi)}] "
        f"({conf:.1%} one-sided per end, {m['df']:.1f} dof{spread}) against {tol}{left}"
    )
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


__all__ = ["MAX_SEEDS_NEEDED", "bias_words", "describe", "verdict", "what_decides"]
