"""The cost of one hopper run of about 50,000 particles on this machine, measured over a short
run and projected to the whole run (docs/HOPPER.md, "Cost of a run of about 50,000
particles"). ``python -m benchmarks.hopper_cost [--steps 400] [--threads 1] [--repeats 3]``.

What it measures and how it projects:

- **The big hopper**: the Beverloo series' widest run (:mod:`benchmarks.hopper_series`, B =
  40 d, fill height max(1.5 B, 20 d), half-angle 30 deg, d = 5 mm +-10 %) with its periodic
  depth doubled to 10 d: about 50,800 particles. Its scene is built, its kernel compiled (set-up,
  not timed), then ``--steps`` steps are timed (wall and CPU seconds) from the poured lattice.
- **The stored run it scales**: the series' run at B = 40 d itself (depth 5 d, about
  25,400 particles), whose digest holds its whole run's steps and CPU seconds. The same
  short measurement on it gives the ratio of the two hoppers' step costs.
- **The projection** (a projection, not a measured run): the stored run's CPU seconds x the
  measured ratio of the big hopper's step cost to its own. The doubled depth changes
  neither the time step nor the settling and discharge times (the same fall height, outlet
  and fill height), so the big run takes the stored run's steps. The ratio is measured on
  the poured lattice, whose grains are 1.1 d apart with few contacts: a step there costs
  about a tenth of a settled or flowing fill's (the phase factor printed), but both hoppers
  are in that same state, and their grains see the same neighbourhoods (the big one is the
  small one twice over along its periodic depth), so the ratio is taken to hold for the
  whole run.

CPU seconds are those of this process (one engine thread by default, as the series ran); the
machine is a 2-core VM shared with other jobs, so wall seconds exceed them.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

from benchmarks import hopper_series as S

#: The series' width the big hopper takes [mean diameters], and its depth factor [-].
WIDTH = 40.0
DEPTH_FACTOR = 2.0


def big_test():
    """The series' B = 40 d run with its depth doubled (module docstring)."""
    t = S.test_of(WIDTH, 1)
    return replace(t, depth=DEPTH_FACTOR * t.depth)


def _build(test, threads: int):
    from engine.hopper.driver import HopperRun

    t0 = time.perf_counter()
    run = HopperRun(test, threads=threads)  # its kernel compiled or loaded: set-up
    return run, time.perf_counter() - t0


def _timed(run, steps: int) -> tuple[float, float]:
    """(wall, CPU) seconds of ``steps`` more steps of ``run``."""
    w0, c0 = time.perf_counter(), time.process_time()
    run.sim.run(steps)
    return time.perf_counter() - w0, time.process_time() - c0


def measure(steps: int = 400, threads: int = 1, repeats: int = 3) -> dict:
    """The measurements and the projection (module docstring): both hoppers built, then
    ``steps`` steps of each timed in turn, ``repeats`` times (the machine is shared: the
    median ratio of their CPU per step is taken)."""
    stored = S.stored(WIDTH, 1)
    if stored is None or not stored.ok:
        raise SystemExit(
            f"the series' run {S.key_name(WIDTH, 1)} is not stored: the projection scales it"
        )
    small, small_setup = _build(S.test_of(WIDTH, 1), threads)
    big, big_setup = _build(big_test(), threads)
    rows = []
    for _ in range(repeats):
        sw, sc = _timed(small, steps)
        bw, bc = _timed(big, steps)
        rows.append((sw, sc, bw, bc))
    ratios = sorted(r[3] / r[1] for r in rows)
    ratio = ratios[len(ratios) // 2]
    n = steps * repeats
    small_cpu = sum(r[1] for r in rows) / n
    big_cpu = sum(r[3] for r in rows) / n
    big_wall = sum(r[2] for r in rows) / n
    whole_steps = float(stored.scalars["steps"])
    whole_cpu = float(stored.extra["cpu_seconds"])
    cpu = whole_cpu * ratio
    return {
        "steps": steps,
        "repeats": repeats,
        "threads": threads,
        "small_particles": small.sim.n,
        "big_particles": big.sim.n,
        "small_dt": small.dt,
        "big_dt": big.dt,
        "setup": small_setup + big_setup,
        "small_cpu_per_step": small_cpu,
        "big_cpu_per_step": big_cpu,
        "big_wall_per_step": big_wall,
        "ratios": ratios,
        "ratio": ratio,
        "stored_steps": whole_steps,
        "stored_cpu": whole_cpu,
        "stored_settle": float(stored.scalars["settle_time"]),
        "stored_discharge": float(stored.scalars["discharge_time"]),
        "phase": (whole_cpu / whole_steps) / small_cpu,
        "projected_cpu": cpu,
        "projected_wall": cpu * big_wall / big_cpu,
    }


def report(m: dict) -> str:
    n = m["steps"]
    return "\n".join(
        [
            f"big hopper: {m['big_particles']} particles, dt {m['big_dt']:.4g} s; stored run "
            f"{S.key_name(WIDTH, 1)}'s hopper: {m['small_particles']} particles, dt "
            f"{m['small_dt']:.4g} s (set-up of both {m['setup']:.0f} s)",
            f"{m['repeats']} x {n} steps of each from the poured lattice, "
            f"{m['threads']} engine thread(s): CPU per step {1e3 * m['big_cpu_per_step']:.2f} "
            f"ms (big), {1e3 * m['small_cpu_per_step']:.2f} ms (stored run's); ratios "
            + ", ".join(f"{r:.3f}" for r in m["ratios"])
            + f", median {m['ratio']:.3f} "
            f"(particles {m['big_particles'] / m['small_particles']:.3f})",
            f"stored run: {m['stored_steps']:.0f} steps (settling {m['stored_settle']:.3g} s, "
            f"discharge {m['stored_discharge']:.3g} s) in {m['stored_cpu']:.0f} CPU s = "
            f"{1e3 * m['stored_cpu'] / m['stored_steps']:.1f} ms per step, "
            f"{m['phase']:.1f} x its lattice steps' cost",
            f"projected whole run of the big hopper: {m['stored_cpu']:.0f} CPU s x "
            f"{m['ratio']:.3f} = {m['projected_cpu']:.0f} CPU s ({m['projected_cpu'] / 60:.0f} "
            f"min) over {m['stored_steps']:.0f} steps; at this measurement's wall/CPU ratio "
            f"{m['projected_wall'] / 60:.0f} min of wall time",
        ]
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=400, help="steps timed (default 400)")
    p.add_argument("--threads", type=int, default=1, help="engine threads (default 1)")
    p.add_argument("--repeats", type=int, default=3, help="timed turns of each (default 3)")
    a = p.parse_args(argv)
    if a.steps < 1 or a.threads < 1 or a.repeats < 1:
        p.error("--steps, --threads and --repeats take a whole number >= 1")
    m = measure(a.steps, a.threads, a.repeats)
    print(report(m))
    return 0 if math.isfinite(m["projected_cpu"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
