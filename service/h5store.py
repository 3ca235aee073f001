"""The study's HDF5 file as the service reads it: written by the engine
(:func:`engine.io.store.save_study`, the one layout of a run and a study; schema version 2,
see docs/SERVICE.md), read back here for the summary, the curves and the plots."""

from __future__ import annotations

import json
from pathlib import Path

import h5py

from engine.io.store import (
    SCHEMA,
    SCHEMA_VERSION,
    StoreRefused,
    save_study,
    stage_names,
    strict_json,
)
from engine.study.report import StudyReport

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "NotOurs",
    "read_plot_data",
    "read_runs",
    "read_summary",
    "write_results",
]

#: The study was taken over while its results were being written: nothing was renamed into
#: place (the engine's refusal, under the service's name).
NotOurs = StoreRefused


def write_results(path: Path, study_id: object, result, still_ours=lambda: True) -> Path:
    """Write the :class:`engine.StudyResult` ``result`` to ``path`` atomically
    (:func:`engine.io.store.save_study`); ``still_ours()`` is asked just before the rename,
    False raises :class:`NotOurs` and leaves ``path`` alone."""
    return save_study(path, study_id, result, before_rename=still_ours)


def read_summary(path: Path) -> dict:
    """The study summary (the answer, table, groups, the report's JSON under ``advisor``,
    units) stored in the file; a summary stored before it had its ``answer`` gets it from
    its report (:func:`engine.study.advice.answer_lines`, the reference radius read from
    its table)."""
    from engine.study.advice import answer_lines

    with h5py.File(path, "r") as f:
        summary = json.loads(f.attrs["summary"])
    if not summary.get("answer"):
        refs = [row["radius"] for row in summary.get("table", []) if not row.get("rule")]
        report = StudyReport.from_dict(summary.get("advisor"))
        answer = answer_lines(report, min(refs) if refs else None)
        summary = {"answer": answer, **summary}
    return summary


def read_run_scalars(path: Path, names: tuple[str, ...]) -> dict[str, dict[str, float]]:
    """Per run key, the stored scalars ``names`` it has (e.g. ``setup_time`` [s]: kernel
    compilation, kept out of the run's wall time)."""
    out: dict[str, dict[str, float]] = {}
    with h5py.File(path, "r") as f:
        for key, g in f["runs"].items():
            attrs = g["scalars"].attrs if "scalars" in g else {}
            out[key] = {n: float(attrs[n]) for n in names if n in attrs}
    return out


def _decode(value):
    return value.decode() if isinstance(value, bytes) else value


def read_runs(
    path: Path, run: str | None = None, stage: str | None = None, with_units: bool = False
) -> dict:
    """Curves of the runs (all, or ``run``) and stages (all, or ``stage``) as
    ``{key: {"label", "reference", "radius", "rule", "seed", "stages": {stage: {curve:
    array}}}}``; a shear study's run also ``"points"`` (its yield points, the pre-shear
    point first: kind, target, sigma, tau, strain, peaked) and ``"locus"`` (the fitted
    yield locus: cohesion, slope, friction_angle, sigma_1, sigma_c, ffc (null where
    sigma_c = 0: infinite), ...); with
    ``with_units`` also ``"units": {curve: unit}`` at the top level. Raises KeyError
    naming what is missing."""
    out: dict = {}
    units: dict = {}
    with h5py.File(path, "r") as f:
        names = list(f["runs"])  # by name: a key such as ".." or "/" is no path into the file
        keys = names if run is None else [run]
        for key in keys:
            if key not in names:
                raise KeyError(f"no run {key!r}; runs: {sorted(f['runs'])}")
            g = f["runs"][key]
            present = stage_names(g)
            stages = present if stage is None else [stage]
            entry = {
                "label": _decode(g.attrs["label"]),
                "reference": bool(g.attrs["reference"]),
                "radius": float(g.attrs["radius"]),
                "rule": _decode(g.attrs["rule"]),
                "seed": int(g.attrs["seed"]),
                "stages": {},
            }
            if "shear_points" in g.attrs:  # a shear run (engine.io.store)
                # strict JSON: an infinite ffc (sigma_c = 0) as null, also in a file stored
                # before engine.io.store wrote it so (Python's json wrote Infinity)
                entry["points"] = json.loads(strict_json(json.loads(g.attrs["shear_points"])))
                entry["locus"] = json.loads(strict_json(json.loads(g.attrs["locus"])))
            for s in stages:
                if s not in present:
                    if run is not None or stage is None:
                        raise KeyError(f"run {key!r} has no stage {s!r}; stages: {present}")
                    continue
                curves = {}
                for name, ds in g["stages"][s].items():
                    if name == "particles":
                        continue
                    curves[name] = ds[()]
                    units[name] = _decode(ds.attrs["units"])
                entry["stages"][s] = curves
            out[key] = entry
    if stage is not None and not any(e["stages"] for e in out.values()):
        raise KeyError(f"no run has a stage {stage!r}")
    return {"runs": out, "units": units} if with_units else out


def read_plot_data(path: Path) -> tuple[dict, list[dict], StudyReport | None]:
    """``(runs, table, report)`` as :func:`engine.io.figures.figure` takes them, from the
    stored file (the report None where the summary has none)."""
    summary = read_summary(path)
    advice = summary.get("advisor")
    report = None if advice is None else StudyReport.from_dict(advice)
    return read_runs(path), summary["table"], report
