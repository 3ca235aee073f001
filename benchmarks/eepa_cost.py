"""What the EEPA law costs, and that a linear scene pays nothing for it (issue 13).

    python -m benchmarks.eepa_cost                   # about 3 minutes on 2 cores
    python -m benchmarks.eepa_cost --baseline REV    # another engine version as the baseline

The 2,025-particle anchor bed of benchmarks/liggghts under a platen at 10 mm/s (the scene of
benchmarks/engine_speed.py), one engine thread, CPU time of the process per particle-step
(the cost of a step whatever else runs on the machine), median of ``--repeats`` runs:

- the bilinear law (K1 = 5e3, K2 = 2.5e4 N/m, f0 = -0.4 N, friction, rolling, damping) on
  this engine and on the baseline engine ``--baseline`` (default: the last commit before the
  EEPA law), checked out into a temporary git worktree and run in its own process in the same
  session: the target is that the linear scene pays nothing for the EEPA law, i.e. costs
  at most 3 % more (the spread of repeated CPU-time measurements of one build); a cheaper
  run is no failure of that target;
- the same law as ``EEPA(n=1, chi=1)``: the EEPA branches with their powers, same trajectory;
- ``EEPA(n=1.5)`` with K1 = 5e5, K2 = 2.5e6 N/m^1.5 (the same force as the linear law at an
  overlap of 0.04 R) and f0 = -0.4 N.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import engine
from benchmarks.checks import report, run_child, worktree
from benchmarks.engine_speed import FULL, anchor_bed, time_run

#: The last commit before engine.EEPA (its parent: "Review mends ...").
BASELINE = "d2d75c5"
LINEAR_TOLERANCE = 0.03

_CHILD = """
import json, sys
from benchmarks.engine_speed import FULL, anchor_bed, time_run
pos, rad, lengths = anchor_bed()
_, cpu, _ = time_run(pos, rad, lengths, FULL, 1, int(sys.argv[1]), int(sys.argv[2]))
print(json.dumps(cpu))
"""


def baseline_cost(rev: str, steps: int, repeats: int) -> float:
    """CPU ns per particle-step of the bilinear law on the engine at git revision ``rev``."""
    with worktree(rev) as tree, tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        return float(run_child(tree, _CHILD, (steps, repeats), DEMSCALE_CACHE_DIR=cache))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline", default=BASELINE, help="git revision of the baseline engine")
    args = ap.parse_args(argv)
    pos, rad, lengths = anchor_bed()
    fields = {
        k: getattr(FULL, k)
        for k in ("k1", "k2", "f0", "kadh", "kt_ratio", "mu_s", "mu_r", "restitution")
    }
    laws = {
        "bilinear": FULL,
        "EEPA n=1": engine.EEPA(n=1.0, chi=1.0, **fields),
        "EEPA n=1.5": engine.EEPA(**{**fields, "k1": 5e5, "k2": 2.5e6, "n": 1.5, "chi": 1.5}),
    }
    print(
        f"anchor bed: {len(rad)} particles, {args.steps} steps x {args.repeats} repeats, 1 thread"
    )
    for _, law in laws.items():  # compile every kernel before timing any
        time_run(pos, rad, lengths, law, 1, 10, 1)
    base = baseline_cost(args.baseline, args.steps, args.repeats)
    cost = {}
    for name, law in laws.items():
        _, cost[name], sim = time_run(pos, rad, lengths, law, 1, args.steps, args.repeats)
        print(
            f"  {name:12s} {cost[name]:7.1f} ns CPU per particle-step "
            f"({len(sim.contacts().pairs)} contacts at the end)"
        )
    print(f"  {'baseline':12s} {base:7.1f} ns CPU per particle-step (bilinear on {args.baseline})")
    lin = cost["bilinear"] / base
    print(f"\nbilinear, this engine / baseline: {lin:.3f}")
    print(f"EEPA n=1 / bilinear: {cost['EEPA n=1'] / cost['bilinear']:.3f}")
    print(f"EEPA n=1.5 / bilinear: {cost['EEPA n=1.5'] / cost['bilinear']:.3f}")
    return report(
        [
            (
                f"a linear scene costs no more than before the EEPA law (ratio {lin:.3f}, "
                f"at most 1 + {LINEAR_TOLERANCE:.0%})",
                lin <= 1 + LINEAR_TOLERANCE,
            )
        ]
    )


if __name__ == "__main__":
    raise SystemExit(main())
