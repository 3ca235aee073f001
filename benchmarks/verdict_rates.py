"""The verdict rule's simulated rates and power (docs/PHYSICS.md section 7.1, the table).

    python -m benchmarks.verdict_rates [--n 20000] [--adaptive-n 4000] [--out FILE.json]

A larger run of tests/engine/test_coverage.py (which asserts the same quantities in CI with
fewer studies), with the two plain alternatives beside the rule to show why it is as it is:
``alpha per end`` (equivalence on the two-sided 90 % interval) and ``Welch-Satterthwaite``
(its degrees of freedom instead of min((n_i - 1) / c_i)). Prints markdown tables; writes the
numbers as JSON with --out. About 4 minutes on one core.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import time

import numpy as np

from engine.study import comparison, judge, pooling, rates
from tests.engine import test_coverage as sim

KINDS = ("normal", "lognormal", "low", "high")
SEEDS = (2, 3, 5, 12)


def _welch_satterthwaite(nc, nr, vc, vr):
    """Welch-Satterthwaite degrees of freedom (Hsu's with two seeds on a side)."""
    vc, vr = np.asarray(vc, dtype=float), np.asarray(vr, dtype=float)
    if min(nc, nr) < 3:
        return np.full(np.broadcast_shapes(vc.shape, vr.shape), float(min(nc, nr) - 1))[()]
    den = vc * vc / (nc - 1) + vr * vr / (nr - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, (vc + vr) ** 2 / np.where(den > 0, den, 1.0), np.inf)[()]


@contextlib.contextmanager
def variant(name: str):
    """The rule (``rule``) or a plain alternative: ``alpha per end`` or
    ``Welch-Satterthwaite``."""
    # where the rule reads them: the rates module's level, the comparison's two paths to
    # the degrees of freedom (arrays, and numbers for one level)
    saved = rates.EQUIVALENCE_LEVEL, comparison.interval_df, comparison._interval_df_scalar
    if name == "alpha per end":
        rates.EQUIVALENCE_LEVEL = 1.0
    elif name == "Welch-Satterthwaite":
        comparison.interval_df = lambda nc, nr, vc, vr, *_, **__: _welch_satterthwaite(
            nc, nr, vc, vr
        )
        comparison._interval_df_scalar = lambda nc, nr, vc, vr, *_: float(
            _welch_satterthwaite(nc, nr, vc, vr)
        )
    try:
        yield
    finally:
        rates.EQUIVALENCE_LEVEL, comparison.interval_df, comparison._interval_df_scalar = saved


def coverage(n: int) -> dict:
    """Per rule variant and kind of values: the worst wrong-equivalent and wrong-differs
    rates at ± tolerance over 2-12 seeds a side and coarse spreads 1x-5x, and where."""
    out = {}
    for name in ("rule", "alpha per end", "Welch-Satterthwaite"):
        out[name] = {}
        with variant(name):
            ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
            for kind in KINDS:
                worst_e, worst_d = (0.0, None), (0.0, None)
                for nr in SEEDS:
                    for nc in SEEDS:
                        for k in (1.0, 3.0, 5.0):
                            for ratio in (1 + sim.TOL, 1 - sim.TOL):
                                seed = 1000 * nr + 10 * nc + int(k) + (ratio > 1)
                                eq, di = sim._rates(
                                    nr, nc, ratio, k, kind, n=n, seed=seed, ae=ae, ad=ad
                                )
                                where = f"{nr} ref / {nc} coarse, {k:g}x, {ratio - 1:+.0%}"
                                worst_e = max(worst_e, (eq, where), key=lambda w: w[0])
                                worst_d = max(worst_d, (di, where), key=lambda w: w[0])
                out[name][kind] = {"equivalent": worst_e, "differs": worst_d}
    return out


def power(n: int) -> dict:
    """The issue-28 scenario (3 reference seeds at 3 %, coarse spread 10 %): per coarse seed
    count, P(equivalent | error 0) and P(differs | error ± 2 tolerance), for the rule and the
    rule before issue 28; and the oracle's seed counts."""
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    rows = []
    for nc in range(3, 13):
        new_eq = sim._power(sim._new_rule, 1.0, nc, n=n, seed=nc)[0]
        new_up = sim._power(sim._new_rule, 1 + 2 * sim.TOL, nc, n=n, seed=100 + nc)[1]
        new_dn = sim._power(sim._new_rule, 1 - 2 * sim.TOL, nc, n=n, seed=200 + nc)[1]
        m = min(n, 2000)
        old_eq = sim._power(sim._old_rule, 1.0, nc, n=m, seed=nc)[0]
        old_up = sim._power(sim._old_rule, 1 + 2 * sim.TOL, nc, n=m, seed=100 + nc)[1]
        rows.append((nc, new_eq, new_up, new_dn, old_eq, old_up))
    return {
        "rows": rows,
        "oracle_equivalent": sim._oracle_equivalent(ae),
        "oracle_equivalent_alpha_per_end": sim._oracle_equivalent(1 - judge.CONFIDENCE),
        "oracle_differs": sim._oracle_differs(ad),
    }


def adaptive(n: int) -> dict:
    """Adaptive studies from a 3 + 3 pilot, one round: rates at ± tolerance, power and mean
    added seeds at 0 and ± 2 tolerance; the plain alpha per end beside it."""
    cases = {
        "+15 %, 3 % / 10 %, lognormal": (1 + sim.TOL, 0.03, 0.10, "lognormal"),
        "-15 %, 3 % / 10 %, normal": (1 - sim.TOL, 0.03, 0.10, "normal"),
        "+15 %, 10 % / 10 %, low": (1 + sim.TOL, 0.10, 0.10, "low"),
        "-15 %, 3 % / 15 %, high": (1 - sim.TOL, 0.03, 0.15, "high"),
    }
    out = {"boundary": {}, "plain": {}}
    for label, (ratio, sr, sc, kind) in cases.items():
        out["boundary"][label] = sim._adaptive(ratio, sr, sc, kind, n=n, seed=7)
        with variant("alpha per end"):
            out["plain"][label] = sim._adaptive(ratio, sr, sc, kind, n=n, seed=7)
    out["error 0"] = sim._adaptive(1.0, n=n, seed=8)
    out["error +30 %"] = sim._adaptive(1 + 2 * sim.TOL, n=n, seed=9)
    out["error -30 %"] = sim._adaptive(1 - 2 * sim.TOL, n=n, seed=10)
    ae, _ = judge.error_rates(judge.CONFIDENCE, 1, look=2, looks=2)
    out["oracle_seeds"] = sim._oracle_equivalent(ae)
    return out


def pooled(n: int) -> dict:
    """Pooled spreads (engine.study.pooling): the worst wrong-verdict rates of the judged
    variant at ± tolerance over 2 or 4 groups at its radius of 2-8 seeds each, with equal
    spreads, its own twice the others' and another's twice; then the issue-39 scenario's
    power (three rules at 10 %, three references at 3 %, error 0) pooled and unpooled, and
    the rates with no screen."""
    out = {"coverage": {}, "power": [], "no_screen": None}
    for wide, label in ((None, "equal spreads"), (0, "judged variant 2x"), (1, "another 2x")):
        for kind in ("normal", "lognormal"):
            worst_e, worst_d = (0.0, None), (0.0, None)
            for groups in (2, 4):
                for seeds in (2, 3, 5, 8):
                    for ratio in (1 + sim.TOL, 1 - sim.TOL):
                        seed = 97 * groups + 13 * seeds + (ratio > 1) + 7 * (wide or 0)
                        eq, di = sim._pooled_rates(groups, seeds, ratio, wide, kind, n, seed=seed)
                        where = f"{groups} groups of {seeds}, {ratio - 1:+.0%}"
                        worst_e = max(worst_e, (eq, where), key=lambda w: w[0])
                        worst_d = max(worst_d, (di, where), key=lambda w: w[0])
            out["coverage"][f"{label}, {kind}"] = {"equivalent": worst_e, "differs": worst_d}
    for k in range(3, 11):
        out["power"].append(
            (k, sim._pooled_power(k, True, n, k), sim._pooled_power(k, False, n, k))
        )
    rng = np.random.default_rng(17)
    r = sim._draw(rng, (n, 3), 1.0, sim.SD_REF, "normal")
    c = sim._draw(rng, (n, 8), 1 + sim.TOL, 2 * sim.SD_COARSE, "normal")
    others = [sim._draw(rng, (n, 8), 1.0, sim.SD_COARSE, "normal") for _ in range(3)]
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    for level, key in (
        (None, "no_screen"),
        (0.05, "screen_5pct"),
        (pooling.SCREEN_LEVEL, "screen"),
    ):
        v = judge.judge_samples(c, r, sim.TOL, ae, ad, others=others, level=level)
        out[key] = float(np.mean(v == "equivalent"))
    return out


def pooled_markdown(po: dict) -> str:
    lines = [
        "Pooled spreads (the judged variant against 3 references at 3 %, pooled with 1 or 3 "
        "other groups of its radius; 2, 3, 5 or 8 seeds each; coarse spread 10 %; worst case "
        "over the grid at ± tolerance):",
        "",
        "| spreads, values | wrong `equivalent` | wrong `differs` |",
        "|---|---|---|",
    ]
    for label, r in po["coverage"].items():
        lines.append(
            f"| {label} | {_pct(r['equivalent'][0])} ({r['equivalent'][1]}) "
            f"| {_pct(r['differs'][0])} ({r['differs'][1]}) |"
        )
    lines += [
        "",
        "A variant with twice the others' spread at +15 %, four groups of 8 seeds, normal "
        f"values: wrong `equivalent` {_pct(po['no_screen'])} pooled without a screen, "
        f"{_pct(po['screen_5pct'])} with a 5 % screen, {_pct(po['screen'])} with the rule's "
        f"{pooling.SCREEN_LEVEL:.0%}.",
        "",
        "Power, three rules at one radius with 10 % spread, three references at 3 %, error 0:",
        "",
        "| seeds per rule | `equivalent`, pooled | `equivalent`, own spread |",
        "|---|---|---|",
    ]
    for k, a, b in po["power"]:
        lines.append(f"| {k} | {_pct(a)} | {_pct(b)} |")
    return "\n".join(lines)


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def markdown(cov: dict, pw: dict, ad: dict) -> str:
    lines = [
        "| values | wrong `equivalent` (rule) | wrong `differs` (rule) "
        "| `equivalent`, α per end | `differs`, Welch-Satterthwaite |",
        "|---|---|---|---|---|",
    ]
    for kind in KINDS:
        r = cov["rule"][kind]
        lines.append(
            f"| {kind} | {_pct(r['equivalent'][0])} ({r['equivalent'][1]}) "
            f"| {_pct(r['differs'][0])} ({r['differs'][1]}) "
            f"| {_pct(cov['alpha per end'][kind]['equivalent'][0])} "
            f"| {_pct(cov['Welch-Satterthwaite'][kind]['differs'][0])} |"
        )
    lines += [
        "",
        f"Power, 3 reference seeds at 3 %, coarse spread 10 % (an oracle z-test knowing both "
        f"spreads needs {pw['oracle_equivalent']} coarse seeds for 80 % `equivalent` at the "
        f"rule's rates, {pw['oracle_equivalent_alpha_per_end']} at α per end, and "
        f"{pw['oracle_differs']} for 80 % `differs` at twice the tolerance):",
        "",
        "| coarse seeds | `equivalent` at error 0 | `differs` at +30 % | `differs` at -30 % "
        "| before issue 28: `equivalent` at 0 | before: `differs` at +30 % |",
        "|---|---|---|---|---|---|",
    ]
    for nc, a, b, c, d, e in pw["rows"]:
        lines.append(f"| {nc} | {_pct(a)} | {_pct(b)} | {_pct(c)} | {_pct(d)} | {_pct(e)} |")
    lines += [
        "",
        "Adaptive studies (pilot 3 + 3, one round, reference runs 8x a coarse run's cost):",
        "",
        "| case | wrong `equivalent` | wrong `differs` | added coarse seeds "
        "| wrong `equivalent` at α per end |",
        "|---|---|---|---|---|",
    ]
    for label, (eq, di, added) in ad["boundary"].items():
        lines.append(
            f"| {label} | {_pct(eq)} | {_pct(di)} | {added:.1f} | {_pct(ad['plain'][label][0])} |"
        )
    lines += [
        "",
        "| true error | `equivalent` | `differs` | added coarse seeds |",
        "|---|---|---|---|",
    ]
    for label in ("error 0", "error +30 %", "error -30 %"):
        eq, di, added = ad[label]
        lines.append(f"| {label[6:]} | {_pct(eq)} | {_pct(di)} | {added:.1f} |")
    lines.append(f"\n(oracle at the final look's rates: {ad['oracle_seeds']} coarse seeds)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.verdict_rates", description=__doc__)
    ap.add_argument("--n", type=int, default=20_000, help="studies per fixed-design cell")
    ap.add_argument("--adaptive-n", type=int, default=4000, help="studies per adaptive case")
    ap.add_argument("--out", help="write the numbers as JSON")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cov = coverage(args.n)
    pw = power(args.n)
    ad = adaptive(args.adaptive_n)
    po = pooled(args.n)
    print(markdown(cov, pw, ad))
    print()
    print(pooled_markdown(po))
    mc = 3 * math.sqrt(0.05 * 0.95 / args.n)
    print(
        f"\n{args.n} studies per cell (3 Monte Carlo s.e. at 5 %: {_pct(mc)}); "
        f"{time.perf_counter() - t0:.0f} s"
    )
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"coverage": cov, "power": pw, "adaptive": ad, "pooled": po}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
