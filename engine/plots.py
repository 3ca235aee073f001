"""Figures of a scaling study, drawn with matplotlib's object API (no pyplot, no display).

Every function works on plain data so that a live :class:`engine.StudyResult` and a study read
back from its HDF5 file draw the same pictures:

``runs``  key -> {"label": str, "reference": bool, "stages": {stage: {curve: 1-D array}}}
``table`` one dict per run with the columns of :data:`engine.study.TABLE_UNITS`

matplotlib is imported only when a figure is drawn (the engine does not depend on it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Plot kinds and their titles.
KINDS = {
    "stress_strain": "Confined compression and unloading: stress against strain",
    "stress_porosity": "Confined compression and unloading: porosity against stress",
    "coordination": "Confined compression and unloading: coordination number against stress",
    "unconfined": "Unconfined compression to failure",
    "error_vs_runtime": "Error against the reference and run time",
}

_CONFINED = ("consolidation", "unloading")
_ERRORS = {
    "err_stress_strain": ("stress-strain", "o"),
    "err_stress_porosity": ("stress-porosity", "s"),
    "err_coordination": ("coordination", "^"),
    "err_strength": ("unconfined strength", "D"),
}


def study_plot_data(result) -> tuple[dict, list[dict]]:
    """``(runs, table)`` of a live :class:`engine.StudyResult`."""
    runs = {
        key: {"label": key, "reference": r.rule is None,
              "stages": {name: st.curves for name, st in r.result.stages.items()}}
        for key, r in result.runs.items()
    }
    return runs, result.table


def _style(i: int, ref: bool) -> dict:
    if ref:
        return {"color": "black", "lw": 2.2, "zorder": 5}
    return {"color": f"C{i % 10}", "lw": 1.3, "alpha": 0.9}


def _confined(ax, runs: dict, x: str | None, y: str | None, xscale=1.0, yscale=1.0) -> None:
    """Consolidation (solid) and unloading (dashed) of every run; ``None`` means stress."""
    for i, (_key, run) in enumerate(runs.items()):
        st = _style(i, run["reference"])
        for stage, ls in zip(_CONFINED, ("-", "--")):
            c = run["stages"].get(stage)
            if c is None:
                continue
            xs = np.asarray(c["stress_top"] if x is None else c[x]) * xscale
            ys = np.asarray(c["stress_top"] if y is None else c[y]) * yscale
            ax.plot(xs, ys, ls=ls, label=run["label"] if stage == "consolidation" else None,
                    **st)


def _error_vs_runtime(ax, table: list[dict]) -> None:
    ref_rows = [r for r in table if r["rule"] == "reference"]
    for row in table:
        if row["rule"] == "reference":
            continue
        for j, (name, (label, marker)) in enumerate(_ERRORS.items()):
            v = row.get(name)
            if v is None:
                continue
            ax.scatter(row["wall_time"], 100 * v, marker=marker, color=f"C{j}", s=36,
                       label=label, zorder=3)
        worst = max(row[n] for n in _ERRORS if row.get(n) is not None)
        ax.annotate(f"{row['run']}\n{row['speedup']:.1f}x", (row["wall_time"], 100 * worst),
                    textcoords="offset points", xytext=(5, 4), fontsize=7)
    for row in ref_rows:
        ax.axvline(row["wall_time"], color="black", ls=":", lw=1)
        ax.scatter(row["wall_time"], 0, marker="*", s=160, color="black", zorder=4,
                   label="reference")
        ax.annotate(row["run"], (row["wall_time"], 0), textcoords="offset points",
                    xytext=(5, 4), fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("run time (wall clock) [s]")
    ax.set_ylabel("error against the reference [%]")
    handles, labels = ax.get_legend_handles_labels()
    seen = {}
    for h, lab in zip(handles, labels):
        seen.setdefault(lab, h)
    ax.legend(seen.values(), seen.keys(), fontsize=8)


def draw(ax, kind: str, runs: dict, table: list[dict]) -> None:
    """Draw plot ``kind`` (one of :data:`KINDS`) on the matplotlib Axes ``ax``."""
    if kind not in KINDS:
        raise ValueError(f"plot kind {kind!r} is not one of {sorted(KINDS)}")
    if kind == "stress_strain":
        _confined(ax, runs, "strain", None, 100.0, 1e-3)
        ax.set_xlabel("axial strain [%]")
        ax.set_ylabel("top platen stress [kPa]")
    elif kind == "stress_porosity":
        _confined(ax, runs, None, "porosity", 1e-3, 1.0)
        ax.set_xlabel("top platen stress [kPa]")
        ax.set_ylabel("porosity [-]")
    elif kind == "coordination":
        _confined(ax, runs, None, "coordination", 1e-3, 1.0)
        ax.set_xlabel("top platen stress [kPa]")
        ax.set_ylabel("coordination number [-]")
    elif kind == "unconfined":
        for i, (_key, run) in enumerate(runs.items()):
            c = run["stages"].get("unconfined")
            if c is not None:
                ax.plot(np.asarray(c["strain"]) * 100, np.asarray(c["stress_top"]) * 1e-3,
                        label=run["label"], **_style(i, run["reference"]))
        ax.set_xlabel("axial strain since release [%]")
        ax.set_ylabel("top platen stress [kPa]")
    else:
        _error_vs_runtime(ax, table)
    if kind != "error_vs_runtime":
        ax.legend(fontsize=8, title="solid: loading, dashed: unloading"
                  if kind not in ("unconfined",) else None, title_fontsize=7)
    ax.set_title(KINDS[kind], fontsize=10)
    ax.grid(alpha=0.3)


def figure(kind: str, runs: dict, table: list[dict]):
    """A new matplotlib Figure (Agg canvas, no pyplot) with plot ``kind``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.8), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    draw(fig.add_subplot(), kind, runs, table)
    return fig


def save_all(directory, runs: dict, table: list[dict]) -> list[Path]:
    """Write ``<kind>.png`` for every kind into ``directory``; returns the paths."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = []
    for kind in KINDS:
        path = d / f"{kind}.png"
        figure(kind, runs, table).savefig(path, format="png")
        out.append(path)
    return out
