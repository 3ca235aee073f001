"""``demscale run``: one uniaxial test (or one hopper discharge) run here with a progress
bar, its snapshots streamed to files as they are taken, its scalars, curves and sections (a
hopper: its discharge-rate plot) written into a folder."""

from __future__ import annotations

import json
from pathlib import Path

from ..options import (
    CLI_EXTRA,
    ERROR,
    add_backend,
    add_out,
    add_quiet,
    attempt,
    command,
    lacks_extra,
    single_test,
)

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
defaults; {"preset": "quick"} (or "paper") starts from a named test. With "type":
"HopperTest" it holds an engine.HopperTest instead (docs/HOPPER.md): the fill settled, the
gate opened, the discharge; its snapshots (particles, contacts and walls.vtkhdf: the gate
moving as it opens) at the gate's opening, every --snapshot-interval of the discharge and at
its end, curves.csv its discharge curves and discharge.png its rate against time. The
snapshots are written as they are taken, so a run that fails keeps those before the
failure.

Exit status: 0 the test ran; 1 a stage failed (see the message); 2 the test is not valid."""


def add_commands(sub) -> None:
    """``run`` on the ``demscale`` parser's subparsers ``sub``."""
    p = command(sub, "run", "run one uniaxial test and write its snapshots", RUN_HELP, run)
    p.add_argument(
        "test",
        metavar="TEST.json",
        help='the test (an engine.UniaxialTest, or with "type": "HopperTest" an '
        "engine.HopperTest, as JSON)",
    )
    add_out(p)
    p.add_argument(
        "--snapshot-interval",
        type=float,
        default=None,
        metavar="SECONDS",
        help="also a snapshot every SECONDS of simulated time (default: stage ends only)",
    )
    add_quiet(p, "no progress bar")
    add_backend(p)


def _read_test(path: Path, snapshot_interval: float | None):
    """The :class:`engine.UniaxialTest` in the JSON file ``path`` (engine.uniaxial_from_json),
    or with ``"type": "HopperTest"`` the :class:`engine.HopperTest`, with
    ``snapshot_interval`` [s] checked."""
    from engine.study.kinds import test_from_json

    fields = json.loads(path.read_text())
    if not isinstance(fields, dict):
        raise ValueError("the file must hold a JSON object of the test's fields")
    if snapshot_interval is not None and not snapshot_interval > 0:
        raise ValueError("--snapshot-interval must be a time > 0 s")
    return single_test(test_from_json(fields), "run")


def run(args) -> int:
    """``demscale run``: one uniaxial test with streamed snapshots."""
    if lacks_extra("run", CLI_EXTRA, "cli"):
        return 2
    from rich.console import Console

    import engine
    from engine.io.curves import write_curves_csv
    from engine.io.figures import section_figure

    from ..report import run_summary, write_json

    console = Console(stderr=True)
    path = Path(args.test)
    test, why = attempt(
        lambda: _read_test(path, args.snapshot_interval),
        f"cannot read the test {path}",
        f"the test {path} is not valid",
    )
    if why is not None:
        console.print(why, **ERROR)
        return 2
    out = Path(args.out)
    snap_dir = out / "snapshots"
    if isinstance(test, engine.HopperTest):
        return _run_hopper(args, test, path, out, console)
    console.print(
        f"{path.name}: {test.n_particles} particles, R = {test.radius * 1e3:g} mm, "
        f"cell {' x '.join(f'{c * 1e3:g}' for c in test.cell)} mm; writing to {out}"
    )
    result, writer = _run_with_snapshots(args, test, engine.run_uniaxial, snap_dir, console)
    if result is None:
        return 1
    for st in result.stages.values():
        section_figure(st.snapshot, path.stem).savefig(snap_dir / f"{st.name}.png", format="png")
    write_curves_csv(result, out / "curves.csv")
    write_json(out / "result.json", run_summary(test, result, out, writer.paths(), writer.labels))
    s = result.scalars
    strength = s.get("unconfined_strength")
    console.print(
        f"done: {s['steps']:.0f} steps in {s['wall_time']:.1f} s; consolidated "
        f"porosity {s['consolidated_porosity']:.3f}"
        + (f", unconfined strength {strength:.4g} Pa" if strength is not None else "")
        + f"; {len(writer.labels)} snapshots in {snap_dir}"
    )
    return 0


def _run_with_snapshots(args, test, run_fn, snap_dir: Path, console):
    """``run_fn(test, progress, on_snapshot=, snapshot_interval=, backend=)`` (engine.run_uniaxial
    or engine.run_hopper) under a progress bar naming the stage and the simulated time, its
    snapshots streamed into ``snap_dir``: (result, writer), or (None, writer) when a stage
    failed or the integration blew up (said, with where the snapshots before it are)."""
    from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

    import engine
    from engine.io.vtkhdf import SnapshotWriter

    bars = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        TextColumn("{task.fields[stage]}"),
        TimeElapsedColumn(),
        console=console,
        disable=args.quiet,
    )
    what = "hopper" if isinstance(test, engine.HopperTest) else "uniaxial test"
    with bars, SnapshotWriter(snap_dir) as writer:
        task = bars.add_task(f"[bold]{what}", total=1.0, stage="setup")

        def report(p) -> None:
            bars.update(task, completed=p.fraction, stage=f"{p.stage} (t = {p.time:.3g} s)")

        try:
            result = run_fn(
                test,
                report,
                on_snapshot=writer.add,
                snapshot_interval=args.snapshot_interval,
                backend=args.backend,
            )
        except (engine.StageError, engine.InstabilityError, FloatingPointError) as e:
            console.print(
                f"[red]the {what} failed:[/red] {e}; the {len(writer.labels)} "
                f"snapshots before it are in {snap_dir}"
            )
            return None, writer
    return result, writer


def _run_hopper(args, test, path: Path, out: Path, console) -> int:
    """``demscale run`` of an :class:`engine.HopperTest`: the discharge with its snapshots,
    curves.csv, discharge.png and result.json."""
    import engine
    from engine.hopper.results import HOPPER_SCALAR_UNITS
    from engine.io.curves import write_curves_csv
    from engine.io.figures import hopper_run_figure

    from ..report import write_json

    snap_dir = out / "snapshots"
    console.print(
        f"{path.name}: a {test.shape} hopper, outlet {test.outlet_width * 1e3:g} mm "
        f"({test.outlet_diameters:.3g} d), {test.n_particles} particles, R = "
        f"{test.radius * 1e3:g} mm; writing to {out}"
    )
    result, writer = _run_with_snapshots(args, test, engine.run_hopper, snap_dir, console)
    if result is None:
        return 1
    write_curves_csv(result, out / "curves.csv")
    title = f"{path.stem}: {test.shape} hopper, B = {test.outlet_diameters:.3g} d"
    hopper_run_figure(result, title).savefig(out / "discharge.png", format="png")
    s = result.scalars
    write_json(
        out / "result.json",
        {
            "test": {"type": "HopperTest", **test.to_dict()},
            "scalars": s,
            "units": {k: HOPPER_SCALAR_UNITS.get(k, "") for k in s},
            "curves": "curves.csv",
            "plots": ["discharge.png"],
            "snapshots": {
                "files": [str(p.relative_to(out)) for p in writer.paths()],
                "time_steps": writer.labels,
            },
        },
    )
    how = "arched" if s["arched"] else ("stopped" if s["stopped"] else "discharged")
    console.print(
        f"done: {how}, {s['discharged_mass'] / s['total_mass']:.1%} of the fill out, "
        f"discharge rate {s['discharge_rate']:.4g} kg/s (discharge number "
        f"{s['discharge_number']:.3g}); {s['steps']:.0f} steps in {s['wall_time']:.1f} s; "
        f"{len(writer.labels)} snapshots in {snap_dir}"
    )
    return 0
