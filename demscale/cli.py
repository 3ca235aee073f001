"""The ``demscale`` command line (argparse; progress bars with rich).

    demscale study SPEC.json --out DIR [--workers N]   run a scaling study here
    demscale run TEST.json --out DIR                    one uniaxial test, with snapshots
    demscale calibrate TARGETS.json --test T.json ...   a law fitted to laboratory data
    demscale export LAW.json [--radius R]               a law for LIGGGHTS, or as a table
    demscale serve [--host H] [--port P]                the job service's HTTP API
    demscale worker [--once]                            a worker of the job service

``demscale --help`` and the commands' own ``--help`` need only the engine; ``study`` needs
the ``cli`` extra (rich, h5py, matplotlib), ``serve`` and ``worker`` the ``service`` extra.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import sys
from pathlib import Path

from .report import summary_text

DESCRIPTION = """\
demscale: coarse-graining studies for cohesive DEM. How large can the particles be, and how
must the contact parameters scale with their size, before the bulk behaviour changes?

A study runs a fine reference (uniaxial test: fill, consolidation, unloading, unconfined
compression to failure) and coarser variants under scaling rules, then judges each variant
against the reference's seed-to-seed noise."""

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

Exit status: 0 every run finished; 1 some run failed (what finished is written; the
failures are in summary.json) or no reference run finished; 2 the spec is not valid."""

RUN_HELP = """\
Run one uniaxial test (fill, pre-compression, consolidation, unloading, release, unconfined
compression) with the engine, with a progress bar, and write into DIR:

  result.json           the test's parameters and its scalars (strength, stiffnesses,
                        porosity, ...) with their units
  curves.csv            every stage's curves, a row per sample, units in the headings
  snapshots/            particles.vtkhdf and contacts.vtkhdf with a time step at every stage
                        end and, with --snapshot-interval, every that many seconds of
                        simulated time (ParaView 5.12+ plays them as an animation), the
                        same as particles.pvd and contacts.pvd (one .vtu per time step: any
                        ParaView, meshio), and a PNG section per stage

TEST.json holds an engine.UniaxialTest: every field may be given, the others take their
defaults; {"preset": "quick"} (or "paper") starts from a named test. The snapshots are
written as they are taken, so a run that fails keeps those before the failure.

Exit status: 0 the test ran; 1 a stage failed (see the message); 2 the test is not valid."""

SERVE_HELP = """\
Start the job service's HTTP API (uvicorn; the same as `python -m service api`). By default
it also starts one worker process that runs the submitted studies. The studies page (status,
live progress, verdicts, plots) is at http://HOST:PORT/ and the API documentation at
http://HOST:PORT/docs.

Every request needs an API token: DEMSCALE_API_TOKEN (one token) or DEMSCALE_API_TOKEN_FILE
(one per line). On 127.0.0.1 without either, the server makes one, keeps it in
DIR/api-token and prints it, to paste into the studies page's login form (a token is never
put in a URL, where access logs and browser histories would keep it).
Settings come from DEMSCALE_* environment variables (docs/SERVICE.md); the options below set
the common ones."""

WORKER_HELP = """\
Start a worker of the job service (the same as `python -m service.worker`): it claims queued
studies from the service's database one at a time and runs them. Use it with
`demscale serve --no-worker` to run the API and the workers as separate processes; they
must share DEMSCALE_DATA_DIR (and DEMSCALE_DATABASE_URL, if set)."""


#: How an error is printed on the console: one line however long (a log or a test reads
#: it whole), red, and its text as it is (an engine field such as ``coarse_radii[0]`` is no
#: rich markup).
_ERROR = {"style": "red", "markup": False, "highlight": False, "soft_wrap": True}


def _missing(modules) -> list[str]:
    return [m for m in modules if importlib.util.find_spec(m) is None]


def _lacks_extra(command: str, modules, extra: str) -> bool:
    """Tell the user which extra ``command`` needs when one of ``modules`` is not
    installed; True then (the command exits with 2)."""
    missing = _missing(modules)
    if missing:
        print(
            f'demscale {command} needs {", ".join(missing)}: pip install "demscale[{extra}]"',
            file=sys.stderr,
        )
    return bool(missing)


def _strict_json(obj):
    """``obj`` with NaN and infinities as None and numpy scalars as Python numbers."""
    if isinstance(obj, dict):
        return {str(k): _strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_strict_json(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


class StudyBars:
    """The study's progress display (:class:`demscale.progress.StudyDisplay`: its bar with
    the fraction of the planned and added work, the runs done, the stage and the time left
    on a terminal; a line per event otherwise; nothing but the runs' results when not
    ``enabled``) with a bar per run. ``update`` is the study's progress callback;
    ``finished`` hears of each run's outcome. ``live``: draw bars (None: on a terminal)."""

    def __init__(self, planned, console, enabled: bool = True, live: bool | None = None):
        from engine.study.plan import cost_weights
        from engine.study.run import Eta

        from .progress import StudyDisplay

        self.planned = planned
        self.console = console
        self.weights = [float(w) for w in cost_weights(planned)]
        self.bases = [sum(self.weights[:i]) for i in range(len(planned))]
        self.display = StudyDisplay(console, live=live, quiet=not enabled)
        self.progress = self.display.progress
        self.study = self.display.study
        self.eta = Eta()
        self.width = max(len(p.key) for p in planned)
        self.runs = {
            p.key: self.progress.add_task(
                f"  {p.key:<{self.width}} {p.test.n_particles:>6} particles",
                total=1.0,
                stage="waiting",
                eta="",
            )
            for p in planned
        }

    def _task(self, key: str):
        """The bar of run ``key``; a run a study added (``decide``) gets one when it starts."""
        if key not in self.runs:
            self.runs[key] = self.progress.add_task(
                f"  {key:<{self.width}} (added)", total=1.0, stage="waiting", eta=""
            )
        return self.runs[key]

    def __enter__(self) -> StudyBars:
        self.display.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.display.__exit__(*exc)

    def update(self, p) -> None:
        """The study's progress callback (an :class:`engine.StudyProgress`)."""
        from engine.study.run import ADDED

        from .progress import State

        state = State(
            p.fraction,
            p.runs_done,
            p.n_runs,
            p.added,
            None if p.stage in (ADDED, "done") else p.run_key,
            p.stage,
            self.eta(p.fraction),
        )
        if p.stage == ADDED:  # a decide round's runs, said before any of them runs
            self.display.event(state, f"+ {p.message}")
            return
        self.display.update(state)
        if p.stage == "done":  # on an executor: a run has finished
            return
        i = p.run_index
        task = self._task(p.run_key)
        if p.run_fraction is not None:
            run_fraction = p.run_fraction
        elif i < len(self.planned) and self.planned[i].key == p.run_key:
            run_fraction = (p.fraction - self.bases[i]) / self.weights[i]
        else:  # an added run of a report without its own fraction: its stage only
            self.progress.update(task, stage=p.stage)
            return
        self.progress.update(task, completed=min(max(run_fraction, 0.0), 1.0), stage=p.stage)

    def finished(self, key: str, outcome) -> None:
        """A run ended with a :class:`engine.UniaxialResult` or an error text."""
        from dataclasses import replace

        task = self._task(key)
        # the run has its outcome: one more done than the last report counted
        state = self.display.state
        state = replace(state, runs_done=(state.runs_done or 0) + 1, run=None)
        if isinstance(outcome, str):
            self.progress.update(task, stage="failed")
            self._say(state, f"{key} failed: {outcome}", "red")
            return
        s = outcome.scalars
        self.progress.update(task, completed=1.0, stage="done")
        strength = s.get("unconfined_strength")
        extra = f", unconfined strength {strength:.4g} Pa" if strength is not None else ""
        if "cohesion" in s:  # a shear run: its yield locus
            extra = (
                f", cohesion {s['cohesion']:.4g} Pa, friction angle "
                f"{s['friction_angle']:.3g} deg, ffc {s['ffc']:.3g}"
            )
        self._say(
            state,
            f"{key} done: {s['particles']:.0f} particles, {s['steps']:.0f} steps, "
            f"{s['wall_time']:.1f} s{extra}",
        )

    def _say(self, state, text: str, style: str | None = None) -> None:
        """A run's outcome: in the display's events, and printed even without bars."""
        if self.display.quiet:
            self.console.print(text, style=style, markup=False, highlight=False, soft_wrap=True)
        else:
            self.display.event(state, text, style)


def study(args) -> int:
    """``demscale study``: run the study, write summary, HDF5, plots and snapshots."""
    if _lacks_extra("study", ("rich", "h5py", "matplotlib"), "cli"):
        return 2
    import concurrent.futures as cf
    import multiprocessing as mp

    from rich.console import Console

    import engine
    import engine.study.spec
    from engine.io.curves import write_curves_csv
    from engine.io.store import save_study
    from engine.io.vtkhdf import save as save_snapshots
    from engine.study.kinds import kind_of

    console = Console(stderr=True)
    spec_path = Path(args.spec)
    shear = None
    if args.shear is not None:
        try:
            shear = _shear_test(Path(args.shear))
        except (OSError, json.JSONDecodeError) as e:
            console.print(f"--shear: cannot read {args.shear}: {e}", **_ERROR)
            return 2
        except (engine.ParameterError, TypeError, ValueError) as e:
            console.print(f"--shear {args.shear} is not a valid shear test: {e}", **_ERROR)
            return 2
    try:
        body = json.loads(spec_path.read_text())
        if isinstance(body, dict) and shear is not None and "reference" not in body:
            body["reference"] = {"type": "ShearTest", **shear.to_dict()}
            shear = None  # the study's own reference now
        ref = body.get("reference") if isinstance(body, dict) else None
        if isinstance(ref, dict) and ref.get("type") == "ShearTest" and "pair_law" not in ref:
            raise ValueError(
                "reference.pair_law: required for a shear reference (no study runs the "
                "record's default law, which nobody chose)"
            )
        if isinstance(body, dict) and "reference" not in body:
            raise ValueError(
                'reference: required (a preset named, e.g. {"preset": "quick"}, or the '
                "pair law with the other fields of the test): no study runs a default "
                "reference"
            )
        if args.decide and isinstance(body, dict):
            body["decide"] = True
        if args.budget is not None and isinstance(body, dict):
            body["budget"] = args.budget
        spec = engine.StudySpec.from_dict(body)
        if shear is not None:  # the same study on the shear test (engine.study.spec.on_test)
            spec = engine.study.spec.on_test(spec, shear)
        study = engine.plan(spec)  # planned once
    except (OSError, json.JSONDecodeError) as e:
        console.print(f"cannot read the spec {spec_path}: {e}", **_ERROR)
        return 2
    except (engine.ParameterError, TypeError, ValueError) as e:
        console.print(f"the spec {spec_path} is not valid: {e}", **_ERROR)
        return 2
    if args.workers < 1:
        console.print(f"--workers {args.workers}: must be at least 1", **_ERROR)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    spec, planned = study.spec, study.runs
    console.print(
        f"{spec_path.name}: {len(planned)} runs, "
        f"{sum(p.test.n_particles for p in planned)} particles in all, about "
        f"{study.estimated_particle_steps():.3g} particle-steps; writing to {out}"
    )
    snapshot_paths: dict[str, list[Path]] = {}
    curve_paths: dict[str, Path] = {}

    with StudyBars(planned, console, enabled=not args.quiet) as bars:

        def on_run(key, outcome) -> None:
            bars.finished(key, outcome)
            if isinstance(outcome, str):
                return
            curve_paths[key] = write_curves_csv(outcome, out / "curves" / f"{key}.csv")
            if args.snapshots and kind_of(outcome).snapshots:
                snapshot_paths[key] = save_snapshots(outcome, out / "snapshots" / key, key)

        try:
            if args.workers > 1:
                ctx = mp.get_context("spawn")
                with cf.ProcessPoolExecutor(args.workers, mp_context=ctx) as pool:
                    result = engine.run_study(
                        study,
                        progress=bars.update,
                        executor=pool,
                        on_run=on_run,
                        backend=args.backend,
                    )
            else:
                result = engine.run_study(
                    study, progress=bars.update, on_run=on_run, backend=args.backend
                )
        except engine.RunFailed as e:
            console.print(f"[red]{e}[/red]: no reference run finished, nothing to compare")
            return 1
        except engine.ParameterError as e:  # e.g. a shear study on --backend cuda
            console.print(f"the study cannot run: {e}", **_ERROR)
            return 2

    h5 = save_study(out / "results.h5", spec_path.stem, result)
    plots = result.save_plots(out / "plots")
    result_summary = result.to_summary()
    summary = {
        "answer": result_summary["answer"],  # first: what the study decided
        "spec": spec.to_dict(),
        **result_summary,
        "files": {
            "results": h5.name,
            "plots": [str(p.relative_to(out)) for p in plots],
            "curves": {k: str(p.relative_to(out)) for k, p in curve_paths.items()},
            "snapshots": {
                k: [str(p.relative_to(out)) for p in v] for k, v in snapshot_paths.items()
            },
        },
    }
    (out / "summary.json").write_text(json.dumps(_strict_json(summary), indent=1, allow_nan=False))
    # the same report as the main job's (demscale.report), from the same summary: the
    # answer first, a line per verdict (--details: the reasons), then the tables
    console.print(
        summary_text(result_summary, details=getattr(args, "details", False)),
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
    given, must be "ShearTest")."""
    import dataclasses

    import engine
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
    if "pair_law" not in raw:
        raise ValueError(
            "pair_law: required (the shear test's particle-particle law: no study runs the "
            "record's default law, which nobody chose)"
        )
    return from_dict(engine.ShearTest, raw, "ShearTest")


def run(args) -> int:
    """``demscale run``: one uniaxial test with streamed snapshots."""
    if _lacks_extra("run", ("rich", "h5py", "matplotlib"), "cli"):
        return 2
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

    import engine
    from engine.io.curves import write_curves_csv
    from engine.io.figures import section_figure
    from engine.io.vtkhdf import SnapshotWriter
    from engine.uniaxial.results import SCALAR_UNITS
    from engine.uniaxial.spec import uniaxial_from_json

    console = Console(stderr=True)
    path = Path(args.test)
    try:
        fields = json.loads(path.read_text())
        if not isinstance(fields, dict):
            raise ValueError("the file must hold a JSON object of the test's fields")
        test = uniaxial_from_json(fields)
        if args.snapshot_interval is not None and not args.snapshot_interval > 0:
            raise ValueError("--snapshot-interval must be a time > 0 s")
    except (OSError, json.JSONDecodeError) as e:
        console.print(f"cannot read the test {path}: {e}", **_ERROR)
        return 2
    except (engine.ParameterError, TypeError, ValueError) as e:
        console.print(f"the test {path} is not valid: {e}", **_ERROR)
        return 2
    out = Path(args.out)
    snap_dir = out / "snapshots"
    console.print(
        f"{path.name}: {test.n_particles} particles, R = {test.radius * 1e3:g} mm, "
        f"cell {' x '.join(f'{c * 1e3:g}' for c in test.cell)} mm; writing to {out}"
    )
    bars = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        TextColumn("{task.fields[stage]}"),
        TimeElapsedColumn(),
        console=console,
        disable=args.quiet,
    )
    with bars, SnapshotWriter(snap_dir) as writer:
        task = bars.add_task("[bold]uniaxial test", total=1.0, stage="setup")

        def report(p) -> None:
            bars.update(task, completed=p.fraction, stage=f"{p.stage} (t = {p.time:.3g} s)")

        try:
            result = engine.run_uniaxial(
                test,
                report,
                on_snapshot=writer.add,
                snapshot_interval=args.snapshot_interval,
                backend=args.backend,
            )
        except (engine.StageError, engine.InstabilityError, FloatingPointError) as e:
            console.print(
                f"[red]the test failed:[/red] {e}; the {len(writer.labels)} "
                f"snapshots before it are in {snap_dir}"
            )
            return 1
    for st in result.stages.values():
        section_figure(st.snapshot, path.stem).savefig(snap_dir / f"{st.name}.png", format="png")
    write_curves_csv(result, out / "curves.csv")
    summary = {
        "test": test.to_dict(),
        "scalars": result.scalars,
        "units": {k: SCALAR_UNITS.get(k, "") for k in result.scalars},
        "curves": "curves.csv",
        "snapshots": {
            "files": [
                *(str(p.relative_to(out)) for p in writer.paths()),
                *(f"snapshots/{k}.png" for k in result.stages),
            ],
            "time_steps": writer.labels,
        },
    }
    (out / "result.json").write_text(json.dumps(_strict_json(summary), indent=1, allow_nan=False))
    s = result.scalars
    strength = s.get("unconfined_strength")
    console.print(
        f"done: {s['steps']:.0f} steps in {s['wall_time']:.1f} s; consolidated "
        f"porosity {s['consolidated_porosity']:.3f}"
        + (f", unconfined strength {strength:.4g} Pa" if strength is not None else "")
        + f"; {len(writer.labels)} snapshots in {snap_dir}"
    )
    return 0


def _service_env(args) -> int:
    if _lacks_extra(
        args.command, ("fastapi", "uvicorn", "sqlmodel", "pydantic_settings", "h5py"), "service"
    ):
        return 2
    if args.data_dir is not None:
        os.environ["DEMSCALE_DATA_DIR"] = str(args.data_dir)
    return 0


def serve(args) -> int:
    """``demscale serve``: the API (``python -m service api``)."""
    if _service_env(args):
        return 2
    os.environ["DEMSCALE_HOST"] = args.host
    os.environ["DEMSCALE_PORT"] = str(args.port)
    if args.no_worker:
        os.environ["DEMSCALE_EMBEDDED_WORKER"] = "false"
    from service.__main__ import main as service_main
    from service.settings import ConfigError, get_settings, with_local_token

    try:  # the token the server will use: configured, or the local one it keeps
        _, token = with_local_token(get_settings(), args.host)
    except ConfigError as e:
        print(f"demscale serve: {e}", file=sys.stderr)
        return 2
    host = "127.0.0.1" if args.host in ("0.0.0.0", "::", "") else args.host
    url = f"http://{host}:{args.port}/"
    if token is not None:
        # the token apart from the URL: a login link would leave it in logs and histories
        print(
            f"demscale serve: the studies page: {url} (log in with the API token {token}, "
            f"kept in {Path(get_settings().data_dir) / 'api-token'})",
            file=sys.stderr,
        )
    else:
        print(
            f"demscale serve: the studies page: {url} (log in with your API token)", file=sys.stderr
        )
    service_main(["api"])
    return 0


def job(argv: list[str]) -> int:
    """The main job over the service (``demscale job --help`` lists its options)."""
    if _lacks_extra("job", ("fastapi", "sqlmodel", "uvicorn", "httpx"), "service"):
        return 2
    from .job import main as job_main

    return job_main(argv)


def worker(args) -> int:
    """``demscale worker``: a worker process (``python -m service.worker``)."""
    if _service_env(args):
        return 2
    from service.worker import main as worker_main

    worker_main(["--once"] if args.once else [])
    return 0


def parser() -> argparse.ArgumentParser:
    """The argument parser of the ``demscale`` command."""
    fmt = argparse.RawDescriptionHelpFormatter
    ap = argparse.ArgumentParser(
        prog="demscale",
        description=DESCRIPTION,
        formatter_class=fmt,
        epilog="examples:\n"
        "  demscale study examples/quick_study.json --out results/quick\n"
        "  demscale study my_study.json --out results/mine --workers 4\n"
        "  demscale run examples/quick_test.json --out results/one "
        "--snapshot-interval 0.02\n"
        "  demscale serve --port 8000          then open http://127.0.0.1:8000/\n"
        "  demscale job --exit                 the main job: the default study "
        "through the service\n"
        "run `demscale COMMAND --help` for the options of each command.",
    )
    ap.add_argument("--version", action="version", version=f"demscale {_version()}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "study",
        help="run a scaling study from a JSON file, here",
        description=STUDY_HELP,
        formatter_class=fmt,
    )
    p.add_argument("spec", metavar="SPEC.json", help="the study (an engine.StudySpec as JSON)")
    p.add_argument(
        "--out",
        "-o",
        metavar="DIR",
        required=True,
        help="folder for the results (created if missing; files are overwritten)",
    )
    p.add_argument(
        "--workers",
        "-j",
        type=int,
        default=1,
        metavar="N",
        help="runs side by side in N processes (one core each; default 1: one "
        "run at a time, the engine using the cores it wants)",
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
    p.add_argument(
        "--quiet",
        "-q",
        action="store_true",
        help="no progress bars (the runs' results are still printed)",
    )
    _backend_option(p)
    p.set_defaults(func=study)

    p = sub.add_parser(
        "run",
        help="run one uniaxial test and write its snapshots",
        description=RUN_HELP,
        formatter_class=fmt,
    )
    p.add_argument("test", metavar="TEST.json", help="the test (an engine.UniaxialTest as JSON)")
    p.add_argument(
        "--out",
        "-o",
        metavar="DIR",
        required=True,
        help="folder for the results (created if missing; files are overwritten)",
    )
    p.add_argument(
        "--snapshot-interval",
        type=float,
        default=None,
        metavar="SECONDS",
        help="also a snapshot every SECONDS of simulated time (default: stage ends only)",
    )
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    _backend_option(p)
    p.set_defaults(func=run)

    p = sub.add_parser(
        "calibrate",
        help="calibrate a law to laboratory data (then, optionally, study it)",
        description=CALIBRATE_HELP,
        formatter_class=fmt,
    )
    p.add_argument("targets", metavar="TARGETS.json", help="the laboratory data (LabTargets)")
    p.add_argument("--test", required=True, metavar="TEST.json", help="the base test and law")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=LOW:HIGH",
        help="a law parameter to calibrate and its box (repeat: --param k1=3e3:2e4 ...)",
    )
    p.add_argument("--out", "-o", metavar="DIR", required=True, help="folder for the results")
    p.add_argument("--runs", type=int, default=25, help="design runs (default 25)")
    p.add_argument("--waves", type=int, default=2, help="history-matching waves (default 2)")
    p.add_argument("--wave-runs", type=int, default=15, help="runs per wave (default 15)")
    p.add_argument("--workers", "-j", type=int, default=1, metavar="N", help="runs side by side")
    p.add_argument(
        "--then-study", action="store_true", help="then a scaling study of the calibrated law"
    )
    p.add_argument("--study", metavar="SPEC.json", help="with --then-study: its radii and rules")
    p.add_argument(
        "--resolution",
        metavar="SUMMARY.json",
        help="correct the cell's values to the bulk by the resolution curve of a study whose "
        "reference is this test (its summary.json), or by {kind: [factor, sd of log]}",
    )
    p.add_argument(
        "--shear-test",
        metavar="SHEAR.json",
        help="with shear data: the shear cell (engine.ShearTest's fields but pair_law, "
        "preshear_stress and normal_stresses, which are the calibrated law and the data's; "
        "default: docs/SHEAR.md's cell, 10 x 5 x 15 diameters of the test's particles)",
    )
    p.add_argument(
        "--vary-seed",
        action="store_true",
        help="each run packs its own sample (the test's seed plus the run's index), so that "
        "the emulators' noise holds the packing scatter; default: every run on the test's "
        "one packing (docs/CALIBRATION.md)",
    )
    p.set_defaults(func=calibrate_cmd)

    p = sub.add_parser(
        "export",
        help="a law (fine or scaled) as a LIGGGHTS fragment or a table",
        description=EXPORT_HELP,
        formatter_class=fmt,
    )
    p.add_argument("law", metavar="LAW.json", help='{"type": "BilinearAdhesive", ...}')
    p.add_argument("--format", choices=("liggghts", "json", "csv"), default="liggghts")
    p.add_argument("--radius", type=float, help="scale the law to this radius [m]")
    p.add_argument("--rule", default="paper", help="the scaling rule (default paper)")
    p.add_argument(
        "--reference-radius",
        type=float,
        default=None,
        metavar="R",
        help="the radius the law is for [m]; needed with --radius when LAW.json has no "
        "reference_radius (demscale calibrate writes it)",
    )
    p.set_defaults(func=export_cmd)

    p = sub.add_parser(
        "serve",
        help="start the job service's HTTP API (and a worker)",
        description=SERVE_HELP,
        formatter_class=fmt,
    )
    p.add_argument(
        "--host",
        default=os.environ.get("DEMSCALE_HOST", "127.0.0.1"),
        help="address to listen on (default 127.0.0.1, this machine only; "
        "0.0.0.0 for every interface)",
    )
    p.add_argument(
        "--port",
        type=int,
        default=int(os.environ.get("DEMSCALE_PORT", "8000")),
        help="port to listen on (default 8000)",
    )
    p.add_argument(
        "--data-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="where the database and result files live (default: DEMSCALE_DATA_DIR, else ./var)",
    )
    p.add_argument(
        "--no-worker",
        action="store_true",
        help="do not start the embedded worker (run `demscale worker` instead)",
    )
    p.set_defaults(func=serve)

    # parsed by demscale.job itself (main() hands it the arguments after "job")
    sub.add_parser(
        "job",
        help="the main job: serve, submit a study (default: the default "
        "study), follow it, print its results",
        add_help=False,
    )

    p = sub.add_parser(
        "worker",
        help="start a worker that runs the service's queued studies",
        description=WORKER_HELP,
        formatter_class=fmt,
    )
    p.add_argument("--once", action="store_true", help="exit after one study")
    p.add_argument(
        "--data-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="the API's data folder (default: DEMSCALE_DATA_DIR, else ./var)",
    )
    p.set_defaults(func=worker)

    from .deck import add_commands  # export-test, judge-liggghts (issue 43)
    from .plan import add_commands as add_plan  # plan (issue 50)

    add_commands(sub, fmt)
    add_plan(sub, fmt)
    return ap


CALIBRATE_HELP = """\
Calibrate the pair law of TEST.json to the laboratory data in TARGETS.json (an
engine.calibration.LabTargets: porosity against stress, loading and unloading stiffness,
K0, unconfined strength at one or several consolidation stresses, and a shear tester's
yield loci ("shear": sigma_pre, points of sigma_n and tau, tau_pre, bulk density), each
with its 1-sd uncertainty and the tester named) over the law parameters given with --param,
with Gaussian-process emulators, history-matching waves and a posterior
(docs/CALIBRATION.md).
Uniaxial data are matched by TEST.json's uniaxial test, each yield locus by a shear test of
its material (--shear-test SHEAR.json, else the default shear cell). Every run is stored
in DIR/runs as it finishes, and a rerun finds them. Writes:

  calibration.json      the calibrated law, each parameter (median, 90 % interval,
                        determined or free), every target met or not, the Sobol indices,
                        every run
  law.json              the calibrated law (an engine contact law as JSON)
  law.liggghts          the law as a LIGGGHTS edinburgh/stiffness fragment (if it maps)
  calibration.png       the compression curve and flow function against the lab points

With --then-study, a scaling study of the calibrated law follows (its coarse radii and
rules: --study SPEC.json, else the default study's), written to DIR/study.

Exit status: 0 every target met; 1 the calibration finished but some target is not met by
the check run (named, with its z; everything is still written) or the then-study had a
failed run; 2 the input is not valid (the message names the flag or the file's field).

Laboratory values are bulk values; a small cell loses some of each property (the
resolution curve of a study with controls says how much). --resolution SUMMARY.json
corrects each run's values to the bulk by the curve of a study whose reference is TEST.json
(docs/CALIBRATION.md), so that the law does not absorb the cell's loss.
"""

EXPORT_HELP = """\
Write a contact law (LAW.json: {"type": "BilinearAdhesive" or "EEPA", fields...,
"reference_radius": R}), or the law scaled to --radius by a rule, as a LIGGGHTS
edinburgh/stiffness fragment (each value's meaning and unit in a comment above it), or as a
JSON or CSV table of its parameters with units, to standard output. A law is calibrated for
one particle radius: LAW.json's reference_radius [m] (demscale calibrate writes it), or
--reference-radius; --radius without either is refused.

Exit status: 0 written; 2 LAW.json or an option is not valid (the message names it).
"""


def _law_from_json(raw):
    """A law file's law and the particle radius it is for [m] (``reference_radius``; None
    where the file does not say)."""
    import engine

    laws = {"BilinearAdhesive": engine.BilinearAdhesive, "EEPA": engine.EEPA}
    if not isinstance(raw, dict) or raw.get("type") not in laws:
        raise ValueError('the law must be a JSON object with "type": "BilinearAdhesive" or "EEPA"')
    from engine.core.records import from_dict

    body = dict(raw)
    radius = body.pop("reference_radius", None)
    if radius is not None and not (_is_number(radius) and math.isfinite(radius) and radius > 0):
        raise ValueError(f"reference_radius = {radius!r}: must be a radius > 0 m")
    return from_dict(laws[body.pop("type")], body), radius


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


#: Where a command-line user gave what an engine field names: the flags of ``calibrate``.
_CALIBRATE_FLAGS = {
    "calibrate.parameters": "--param",
    "calibrate.runs": "--runs",
    "calibrate.resolution": "--resolution",
    "calibrate.targets": "TARGETS.json",
    "calibrate.shear_test": "--shear-test",
}


def _calibrate_where(field: str, args) -> str:
    """The flag or file of ``demscale calibrate`` that holds the engine's ``field``."""
    head = field.split(".")[0]
    if field.startswith("calibrate.parameters."):
        name = field.split(".")[2]
        box = next((p for p in args.param if p.partition("=")[0].strip() == name), name)
        return f"--param {box}"
    for prefix, flag in _CALIBRATE_FLAGS.items():
        if field.startswith(prefix):
            return flag
    if head in ("LabTargets", "CompressionPoint", "StrengthPoint", "ShearLocus", "LocusPoint"):
        return f"{args.targets} ({field})"
    return f"--test {args.test} ({field})"


def _resolution(raw) -> dict:
    """--resolution: a study's summary.json (its advisor's resolution curve), or the
    corrections themselves ({kind: [factor, sd of its log]})."""
    from engine.calibration.calibrate import resolution_corrections

    if isinstance(raw, dict) and "advisor" in raw:
        curve = (raw["advisor"] or {}).get("resolution_curve")
        if not curve:
            raise ValueError("--resolution: the study has no resolution curve (no controls)")
        return resolution_corrections(curve)
    if not isinstance(raw, dict):
        raise ValueError("--resolution: a study's summary.json or {kind: [factor, sd]}")
    return raw


def _param_box(text: str) -> tuple[str, tuple[float, float]]:
    name, _, box = text.partition("=")
    lo, _, hi = box.partition(":")
    try:
        return name.strip(), (float(lo), float(hi))
    except ValueError:
        raise ValueError(f"--param {text!r}: write NAME=LOW:HIGH, e.g. k1=3e3:2e4") from None


def calibrate_cmd(args) -> int:
    """``demscale calibrate``: calibrate a law to laboratory data, then (optionally) study it."""
    import concurrent.futures as cf
    import multiprocessing as mp

    import engine
    from engine.calibration import LabTargets, calibrate
    from engine.calibration.calibrate import check_request
    from engine.core.records import to_dict
    from engine.io.liggghts import to_liggghts
    from engine.uniaxial.spec import uniaxial_from_json

    try:
        targets = LabTargets.from_dict(json.loads(Path(args.targets).read_text()))
        fields = json.loads(Path(args.test).read_text())
        test = uniaxial_from_json(fields)
        boxes = dict(_param_box(p) for p in args.param)
        if not boxes:
            raise ValueError("give the parameters to calibrate: --param k1=3e3:2e4 ...")
        resolution = None
        if args.resolution:
            resolution = _resolution(json.loads(Path(args.resolution).read_text()))
        shear_test = None  # the shear cell's fields (judged with each locus's stresses)
        if args.shear_test:
            shear_test = json.loads(Path(args.shear_test).read_text())
        # the whole request checked before anything is written
        check_request(test, targets, boxes, args.runs, shear_test)
    except (OSError, json.JSONDecodeError) as e:
        print(f"cannot read the input: {e}", file=sys.stderr)
        return 2
    except engine.ParameterError as e:
        print(f"{_calibrate_where(e.field, args)}: not valid: {e}", file=sys.stderr)
        return 2
    except (TypeError, ValueError) as e:
        print(f"not valid: {e}", file=sys.stderr)
        return 2
    if args.workers < 1:
        print(f"--workers {args.workers}: must be at least 1", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    total = args.runs + args.waves * args.wave_runs  # on_run: the design and wave runs

    def on_run(i, quantities):
        if isinstance(quantities, str):  # a run that failed: left out
            print(f"[{i + 1}/{total}] run failed: {quantities}", file=sys.stderr, flush=True)
            return
        q = ", ".join(f"{x['name']} {x['value']:.4g}" for x in quantities)
        print(f"[{i + 1}/{total}] run done: {q}", file=sys.stderr, flush=True)

    pool = None
    if args.workers > 1:
        pool = cf.ProcessPoolExecutor(args.workers, mp_context=mp.get_context("spawn"))
    try:
        cal = calibrate(
            test,
            targets,
            boxes,
            runs=args.runs,
            waves=args.waves,
            wave_runs=args.wave_runs,
            store=out / "runs",
            executor=pool,
            on_run=on_run,
            resolution=resolution,
            shear_test=shear_test,
            vary_seed=args.vary_seed,
        )
    except engine.ParameterError as e:
        print(f"{_calibrate_where(e.field, args)}: not valid: {e}", file=sys.stderr)
        return 2
    finally:
        if pool is not None:
            pool.shutdown()
    summary = cal.to_summary()
    (out / "calibration.json").write_text(json.dumps(summary, indent=1))
    # the law with the particle radius it is calibrated for: `demscale export --radius`
    # scales it from there
    law = {"type": type(cal.law).__name__, **to_dict(cal.law), "reference_radius": test.radius}
    (out / "law.json").write_text(json.dumps(law, indent=1))
    try:
        (out / "law.liggghts").write_text(
            to_liggghts(cal.law, note="calibrated by demscale", radius=test.radius)
        )
    except engine.ParameterError as e:
        print(f"no LIGGGHTS fragment: {e}", file=sys.stderr)
    # first, whether the data determine the parameters, and which target would determine
    # a free one (engine.calibration.calibrate.determination)
    for line in summary["determination"]["lines"]:
        print(line)
    print(f"parameters (calibrated for R = {test.radius:g} m):")
    for n, p in cal.parameters.items():
        lo, hi = p["interval"]
        u = f" {p['unit']}" if p.get("unit") not in (None, "", "1") else ""
        print(f"  {n} = {p['median']:.4g}{u} (90 %: {lo:.4g} to {hi:.4g}{u}), {p['status']}")
    print("targets (check run of the calibrated law against the laboratory, 1 sd):")
    for q in cal.targets_met:
        u = f" {q['unit']}" if q.get("unit") not in (None, "", "1") else ""
        z = "the check run failed" if q["z"] is None else f"z = {q['z']:+.1f}"
        print(
            f"  {q['name']}: {q['value']:.4g}{u} against {q['lab']:.4g} +/- {q['sd']:.2g}{u}: "
            + ("met" if q["met"] else f"NOT met ({z})")
        )
    if importlib.util.find_spec("matplotlib") is not None:
        from engine.io.figures import calibration_figure

        calibration_figure(summary).savefig(out / "calibration.png", format="png")
    print(f"written to {out}/calibration.json, calibration.png, law.json, law.liggghts")
    code = 0
    if not cal.all_met:
        n = len(cal.targets_met)
        print(
            f"calibration finished, but {len(cal.not_met)} of {n} targets NOT met (exit "
            "status 1): " + "; ".join(cal.not_met),
            file=sys.stderr,
        )
        code = 1
    if not args.then_study:
        return code
    spec = None
    if args.study:  # its radii and rules; its reference is the calibrated test
        body = json.loads(Path(args.study).read_text())
        body["reference"] = test.to_dict()
        spec = engine.StudySpec.from_dict(body)
    body = cal.study(spec).to_dict()
    (out / "study.json").write_text(json.dumps(body, indent=1))
    ns = argparse.Namespace(
        spec=str(out / "study.json"),
        out=str(out / "study"),
        workers=args.workers,
        decide=False,
        budget=None,
        snapshots=False,
        quiet=False,
        backend=None,
        shear=None,
    )
    return max(code, study(ns))


def _radius_flag(flag: str, value) -> str | None:
    """Why ``value`` of ``flag`` is not a particle radius, or None."""
    if value is None or (math.isfinite(value) and value > 0):
        return None
    return f"{flag} {value:g}: must be a particle radius > 0 m"


def export_cmd(args) -> int:
    """``demscale export``: a law, fine or scaled, for LIGGGHTS or as a table."""
    import engine
    from engine.io.liggghts import law_table, to_liggghts

    def refuse(msg: str) -> int:
        print(f"demscale export: {msg}", file=sys.stderr)
        return 2

    try:
        raw = json.loads(Path(args.law).read_text())
    except (OSError, json.JSONDecodeError) as e:
        return refuse(f"cannot read the law {args.law}: {e}")
    try:
        law, own_radius = _law_from_json(raw)
    except (engine.ParameterError, TypeError, ValueError) as e:
        return refuse(f"{args.law} is not a law: {e}")
    for flag, value in (("--radius", args.radius), ("--reference-radius", args.reference_radius)):
        if (why := _radius_flag(flag, value)) is not None:
            return refuse(why)
    if (
        args.reference_radius is not None
        and own_radius is not None
        and not math.isclose(args.reference_radius, own_radius, rel_tol=1e-12)
    ):
        return refuse(
            f"--reference-radius {args.reference_radius:g}: {args.law} says the law is for "
            f"R = {own_radius:g} m (its reference_radius); leave the flag out"
        )
    radius = args.reference_radius if args.reference_radius is not None else own_radius
    note = ""
    if args.radius is not None:
        if radius is None:
            return refuse(
                f"--radius {args.radius:g}: scaling needs the radius the law is for, and "
                f"{args.law} has no reference_radius: give --reference-radius R [m]"
            )
        try:
            rule = engine.ScalingRule.named(args.rule)
        except (engine.ParameterError, KeyError, ValueError) as e:
            return refuse(f"--rule {args.rule}: {e}")
        try:
            ref = engine.UniaxialTest(radius=radius, pair_law=law)
            law = rule.apply(ref, args.radius, ref.dt).pair_law
        except engine.ParameterError as e:
            return refuse(
                f"--radius {args.radius:g}: the law scaled from R = {radius:g} m by rule "
                f"{args.rule!r} is not valid: {e}"
            )
        note = f"scaled from R = {radius:g} m to R = {args.radius:g} m by rule {args.rule!r}"
        radius = args.radius
    try:
        if args.format == "liggghts":
            text = to_liggghts(law, note=note, radius=radius)
        elif args.format == "csv":
            text = law_table(law, "csv", radius=radius)
        else:
            text = json.dumps(law_table(law, radius=radius), indent=1) + "\n"
    except engine.ParameterError as e:
        return refuse(f"--format {args.format}: {e}")
    sys.stdout.write(text)
    sys.stdout.flush()
    return 0


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("demscale")
    except PackageNotFoundError:
        return "(not installed)"


def _backend_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--backend",
        choices=("cpu", "cuda", "auto"),
        default=None,
        help="where the engine runs: cpu, cuda (an NVIDIA GPU, the gpu extra) or "
        "auto (the GPU when usable); default: DEMSCALE_BACKEND, else cpu",
    )


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``demscale`` console script."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        if argv[:1] == ["job"]:
            return job(argv[1:])
        args = parser().parse_args(argv)
        return args.func(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`demscale export law.json | head -1`): nothing to say to
        # it; stdout goes to /dev/null so that the interpreter's own flush at exit is quiet
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a program the signal stopped
