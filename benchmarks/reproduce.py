"""Reproduction of Thakur et al. (DEM 6, 2013) and docs/VALIDATION.md.

    python -m benchmarks.reproduce --scale paper --workers 2   # the seed's scale (hours)
    python -m benchmarks.reproduce --scale paper --report      # report from stored runs only
    python -m benchmarks.reproduce --scale quick               # smoke run (minutes)
    python -m benchmarks.reproduce --scale paper --protocol default --adopt \
        benchmarks/results/paper/protocol                      # the claims at the default protocol

(a) cohesionless bed: R_ref = 2.5 mm against 2 R_ref, stiffness unscaled (a = 0) against
    linearly scaled (a = 1); confined stages only (a cohesionless sample has no unconfined
    strength to compare);
(b) cohesive bed (f0 = -0.8 N at R_ref): R = 3.75 and 5 mm with stiffness ~ R and adhesion
    exponent b = 1, 2, 3.
(c), (d) the same two experiments with the non-linear EEPA law at n = 1.5
    (K1 = 5e5 N/m^1.5, K2 = 2.5e6 N/m^1.5: the force of the seed's K1 = 5e3 N/m at an
    overlap of 0.04 R) under the stress-similarity rule (K ~ R^(2-n) = R^0.5, f0 ~ R^2) and
    the seed's linear-stiffness rule (K ~ R, f0 ~ R^2): issue 13's question of how to
    coarse-grain a non-linear adhesive law.
Three reference seeds and two seeds per coarse variant. At the quick scale (c) and (d) take
six per coarse variant, whose first quick-scale runs showed that two 286-particle beds (5
diameters thick) scatter too much to decide (loading stiffness 297 and 704 kPa for one rule):
a coarse run costs about a thirteenth of a reference, so six cost less than half a reference
and together hold about as many particles as one reference at s = 2 (the verdict rule is
unchanged). At the paper scale a coarse bed holds 2,578 particles (9 times as many, in a
cell as thick, 5 diameters, but 3 times as wide and tall), so two seeds per variant, as in
(a) and (b); (d) is run there at 2 R_ref only, for cost: an EEPA
n = 1.5 step costs 1.34x a bilinear one (benchmarks/eepa_cost.py), a cohesive paper-scale
reference about 1e10 particle-steps, and a 3.75 mm coarse run 3e9.
Every finished run is stored at once as ``benchmarks/results/<scale>/<experiment>/<run>.h5``
(:mod:`engine.io.store`); a rerun resumes with the runs not yet stored (a run cut off
resumes from its checkpoint in ``.checkpoints/`` beside them), and ``--report``
recomputes every metric, verdict and figure from the stored curves. ``--scale paper`` writes
docs/VALIDATION.md and docs/figures/; ``--scale quick`` writes docs/VALIDATION_quick.md (the
smoke-test scale). ``--protocol default`` runs the same experiments at the default protocol
of new studies (docs/PROTOCOL.md), stored in ``benchmarks/results/<scale>_default/`` and
reported in docs/VALIDATION_<scale>_default.md; ``--adopt DIR`` first copies into the store
every run stored in DIR whose test is a run of the study (the protocol benchmark's runs of
experiment (b) at the default protocol), so that none is run twice.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import multiprocessing as mp
import time
from pathlib import Path

import benchmarks.experiments as _experiments
import engine
from benchmarks.checks import Ticker
from benchmarks.experiments import (  # noqa: F401  (names of this module before the split)
    COARSE_SEEDS,
    DECIDE,
    EEPA_COARSE_RADII,
    EEPA_COARSE_SEEDS,
    EXPERIMENTS,
    PROTOCOLS,
    REFERENCE_SEEDS,
    ROOT,
    STORE,
    R,
    experiments,
    judged_experiments,
    label,
    store_dir,
)
from engine.io.store import completed_runs, load_all, save_run, stored_code, stored_machine
from engine.study.plan import plan_runs, stored_plan_runs


def stored_runs(spec: engine.StudySpec, directory: Path) -> dict:
    """Stored outcomes whose test is exactly the planned one (others are rerun)."""
    done, stale = completed_runs(spec, directory)
    for k in stale:
        print(f"  {k}: stored with other parameters, will run again", flush=True)
    return done


def all_stored_runs(spec: engine.StudySpec, directory: Path) -> dict:
    """Every stored run of the study's variants and reference whose test is exactly the
    planned one with its seed: the planned runs and any added ones, whichever rule added
    them (the report judges the stored runs as they are, engine.study.plan.stored_plan_runs)."""
    done = stored_runs(spec, directory)
    for p in stored_plan_runs(spec, [k.stem for k in sorted(Path(directory).glob("*.h5"))]):
        if p.key in done:
            continue
        outcome = load_all(directory, [p.key]).get(p.key)
        if outcome is not None and (isinstance(outcome, str) or outcome.test == p.test):
            done[p.key] = outcome
    return done


def _ticker() -> Ticker:
    """A study's progress line (one run at a time) at most once a minute."""
    return Ticker(
        lambda pr, _: (
            f"    {pr.run_key}: {pr.stage}, t = {pr.time:.3f} s simulated, "
            f"study {100 * pr.fraction:.1f} % done"
        )
    )


SKIPPED = "skipped by --runs"


def select(spec: engine.StudySpec, stored: dict, runs: list[str] | None) -> tuple[dict, list[str]]:
    """(outcomes to hand to run_study as done, keys to run): the planned runs not stored,
    and with ``runs`` only those of them named there (every other one counts as done, with
    the text ``SKIPPED``, for this call)."""
    done = dict(stored)
    if runs:
        done = {**{p.key: SKIPPED for p in plan_runs(spec, stored)[0] if p.key not in runs}, **done}
    return done, [p.key for p in plan_runs(spec, done)[0] if p.key not in done]


def codes_of(directory: Path) -> dict:
    """Run key -> the code that stored it (engine.io.store.stored_code; None where not
    recorded)."""
    return {p.stem: stored_code(p) for p in sorted(directory.glob("*.h5"))}


def machines_of(directory: Path) -> dict:
    """Run key -> the machine that stored it (None where not recorded)."""
    return {p.stem: stored_machine(p) for p in sorted(directory.glob("*.h5"))}


def adopt(spec: engine.StudySpec, directory: Path, sources: list[Path]) -> list[str]:
    """Copy into ``directory`` each run stored under ``sources`` whose test is a run of the
    study (a planned run, or one of its variants or its reference with another seed, up to
    :data:`DECIDE`'s ``max_seeds``) and is not stored there yet, named by its run key."""
    import shutil

    from engine.io.store import load_run

    stems = {p.key.rpartition("-s")[0] for p in engine.plan(spec).runs}
    keys = [f"{st}-s{k}" for st in sorted(stems) for k in range(1, DECIDE["max_seeds"] + 1)]
    by_test = {p.test: p.key for p in stored_plan_runs(spec, keys)}
    done = []
    for src in sources:
        for path in sorted(Path(src).glob("*.h5")):
            run = load_run(path)
            key = None if isinstance(run, str) else by_test.get(run.test)
            if key is None or (directory / f"{key}.h5").exists():
                continue
            directory.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, directory / f"{key}.h5")
            done.append(f"{key} <- {path}")
    return done


def run(
    scale: str,
    workers: int,
    only: list[str] | None,
    runs: list[str] | None = None,
    protocol: str = "seed",
) -> None:
    specs = experiments(scale, protocol)
    for name in only or specs:
        spec = specs[name]
        d = store_dir(scale, name, protocol)
        stored = stored_runs(spec, d)
        if runs:
            unknown = set(runs) - {p.key for p in plan_runs(spec, stored)[0]}
            if unknown and len(only or specs) == 1:
                raise SystemExit(f"--runs: {name} has no run {', '.join(sorted(unknown))}")
        done, todo = select(spec, stored, runs)
        print(
            f"{name}: {len(stored)} runs stored, {len(todo)} to run: {', '.join(todo)}", flush=True
        )
        if not todo:
            continue
        t0 = time.perf_counter()
        ckpt = d / ".checkpoints"  # a run cut off resumes there (not tracked)

        def on_run(key, outcome, d=d, t0=t0):
            save_run(d / f"{key}.h5", outcome, keep_particles=False)
            what = (
                outcome
                if isinstance(outcome, str)
                else f"{outcome.scalars['particles']:.0f} particles, "
                f"{outcome.scalars['wall_time']:.0f} s"
            )
            print(f"  [{time.perf_counter() - t0:7.0f} s] {key}: {what}", flush=True)

        try:
            if workers > 1:
                ctx = mp.get_context("spawn")
                with cf.ProcessPoolExecutor(workers, mp_context=ctx) as pool:
                    engine.run_study(
                        spec, executor=pool, completed=done, on_run=on_run, checkpoints=ckpt
                    )
            else:
                engine.run_study(spec, _ticker(), completed=done, on_run=on_run, checkpoints=ckpt)
        except engine.RunFailed:
            if not runs:
                raise
            # with --runs the skipped references count as failed, so the study cannot be
            # judged here; every run asked for is stored, and --report judges them all


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", choices=("paper", "quick"), default="quick")
    ap.add_argument(
        "--protocol",
        choices=PROTOCOLS,
        default="seed",
        help="the seed's protocol (the stored reproduction) or the default of new studies",
    )
    ap.add_argument(
        "--adopt",
        nargs="*",
        type=Path,
        default=[],
        metavar="DIR",
        help="folders of stored runs to take instead of running them where the test matches",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=1,
        help="runs side by side (a process pool, one engine thread each); 1: one "
        "run at a time with the engine's own threads",
    )
    ap.add_argument(
        "--report", action="store_true", help="only recompute the report from the stored runs"
    )
    ap.add_argument(
        "--only",
        nargs="*",
        choices=EXPERIMENTS,
        help="experiments to run, in this order (default: all)",
    )
    ap.add_argument(
        "--runs",
        nargs="*",
        metavar="KEY",
        help="only these runs, by key (e.g. ref-s3 r5mm-similarity-s2); "
        "for running a study's runs on several machines",
    )
    ap.add_argument(
        "--store",
        type=Path,
        default=None,
        help="folder of the stored runs (default: benchmarks/results)",
    )
    args = ap.parse_args(argv)
    if args.store is not None:  # where experiments.store_dir looks
        _experiments.STORE = args.store
    t0 = time.perf_counter()
    if args.adopt:
        for name, spec in experiments(args.scale, args.protocol).items():
            if not args.only or name in args.only:
                d = store_dir(args.scale, name, args.protocol)
                for line in adopt(spec, d, args.adopt):
                    print(f"{name}: adopted {line}", flush=True)
    if not args.report:
        run(args.scale, args.workers, args.only, args.runs, args.protocol)
        if args.runs:  # a share of a study: the report waits for all of its runs
            print(
                f"stored the runs asked for ({time.perf_counter() - t0:.0f} s); no report written"
            )
            return 0
    from benchmarks.report import write_report

    specs = judged_experiments(args.scale, args.protocol)
    dirs = {name: store_dir(args.scale, name, args.protocol) for name in specs}
    path = write_report(
        args.scale,
        {name: (spec, all_stored_runs(spec, dirs[name])) for name, spec in specs.items()},
        machines={name: machines_of(d) for name, d in dirs.items()},
        codes={name: codes_of(d) for name, d in dirs.items()},
        protocol=args.protocol,
    )
    print(f"wrote {path} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
