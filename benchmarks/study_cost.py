"""Cost of a scaling study's runs: the quick reference run and the R -> 2R cost ratios.

    python -m benchmarks.study_cost            # quick preset, cohesive law (a few minutes)

Runs the ``quick`` preset (cohesive law of the engine benchmark, f0 = -0.4 N) at R = 2.5 mm,
then at 2R with the paper's rule (stiffness ~ R, adhesion ~ R^2) at the same time step and at
a time step scaled with R. Prints wall time (kernel compilation excluded), steps, particles,
particle-steps per second and the cost ratios against the reference, with the expectation of
issue 3: at least 8x at fixed dt (8x fewer particles) and 14x at scaled dt (also half the
steps).
"""

from __future__ import annotations

import sys

import engine
from benchmarks.checks import report

R = 2.5e-3
LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)


def main(argv=None) -> int:
    ref = engine.preset("quick", pair_law=LAW)
    # warm the kernels (compile or load from the disk cache) outside the timed runs
    engine.run_uniaxial(engine.preset("quick", pair_law=LAW, cell=(0.015, 0.015, 0.03),
                                      unconfined=True, output_interval=2e-3))
    runs = {"reference R": ref}
    paper = engine.ScalingRule.named("paper")
    runs["2R, fixed dt"] = paper.apply(ref, 2 * R, ref.dt)
    runs["2R, scaled dt"] = engine.ScalingRule.named("paper", dt="scaled").apply(ref, 2 * R,
                                                                                ref.dt)
    rows = []
    for name, test in runs.items():
        res = engine.run_uniaxial(test)
        s = res.scalars
        rows.append((name, int(s["particles"]), int(s["steps"]), s["dt"], s["wall_time"],
                     s["particle_steps"] / s["wall_time"], s["unconfined_strength"]))
        print(f"  {name:14s} {rows[-1][1]:5d} particles {rows[-1][2]:7d} steps "
              f"{s['wall_time']:7.1f} s", flush=True)
    base = rows[0][4]
    print("\n| run | particles | steps | dt [s] | wall time [s] | particle-steps/s | "
          "UCS [Pa] | cost ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, n, steps, dt, wall, rate, ucs in rows:
        print(f"| {name} | {n} | {steps} | {dt:.2g} | {wall:.1f} | {rate:.3e} | {ucs:.0f} | "
              f"{base / wall:.1f}x |")
    fixed, scaled = base / rows[1][4], base / rows[2][4]
    checks = [("2R at fixed dt >= 8x cheaper", fixed >= 8.0),
              ("2R at scaled dt >= 14x cheaper", scaled >= 14.0)]
    return report(checks)


if __name__ == "__main__":
    sys.exit(main())
