"""A fill that does not blow up at b = 3: experiment (b)'s two failed seeds with a capped pour.

    python -m benchmarks.pour --workers 2     # the runs not yet stored (paper scale)
    python -m benchmarks.pour --report        # what they did (and docs/VALIDATION_capped.md)

At the paper scale two of experiment (b)'s b = 3 runs (r3.75mm-b3-s1, r5mm-b3-s1) stopped in
the fill with an overlap of half a radius: the cloud falls 0.6 m and reaches 3.4 m/s, and a
soft law whose adhesion grows as R^3 (f0 = -6.4 N at 5 mm against K1 = 1e4 N/m) lets the
clusters that form in the fall strike deeper than the overlap limit. ``UniaxialTest.
pour_speed`` caps every particle's speed during the fill, as a sieve or a fluid would. This
benchmark runs those two tests again with ``pour_speed`` = :data:`POUR_SPEED` (the speed of a
free fall from 5 cm, chosen as a gentle fill before any run, not tuned), storing each in
``benchmarks/results/paper/pour/``. A capped pour changes every run's packing, so it decides
nothing about the rule by itself: experiment (b) judged with it needs all its runs redone
with the same pour (its references included): ``--study`` runs it, stored run by run in
``benchmarks/results/paper/b_cohesive_capped/`` and resumed across sessions (31 runs, its
pilot and the seeds its two-stage design added: 10 h of one-core wall time summed over its
runs, on the two machines its column 'ran on' names); ``--report`` lists its runs and those
in flight and judges it (claim (c) included); docs/VALIDATION.md judges it beside (b)
(``python -m benchmarks.reproduce --scale paper --report``).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import multiprocessing as mp
import time
from dataclasses import replace
from pathlib import Path

from benchmarks.experiments import CAPPED, POUR_SPEED, capped_study, store_dir
from engine.io.store import load_run, save_run
from engine.study.plan import plan

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "paper" / "pour"
#: The runs of experiment (b) that blew up in the free-fall fill.
FAILED = ("r3.75mm-b3-s1", "r5mm-b3-s1")


def capped_test(key: str):
    """The planned test of run ``key`` of experiment (b) at the paper scale, with the capped
    pour."""
    from benchmarks.experiments import experiments

    p = next(p for p in plan(experiments("paper")["b_cohesive"]).runs if p.key == key)
    return replace(p.test, pour_speed=POUR_SPEED)


#: Wall time between two checkpoints of a run in flight [s]: a paper-scale run takes longer
#: than a session, and one cut off resumes from its last checkpoint in the next.
CHECKPOINT_INTERVAL = 300.0


def _run_and_store(test, path: Path) -> str:
    """One run on one engine thread, stored at ``path`` (its error text where it fails, as
    the studies store it); a picklable task. While it runs it keeps a checkpoint beside
    ``path`` (``.checkpoints/<key>.ckpt``, not tracked by git), from which a run cut off (a
    session's end) resumes, bit for bit; the checkpoint goes once the run is stored."""
    import numba

    from engine.uniaxial.checkpoint import Checkpoint
    from engine.uniaxial.driver import run_uniaxial

    numba.set_num_threads(1)
    ckpt = Checkpoint(path.parent / ".checkpoints" / f"{path.stem}.ckpt", CHECKPOINT_INTERVAL)
    t0 = time.perf_counter()
    try:
        outcome = run_uniaxial(test, checkpoint=ckpt)
    except Exception as e:  # stored as the run's error, as the studies do
        outcome = f"{type(e).__name__}: {e}"
    save_run(path, outcome, keep_particles=False)
    ckpt.remove()
    resumed = "" if ckpt.resumed_steps is None else f", resumed at step {ckpt.resumed_steps}"
    return f"{path.stem}: {time.perf_counter() - t0:.0f} s{resumed}"


def _store_all(jobs: dict[Path, object], workers: int) -> None:
    """Run every (path -> test) not yet stored, side by side, each stored as it ends."""
    todo = {p: t for p, t in jobs.items() if not p.exists()}
    if not todo:
        return
    next(iter(todo)).parent.mkdir(parents=True, exist_ok=True)
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        for f in cf.as_completed([ex.submit(_run_and_store, t, p) for p, t in todo.items()]):
            print("stored", f.result(), flush=True)


def run(workers: int) -> None:
    _store_all({STORE / f"{k}.h5": capped_test(k) for k in FAILED}, workers)


def report() -> str:
    lines = [
        f"Capped pour ({POUR_SPEED:g} m/s) of the b = 3 runs that blew up in the free-fall fill "
        "(`python -m benchmarks.pour`):",
        "",
        "| run | fill | particles | steps | wall time [s] | UCS [kPa] |",
        "|---|---|---|---|---|---|",
    ]
    for key in FAILED:
        path = STORE / f"{key}.h5"
        if not path.exists():
            lines.append(f"| {key} | not run yet | - | - | - | - |")
            continue
        r = load_run(path)
        if isinstance(r, str):
            lines.append(f"| {key} | failed: {r} | - | - | - | - |")
            continue
        s = r.scalars
        ucs = s.get("unconfined_strength")
        lines.append(
            f"| {key} | settled | {s['particles']:.0f} | {s['steps']:.0f} | "
            f"{s['wall_time']:.0f} | {'-' if ucs is None else f'{ucs / 1e3:.2f}'} |"
        )
    return "\n".join(lines)


# ------------------------------------------------------------------ (b) with one capped pour
#: Where experiment (b) with the capped pour is stored, run by run.
STUDY_STORE = store_dir("paper", CAPPED)
#: Its run page, rewritten by every ``--report``.
DOC = ROOT / "docs" / "VALIDATION_capped.md"


def run_study(workers: int) -> None:
    """The runs of :func:`capped_study` not yet stored (resumable across sessions)."""
    import engine
    from engine.io.store import completed_runs

    spec = capped_study()
    STUDY_STORE.mkdir(parents=True, exist_ok=True)
    done, _ = completed_runs(spec, STUDY_STORE)

    def on_run(key, outcome):
        save_run(STUDY_STORE / f"{key}.h5", outcome, keep_particles=False)
        print("stored", key, flush=True)

    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        engine.run_study(spec, executor=ex, completed=done, on_run=on_run)


def run_keys(keys: list[str], workers: int) -> None:
    """Only these runs of :func:`capped_study`, planned or added by its design given the
    runs stored so far (a share to run where a whole study would not finish), each stored
    as it ends; keys already stored are skipped."""
    from benchmarks.reproduce import all_stored_runs
    from engine.study.plan import plan_runs

    spec = capped_study()
    stored = all_stored_runs(spec, STUDY_STORE) if STUDY_STORE.is_dir() else {}
    tests = {p.key: p.test for p in plan(spec).runs}
    tests.update({p.key: p.test for p in plan_runs(spec, stored)[0]})
    unknown = sorted(set(keys) - set(tests))
    if unknown:
        raise SystemExit(f"--runs: the capped study has no run {', '.join(unknown)}")
    _store_all({STUDY_STORE / f"{k}.h5": tests[k] for k in keys}, workers)


def in_flight(store: Path) -> list[str]:
    """One line per run cut off in flight (its checkpoint beside ``store``): how far it came,
    when the checkpoint was written, and whether this engine code would resume it (a
    checkpoint written by other engine code is not resumed: that run starts again)."""
    import datetime
    import pickle

    from engine.uniaxial.checkpoint import trajectory_digest

    out = []
    for path in sorted((store / ".checkpoints").glob("*.ckpt")):
        try:
            with open(path, "rb") as fh:
                stored = pickle.load(fh)
            d = stored["driver"]
            how = (
                f"{d.stage_now} {100 * d.stage_fraction:.0f} %, step {d.sim.steps}, "
                f"t = {d.sim.time:.3f} s"
            )
            code = "resumable" if stored.get("code") == trajectory_digest() else "other engine code"
        except Exception as e:  # a torn or foreign file: said, not fatal
            how, code = f"unreadable ({type(e).__name__})", "starts again"
        when = datetime.datetime.fromtimestamp(path.stat().st_mtime, datetime.UTC)
        out.append(
            f"- in flight: {path.stem}: {how} (checkpoint {when:%Y-%m-%d %H:%M} UTC, {code})"
        )
    return out


def study_report() -> str:
    """How far experiment (b) with the capped pour has come, and, once its references are
    stored, its verdicts and the claim (c) lines."""
    from engine.io.store import completed_runs
    from engine.study.plan import plan_runs

    spec = capped_study()
    done, _ = completed_runs(spec, STUDY_STORE) if STUDY_STORE.exists() else ({}, [])
    planned = plan_runs(spec, done)[0]
    lines = [
        "",
        f"Experiment (b) with every run filled at {POUR_SPEED:g} m/s "
        f"(`python -m benchmarks.pour --study`): {len(done)} of {len(planned)} planned runs "
        "stored.",
    ]
    lines += in_flight(STUDY_STORE)
    if not any(p.is_reference and p.key in done for p in planned):
        return "\n".join(lines)
    from benchmarks.report import claim_c, verdict_table
    from engine.study.results import assemble

    res = assemble(spec, planned, done)
    lines += ["", verdict_table(res), "", *[f"- {x}" for x in claim_c(res)]]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--report", action="store_true")
    ap.add_argument(
        "--study", action="store_true", help="run experiment (b) whole with the capped pour"
    )
    ap.add_argument(
        "--runs", nargs="*", metavar="KEY", help="with --study: only these of its planned runs"
    )
    args = ap.parse_args(argv)
    if not args.report:
        if args.study and args.runs:
            run_keys(args.runs, args.workers)
        elif args.study:
            run_study(args.workers)
        else:
            run(args.workers)
    text = report() + "\n" + study_report()
    print(text)
    DOC.write_text(
        "# Experiment (b) with a capped pour\n\n"
        "Generated by `python -m benchmarks.pour --report` from the runs stored in "
        "`benchmarks/results/paper/b_cohesive_capped/` (docs/PHYSICS.md, 'A capped pour'). "
        "The study is run share by share across sessions (`--study --runs ...`); "
        "[VALIDATION.md](VALIDATION.md) judges it in full beside experiment (b) with the "
        "free-fall fill (`python -m benchmarks.reproduce --scale paper --report`), this "
        "page says how far it has come.\n\n" + text + "\n"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
