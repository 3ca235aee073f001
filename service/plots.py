"""PNG plots of a finished study, drawn from its HDF5 file with matplotlib's object API
(``engine.io.figures.figure`` on an Agg canvas; pyplot is never imported) and cached next to it.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

from engine.io import figures as engine_plots

from .h5store import read_plot_data

#: Plot kinds the API knows (of either kind of test); a study has only those of its own
#: kind of test (:func:`study_kinds`).
KINDS = tuple(engine_plots.KINDS)


def study_kinds(spec: dict) -> tuple[str, ...]:
    """The plot kinds of the study whose stored spec (engine.StudySpec.to_dict) is
    ``spec``: engine.io.figures.plot_kinds, asked of its kind of test."""
    return engine_plots.plot_kinds(spec)


def not_a_kind_of(spec: dict, kind: str) -> str | None:
    """Why the study of ``spec`` has no plot ``kind`` (naming the kinds it has), or None
    when it has it."""
    kinds = study_kinds(spec)
    if kind in kinds:
        return None
    test = engine_plots.TEST_NAMES[engine_plots.reference_type(spec.get("reference") or {})]
    return f"this {test} study has no {kind} plot; its plots: {', '.join(kinds)}"


def render_png(kind: str, runs: dict, table: list[dict], report=None) -> bytes:
    """PNG bytes of plot ``kind`` for the given runs, summary table and the study's
    :class:`engine.study.report.StudyReport`."""
    fig = engine_plots.figure(kind, runs, table, report)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def plot_png(results: Path, kind: str) -> bytes:
    """PNG of ``kind`` for the study stored in ``results``: from the cache file
    ``plots/<kind>.png`` beside it when that is newer than the results, else drawn and
    cached (written atomically, so concurrent requests never see half a file)."""
    if kind not in KINDS:
        raise KeyError(f"unknown plot kind {kind!r}; kinds: {list(KINDS)}")
    # the figures' version in the name: a plot drawn by older code is drawn again
    cached = results.parent / "plots" / f"{kind}.v{engine_plots.FIGURES_VERSION}.png"
    try:
        if cached.stat().st_mtime >= results.stat().st_mtime:
            return cached.read_bytes()
    except FileNotFoundError:
        pass
    png = render_png(kind, *read_plot_data(results))
    cached.parent.mkdir(parents=True, exist_ok=True)
    tmp = cached.with_name(f".{kind}.{os.getpid()}.{id(png)}.tmp")
    tmp.write_bytes(png)
    os.replace(tmp, cached)
    return png
