"""The tail of a shear cell's contact overlaps as its run goes on: a size-series shear run
(:mod:`benchmarks.size_series`) made again, its contacts read when the platens are glued
and every ``EVERY`` servo updates after, until it ends or stops (docs/RESOLUTION.md,
"Runs stopped at the overlap guard").

    python -m benchmarks.overlap_tail bond3 7.5 3   # about 2 min on one core

Writes ``benchmarks/results/overlap_tail/<law>-d<size>-s<seed>.json``: how the run ended,
and per reading the stage in flight (``glued`` when the platens are glued), the simulated
time [s], the lid's normal-stress target [Pa], the
contacts, the mean, 99.9th percentile, largest and smallest normal force [N] and the mean,
99.9th percentile and largest overlap over the grains' radius [-]. The bilinear law keeps
each contact's largest overlap (its plastic overlap is (1 - k1 / k2) of it), and with
kadh = 0 the adhesion pulls an unloaded contact back to that plastic overlap: the overlaps
record the largest force each contact has carried.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from benchmarks import size_series as S

OUT = Path(__file__).resolve().parent / "results" / "overlap_tail"
#: Servo updates between two readings (SERVO_STEPS steps each).
EVERY = 200


def reading(sim, radius: float, stage: str, target: float) -> dict:
    """The contact forces' and overlaps' summary of ``sim`` now."""
    c = sim.contacts()
    fn = np.einsum("ij,ij->i", c.forces, c.normals)
    ov = c.overlaps / radius
    return {
        "stage": stage,
        "time": float(sim.time),
        "target": float(target),
        "contacts": int(ov.size),
        "force_mean": float(np.mean(fn)),
        "force_p999": float(np.percentile(fn, 99.9)),
        "force_max": float(np.max(fn)),
        "force_min": float(np.min(fn)),
        "overlap_mean": float(np.mean(ov)),
        "overlap_p999": float(np.percentile(ov, 99.9)),
        "overlap_max": float(np.max(ov)),
    }


def main(argv=None) -> int:
    import numba

    import engine
    import engine.shear.driver as drv

    law, size, seed = (argv or sys.argv[1:])[:3]
    size, seed = float(size), int(seed)
    numba.set_num_threads(1)
    test = S.test_of("shear", law, size, seed)
    rows: list[dict] = []
    updates = [0]

    class Watched(drv._Shear):
        def glue(self, d):
            cell = super().glue(d)
            rows.append(reading(cell.sim, test.radius, "glued", test.preshear_stress))
            return cell

    run = Watched(test, None)
    advance = drv._Cell.advance

    def watched_advance(cell, steps, target, stop=None):
        out = advance(cell, steps, target, stop)
        updates[0] += 1
        if updates[0] % EVERY == 0:
            stage = run.current.name if run.current is not None else "between stages"
            rows.append(reading(cell.sim, test.radius, stage, target))
        return out

    drv._Cell.advance = watched_advance
    try:
        run.run()
        outcome = "finished"
    except (engine.InstabilityError, engine.StageError, FloatingPointError) as e:
        outcome = f"{type(e).__name__}: {e}"  # how the run ended (a bug of this script raises)
    finally:
        drv._Cell.advance = advance
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{law}-d{S.label(size)[1:]}-s{seed}.json"
    doc = {"law": law, "size": size, "seed": seed, "outcome": outcome, "readings": rows}
    path.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"{path.name}: {outcome[:120]}")
    for r in rows:
        print(
            f"{r['stage']:16s} {r['time']:.3f} s  target {r['target']:.0f} Pa  "
            f"force mean {r['force_mean']:.3f} "
            f"p99.9 {r['force_p999']:.2f} max {r['force_max']:.2f} N  overlap / R mean "
            f"{r['overlap_mean']:.3f} p99.9 {r['overlap_p999']:.3f} max {r['overlap_max']:.3f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
