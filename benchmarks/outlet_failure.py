"""Where a discharge of the outlet series fails: the run made again, its state at the failure
reduced to bands of height (docs/HOPPER.md, "Not measured", the 80 d discharge).

    python -m benchmarks.outlet_failure flow 30 80 1   # about 20 min on one core

Writes ``benchmarks/results/outlet_failures/<series>-w<width>-s<seed>.json`` (beside the
series' digests, not among them): the
failure's message, the sink's height and the floor [m], and per 5 cm band of height
the grains in it, their median vertical velocity and the largest speed [m/s].
"""

from __future__ import annotations

import json
import sys

import numpy as np

from benchmarks import jenike_series
from benchmarks import outlet_series as O

BAND = 0.05


def bands(z: np.ndarray, v: np.ndarray, width: float = BAND) -> list[dict]:
    """Per band of height ``width`` [m] holding grains: its bounds [m], the grains, the median
    vertical velocity and the largest speed [m/s]."""
    speed = np.linalg.norm(v, axis=1)
    lo = width * np.floor(z.min() / width)
    out = []
    for a in np.arange(lo, z.max() + width, width):
        m = (z >= a) & (z < a + width)
        if m.any():
            out.append(
                {
                    "from": round(float(a), 6),
                    "to": round(float(a + width), 6),
                    "grains": int(m.sum()),
                    "median_vz": float(np.median(v[m, 2])),
                    "max_speed": float(speed[m].max()),
                }
            )
    return out


def main(argv=None) -> int:
    import numba

    from engine.hopper.driver import HopperRun

    kind, x, width, seed = (argv or sys.argv[1:])[:4]
    key = (kind, float(x), float(width), int(seed))
    numba.set_num_threads(1)
    test = O.test_of(*key)
    run = HopperRun(test, threads=1)
    ids: tuple = ()
    try:
        jenike_series.ramped_hopper(test, run)
        what = "finished"
    except Exception as e:
        what = f"{type(e).__name__}: {e}"
        ids = tuple(getattr(e, "particles", ()) or ())
    sim = run.sim
    p, v, r = sim.positions, sim.velocities, sim.radii
    body = {
        "run": O.key_name(*key),
        "outcome": what,
        "time": sim.time,
        "sink": run.geo.sink,
        "floor": -run.geo.catch_depth,
        "bands": bands(p[:, 2], v),
        # the failing particles: where (z against the outlet at 0, the sink and the
        # floor; the distance from the axis or mid-plane) and how fast
        "failing": [
            {
                "id": int(i),
                "position": p[i].tolist(),
                "across": float(run._across(p[i : i + 1])[0]),
                "velocity": v[i].tolist(),
                "radius": float(r[i]),
            }
            for i in ids
        ],
    }
    path = O.STORE.parent / "outlet_failures" / f"{O.key_name(*key).replace('/', '-')}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(body, indent=1) + "\n")
    print(f"{what}; wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
