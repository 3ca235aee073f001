"""How much of a packing seed's imprint a coarse run and its resolution control share.

    python -m benchmarks.pairing            # from the stored runs of benchmarks/results

A resolution control and a coarse run of one seed start from the exactly scaled same loose
cloud (engine.simulation.packing draws positions as fractions of the box). Whether their
values stay correlated decides whether the rule's own error is worth judging paired by seed
(engine.study.judge.judge_rule_error). For every variant with two or more seeds that have
a control, the logs of each metric (summed over stress levels for density and coordination)
are centred within the variant, for the coarse runs and for their controls; the pooled
correlation is the sum of the cross products over the root of the sums of squares, with
sum(n - 1) degrees of freedom, and the variance ratio is
var(log c - log k) / (var log c + var log k), which
:data:`engine.study.judge.PAIRING_VARIANCE_RATIO` holds.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from engine.io.store import load_run
from engine.study.metrics import METRICS, metric_values

ROOT = Path(__file__).resolve().parent / "results"
COARSE = re.compile(r"^r(?P<r>[\d.]+)mm-(?P<rule>.+)-s(?P<s>\d+)$")
CONTROL = re.compile(r"^ctl-r(?P<r>[\d.]+)mm-s(?P<s>\d+)$")


def centred_pairs(store: Path = ROOT) -> dict[str, list[tuple[str, np.ndarray, np.ndarray]]]:
    """Per metric, per (scale/experiment, radius, rule) with two or more seeds that have a
    control: the centred logs of the coarse runs and of their controls, seed by seed."""
    out: dict[str, list] = {n: [] for n in METRICS}
    for exp in sorted(p for p in store.glob("*/*") if p.is_dir()):
        ctl, coarse = {}, {}
        for path in sorted(exp.glob("*.h5")):
            m = CONTROL.match(path.stem) or COARSE.match(path.stem)
            if m is None:
                continue
            res = load_run(path)
            if isinstance(res, str):
                continue
            if m.re is CONTROL:
                ctl[(m["r"], int(m["s"]))] = metric_values(res)
            else:
                coarse.setdefault((m["r"], m["rule"]), {})[int(m["s"])] = metric_values(res)
        for (r, rule), by_seed in coarse.items():
            seeds = [s for s in by_seed if (r, s) in ctl]
            if len(seeds) < 2:
                continue
            for n in METRICS:
                if n not in by_seed[seeds[0]] or n not in ctl[(r, seeds[0])]:
                    continue
                x = np.log([np.sum(by_seed[s][n]) for s in seeds])
                y = np.log([np.sum(ctl[(r, s)][n]) for s in seeds])
                where = f"{exp.parent.name}/{exp.name} {r} mm {rule}"
                out[n].append((where, x - x.mean(), y - y.mean()))
    return out


def pooled(rows) -> dict:
    """Pooled correlation, degrees of freedom and variance ratio of centred pairs."""
    x = np.concatenate([r[1] for r in rows])
    y = np.concatenate([r[2] for r in rows])
    sxx, syy = float(np.sum(x**2)), float(np.sum(y**2))
    return {
        "rho": float(np.sum(x * y) / np.sqrt(sxx * syy)),
        "dof": sum(len(r[1]) - 1 for r in rows),
        "variance_ratio": float(np.sum((x - y) ** 2) / (sxx + syy)),
        "variants": len(rows),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", type=Path, default=ROOT)
    args = ap.parse_args(argv)
    rows = centred_pairs(args.store)
    print("| metric | correlation | dof | var(diff) / (var c + var k) | quick | paper |")
    print("|---|---|---|---|---|---|")
    for n, r in rows.items():
        if not r:
            continue
        p = pooled(r)
        by_scale = []
        for scale in ("quick", "paper"):
            sub = [x for x in r if x[0].startswith(scale + "/")]
            by_scale.append(f"{pooled(sub)['rho']:+.2f} ({pooled(sub)['dof']} dof)" if sub else "-")
        print(
            f"| {n} | {p['rho']:+.2f} | {p['dof']} | {p['variance_ratio']:.2f} | "
            f"{by_scale[0]} | {by_scale[1]} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
