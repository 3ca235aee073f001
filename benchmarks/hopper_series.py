"""Cohesionless discharge of a slot hopper against Beverloo's law (issue 52 item 3): the
runs, stored as compact digests in git; the fit and docs/HOPPER.md's section are
:mod:`benchmarks.hopper_report`'s.

    python -m benchmarks.hopper_series            # every run not yet stored, cheapest first
    python -m benchmarks.hopper_series --list     # the runs, particles, stored or estimated cost
    python -m benchmarks.hopper_series --only w6  # the runs whose key contains w6
    python -m benchmarks.hopper_report           # docs/HOPPER.md's Beverloo section

Choices, fixed here before any run of the series (2026-12-06):

- **Hopper**: ``engine.HopperTest(shape="slot")``, plane flow, periodic in a depth of
  :data:`DEPTH` = 25 mm = 5 mean diameters (the smallest the engine allows for these grains
  is 4.6 diameters: twice the neighbour cut-off), wall half-angle :data:`HALF_ANGLE` = 30 deg
  from the vertical (the hopper tests' angle; steep enough for mass flow with the wall
  friction below).
- **Grains and laws** (the hopper tests' cohesionless laws, the HopperTest defaults):
  R = 2.5 mm (mean diameter d = 5 mm, the d of the fit), radii uniform in R (1 +- 0.1)
  (:data:`POLYDISPERSITY`: a monodisperse fill in a thin periodic slot crystallises,
  and a crystal discharges in bursts), density 2000 kg/m^3, g = 9.81 m/s^2; the
  particle-particle law the **bilinear law without adhesion** (k1 = 5e3 N/m, k2 = 2.5e4
  N/m, f0 = 0, mu_s = 0.5, mu_r = 0.001, e = 0.4); the walls' and the gate's **Hertz** law
  E = 1e8 Pa, nu = 0.25, e = 0.4, wall friction mu = 0.3; the time step 0.4 of the stable
  limit (the default).
- **Outlet widths** B / d = 6, 8, 12, 18, 27, 40 (:data:`WIDTHS`: about geometric, 6 to
  40 as the issue asks), **seeds** 1, 2, 3 each (the lattice's jitter and top level, the
  radii).
- **Fill**: the settled fill's height H = max(1.5 B, 20 d) (:func:`fill_height`): at
  the end of the steady window (60 % of the mass discharged, the HopperTest default window
  0.2-0.6) the level surface is still about 0.8 B above the outlet at the widest outlet and
  higher, relative to B, at the others; a hopper's rate does not depend on the head there
  (Beverloo et al. 1961: it is set at the outlet). Fills of 2.0k (6 d) to 25.4k (40 d)
  particles.
- **Order** (:func:`keys`): seed 1 of the five widths up to 27 d (the fewest runs that give
  five widths), then their seeds 2 and 3 (five widths x three seeds: the least the fit's
  verdict takes), then the 40 d outlet's three seeds (the costliest: 25k particles each).
- **Stored**: each run at once, on one engine thread, as a digest
  ``benchmarks/results/hopper_series/w<B/d>-s<seed>.json`` (:mod:`engine.io.digest`: the
  test, the scalars bit-exact, the code version; ``extra``: the discharge curve decimated to
  at most :data:`CURVE_POINTS` samples, the wall stress profiles, the flow mode, the wall
  and CPU seconds of the run); the full run (``save_hopper``: .json and its curves in .npz)
  under ``var/hopper_series/`` outside git, named in the digest by the .npz's sha256.
  A run that is cut off starts again (the hopper has no checkpoints).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

import engine
from benchmarks.series import list_or_run
from engine.io.digest import make_digest, read_digest, write_digest

ROOT = Path(__file__).resolve().parent.parent
#: The digests (in git) and the full runs (outside git); the environment can move both.
STORE = Path(
    os.environ.get("HOPPER_SERIES_STORE", ROOT / "benchmarks" / "results" / "hopper_series")
)
FULL = Path(os.environ.get("HOPPER_SERIES_FULL", ROOT / "var" / "hopper_series"))

RADIUS = 2.5e-3
#: The mean diameter 2R [m]: the d of Beverloo's (B - k d).
D = 2.0 * RADIUS
POLYDISPERSITY = 0.1
DEPTH = 5.0 * D
HALF_ANGLE = 30.0
#: Outlet widths [mean diameters] and seeds per width.
WIDTHS = (6.0, 8.0, 12.0, 18.0, 27.0, 40.0)
SEEDS = 3
#: The widths whose seeds come first (five widths: the least a fit takes).
FIRST_WIDTHS = (6.0, 8.0, 12.0, 18.0, 27.0)
#: The most samples of the discharge curve a digest keeps.
CURVE_POINTS = 400


def fill_height(width: float) -> float:
    """The settled fill's height above the outlet for an outlet ``width`` diameters wide [m]:
    max(1.5 B, 20 d)."""
    b = width * D
    return max(1.5 * b, 20.0 * D)


def test_of(width: float, seed: int) -> engine.HopperTest:
    """The run at outlet ``width`` [mean diameters], packing ``seed`` (module docstring)."""
    return engine.HopperTest(
        shape="slot",
        half_angle=HALF_ANGLE,
        outlet_width=width * D,
        depth=DEPTH,
        particles=None,
        fill_height=fill_height(width),
        radius=RADIUS,
        polydispersity=POLYDISPERSITY,
        seed=seed,
    )


def label(width: float) -> str:
    return f"w{width:g}"


def key_name(width: float, seed: int) -> str:
    return f"{label(width)}-s{seed}"


def keys(only=None) -> list[tuple[float, int]]:
    """(width, seed) of every run in the order they are taken (module docstring)."""
    out = [(w, 1) for w in FIRST_WIDTHS]
    out += [(w, s) for s in range(2, SEEDS + 1) for w in FIRST_WIDTHS]
    out += [(w, s) for w in WIDTHS if w not in FIRST_WIDTHS for s in range(1, SEEDS + 1)]
    if only:
        out = [k for k in out if any(o in key_name(*k) for o in only)]
    return out


def path_of(width: float, seed: int, store: Path | None = None) -> Path:
    """The run's digest (in git)."""
    return Path(store or STORE) / f"{key_name(width, seed)}.json"


def full_path_of(width: float, seed: int) -> Path:
    """The run's full record (``save_hopper``'s .json; its curves in the .npz beside it)."""
    return FULL / f"{key_name(width, seed)}.json"


def stored(width: float, seed: int, store: Path | None = None):
    """The stored run's :class:`engine.io.digest.Digest` if it was made with today's test,
    else None."""
    path = path_of(width, seed, store)
    if not path.exists():
        return None
    d = read_digest(path)
    want = json.loads(json.dumps(test_of(width, seed).to_dict()))
    return d if d.test == want else None


#: Throughput of the engine on these fills, one thread of this 2-core VM shared with other
#: jobs [particle-steps per CPU second]: 3.3e6 and 3.5e6 measured in the runs w8-s1 and
#: w12-s1 (2026-12-06; the first run, w6-s1, 1.4e6 with the kernels' compilation in it).
THROUGHPUT = 3.4e6
#: The time step of these grains, 0.4 of the stable limit [s] (1.81e-5 to 1.84e-5 s measured).
DT_ESTIMATE = 1.83e-5
#: The settling's simulated time [s] (0.368-0.374 s measured at 6-12 d).
SETTLE_ESTIMATE = 0.4


def estimate(width: float, seed: int) -> float:
    """A run's CPU time on one thread [s], estimated: the settling
    (:data:`SETTLE_ESTIMATE`) and the discharge (the fill's mass at rho_b = 0.56 rho over
    the rate y = 1.0 (B/d)^1.5, about what the first runs gave, 1.3 times for the start and
    the tail) in steps of :data:`DT_ESTIMATE`, times the particles, over
    :data:`THROUGHPUT`."""
    t = test_of(width, seed)
    rho_b = 0.56 * t.density
    mass = rho_b * t.volume_below(t.fill_height)
    rate = 1.0 * rho_b * math.sqrt(t.gravity) * t.outlet_width**1.5 * t.depth
    steps = (SETTLE_ESTIMATE + 1.3 * mass / rate) / DT_ESTIMATE
    return t.n_particles * steps / THROUGHPUT


def decimate(curves: dict, most: int = CURVE_POINTS) -> dict:
    """The discharge curve (time [s], discharged mass [kg]) at no more than ``most``
    samples: every k-th sample and the last."""
    t = np.asarray(curves["time"], dtype=float)
    m = np.asarray(curves["discharged_mass"], dtype=float)
    step = max(1, math.ceil(len(t) / (most - 1)))
    idx = np.unique(np.r_[np.arange(0, len(t), step), len(t) - 1]) if len(t) else np.array([], int)
    return {"time": t[idx].tolist(), "discharged_mass": m[idx].tolist(), "every": step}


def extra_of(outcome, wall: float, cpu: float) -> dict:
    """What the report reads beyond the scalars (module docstring)."""
    out = {"wall_seconds": wall, "cpu_seconds": cpu, "threads": 1}
    if isinstance(outcome, str):
        return out
    out.update(
        {
            "flow_mode": outcome.flow_mode,
            "curve": decimate(outcome.curves),
            "wall_edges": [float(x) for x in outcome.wall_edges],
            "wall_stress_fill": [float(x) for x in outcome.wall_stress_fill],
            "wall_stress_flow": [float(x) for x in outcome.wall_stress_flow],
        }
    )
    return out


def run_one(width: float, seed: int) -> str:
    """Run and store one run; a line for the log."""
    import numba

    from engine.hopper.results import save_hopper

    numba.set_num_threads(1)
    test = test_of(width, seed)
    full = full_path_of(width, seed)
    full.parent.mkdir(parents=True, exist_ok=True)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        outcome = engine.run_hopper(test, threads=1)
    except Exception as e:
        outcome = f"{type(e).__name__}: {e}"
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    npz = None
    if not isinstance(outcome, str):
        save_hopper(full, outcome)
        npz = full.with_suffix(".npz")
    digest = make_digest(outcome, test, npz, extra_of(outcome, wall, cpu))
    write_digest(path_of(width, seed), digest)
    if isinstance(outcome, str):
        what = outcome
    else:
        s = outcome.scalars
        what = (
            f"W = {s['discharge_rate']:.4g} +- {s['discharge_rate_se']:.2g} kg/s, "
            f"rho_b = {s['bulk_density']:.0f} kg/m^3, {outcome.flow_mode} flow, "
            f"{s['particle_steps']:.3g} particle-steps"
        )
    return f"{key_name(width, seed)}: {what} ({wall:.0f} s wall, {cpu:.0f} s CPU)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="runs whose key contains any of these")
    ap.add_argument("--list", action="store_true", help="list the runs and their cost")
    args = ap.parse_args(argv)
    todo = keys(args.only)

    def line(k, s, est) -> str:
        if s is None:
            state = f"about {est / 60:.0f} min CPU on one thread"
        else:
            cpu = s.extra.get("cpu_seconds", float("nan"))
            state = f"stored ({s.outcome if not s.ok else 'ok'}; {cpu / 60:.0f} min CPU)"
        return f"{key_name(*k):10s} {test_of(*k).n_particles:7d} particles  {state}"

    return list_or_run(
        args.list,
        todo,
        stored,
        estimate,
        line,
        key_name,
        test_of,
        run_one,
        "benchmarks.hopper_report",
    )


if __name__ == "__main__":
    raise SystemExit(main())
