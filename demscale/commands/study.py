"""``demscale study``: a scaling study from a JSON file, run here with the engine, its
results written into a folder (summary.json, results.h5, plots, curves, snapshots).

:func:`study_from_file` is the command as a function of typed arguments; ``calibrate
--then-study`` calls it too.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..options import (
    CLI_EXTRA,
    ERROR,
    add_backend,
    add_out,
    add_quiet,
    add_workers,
    attempt,
    command,
    lacks_extra,
    workers_error,
)

STUDY_HELP = """\
Run every run of the study in SPEC.json with the engine, here (no service needed), with a
progress bar per run and one for the whole study. Writes into DIR:

  summary.json          the table (one row per run), groups, verdicts, failed runs, units
  results.h5            curves, scalars and particle positions of every run (HDF5; the
                        layout of the job service's result files, docs/SERVICE.md)
  plots/*.png           stress-strain, porosity, coordination, unconfined, error vs time
  curves/<run>.csv      every run's curves, a row per sample, units in the headings
  snapshots/<run>/      particles.vtkhdf and contacts.vtkhdf (ParaView 5.12+; one time step
                        per stage end), particles.pvd and contacts.pvd (any ParaView, meshio:
                        one .vtu file per time step) and a PNG section per stage

SPEC.json holds an engine.StudySpec: "reference" (a preset name and overrides, or every
field of a uniaxial test), "coarse_radii" [m], "rules" (names such as "paper" or objects
with stiffness_exponent, adhesion_exponent and adhesive_exponent), "seeds",
"reference_seeds", "tolerances".
examples/quick_study.json is one (7 runs of at most 286 particles: two reference seeds,
each again at half the time step and loading rate as the protocol check, two coarse
variants and their resolution control).

A shear study (docs/SHEAR.md): a "reference" with "type": "ShearTest" and the fields of an
engine.ShearTest (its pair law required), or --shear TEST.json: the shear test in TEST.json
becomes the reference of the study in SPEC.json (same radii, rules and seeds, each shear
metric at its default tolerance; a reference in SPEC.json must have the shear test's
radius). It judges the yield locus, sigma_1, sigma_c, ffc and bulk density; plots/ then
holds yield_locus, preshear, error_vs_runtime (and resolution), curves/ the shear stages,
and no snapshots are written (the shear stages keep none). It runs on the CPU.

A hopper study (docs/HOPPER.md): a "reference" with "type": "HopperTest" and the fields of
an engine.HopperTest (its pair law required; give fill_height, not particles, so that a
coarse run fills the same hopper). It judges the discharge number and bulk density;
curves/ holds the discharge, plots/ error_vs_runtime (and resolution), no snapshots. It
runs on the CPU.

Exit status: 0 every run finished; 1 some run failed (what finished is written; the
failures are in summary.json) or no reference run finished; 2 the spec is not valid."""


def add_commands(sub) -> None:
    """``study`` on the ``demscale`` parser's subparsers ``sub``."""
    p = command(sub, "study", "run a scaling study from a JSON file, here", STUDY_HELP, study)
    p.add_argument("spec", metavar="SPEC.json", help="the study (an engine.StudySpec as JSON)")
    add_out(p)
    add_workers(
        p,
        "runs side by side in N processes (one core each; default 1: one "
        "run at a time, the engine using the cores it wants); on the cuda backend N "
        "threads sharing the GPU, a CUDA stream each",
    )
    p.add_argument(
        "--details",
        action="store_true",
        help="print each verdict's full reason and what would decide it",
    )
    p.add_argument(
        "--decide",
        action="store_true",
        help="add seeds where a verdict is undecided (the spec's decide: its "
        "max_seeds, max_reference_seeds, rounds and budget apply)",
    )
    p.add_argument(
        "--budget",
        type=float,
        default=None,
        metavar="PARTICLE_STEPS",
        help="with --decide: most particle-steps of the added runs",
    )
    p.add_argument(
        "--shear",
        metavar="TEST.json",
        default=None,
        help="judge the study on the shear test in TEST.json (engine.ShearTest's fields, its "
        "pair_law required): it becomes the reference, with the spec's radii, rules and seeds",
    )
    p.add_argument(
        "--no-snapshots",
        dest="snapshots",
        action="store_false",
        help="do not write the ParaView snapshots and PNG sections",
    )
    add_quiet(p, "no progress bars (the runs' results are still printed)")
    add_backend(p)


def study(args) -> int:
    """``demscale study``: run the study, write summary, HDF5, plots and snapshots."""
    return study_from_file(
        Path(args.spec),
        Path(args.out),
        workers=args.workers,
        details=args.details,
        decide=args.decide,
        budget=args.budget,
        shear=None if args.shear is None else Path(args.shear),
        snapshots=args.snapshots,
        quiet=args.quiet,
        backend=args.backend,
    )


def _read_spec(spec_path: Path, shear, decide: bool, budget: float | None):
    """The study in ``spec_path`` planned (:func:`engine.plan`), on the shear test
    ``shear`` where one is given; ``decide`` and ``budget`` set over the file's. Raises
    what reading, the request's rules (engine.core.inputs) or the engine refuse."""
    import engine
    import engine.study.spec
    from engine.core.inputs import check_study_json

    body = json.loads(spec_path.read_text())
    if isinstance(body, dict) and shear is not None and "reference" not in body:
        body["reference"] = {"type": "ShearTest", **shear.to_dict()}
        shear = None  # the study's own reference now
    check_study_json(body)  # the same rules as the service's (a reference, its pair law)
    if decide and isinstance(body, dict):
        body["decide"] = True
    if budget is not None and isinstance(body, dict):
        body["budget"] = budget
    spec = engine.StudySpec.from_dict(body)
    if shear is not None:  # the same study on the shear test (engine.study.spec.on_test)
        spec = engine.study.spec.on_test(spec, shear)
    return engine.plan(spec)  # planned once


def study_from_file(
    spec_path: Path,
    out: Path,
    *,
    workers: int = 1,
    details: bool = False,
    decide: bool = False,
    budget: float | None = None,
    shear: Path | None = None,
    snapshots: bool = True,
    quiet: bool = False,
    backend: str | None = None,
) -> int:
    """Run the study in the JSON file ``spec_path`` and write its results into ``out``
    (created): ``workers`` runs side by side (spawned processes; on the cuda backend
    threads in this process, a CUDA stream each: engine.cuda.batch), ``details`` the verdicts'
    reasons printed, ``decide`` and ``budget`` (particle-steps) over the file's, the study
    judged on the shear test in the file ``shear``, ``snapshots`` written, no bars when
    ``quiet``, the engine on ``backend`` (None: DEMSCALE_BACKEND). Returns the exit status:
    0 every run finished, 1 some run failed or no reference run finished, 2 the input is not
    valid or the ``cli`` extra is missing."""
    if lacks_extra("study", CLI_EXTRA, "cli"):
        return 2
    import concurrent.futures as cf
    import multiprocessing as mp
    import os

    from rich.console import Console

    import engine
    from engine.io.curves import write_curves_csv
    from engine.io.store import save_study
    from engine.io.vtkhdf import save as save_snapshots
    from engine.study.kinds import kind_of

    from ..progress import StudyBars
    from ..report import study_summary, summary_text, write_json

    console = Console(stderr=True)
    shear_test = why = None
    if shear is not None:
        shear_test, why = attempt(
            lambda: _shear_test(shear),
            f"--shear: cannot read {shear}",
            f"--shear {shear} is not a valid shear test",
        )
    if why is None:
        study, why = attempt(
            lambda: _read_spec(spec_path, shear_test, decide, budget),
            f"cannot read the spec {spec_path}",
            f"the spec {spec_path} is not valid",
        )
    if why is None:
        why = workers_error(workers)
    if why is not None:
        console.print(why, **ERROR)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    spec, planned = study.spec, study.runs
    console.print(
        f"{spec_path.name}: {len(planned)} runs, "
        f"{sum(p.test.n_particles for p in planned)} particles in all, about "
        f"{study.estimated_particle_steps():.3g} particle-steps; writing to {out}"
    )
    snapshot_paths: dict[str, list[Path]] = {}
    curve_paths: dict[str, Path] = {}

    with StudyBars(planned, console, enabled=not quiet) as bars:

        def on_run(key, outcome) -> None:
            bars.finished(key, outcome)
            if isinstance(outcome, str):
                return
            curve_paths[key] = write_curves_csv(outcome, out / "curves" / f"{key}.csv")
            if snapshots and kind_of(outcome).snapshots:
                snapshot_paths[key] = save_snapshots(outcome, out / "snapshots" / key, key)

        try:
            if workers > 1:
                named = backend or os.environ.get("DEMSCALE_BACKEND") or ""
                if named.strip().lower() == "cuda":  # side by side on the card, a stream each
                    from engine.cuda.batch import StreamExecutor

                    pool = StreamExecutor(workers)
                else:
                    pool = cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"))
                with pool:
                    result = engine.run_study(
                        study, progress=bars.update, executor=pool, on_run=on_run, backend=backend
                    )
            else:
                result = engine.run_study(
                    study, progress=bars.update, on_run=on_run, backend=backend
                )
        except engine.RunFailed as e:
            console.print(f"[red]{e}[/red]: no reference run finished, nothing to compare")
            return 1
        except engine.ParameterError as e:  # e.g. a shear study on --backend cuda
            console.print(f"the study cannot run: {e}", **ERROR)
            return 2

    h5 = save_study(out / "results.h5", spec_path.stem, result)
    plots = result.save_plots(out / "plots")
    result_summary = result.to_summary()
    files = {"results": h5, "plots": plots, "curves": curve_paths, "snapshots": snapshot_paths}
    write_json(out / "summary.json", study_summary(spec, result_summary, out, files))
    # the same report as the main job's (demscale.report), from the same summary: the
    # answer first, a line per verdict (--details: the reasons), then the tables
    console.print(
        summary_text(result_summary, details=details),
        soft_wrap=True,
        markup=False,
        highlight=False,
    )
    console.print(
        f"wrote {out / 'summary.json'}, {h5}, {len(plots)} plots"
        + (
            f", snapshots of {len(snapshot_paths)} runs in {out / 'snapshots'}"
            if snapshot_paths
            else ""
        )
    )
    if result.failed:
        console.print(
            f"[red]{len(result.failed)} runs failed:[/red] "
            + "; ".join(f"{k}: {v}" for k, v in result.failed.items())
        )
        return 1
    return 0


def _shear_test(path: Path):
    """The :class:`engine.ShearTest` in the JSON file ``path`` (its fields; a ``"type"``, if
    given, must be "ShearTest"; its pair law required, engine.core.inputs)."""
    import dataclasses

    import engine
    from engine.core.inputs import check_test_json
    from engine.core.records import from_dict

    raw = json.loads(path.read_text())
    if not isinstance(raw, dict):
        raise ValueError("a JSON object of engine.ShearTest's fields is needed")
    kind = raw.pop("type", "ShearTest")
    if kind != "ShearTest":
        raise ValueError(f'type = {kind!r}: a shear test is "ShearTest"')
    study_fields = sorted(set(raw) & {f.name for f in dataclasses.fields(engine.StudySpec)})
    if study_fields:  # e.g. the study's own spec given twice
        raise ValueError(
            f"it has the study fields {study_fields}: --shear takes one shear test's fields "
            "(engine.ShearTest's: cell, pair_law, normal_stresses, ...), the study's design "
            "is SPEC.json"
        )
    check_test_json({"type": kind, **raw}, "")  # pair_law: required
    return from_dict(engine.ShearTest, raw, "ShearTest")
