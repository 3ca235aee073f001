"""This engine against another version of it, on the same machine in the same sitting.

    python -m benchmarks.engine_ab                      # against BASELINE (about 8 minutes)
    python -m benchmarks.engine_ab --baseline REV --rounds 7
    python -m benchmarks.engine_ab --code               # the hot loop's machine code, compared

The baseline engine (git revision ``--baseline``, default the last commit before the issue-20
redesign) is checked out into a temporary git worktree. Each round runs one process of each
engine, in alternating order, on the 2,025-particle anchor bed of benchmarks/engine_speed.py
under a platen at 10 mm/s with one engine thread, and takes the CPU time of the process per
particle-step (the cost of a step whatever else runs) for three laws: the seed's bilinear law
with adhesion, friction, rolling and damping (``full``), the cohesionless frictionless one
(``plain``: the smallest kernel, where overhead shows most) and EEPA n = 1.5. Rounds
interleave the two engines so that a slow spell of a shared machine falls on both; the
figure is the median over rounds of each round's ratio. The target: not slower than the
baseline by more than the measurement's own spread (3 %: repeated measurements of one build
scatter that much, benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from benchmarks.checks import ROOT, report, run_child, worktree

#: The last commit before the issue-20 redesign (subpackages, a law per module).
BASELINE = "b777942"
TOLERANCE = 0.03

#: What both children set up: the engine of their tree, the three laws, the anchor bed.
_SETUP = """
import json, re, sys
import numba
numba.set_num_threads(1)
import engine
from benchmarks.engine_speed import DT, FULL, PLAIN, R, anchor_bed, scene_for, time_run
fields = {k: getattr(FULL, k) for k in ("f0", "kadh", "kt_ratio", "mu_s", "mu_r", "restitution")}
laws = {
    "full": FULL,
    "plain": PLAIN,
    "eepa": engine.EEPA(k1=5e5, k2=2.5e6, n=1.5, chi=1.5, **fields),
}
pos, rad, lengths = anchor_bed()
"""

_CHILD = (
    _SETUP
    + """
for law in laws.values():  # compile (or load) every kernel before timing any
    time_run(pos, rad, lengths, law, 1, 10, 1)
steps, repeats = int(sys.argv[1]), int(sys.argv[2])
print(json.dumps({n: time_run(pos, rad, lengths, law, 1, steps, repeats)[1]
                  for n, law in laws.items()}))
"""
)

_CODE = (
    _SETUP
    + """
top = float((pos[:, 2] + rad).max()) + 0.1 * R
out = {}
for law_name, law in laws.items():
    sim = engine.Simulation(scene_for(pos, rad, lengths, law, top), dt=DT, threads=1)
    sim.run(2)
    for name in ("_pair_chunk", "_particle_chunk", "_pass"):
        d = getattr(sim._k, name)
        lines = []
        for line in d.inspect_asm(d.signatures[0]).splitlines():
            line = line.split("#")[0].rstrip()
            if not line.strip() or line.strip().startswith("."):
                continue
            line = re.sub(r"_ZN[\\w$.]+|__numba_\\w+", "SYM", line)
            lines.append(re.sub(r"\\.L(BB|CPI)\\d+_\\d+", r".L\\1", line))
        out[f"{law_name} {name}"] = lines
print(json.dumps(out))
"""
)


def _code(tree: Path, tmp: Path) -> dict[str, list[str]]:
    # compiled afresh (empty caches): every callee's code is made in this process
    return run_child(
        tree,
        _CODE,
        NUMBA_NUM_THREADS=1,
        DEMSCALE_CACHE_DIR=tmp / "kernels",
        NUMBA_CACHE_DIR=tmp / "numba",
    )


def compare_code(baseline: str) -> int:
    """The ``--code`` comparison: PASS per function whose instructions are identical."""
    with worktree(baseline) as base_tree, tempfile.TemporaryDirectory() as tmp:
        this = _code(ROOT, Path(tmp) / "this")
        base = _code(base_tree, Path(tmp) / "base")
    checks = []
    for key, lines in this.items():
        same = lines == base.get(key)
        changed = sum(a != b for a, b in zip(lines, base.get(key, []))) + abs(
            len(lines) - len(base.get(key, []))
        )
        print(
            f"  {key:28s} {len(lines):5d} lines: " + ("identical" if same else f"{changed} differ")
        )
        checks.append((f"{key}: the machine code of {baseline}'s", same))
    return report(checks)


def _measure(tree: Path, cache: Path, steps: int, repeats: int) -> dict[str, float]:
    return run_child(tree, _CHILD, (steps, repeats), NUMBA_NUM_THREADS=1, DEMSCALE_CACHE_DIR=cache)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=BASELINE, help="git revision of the baseline engine")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=2, help="timed runs per process (median)")
    ap.add_argument(
        "--code", action="store_true", help="compare the hot loop's machine code instead"
    )
    args = ap.parse_args(argv)
    if args.code:
        return compare_code(args.baseline)
    with worktree(args.baseline) as base_tree, tempfile.TemporaryDirectory() as tmp:
        trees = {
            "this": (ROOT, Path(tmp) / "cache-this"),
            "baseline": (base_tree, Path(tmp) / "cache-base"),
        }
        rows: dict[str, list[dict[str, float]]] = {"this": [], "baseline": []}
        for r in range(args.rounds):
            order = ("this", "baseline") if r % 2 == 0 else ("baseline", "this")
            for who in order:
                tree, cache = trees[who]
                rows[who].append(_measure(tree, cache, args.steps, args.repeats))
            print(
                f"round {r + 1}: "
                + "; ".join(
                    f"{n} {rows['this'][-1][n]:.0f} / {rows['baseline'][-1][n]:.0f} ns"
                    for n in rows["this"][-1]
                ),
                flush=True,
            )
    print(
        f"\nanchor bed, 1 thread, {args.steps} steps x {args.repeats} per process, "
        f"{args.rounds} rounds; CPU ns per particle-step (median over rounds)"
    )
    print(
        "| law | this engine | baseline " + args.baseline + " | ratio (median of rounds) "
        "| ratios of the rounds, lowest to highest |"
    )
    print("|---|---:|---:|---:|---|")
    checks = []
    for n in rows["this"][0]:
        this = statistics.median(x[n] for x in rows["this"])
        base = statistics.median(x[n] for x in rows["baseline"])
        ratios = sorted(a[n] / b[n] for a, b in zip(rows["this"], rows["baseline"]))
        ratio = statistics.median(ratios)
        spread = " ".join(f"{r:.2f}" for r in ratios)
        print(f"| {n} | {this:.1f} | {base:.1f} | {ratio:.3f} | {spread} |")
        checks.append(
            (
                f"{n} law: this engine / baseline = {ratio:.3f} <= {1 + TOLERANCE:.2f}",
                ratio <= 1 + TOLERANCE,
            )
        )
    return report(checks)


if __name__ == "__main__":
    sys.exit(main())
