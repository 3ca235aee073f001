"""The one HDF5 layout of a run, in its own file (one per finished run, written atomically,
read back as a :class:`engine.UniaxialResult`) and inside a study's file
(:func:`save_study`: the study's runs in that same layout, plus its tables).

Long runs are stored once and every metric, verdict and report is recomputed from the stored
curves (``engine.study.results.assemble``); a study resumes with the runs not yet stored
(``run_study(completed=...)``). A failed run is stored as a file holding only its error.
h5py is imported only here, when a run is stored or read (the engine itself needs only numpy
and numba).

Layout of ``<key>.h5``: attrs ``test`` (JSON of :meth:`engine.UniaxialTest.to_dict`),
``error`` (only for a failed run), ``versions``, ``machine`` (JSON: the processor and the
number of logical CPUs of the machine that stored the run, which for a process pool or
``benchmarks/run_batch.py`` is the one that ran it; absent in runs stored before it was
recorded); group ``scalars`` (attrs, with
``<name>_units``); one group ``stages/<name>`` per stage (attrs ``steps``, ``position``) with
one dataset per curve (attr ``units``) and, when kept, a group ``particles`` (``positions``
(N, 3), ``radii`` (N,) at the stage's end [m]).

A shear test's run (:class:`engine.ShearResult`, a shear study's) has the same layout: its
``test`` names its kind (``"type": "ShearTest"``), its stages are the consolidation's (attr
``part`` "consolidation", with particles) and then the shear stages (``part`` "shear", the
curves of :data:`engine.shear.results.SHEAR_CURVE_UNITS`), and the attrs ``shear_points``
(JSON: the pre-shear point, then each point of incipient failure) and ``locus`` (JSON: the
fitted yield locus) hold what the curves were read into. Both are strict JSON (RFC 8259):
the ffc of a locus without cohesion (sigma_c = 0), infinite, is stored as null and read
back as infinity.

A hopper's run (:class:`engine.HopperResult`, a hopper study's): ``test`` names its kind
(``"type": "HopperTest"``); its discharge curves (:data:`engine.hopper.results.HOPPER_CURVE_UNITS`,
one sample every ``output_interval`` from the gate's opening) are the one stage
``stages/discharge`` (attr ``part`` "discharge"; its ``steps`` are the run's, settling and
discharge together: a hopper counts no stage's own; no particles); its wall normal stress
profiles are the datasets ``edges`` [m], ``fill`` and ``flow`` [Pa] of group
``wall_stress``. Each kind writes and reads its own (``TestKind.write_group`` and
``read_group``, engine.study.kinds); the uniaxial and shear layouts are as they were.

A run a ``decide`` study added (engine.study.loop) also holds its round: attrs ``round``,
``reason`` and ``added_kind`` (``"coarse"``, ``"reference"`` or ``"control"``), and
``round_added`` (JSON: every addition of its round, ``{run, round, kind, reason}``, its own
among them), so that loading the study reads its rounds (:func:`stored_additions`) instead
of judging them again. Runs stored before these were recorded have none of them: their
rounds are replayed from their outcomes, which finds the same runs.
"""

from __future__ import annotations

import json
import os
import platform
import socket
from pathlib import Path

import numpy as np

from ..uniaxial.checkpoint import this_code
from ..uniaxial.measures import curve_failed
from ..uniaxial.results import CURVE_UNITS, SCALAR_UNITS, StageResult, UniaxialResult
from ..uniaxial.spec import UniaxialTest


def this_machine() -> dict:
    """The processor (model name from /proc/cpuinfo where there is one) and the number of
    logical CPUs of this machine: where a stored run's wall time was measured."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(
                (line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu
            )
    except OSError:
        pass
    return {"cpu": cpu, "logical_cpus": os.cpu_count()}


def stored_machine(path: Path) -> dict | None:
    """The ``machine`` attribute of a stored run, or None where it was not recorded."""
    import h5py

    with h5py.File(path, "r") as f:
        text = f.attrs.get("machine")
    return None if text is None else json.loads(text)


def stored_code(path: Path) -> dict | None:
    """The ``code`` attribute of a stored run (:func:`this_code`), or None where it was not
    recorded (runs stored before it was)."""
    import h5py

    with h5py.File(path, "r") as f:
        text = f.attrs.get("code")
    return None if text is None else json.loads(text)


def write_run_group(g, outcome, keep_particles: bool = True) -> None:
    """Write ``outcome`` (a result of a registered test kind, or an error text) into the
    h5py group (or file) ``g``: the one layout of a run, in its own file and inside a
    study's file alike. The result's kind writes it (``TestKind.write_group``,
    engine.study.kinds: :func:`write_uniaxial_group`, :func:`write_shear_group`,
    :func:`write_hopper_group`)."""
    if isinstance(outcome, str):
        g.attrs["error"] = outcome
        return
    from ..study.kinds import kind_of

    kind_of(outcome).write_group(g, outcome, keep_particles)


def _write_scalars(g, scalars: dict, units: dict) -> None:
    sc = g.create_group("scalars")
    for k, v in scalars.items():
        sc.attrs[k] = float(v)
        sc.attrs[f"{k}_units"] = units.get(k, "")


def _write_stages(g, stages, curve_units: dict, keep_particles: bool) -> None:
    """``stages``: (name, stage, part) in the order they ran; each stage has ``curves`` and
    ``steps`` and, where it keeps them, ``positions`` and ``radii`` [m]."""
    for i, (name, st, part) in enumerate(stages):
        sg = g.create_group(f"stages/{name}")
        sg.attrs.update({"steps": int(st.steps), "position": i})
        if part is not None:
            sg.attrs["part"] = part
        for c, v in st.curves.items():
            ds = sg.create_dataset(c, data=np.asarray(v), compression="gzip", shuffle=True)
            ds.attrs["units"] = curve_units.get(c, "")
        if keep_particles and getattr(st, "positions", None) is not None:
            p = sg.create_group("particles")
            for pname, v in (("positions", st.positions), ("radii", st.radii)):
                ds = p.create_dataset(pname, data=np.asarray(v), compression="gzip")
                ds.attrs["units"] = "m"


def write_uniaxial_group(g, outcome, keep_particles: bool = True) -> None:
    """A :class:`engine.UniaxialResult` in the run layout (module docstring)."""
    g.attrs["test"] = json.dumps(outcome.test.to_dict())
    _write_scalars(g, outcome.scalars, SCALAR_UNITS)
    stages = [(n, st, None) for n, st in outcome.stages.items()]
    _write_stages(g, stages, CURVE_UNITS, keep_particles)


def write_shear_group(g, outcome, keep_particles: bool = True) -> None:
    """An :class:`engine.ShearResult` in the run layout (module docstring)."""
    from ..shear.results import SHEAR_CURVE_UNITS, SHEAR_SCALAR_UNITS

    g.attrs["test"] = json.dumps({"type": "ShearTest", **outcome.test.to_dict()})
    g.attrs["shear_points"] = strict_json(outcome.yield_points())
    g.attrs["locus"] = strict_json(outcome.locus.to_dict())
    _write_scalars(g, outcome.scalars, {**SCALAR_UNITS, **SHEAR_SCALAR_UNITS})
    stages = [(n, st, "consolidation") for n, st in outcome.consolidation.items()]
    stages += [(n, st, "shear") for n, st in outcome.stages.items()]
    _write_stages(g, stages, {**CURVE_UNITS, **SHEAR_CURVE_UNITS}, keep_particles)


#: The stage a hopper run's discharge curves are stored as (module docstring).
HOPPER_STAGE = "discharge"
#: A hopper run's wall normal stress profiles: dataset name in group ``wall_stress`` ->
#: (the :class:`engine.HopperResult` attribute, its units).
HOPPER_WALL_STRESS = {
    "edges": ("wall_edges", "m"),
    "fill": ("wall_stress_fill", "Pa"),
    "flow": ("wall_stress_flow", "Pa"),
}


def write_hopper_group(g, outcome, keep_particles: bool = True) -> None:
    """An :class:`engine.HopperResult` in the run layout (module docstring): its discharge
    curves as the one stage :data:`HOPPER_STAGE` (no particles: a hopper run keeps none, so
    ``keep_particles`` changes nothing), its wall stress profiles in group ``wall_stress``."""
    from types import SimpleNamespace

    from ..hopper.results import HOPPER_CURVE_UNITS, HOPPER_SCALAR_UNITS

    g.attrs["test"] = json.dumps({"type": "HopperTest", **outcome.test.to_dict()})
    _write_scalars(g, outcome.scalars, HOPPER_SCALAR_UNITS)
    # the run's steps, settling and discharge together: a hopper counts no stage's own
    stage = SimpleNamespace(curves=outcome.curves, steps=outcome.scalars["steps"])
    _write_stages(g, [(HOPPER_STAGE, stage, "discharge")], HOPPER_CURVE_UNITS, False)
    ws = g.create_group("wall_stress")
    for name, (attr, units) in HOPPER_WALL_STRESS.items():
        ds = ws.create_dataset(name, data=np.asarray(getattr(outcome, attr), dtype=float))
        ds.attrs["units"] = units


def write_addition(g, key: str, added: list[dict]) -> None:
    """The round of the added run ``key``, as attrs of its group (or file) ``g`` (module
    docstring): ``added`` lists every addition of the round, ``key``'s among them
    (``ValueError`` where it is not)."""
    own = next((a for a in added if a["run"] == key), None)
    if own is None:
        raise ValueError(f"run {key}: not among the additions of its round {added!r}")
    g.attrs.update(
        {
            "round": int(own["round"]),
            "reason": str(own["reason"]),
            "added_kind": str(own["kind"]),
            "round_added": strict_json(
                [{k: a[k] for k in ("run", "round", "kind", "reason")} for a in added]
            ),
        }
    )


def read_addition(g) -> list[dict] | None:
    """The additions of the round stored with a run (its group ``g``), None for a planned
    run or one stored before rounds were recorded."""
    text = g.attrs.get("round_added")
    return None if text is None else json.loads(text)


def stored_additions(directory: Path) -> list[dict]:
    """Every addition stored with the runs in ``directory`` (``<key>.h5``), each ``{run,
    round, kind, reason}``, by round and in each round's order: what a ``decide`` study's
    rounds added (engine.study.loop.StudyLoop's ``decided``). Empty for a folder of runs
    stored before rounds were recorded."""
    import h5py

    rounds: dict[int, list[dict]] = {}
    for path in sorted(Path(directory).glob("*.h5")):
        try:
            with h5py.File(path, "r") as f:
                added = read_addition(f)
        except OSError:  # a file being written, or not HDF5: no round read from it
            continue
        if added:
            rounds.setdefault(int(added[0]["round"]), added)
    return [a for r in sorted(rounds) for a in rounds[r]]


def read_shear_group(g, test: dict):
    """The :class:`engine.ShearResult` stored in the group ``g`` (its test's JSON ``test``,
    the kind's tag removed)."""
    from ..shear.locus import YieldLocus
    from ..shear.results import ShearPoint, ShearResult, ShearStage
    from ..shear.spec import ShearTest

    scalars = _read_scalars(g)
    consolidation, stages = {}, {}
    for name in stage_names(g):
        sg = g["stages"][name]
        curves = {c: sg[c][()] for c in sg if c != "particles"}
        if sg.attrs.get("part") == "consolidation":
            p = sg.get("particles")
            consolidation[name] = StageResult(
                name,
                curves,
                None if p is None else p["positions"][()],
                None if p is None else p["radii"][()],
                int(sg.attrs["steps"]),
            )
        else:
            stages[name] = ShearStage(name, curves, int(sg.attrs["steps"]))
    points = tuple(
        ShearPoint(p["target"], p["sigma"], p["tau"], p["strain"], bool(p["peaked"]))
        for p in json.loads(g.attrs["shear_points"])
        if p["kind"] == "failure"
    )
    locus = json.loads(g.attrs["locus"])
    if locus.get("ffc") is None:  # stored as null: sigma_c = 0, ffc infinite
        locus["ffc"] = float("inf")
    locus = YieldLocus(**locus)
    return ShearResult(ShearTest.from_dict(test), consolidation, stages, points, locus, scalars)


def stage_names(g) -> list[str]:
    """The stages of a stored run (group ``g``) in the order they ran."""
    return sorted(g["stages"], key=lambda n: int(g["stages"][n].attrs["position"]))


def read_run_group(g):
    """The outcome stored in the group (or file) ``g``: a result of the kind its test's JSON
    names by its ``"type"`` (``TestKind.read_group``, engine.study.kinds; none: a uniaxial
    test) or the error text."""
    if "error" in g.attrs:
        return str(g.attrs["error"])
    from ..study.kinds import KINDS

    stored = json.loads(g.attrs["test"])
    tag = stored.get("type")
    kinds = {k.json_type or k.spec.__name__: k for k in KINDS.values()}
    kind = next(k for k in KINDS.values() if k.json_type is None) if tag is None else kinds.get(tag)
    if kind is None:
        raise ValueError(f"stored run {g.name}: a test of an unknown type {tag!r}")
    return kind.read_group(g, {k: v for k, v in stored.items() if k != "type"})


def _read_scalars(g) -> dict[str, float]:
    return {k: float(v) for k, v in g["scalars"].attrs.items() if not k.endswith("_units")}


def read_uniaxial_group(g, test: dict):
    """The :class:`engine.UniaxialResult` stored in the group ``g`` (its test's JSON
    ``test``)."""
    test = UniaxialTest.from_stored(test)
    scalars = _read_scalars(g)
    stages = {}
    for name in stage_names(g):
        sg = g["stages"][name]
        p = sg.get("particles")
        stages[name] = StageResult(
            name,
            {c: sg[c][()] for c in sg if c != "particles"},
            None if p is None else p["positions"][()],
            None if p is None else p["radii"][()],
            int(sg.attrs["steps"]),
        )
    if "unconfined_failure" in scalars and "unconfined" in stages:
        # one criterion for every run, stored before or after it was written: failure is
        # derived from the stored curve its strength is read from
        # (engine.uniaxial.measures.failed_by_curve, strength_curve)
        u = stages["unconfined"].curves
        failed = scalars["unconfined_failure"] == 1.0 or curve_failed(test, u)
        scalars["unconfined_failure"] = 1.0 if failed else 0.0
    return UniaxialResult(test, stages, scalars)


def read_hopper_group(g, test: dict):
    """The :class:`engine.HopperResult` stored in the group ``g`` (its test's JSON ``test``,
    the kind's tag removed)."""
    from ..hopper.results import HopperResult
    from ..hopper.spec import HopperTest

    sg = g["stages"][HOPPER_STAGE]
    ws = g["wall_stress"]
    profiles = {attr: ws[name][()] for name, (attr, _) in HOPPER_WALL_STRESS.items()}
    return HopperResult(
        HopperTest.from_dict(test),
        {c: sg[c][()] for c in sg},
        scalars=_read_scalars(g),
        **profiles,
    )


def save_run(
    path: Path, outcome, keep_particles: bool = True, added: list[dict] | None = None
) -> Path:
    """Write ``outcome`` (a result of a registered test kind, or an error text) to ``path``
    atomically; with
    ``keep_particles`` also the particle positions and radii at each stage's end; with
    ``added`` (a ``decide`` study's added run: the additions of its round, as
    ``run_study``'s ``on_run`` hears them) its round and reason (module docstring)."""
    import h5py
    import numba

    from .. import __version__

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{socket.gethostname()}.{os.getpid()}.tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["versions"] = json.dumps(
                {"demscale": __version__, "numba": numba.__version__, "numpy": np.__version__}
            )
            f.attrs["machine"] = json.dumps(this_machine())
            f.attrs["code"] = json.dumps(this_code())
            write_run_group(f, outcome, keep_particles)
            if added:
                write_addition(f, path.stem, added)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def load_run(path: Path):
    """The stored outcome: a result of its test's kind (:func:`read_run_group`) or the
    error text."""
    import h5py

    with h5py.File(path, "r") as f:
        return read_run_group(f)


# ---------------------------------------------------------------------- a study's file
SCHEMA = "demscale-study"
#: 2: each run is stored in the per-run layout (attrs test, group scalars, stages/<name>),
#: the study's own attributes beside it; 1 (before 0.2.0): curves and scalars on the run group.
SCHEMA_VERSION = 2


class StoreRefused(RuntimeError):
    """``before_rename`` said no: the study's file was not put in place."""


def versions() -> dict[str, str]:
    """Versions of the packages that produced a result."""
    from importlib.metadata import PackageNotFoundError, version

    from .. import __version__

    out = {}
    for name in ("demscale", "numpy", "numba", "h5py"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = __version__ if name == "demscale" else "unknown"
    return out


def strict_json(obj) -> str:
    """JSON text with NaN and infinities as null (strict JSON, as the API serves it)."""
    if isinstance(obj, float) and not np.isfinite(obj):
        return "null"
    if isinstance(obj, dict):
        return (
            "{" + ", ".join(f"{json.dumps(str(k))}: {strict_json(v)}" for k, v in obj.items()) + "}"
        )
    if isinstance(obj, (list, tuple)):
        return "[" + ", ".join(strict_json(v) for v in obj) + "]"
    return json.dumps(obj.item() if isinstance(obj, np.generic) else obj)


def _column(values: list, text) -> np.ndarray:
    if all(isinstance(v, str) for v in values):
        return np.array(values, dtype=text)
    if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int64)
    return np.array(values, dtype=np.float64)


def save_study(path: Path, study_id: object, result, before_rename=lambda: True) -> Path:
    """Write the :class:`engine.StudyResult` ``result`` to ``path`` atomically (a temporary
    file in the same folder, fsynced, renamed over ``path``, the folder fsynced).

    Layout (``schema`` "demscale-study", ``schema_version`` :data:`SCHEMA_VERSION`)::

        /                 attrs: schema, schema_version, study_id, created, spec, summary,
                          advisor (the report's JSON), versions (JSON), version_<package>
        /runs/<key>       a run in the per-run layout (:func:`write_run_group`: attrs test,
                          group scalars, stages/<stage>/<curve>, stages/<stage>/particles),
                          plus attrs label, reference, position, radius (+ radius_units),
                          rule, seed, the rule's stiffness_exponent, adhesion_exponent,
                          adhesive_exponent and dt_rule, and each error err_* (+ _units);
                          a run a decide study added: round, reason, added_kind,
                          round_added (:func:`write_addition`)
        /summary          attrs: columns; one 1-D dataset per table column with units

    ``before_rename()`` is asked right before the rename: False raises
    :class:`StoreRefused` and leaves ``path`` alone (no temporary file is left either)."""
    import uuid
    from datetime import datetime, timezone

    import h5py

    from ..study.results import table_units

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # unique even for two containerised workers that are both PID 1 on a shared volume
    tmp = path.with_name(f"{path.stem}.{uuid.uuid4().hex}.h5.tmp")
    text = h5py.string_dtype("utf-8")
    try:
        with h5py.File(tmp, "w", track_order=True) as f:
            vs = versions()
            f.attrs.update(
                {
                    "schema": SCHEMA,
                    "schema_version": SCHEMA_VERSION,
                    "study_id": str(study_id),
                    "created": datetime.now(timezone.utc).isoformat(),
                    "spec": json.dumps(result.spec.to_dict()),
                    "summary": strict_json(result.to_summary()),
                    "advisor": strict_json(result.report.to_dict()),
                    "versions": json.dumps(vs),
                    **{f"version_{k}": v for k, v in vs.items()},
                }
            )
            runs = f.create_group("runs", track_order=True)
            rounds = _rounds_of(result.report)
            for i, (key, run) in enumerate(result.runs.items()):
                g = runs.create_group(key, track_order=True)
                write_run_group(g, run.result)
                if key in rounds:
                    write_addition(g, key, rounds[key])
                g.attrs.update(
                    {
                        "label": run.key,
                        "reference": run.is_reference,
                        "control": run.control,
                        "position": i,
                        "radius": run.radius,
                        "radius_units": "m",
                        "seed": run.seed,
                        "rule": run.label,
                    }
                )
                if run.rule is not None:
                    a, b, c = run.rule.exponents(run.result.test.pair_law)
                    g.attrs.update(
                        {
                            "stiffness_exponent": a,
                            "adhesion_exponent": b,
                            "adhesive_exponent": c,
                            "dt_rule": run.rule.dt,
                        }
                    )
                for name, value in run.errors.items():
                    g.attrs[name] = float(value)
                    g.attrs[f"{name}_units"] = "1"
            summary = f.create_group("summary", track_order=True)
            units = table_units(result.spec)
            columns = [c for c in units if c in result.table[0]]
            columns += [c for c in result.table[0] if c not in columns]
            summary.attrs["columns"] = columns
            for c in columns:
                ds = summary.create_dataset(c, data=_column([row[c] for row in result.table], text))
                ds.attrs["units"] = units.get(c, "")
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        if not before_rename():
            raise StoreRefused(f"study {study_id}: its file was not stored")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
    return path


def _rounds_of(report) -> dict[str, list[dict]]:
    """Run key -> the additions of its round, from a report's (an
    :class:`engine.study.report.StudyReport`) ``adaptive`` entry."""
    added = [dict(a) for a in report.adaptive.added_runs] if report.adaptive else []
    return {a["run"]: [b for b in added if b["round"] == a["round"]] for a in added}


def completed_runs(study, directory: Path, decided: list | None = None):
    """The runs of ``study`` (an :class:`engine.StudyPlan`, or a spec planned here) stored in
    ``directory`` whose test is exactly the planned one (what ``run_study(completed=...)``
    resumes from), and the keys of stored runs made with other parameters (to be run again).
    With ``decide`` the runs its rounds added are found too: read from their stored rounds
    (:func:`stored_additions`; a ``decided`` list, filled here, receives them, for
    ``run_study(decided=...)``), or, for runs stored before rounds were recorded, replayed
    round by round from the stored outcomes (engine.study.loop.plan_runs)."""
    from ..study.loop import plan_runs
    from ..study.plan import as_plan

    study = as_plan(study)
    rounds = stored_additions(directory) if study.spec.decide else []
    while True:
        done, stale, seen = {}, [], set()
        while True:
            planned = {p.key: p.test for p in plan_runs(study, done, rounds)[0]}
            fresh = [k for k in planned if k not in seen]
            if not fresh:
                break
            seen.update(fresh)
            for key, outcome in load_all(directory, fresh).items():
                if isinstance(outcome, str) or outcome.test == planned[key]:
                    done[key] = outcome
                else:
                    stale.append(key)
        if not rounds or not any(a["run"] in stale for a in rounds):
            break
        rounds = []  # rounds stored by another study's runs: replayed from the outcomes
    if decided is not None:
        decided[:] = rounds
    return done, stale


def load_study(path: Path):
    """The :class:`engine.StudyResult` of a study's file (:func:`save_study`), recomputed
    from its stored runs (engine.study.results.assemble) with the rounds its added runs
    were stored with (attrs ``round_added``; a file stored before they were recorded has
    its rounds replayed from its runs, which finds the same ones). Runs the file does not
    hold (failed, or not comparable) are what its stored summary says of them: a failed
    run's error text, else not run."""
    import h5py

    from ..study.loop import StudyLoop
    from ..study.spec import StudySpec

    with h5py.File(path, "r") as f:
        spec = StudySpec.from_dict(json.loads(f.attrs["spec"]))
        outcomes = {k: read_run_group(g) for k, g in f["runs"].items()}
        rounds: dict[int, list] = {}
        for g in f["runs"].values():
            added = read_addition(g)
            if added:
                rounds.setdefault(int(added[0]["round"]), added)
        failed = json.loads(f.attrs["summary"]).get("failed", {})
    for key, text in failed.items():
        if key not in outcomes and text != "not run" and not text.startswith("not comparable"):
            outcomes[key] = text
    decided = [a for r in sorted(rounds) for a in rounds[r]]
    return StudyLoop(spec, outcomes, decided).result()


def load_all(directory: Path, keys) -> dict:
    """Stored outcomes of the given run keys found in ``directory``."""
    out = {}
    for k in keys:
        p = Path(directory) / f"{k}.h5"
        if p.exists():
            out[k] = load_run(p)
    return out
