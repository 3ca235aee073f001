"""Cost of a scaling study's runs: the quick reference run, the R -> 2R cost ratios, and a
study run side by side on a process pool against the same study run in process.

    python -m benchmarks.study_cost            # both parts (about 10 minutes on 2 cores)
    python -m benchmarks.study_cost --pool     # only the pool part

Runs the ``quick`` preset (cohesive law of the engine benchmark, f0 = -0.4 N) at R = 2.5 mm,
then at 2R with the paper's rule (stiffness ~ R, adhesion ~ R^2) at the same time step and at
a time step scaled with R. Prints wall time (kernel compilation excluded), steps, particles,
particle-steps per second and the cost ratios against the reference, with the expectation of
issue 3: at least 8x at fixed dt (8x fewer particles) and 14x at scaled dt (also half the
steps).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import multiprocessing as mp
import os
import sys
import time

import engine
from benchmarks.checks import report

R = 2.5e-3
LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)


def pool_speedup(workers: int = 2) -> list[tuple[str, bool]]:
    """Wall time of one study (four reference seeds and four coarse runs of a 50 x 50 x 50 mm
    cell: comparable runs) run in process against the same study on a ``workers``-process
    pool, in the same run; the tables must be identical."""
    ref = engine.preset("quick", protocol="seed", pair_law=LAW, cell=(0.05, 0.05, 0.05))
    spec = engine.StudySpec(
        reference=ref,
        coarse_radii=(3e-3,),
        rules=(engine.ScalingRule.named("paper"), engine.ScalingRule.named("unscaled")),
        reference_seeds=(1, 2, 3, 4),
        seeds=(1, 2),
        protocol_check=False,
    )
    engine.run_uniaxial(
        engine.preset("quick", protocol="seed", pair_law=LAW, cell=(0.015, 0.015, 0.015))
    )
    t0 = time.perf_counter()
    seq = engine.run_study(spec)
    t_seq = time.perf_counter() - t0
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
        # start the workers (and import the engine there) outside the timing
        [f.result() for f in [pool.submit(os.getpid) for _ in range(workers)]]
        t0 = time.perf_counter()
        par = engine.run_study(spec, executor=pool)
        t_par = time.perf_counter() - t0
    same = [
        {k: v for k, v in r.items() if k not in ("wall_time", "speedup")} for r in seq.table
    ] == [{k: v for k, v in r.items() if k not in ("wall_time", "speedup")} for r in par.table]
    n = len(engine.plan(spec).runs)
    print(
        f"\n| study ({n} runs, {ref.n_particles} particles per reference) | wall time [s] |"
        " ratio |\n|---|---:|---:|"
    )
    print(
        f"| in process (engine threads: one per {engine.core.config.PARTICLES_PER_THREAD:,} "
        f"particles) | {t_seq:.1f} | baseline |"
    )
    print(f"| process pool, {workers} workers x 1 thread | {t_par:.1f} | {t_seq / t_par:.2f}x |")
    print(f"load average during the run: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    return [
        (f"{workers}-worker pool >= 1.6x less wall time than in process", t_seq / t_par >= 1.6),
        ("pool table identical to the in-process table", same),
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pool", action="store_true", help="only the process-pool comparison")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    if args.pool:
        return report(pool_speedup(args.workers))
    ref = engine.preset("quick", protocol="seed", pair_law=LAW)
    # warm the kernels (compile or load from the disk cache) outside the timed runs
    engine.run_uniaxial(
        engine.preset(
            "quick", pair_law=LAW, cell=(0.015, 0.015, 0.015), unconfined=True, output_interval=2e-3
        )
    )
    runs = {"reference R": ref}
    paper = engine.ScalingRule.named("paper")
    runs["2R, fixed dt"] = paper.apply(ref, 2 * R, ref.dt)
    runs["2R, scaled dt"] = engine.ScalingRule.named("paper", dt="scaled").apply(ref, 2 * R, ref.dt)
    rows = []
    for name, test in runs.items():
        res = engine.run_uniaxial(test)
        s = res.scalars
        rows.append(
            (
                name,
                int(s["particles"]),
                int(s["steps"]),
                s["dt"],
                s["wall_time"],
                s["particle_steps"] / s["wall_time"],
                s["unconfined_strength"],
            )
        )
        print(
            f"  {name:14s} {rows[-1][1]:5d} particles {rows[-1][2]:7d} steps "
            f"{s['wall_time']:7.1f} s",
            flush=True,
        )
    base = rows[0][4]
    print(
        "\n| run | particles | steps | dt [s] | wall time [s] | particle-steps/s | "
        "UCS [Pa] | cost ratio |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, n, steps, dt, wall, rate, ucs in rows:
        print(
            f"| {name} | {n} | {steps} | {dt:.2g} | {wall:.1f} | {rate:.3e} | {ucs:.0f} | "
            f"{base / wall:.1f}x |"
        )
    fixed, scaled = base / rows[1][4], base / rows[2][4]
    checks = [
        ("2R at fixed dt >= 8x cheaper", fixed >= 8.0),
        ("2R at scaled dt >= 14x cheaper", scaled >= 14.0),
    ]
    return report(checks + pool_speedup(args.workers))


if __name__ == "__main__":
    sys.exit(main())
