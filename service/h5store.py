"""HDF5 result files: one per study, written once by the worker, atomically.

Layout (schema version 1; see docs/SERVICE.md)::

    /                      attrs: schema, schema_version, study_id, created, spec (JSON),
                           summary (JSON), advisor (JSON), versions (JSON), version_<package>
    /runs/<key>            attrs: label, reference, position, radius (+ radius_units), rule,
                           stiffness_exponent, adhesion_exponent, adhesive_exponent (the
                           rule's exponents for the run's law), dt_rule, seed, every scalar
                           <name> with <name>_units, every error err_* with err_*_units
    /runs/<key>/<stage>    attrs: steps, position; datasets: one 1-D per curve and
                           positions (N, 3), radii (N,), each with a ``units`` attribute
    /summary               attrs: columns; one 1-D dataset per table column with ``units``
"""

from __future__ import annotations

import json
import os
import uuid
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import h5py
import numpy as np

import engine
from engine.study import TABLE_UNITS
from engine.uniaxial import CURVE_UNITS, SCALAR_UNITS

SCHEMA = "demscale-study"
SCHEMA_VERSION = 1
_STR = h5py.string_dtype("utf-8")


def versions() -> dict[str, str]:
    """Versions of the packages that produced a result."""
    out = {}
    for name in ("demscale", "numpy", "numba", "h5py"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = engine.__version__ if name == "demscale" else "unknown"
    return out


def _json(obj) -> str:
    """JSON text with NaN and infinities as null (strict JSON, as the API serves it)."""
    if isinstance(obj, float) and not np.isfinite(obj):
        return "null"
    if isinstance(obj, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_json(v)}" for k, v in obj.items()) + "}"
    if isinstance(obj, (list, tuple)):
        return "[" + ", ".join(_json(v) for v in obj) + "]"
    return json.dumps(obj.item() if isinstance(obj, np.generic) else obj)


def _column(values: list) -> np.ndarray:
    if all(isinstance(v, str) for v in values):
        return np.array(values, dtype=_STR)
    if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int64)
    return np.array(values, dtype=np.float64)


def _write_run(g: h5py.Group, position: int, run) -> None:
    g.attrs.update(
        {
            "label": run.key,
            "reference": run.rule is None,
            "position": position,
            "radius": run.radius,
            "radius_units": "m",
            "seed": run.seed,
            "rule": "reference" if run.rule is None else run.rule.name,
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
    for name, value in run.result.scalars.items():
        g.attrs[name] = float(value)
        g.attrs[f"{name}_units"] = SCALAR_UNITS.get(name, "")
    for name, value in run.errors.items():
        g.attrs[name] = float(value)
        g.attrs[f"{name}_units"] = "1"
    for i, (stage_name, stage) in enumerate(run.result.stages.items()):
        sg = g.create_group(stage_name, track_order=True)
        sg.attrs.update({"steps": int(stage.steps), "position": i})
        for curve, values in stage.curves.items():
            ds = sg.create_dataset(curve, data=np.asarray(values, dtype=np.float64))
            ds.attrs["units"] = CURVE_UNITS.get(curve, "")
        for name, values in (("positions", stage.positions), ("radii", stage.radii)):
            if values is None:  # a run read back from a store that did not keep particles
                continue
            ds = sg.create_dataset(
                name, data=np.asarray(values, dtype=np.float64), compression="gzip"
            )
            ds.attrs["units"] = "m"


class NotOurs(RuntimeError):
    """The study was taken over while its results were being written: nothing was renamed
    into place."""


def write_results(path: Path, study_id: object, result, still_ours=lambda: True) -> Path:
    """Write the :class:`engine.StudyResult` ``result`` to ``path`` atomically (a temporary
    file in the same directory, fsynced, then renamed over ``path``). ``still_ours()`` is
    asked just before the rename; False raises :class:`NotOurs` and leaves ``path`` alone."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # unique even for two containerised workers that are both PID 1 on a shared volume
    tmp = path.with_name(f"{path.stem}.{uuid.uuid4().hex}.h5.tmp")
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
                    "summary": _json(result.to_summary()),
                    "advisor": _json(result.advisor),
                    "versions": json.dumps(vs),
                    **{f"version_{k}": v for k, v in vs.items()},
                }
            )
            runs = f.create_group("runs", track_order=True)
            for i, (key, run) in enumerate(result.runs.items()):
                _write_run(runs.create_group(key, track_order=True), i, run)
            summary = f.create_group("summary", track_order=True)
            columns = [c for c in TABLE_UNITS if c in result.table[0]]
            columns += [c for c in result.table[0] if c not in columns]
            summary.attrs["columns"] = columns
            for c in columns:
                ds = summary.create_dataset(c, data=_column([row[c] for row in result.table]))
                ds.attrs["units"] = TABLE_UNITS.get(c, "")
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        if not still_ours():
            raise NotOurs(f"study {study_id} is no longer this worker's: results not stored")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
    return path


def read_summary(path: Path) -> dict:
    """The study summary (table, groups, advisor, units) stored in the file."""
    with h5py.File(path, "r") as f:
        return json.loads(f.attrs["summary"])


def _decode(value):
    return value.decode() if isinstance(value, bytes) else value


def read_runs(
    path: Path, run: str | None = None, stage: str | None = None, with_units: bool = False
) -> dict:
    """Curves of the runs (all, or ``run``) and stages (all, or ``stage``) as
    ``{key: {"label", "reference", "radius", "rule", "seed", "stages": {stage: {curve:
    array}}}}``; with ``with_units`` also ``"units": {curve: unit}`` at the top level.
    Raises KeyError naming what is missing."""
    out: dict = {}
    units: dict = {}
    with h5py.File(path, "r") as f:
        names = list(f["runs"])  # by name: a key such as ".." or "/" is no path into the file
        keys = names if run is None else [run]
        for key in keys:
            if key not in names:
                raise KeyError(f"no run {key!r}; runs: {sorted(f['runs'])}")
            g = f["runs"][key]
            stages = list(g) if stage is None else [stage]
            entry = {
                "label": _decode(g.attrs["label"]),
                "reference": bool(g.attrs["reference"]),
                "radius": float(g.attrs["radius"]),
                "rule": _decode(g.attrs["rule"]),
                "seed": int(g.attrs["seed"]),
                "stages": {},
            }
            for s in stages:
                if s not in g:
                    if run is not None or stage is None:
                        raise KeyError(f"run {key!r} has no stage {s!r}; stages: {list(g)}")
                    continue
                curves = {}
                for name, ds in g[s].items():
                    if name in ("positions", "radii"):
                        continue
                    curves[name] = ds[()]
                    units[name] = _decode(ds.attrs["units"])
                entry["stages"][s] = curves
            out[key] = entry
    if stage is not None and not any(e["stages"] for e in out.values()):
        raise KeyError(f"no run has a stage {stage!r}")
    return {"runs": out, "units": units} if with_units else out


def read_plot_data(path: Path) -> tuple[dict, list[dict], dict | None]:
    """``(runs, table, advisor)`` as :func:`engine.plots.figure` takes them, from the stored
    file."""
    summary = read_summary(path)
    return read_runs(path), summary["table"], summary.get("advisor")
