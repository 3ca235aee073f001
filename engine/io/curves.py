"""A run's curves as CSV: one row per curve sample of every stage, in the order the stages
ran, the stage named in the first column and each curve's unit in its heading (``time
[s]``, ``stress_top [Pa]``, ``porosity [1]``). What a spreadsheet or pandas reads without
HDF5 (``pandas.read_csv(path)``). numpy and the standard library only."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from ..hopper.results import HOPPER_CURVE_UNITS
from ..shear.results import SHEAR_CURVE_UNITS
from ..uniaxial.results import CURVE_UNITS

#: Units of every curve a run has: the uniaxial test's, then the shear test's stages', then
#: a hopper's discharge.
_UNITS = {**CURVE_UNITS, **{k: v for k, v in SHEAR_CURVE_UNITS.items() if k not in CURVE_UNITS}}
_UNITS.update({k: v for k, v in HOPPER_CURVE_UNITS.items() if k not in _UNITS})

__all__ = ["curves_csv", "runs_csv", "write_curves_csv"]


def stage_curves(result) -> dict:
    """Stage -> {curve: 1-D array} of ``result``, in the order its stages ran: a uniaxial or
    shear result's stages, a hopper's discharge as the one stage ``"discharge"`` (as
    engine.io.store stores it), or a mapping of that form as it is."""
    if hasattr(result, "stages"):
        return {name: st.curves for name, st in result.stages.items()}
    if hasattr(result, "curves"):  # an engine.HopperResult
        from .store import HOPPER_STAGE

        return {HOPPER_STAGE: result.curves}
    return dict(result)


def curves_csv(result) -> str:
    """The curves of every stage of ``result`` (an :class:`engine.UniaxialResult`, an
    :class:`engine.ShearResult`: its shear stages, an :class:`engine.HopperResult`: its
    discharge (:func:`stage_curves`), or a mapping stage -> {curve: 1-D array}
    in the order the stages ran) as CSV text: a heading ``stage,<curve> [<unit>],...`` (in
    :data:`engine.uniaxial.results.CURVE_UNITS` order, then the shear test's
    :data:`engine.shear.results.SHEAR_CURVE_UNITS`, then any others), then a row per
    sample. Values are written in full precision (``repr``); a stage that lacks a curve
    another has leaves it empty."""
    stages = stage_curves(result)
    names: list[str] = []
    for curves in stages.values():
        names += [n for n in curves if n not in names]
    order = list(_UNITS)
    names.sort(key=lambda n: (order.index(n) if n in order else len(order), n))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["stage", *(f"{n} [{_UNITS.get(n, '1')}]" for n in names)])
    for stage, curves in stages.items():
        cols = [np.asarray(curves[n]) if n in curves else None for n in names]
        rows = max((len(c) for c in cols if c is not None), default=0)
        for i in range(rows):
            w.writerow([stage, *("" if c is None else repr(float(c[i])) for c in cols)])
    return buf.getvalue()


def runs_csv(runs: dict) -> str:
    """The curves of several runs (run key -> an :class:`engine.UniaxialResult` or a
    mapping stage -> curves) as one CSV text: :func:`curves_csv`'s columns after a ``run``
    column, the runs in the order given."""
    parts = {key: curves_csv(value).splitlines() for key, value in runs.items()}
    heads = {lines[0] for lines in parts.values() if lines}
    if len(heads) > 1:  # runs with other curves: one heading of them all
        names: list[str] = []
        for lines in parts.values():
            names += [h for h in lines[0].split(",")[1:] if h not in names]
        order = list(_UNITS)
        names.sort(
            key=lambda h: (
                order.index(h.split(" [")[0]) if h.split(" [")[0] in order else len(order),
                h,
            )
        )
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["run", "stage", *names])
        for key, lines in parts.items():
            head = lines[0].split(",")[1:]
            for row in csv.reader(lines[1:]):
                values = dict(zip(head, row[1:]))
                w.writerow([key, row[0], *(values.get(n, "") for n in names)])
        return buf.getvalue()
    head = next(iter(heads), "stage")
    out = [f"run,{head}"]
    for key, lines in parts.items():
        out += [f"{key},{line}" for line in lines[1:]]
    return "\n".join(out) + "\n"


def write_curves_csv(result, path) -> Path:
    """Write :func:`curves_csv` of ``result`` to ``path`` (a temporary file, then renamed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(curves_csv(result))
    os.replace(tmp, path)
    return path
