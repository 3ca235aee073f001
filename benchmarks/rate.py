"""Rate independence of the reference: the cohesive reference of experiment (b) at half and
at double its platen speed, judged against the stored references by the verdict rule.

    python -m benchmarks.rate --workers 2     # the 6 runs not yet stored (quick scale)
    python -m benchmarks.rate --report        # docs/RATE_quick.md from the stored runs

A quasi-static test should not depend on the platen speed: the strain rate enters through
the inertial number I = rate d sqrt(rho / sigma), which the runs record (its largest value
over the confined stages, ``max_inertial_number``), and an inertial number far below 1e-3 is
the usual criterion. That criterion is an average; this benchmark shows the claim instead.
The quick scale (2,292 particles, 10 diameters thick) is used: a paper-scale reference takes
35-100 min on 2 cores and this check needs six of them (half speed doubles a run's
compression stages). Speeds 0.5x and 2x of the reference test's platen speed, seeds 1-3,
each stored as it finishes in ``benchmarks/results/quick/rate/``; the 1x runs are the stored
references of experiment (b) (``benchmarks/results/quick/b_cohesive/ref-s*.h5``). Each speed
is judged against them with :func:`engine.study.judge.judge_groups` at the study's
tolerances and confidence: ``equivalent`` means the reference's properties do not depend on
the platen speed within tolerance over a factor of 4 in rate.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import multiprocessing as mp
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.checks import publish
from engine.io.store import load_run, save_run
from engine.study.judge import judge_groups
from engine.study.metrics import metric_names, metric_values
from engine.study.plan import reference_test as study_reference
from engine.uniaxial.driver import run_uniaxial

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "quick" / "rate"
B_STORE = ROOT / "benchmarks" / "results" / "quick" / "b_cohesive"
REPORT = ROOT / "docs" / "RATE_quick.md"
SEEDS = (1, 2, 3)
#: Platen speeds as multiples of the reference test's, and their names.
SPEEDS = {"half": 0.5, "double": 2.0}


def study():
    from benchmarks.experiments import experiments

    return experiments("quick")["b_cohesive"]


def speed_test(name: str, seed: int):
    """The reference test of experiment (b) (quick scale, as its study runs it) at
    ``SPEEDS[name]`` times its platen speed, packing ``seed``."""
    ref = study_reference(study())
    return replace(ref, seed=seed, platen_speed=SPEEDS[name] * ref.platen_speed)


def _run_one(name: str, seed: int) -> str:
    import numba

    numba.set_num_threads(1)
    key = f"{name}-s{seed}"
    path = STORE / f"{key}.h5"
    t0 = time.perf_counter()
    try:
        outcome = run_uniaxial(speed_test(name, seed))
    except Exception as e:  # stored as the run's error, as the studies do
        outcome = f"{type(e).__name__}: {e}"
    save_run(path, outcome, keep_particles=False)
    return f"{key}: {time.perf_counter() - t0:.0f} s"


def todo() -> list[tuple[str, int]]:
    out = []
    for name in SPEEDS:
        for seed in SEEDS:
            path = STORE / f"{name}-s{seed}.h5"
            if path.exists():
                old = load_run(path)
                if isinstance(old, str) or old.test == speed_test(name, seed):
                    continue
            out.append((name, seed))
    return out


def run(workers: int) -> None:
    STORE.mkdir(parents=True, exist_ok=True)
    jobs = todo()
    print(f"{len(jobs)} runs to make: {', '.join(f'{n}-s{s}' for n, s in jobs)}", flush=True)
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        for f in cf.as_completed([ex.submit(_run_one, n, s) for n, s in jobs]):
            print("  stored", f.result(), flush=True)


def report() -> str:
    spec = study()
    refs = [load_run(B_STORE / f"ref-s{s}.h5") for s in spec.reference_seeds]
    if any(isinstance(r, str) for r in refs):
        raise SystemExit("the stored references of experiment (b) are missing or failed")
    ref_test = study_reference(spec)
    for r, s in zip(refs, spec.reference_seeds):
        if r.test != replace(ref_test, seed=s):
            raise SystemExit(f"ref-s{s} was made with another test than the study's reference")
    names = metric_names(ref_test.unconfined)
    runs = {n: {} for n in SPEEDS}
    for name in SPEEDS:
        for seed in SEEDS:
            p = STORE / f"{name}-s{seed}.h5"
            if p.exists():
                runs[name][seed] = load_run(p)
    ok = {n: [r for r in rs.values() if not isinstance(r, str)] for n, rs in runs.items()}
    variants = {
        (ref_test.radius, name): [metric_values(r) for r in rs] for name, rs in ok.items() if rs
    }
    _, verdicts = judge_groups(spec, [metric_values(r) for r in refs], variants, names)
    lines = [
        "# Rate independence of the reference (quick scale)",
        "",
        "Generated by `python -m benchmarks.rate --report` from the stored runs "
        "(benchmarks/results/quick/rate/, the 1x runs: benchmarks/results/quick/b_cohesive/"
        "ref-s*.h5). The cohesive reference test of experiment (b) "
        f"({ref_test.n_particles} particles, {ref_test.thickness_diameters:g} diameters "
        f"thick, platen {1e3 * ref_test.platen_speed:g} mm/s) at half and double its platen "
        "speed, judged against the 1x references by the verdict rule (docs/PHYSICS.md "
        "section 7.1) at the study's tolerances. The quick scale stands in for the paper "
        "scale, where a reference takes 35-100 min on 2 cores.",
        "",
        "| platen speed | seeds | max inertial number | density | K load | K unload | "
        "coordination | strength | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    inertial = {"1x": [r.scalars["max_inertial_number"] for r in refs]}
    for name in SPEEDS:
        inertial[name] = [r.scalars["max_inertial_number"] for r in ok[name]]
    lines.append(
        f"| 1x (references) | {len(refs)} | {np.mean(inertial['1x']):.2e} | - | - | - | - | - | - |"
    )
    for v in verdicts:
        name = v["rule"]
        cells = []
        for m in v["metrics"]:
            if m["interval"] is None:
                cells.append(f"{100 * m['signed_error']:+.1f} %")
                continue
            lo, hi = m["interval"]
            cells.append(
                f"{100 * m['level_error']:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}] % "
                f"({m['verdict']})"
            )
        lines.append(
            f"| {SPEEDS[name]:g}x ({name}) | {v['seeds']} | {np.mean(inertial[name]):.2e} | "
            + " | ".join(cells)
            + f" | **{v['verdict']}** |"
        )
    failed = {f"{n}-s{s}": r for n, rs in runs.items() for s, r in rs.items() if isinstance(r, str)}
    missing = [f"{n}-s{s}" for n in SPEEDS for s in SEEDS if s not in runs[n]]
    lines.append("")
    for v in verdicts:
        lines.append(f"- {SPEEDS[v['rule']]:g}x: {v['verdict']}: {v['reason']}")
    for k, e in failed.items():
        lines.append(f"- {k} failed: {e}")
    if missing:
        lines.append(f"- not run yet: {', '.join(missing)} (`python -m benchmarks.rate`)")
    lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--report", action="store_true", help="only write the report")
    args = ap.parse_args(argv)
    if not args.report:
        run(args.workers)
    publish(REPORT, report())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
