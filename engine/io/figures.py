"""Figures of a scaling study, drawn with matplotlib's object API (no pyplot, no display).

Every function works on plain data so that a live :class:`engine.StudyResult` and a study read
back from its HDF5 file draw the same pictures:

``runs``  key -> {"label": str, "reference": bool, "stages": {stage: {curve: 1-D array}}}
          (a shear run's also "points": its yield points, the pre-shear point first, as
          :meth:`engine.ShearResult.yield_points` gives them, and "locus": its fitted locus)
``table`` one dict per run with the columns of :data:`engine.study.kinds.TABLE_UNITS`
``report`` the study's :class:`engine.study.report.StudyReport` (tolerances, noise floor,
          verdicts), or None

matplotlib is imported only when a figure is drawn (the engine does not depend on it).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from ..simulation.snapshot import Snapshot, particle_fields
from ..study.kinds import kind_of_table
from ..study.metrics import METRIC_COLUMNS, SHEAR_METRIC_COLUMNS
from .curves import stage_curves

#: Plot kinds and their titles (with the units of their axes).
KINDS = {
    "stress_strain": "Confined compression and unloading: stress [kPa] against strain [%]",
    "stress_porosity": "Confined compression and unloading: porosity [-] against stress [kPa]",
    "coordination": "Confined compression and unloading: coordination number [-] against "
    "stress [kPa]",
    "unconfined": "Unconfined compression to failure: stress [kPa] against strain [%]",
    "error_vs_runtime": "Signed error against the reference [%] and run time [s]",
    "resolution": "Resolution: each property [% from the bulk or the reference] against "
    "particle diameter / sample thickness [-]",
    "yield_locus": "Shear test: yield loci, shear stress [kPa] against normal stress [kPa]",
    "preshear": "Shear test: pre-shear, shear stress [kPa] against shear strain [-]",
    "discharge": "Hopper discharge: mass discharge rate [kg/s] against time since the gate "
    "opened [s]",
}
#: The kinds of a uniaxial study and of a shear study (:func:`kinds_of`).
UNIAXIAL_KINDS = (
    "stress_strain",
    "stress_porosity",
    "coordination",
    "unconfined",
    "error_vs_runtime",
    "resolution",
)
SHEAR_KINDS = ("yield_locus", "preshear", "error_vs_runtime", "resolution")
#: A hopper study's (docs/HOPPER.md): the discharge rate against time, and the verdicts'.
HOPPER_KINDS = ("discharge", "error_vs_runtime", "resolution")
#: The discharge plot's rate is the slope of the discharged mass over a centred window of
#: this fraction of each run's discharge time (at least one sample on each side) [-]: short
#: enough to show the start, the steady stretch and the emptying, long enough that single
#: grains crossing the discharge level do not make it a comb.
RATE_WINDOW = 0.05
#: The plot kinds of each kind of test a study's reference can be, keyed on the test
#: record's type (its JSON form's ``"type"``): the one place that says which plots a study
#: has (:func:`plot_kinds`). The study's links, the API and the pages ask it.
TEST_PLOTS = {"UniaxialTest": UNIAXIAL_KINDS, "ShearTest": SHEAR_KINDS, "HopperTest": HOPPER_KINDS}
#: What each kind of test is called in a figure's words.
TEST_NAMES = {"UniaxialTest": "uniaxial", "ShearTest": "shear", "HopperTest": "hopper"}
#: Bumped when a figure's drawing changes, so that cached PNGs are drawn again.
FIGURES_VERSION = 9

#: Kinds drawn from the report on a whole figure (several panels), not from the curves.
_WHOLE_FIGURE = ("error_vs_runtime", "resolution")

#: Verdict metrics: table column (engine.study.metrics.METRIC_COLUMNS) and panel title.
_TITLES = {
    "density": "bulk density (interior)",
    "loading_stiffness": "loading stiffness",
    "unloading_stiffness": "unloading stiffness",
    "coordination": "coordination (interior)",
    "strength": "unconfined strength",
    # a shear study's (engine.study.metrics.SHEAR_METRICS)
    "yield_locus": "yield locus tau(sigma_n)",
    "sigma_1": "sigma_1 (consolidation)",
    "sigma_c": "sigma_c (strength)",
    "ffc": "flowability ffc",
    "bulk_density": "bulk density",
    # a hopper study's (engine.hopper.study.HOPPER_METRICS)
    "discharge_number": "discharge number (steady rate)",
}
_METRIC_PANELS = {
    n: ({**METRIC_COLUMNS, **SHEAR_METRIC_COLUMNS}.get(n, f"err_{n}"), t)
    for n, t in _TITLES.items()
}
_MARKERS = "osD^vP*X"


def study_plot_data(result) -> tuple[dict, list[dict], object]:
    """``(runs, table, report)`` of a live :class:`engine.StudyResult`."""
    runs = {}
    for key, r in result.runs.items():
        runs[key] = {
            "label": key,
            "reference": r.is_reference,
            "stages": stage_curves(r.result),
        }
        if hasattr(r.result, "yield_points"):  # a shear run (engine.ShearResult)
            runs[key]["points"] = r.result.yield_points()
            runs[key]["locus"] = r.result.locus.to_dict()
    return runs, result.table, result.report


def reference_type(reference) -> str:
    """The type of a study's reference test, a key of :data:`TEST_PLOTS`: the record's class
    name, or in its JSON form the ``"type"`` (a uniaxial test's may leave it out)."""
    if isinstance(reference, dict):
        return str(reference.get("type") or "UniaxialTest")
    return type(reference).__name__


def _kinds(test_type: str, unconfined: bool, controls: bool) -> tuple[str, ...]:
    kinds = TEST_PLOTS.get(test_type)
    if kinds is None:
        raise ValueError(f"no plots of a {test_type!r} reference; known: {sorted(TEST_PLOTS)}")
    return tuple(
        k for k in kinds if (k != "resolution" or controls) and (k != "unconfined" or unconfined)
    )


def plot_kinds(spec) -> tuple[str, ...]:
    """The plot kinds of the study ``spec`` (an :class:`engine.StudySpec` or its JSON form,
    as the service stores it): those of its reference's kind of test (:data:`TEST_PLOTS`),
    ``unconfined`` only where the test has the unconfined stage, ``resolution`` only with
    resolution controls. Known before any run: a study's links and the API's answers
    follow it."""
    if isinstance(spec, dict):
        from ..study.spec import StudySpec

        ref = spec.get("reference") or {}
        controls = spec.get("controls", StudySpec.__dataclass_fields__["controls"].default)
        unconfined = ref.get("unconfined", True) if isinstance(ref, dict) else True
    else:
        ref, controls = spec.reference, spec.controls
        unconfined = getattr(ref, "unconfined", True)
    return _kinds(reference_type(ref), bool(unconfined), bool(controls))


def kinds_of(table: list[dict]) -> tuple[str, ...]:
    """The plot kinds of a study from its result table alone (a study read back without
    its spec): a shear study's :data:`SHEAR_KINDS` or a uniaxial study's
    :data:`UNIAXIAL_KINDS`, ``unconfined`` only where a run has an unconfined strength,
    ``resolution`` only with resolution controls."""
    unconfined = any("unconfined_strength" in r for r in table)
    return _kinds(_table_type(table), unconfined, has_controls(table))


def _table_type(table: list[dict]) -> str:
    """The type of the test of the study of ``table``, a key of :data:`TEST_PLOTS`: its
    kind's (:func:`engine.study.kinds.kind_of_table`)."""
    return kind_of_table(table).spec.__name__


def _style(i: int, ref: bool) -> dict:
    if ref:
        return {"color": "black", "lw": 2.2, "zorder": 5}
    return {"color": f"C{i % 10}", "lw": 1.3, "alpha": 0.9}


def _groups(runs: dict, table: list[dict]) -> dict[str, list[str]]:
    """Run keys by group: the references, and each (radius, rule) variant, in table order;
    runs not in the table form a group each."""
    rows = {r["run"]: r for r in table}
    out: dict[str, list[str]] = {}
    for key, run in runs.items():
        r = rows.get(key)
        if run["reference"]:
            label = "reference"
        elif r is not None:
            label = f"R = {r['radius'] * 1e3:g} mm, {r['rule']}"
        else:
            label = run["label"]
        out.setdefault(label, []).append(key)
    return out


def _mean_band(
    xs: list[np.ndarray], ys: list[np.ndarray], increasing: bool, n: int = 120
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Mean and sample standard deviation over seeds of curves y(x), each read along its
    monotone part in x (running max, or min where x falls) on the x range all share."""
    parts = []
    for x, y in zip(xs, ys):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        if len(x) < 2:
            return None
        env = np.maximum.accumulate(x) if increasing else np.minimum.accumulate(x)
        keep = np.ones(len(x), dtype=bool)
        keep[1:] = env[1:] != env[:-1]
        order = np.argsort(x[keep])
        parts.append((x[keep][order], y[keep][order]))
    lo = max(p[0][0] for p in parts)
    hi = min(p[0][-1] for p in parts)
    if not hi > lo:
        return None
    grid = np.linspace(lo, hi, n)
    a = np.array([np.interp(grid, px, py) for px, py in parts])
    return grid, a.mean(axis=0), a.std(axis=0, ddof=1)


def _unconfined_stress(runs: dict) -> str:
    """The unconfined curve to draw: ``stress_interior`` (the interior's axial contact-virial
    stress [Pa], which a test at the default protocol reads its strength from) where every
    run's unconfined stage has it finite, else ``stress_top`` (the seed's protocol, and runs
    stored before the interior curve existed)."""
    for r in runs.values():
        c = r["stages"].get("unconfined")
        if c is None:
            continue
        v = c.get("stress_interior")
        if v is None or not np.all(np.isfinite(np.asarray(v, dtype=float))):
            return "stress_top"
    return "stress_interior"


def _plot_groups(
    ax, runs: dict, table: list[dict], curve, stages, styles, along_y: bool = False
) -> None:
    """Every group of runs: one seed as its curve; two or more as the mean curve over the
    seeds with a band of one standard deviation (many seeds stay readable). ``curve(c)``
    gives (x, y) of a stage's curves; the mean is taken at common values of x (of y with
    ``along_y``: the controlled quantity, e.g. the stress of a stress-strain curve);
    ``stages`` pairs a stage with whether that quantity rises along it; ``styles`` a line
    style per stage."""
    for i, (label, keys) in enumerate(_groups(runs, table).items()):
        st = _style(i, runs[keys[0]]["reference"])
        n = len(keys)
        for (stage, increasing), ls in zip(stages, styles):
            cs = [runs[k]["stages"].get(stage) for k in keys]
            cs = [c for c in cs if c is not None]
            if not cs:
                continue
            name = (
                (label if n == 1 else f"{label} (mean of {len(cs)} seeds ± 1 sd)")
                if (stage == stages[0][0])
                else None
            )
            if len(cs) == 1:
                x, y = curve(cs[0])
                ax.plot(x, y, ls=ls, label=name, **st)
                continue
            xs, ys = zip(*(curve(c) for c in cs))
            band = _mean_band(ys, xs, increasing) if along_y else _mean_band(xs, ys, increasing)
            if band is None:
                continue
            grid, mean, sd = band
            # every quantity drawn (stress, strain, porosity, coordination) is >= 0 where
            # its mean is: the band stops at zero instead of promising negative values
            low = np.where(mean >= 0, np.maximum(mean - sd, 0.0), mean - sd)
            if along_y:
                ax.plot(mean, grid, ls=ls, label=name, **st)
                ax.fill_betweenx(grid, low, mean + sd, color=st["color"], alpha=0.2, lw=0)
            else:
                ax.plot(grid, mean, ls=ls, label=name, **st)
                ax.fill_between(grid, low, mean + sd, color=st["color"], alpha=0.2, lw=0)


def _confined(
    ax, runs: dict, table: list[dict], x: str | None, y: str | None, xscale=1.0, yscale=1.0
) -> None:
    """Consolidation (solid) and unloading (dashed) of every group; ``None`` means stress."""

    def curve(c):
        xs = np.asarray(c["stress_top"] if x is None else c[x]) * xscale
        ys = np.asarray(c["stress_top"] if y is None else c[y]) * yscale
        return xs, ys

    # seeds are averaged at common stresses (the controlled quantity), which rise on
    # loading and fall on unloading
    _plot_groups(
        ax,
        runs,
        table,
        curve,
        (("consolidation", True), ("unloading", False)),
        ("-", "--"),
        along_y=y is None,
    )


def _sd(values: np.ndarray) -> float:
    """Sample standard deviation over seeds; 0 for one seed."""
    return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0


def _yield_loci(ax, runs: dict, table: list[dict]) -> None:
    """The yield locus of every group of runs (the references, each coarse variant, each
    resolution control, the protocol check): the points of incipient failure (circles) and
    the pre-shear point (triangle), each the mean over the group's seeds with 1 sd bars in
    both stresses, and the mean of the seeds' fitted lines c + sigma tan(phi) from sigma = 0
    to the pre-shear point with a band of 1 sd of the lines over the seeds; the references'
    Mohr circles (:func:`_mohr_circles`)."""
    kpa = 1e-3
    for i, (label, keys) in enumerate(_groups(runs, table).items()):
        members = [runs[k] for k in keys if runs[k].get("points")]
        if not members:
            continue
        st = _style(i, members[0]["reference"])
        colour = st["color"]
        n = len(members)
        name = label if n == 1 else f"{label} (mean of {n} seeds ± 1 sd)"
        marker = _MARKERS[i % len(_MARKERS)]
        failure = [[p for p in m["points"] if p["kind"] == "failure"] for m in members]
        pre = [next(p for p in m["points"] if p["kind"] == "preshear") for m in members]
        n_pts = min(len(f) for f in failure)
        for j in range(n_pts):  # the j-th normal stress of every seed's test
            sig = np.array([f[j]["sigma"] for f in failure]) * kpa
            tau = np.array([f[j]["tau"] for f in failure]) * kpa
            ax.errorbar(
                sig.mean(),
                tau.mean(),
                xerr=_sd(sig),
                yerr=_sd(tau),
                fmt=marker,
                color=colour,
                ms=6 if st.get("zorder") else 5,
                capsize=2,
                elinewidth=0.8,
                zorder=st.get("zorder", 3),
            )
        sp = np.array([p["sigma"] for p in pre]) * kpa
        tp = np.array([p["tau"] for p in pre]) * kpa
        ax.errorbar(
            sp.mean(),
            tp.mean(),
            xerr=_sd(sp),
            yerr=_sd(tp),
            fmt="^",
            mfc="none",
            color=colour,
            ms=7,
            capsize=2,
            elinewidth=0.8,
            zorder=st.get("zorder", 3),
        )
        grid = np.linspace(0.0, float(sp.max()), 60)
        lines = np.array(
            [
                (m["locus"]["cohesion"] + m["locus"]["slope"] * grid / kpa) * kpa
                for m in members
                if m.get("locus")
            ]
        )
        if len(lines):
            mean = lines.mean(axis=0)
            ax.plot(grid, mean, label=name, **{k: v for k, v in st.items() if k != "alpha"})
            if len(lines) > 1:
                band = lines.std(axis=0, ddof=1)
                ax.fill_between(grid, mean - band, mean + band, color=colour, alpha=0.15, lw=0)
    if not any(r.get("points") for r in runs.values()):
        return  # draw() says why the panel is empty
    _mohr_circles(ax, [r["locus"] for r in runs.values() if r["reference"] and r.get("locus")])
    ax.errorbar([], [], fmt="o", color="0.3", label="incipient failure (mean ± 1 sd)")
    ax.errorbar([], [], fmt="^", mfc="none", color="0.3", label="pre-shear (steady flow)")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    ax.set_xlabel("normal stress sigma [kPa]")
    ax.set_ylabel("shear stress tau [kPa]")


def _mohr_circles(ax, loci: list[dict]) -> None:
    """The references' two Mohr circles (upper halves, dashed) from their loci's means over
    seeds: the unconfined yield circle through 0 and sigma_c, and the consolidation circle
    through sigma_2 and sigma_1 (tangent to the locus, through the pre-shear point), their
    stresses [kPa] in the legend; the unconfined circle is left out where sigma_c = 0 (no
    cohesion)."""
    if not loci:
        return
    kpa = 1e-3
    mean = {k: float(np.mean([lo[k] for lo in loci])) * kpa for k in ("sigma_1", "sigma_2")}
    sigma_c = float(np.mean([lo["sigma_c"] for lo in loci])) * kpa
    theta = np.linspace(0.0, np.pi, 90)
    circles = [(mean["sigma_2"], mean["sigma_1"])]
    label = f"reference's Mohr circles: sigma_1 {mean['sigma_1']:.3g} kPa"
    if sigma_c > 0:
        circles.insert(0, (0.0, sigma_c))
        label = (
            f"reference's Mohr circles: sigma_c {sigma_c:.3g}, sigma_1 {mean['sigma_1']:.3g} kPa"
        )
    else:
        label += " (sigma_c = 0)"
    for i, (lo, hi) in enumerate(circles):
        p, r = 0.5 * (lo + hi), 0.5 * (hi - lo)
        ax.plot(
            p + r * np.cos(theta),
            r * np.sin(theta),
            color="black",
            ls="--",
            lw=0.9,
            zorder=2,
            label=label if i == 0 else None,
        )


def _metric_bias(m) -> tuple[float, float, float] | None:
    """(signed error, low, high) of a verdict metric [-] (an
    :class:`engine.study.report.MetricVerdict`): its bias and the bias's 95 % interval, or
    its signed error alone; None where the metric compared nothing."""
    if m is None:
        return None
    err = m.bias.error if m.bias is not None else m.signed_error
    if err is None:
        return None
    lo, hi = m.bias.interval if m.bias is not None else (err, err)
    return float(err), float(lo), float(hi)


def _run_times(table: list[dict]) -> dict[tuple, float]:
    """Mean wall time [s] of each (radius, rule) group of runs (controls: rule 'control')."""
    acc: dict[tuple, list[float]] = {}
    for r in table:
        if r["rule"] != "reference" and r.get("wall_time") is not None:
            acc.setdefault((r["radius"], r["rule"]), []).append(float(r["wall_time"]))
    return {k: float(np.mean(v)) for k, v in acc.items()}


def _time_axis(ax, times: list[float]) -> None:
    """A run-time axis that reads: linear within a decade, else log with 1-2-5 ticks, each
    tick written as a plain number of seconds."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    if times and max(times) / max(min(times), 1e-9) > 10:
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_minor_locator(LogLocator(subs="auto"))
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))


def _error_vs_runtime(fig, table: list[dict], report) -> None:
    """One panel per verdict metric: each coarse variant's signed error against the
    reference [%] (the mean over its seeds, with its 95 % interval) at its mean run time
    [s]; the resolution controls' likewise (the error of the reference law that many
    diameters across), and, open, each rule's own error against its controls. The
    tolerance (dashed, both signs) and the reference's seed-to-seed noise (grey band, 1 sd)
    around zero. A symmetric-log error axis: linear within the widest tolerance, logarithmic
    beyond, so that -26 % and +26 % read as themselves and a wide interval stays on the
    panel."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter

    tol = report.tolerances if report is not None else {}
    noise = report.noise_floor if report is not None else {}
    names = [n for n, (col, _) in _METRIC_PANELS.items() if any(col in r for r in table)]
    rules = sorted({r["rule"] for r in table if r["rule"] != "reference"})
    radii = sorted({r["radius"] for r in table if r["rule"] != "reference"})
    times = _run_times(table)
    ref_times = [r["wall_time"] for r in table if r["rule"] == "reference"]
    groups = []
    if report is not None:
        groups = [(v, False) for v in (*report.verdicts, *report.resolution)]
        groups += [(v, True) for v in report.rule_errors]
    axes = fig.subplots(1, max(1, len(names)), sharex=True, squeeze=False)[0]
    clipped = False  # an interval cut at +-CAP: drawn to the edge with an arrow
    for ax, name in zip(axes, names):
        _, title = _METRIC_PANELS[name]
        if noise.get(name) is not None:
            band = 100 * noise[name]
            ax.axhspan(-band, band, color="0.85", zorder=0, label="reference noise (1 sd)")
        if name in tol:
            for sign in (1, -1):
                ax.axhline(sign * 100 * tol[name], color="black", ls="--", lw=1)
        ax.axhline(0.0, color="0.4", lw=0.8)
        for t in ref_times:
            ax.axvline(t, color="black", ls=":", lw=0.8)
        drawn = 0
        lin = 100 * tol.get(name, 0.1)  # linear within the tolerance
        reach = [lin, 100 * noise.get(name) if noise.get(name) is not None else 0.0]
        for v, own in groups:
            rule = "control" if v.what == "resolution" else v.rule
            got = _metric_bias(v.metric(name))
            t = times.get((v.radius, rule))
            if got is None or t is None or rule not in rules:
                continue
            err, lo, hi = (100 * x for x in got)
            colour = f"C{rules.index(rule) % 10}"
            x = t * (1.04 if own else 1.0)
            err, lo, hi = _cap(ax, x, err, lo, hi, colour)
            clipped = clipped or (lo, hi) != tuple(100 * y for y in got[1:])
            reach += [abs(err), abs(lo), abs(hi)]
            marker = _MARKERS[radii.index(v.radius) % len(_MARKERS)]
            ax.errorbar(
                x,
                err,
                yerr=[[max(err - lo, 0.0)], [max(hi - err, 0.0)]],
                fmt=marker,
                ms=7 if own else 6,
                mfc="none" if own else colour,
                color=colour,
                elinewidth=0.8,
                capsize=2,
                zorder=4 if own else 3,
            )
            drawn += 1
        if not drawn:
            ax.text(
                0.5,
                0.5,
                "nothing compared\n(no failed run)" if name == "strength" else "nothing compared",
                ha="center",
                va="center",
                transform=ax.transAxes,
                fontsize=8,
                color="0.3",
            )
        ax.set_title(f"{title} [%]", fontsize=9)
        top = 1.15 * max(reach)
        if top > 10 * lin:  # a wide interval: logarithmic beyond the tolerance
            ax.set_yscale("symlog", linthresh=lin, linscale=1.0)
            ax.yaxis.set_major_locator(_symlog_locator(lin, top))
        ax.set_ylim(-top, top)
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:+g}" if v else "0"))
        _time_axis(ax, list(times.values()) + ref_times)
        ax.set_xlabel("mean run time [s]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("signed error against the mean reference [%] (95 % interval)", fontsize=8)
    handles, labels = axes[0].get_legend_handles_labels()
    handles.append(Line2D([], [], ls="--", color="black"))
    labels.append("tolerance (±)")
    for i, rule in enumerate(rules):
        handles.append(Line2D([], [], ls="", marker="o", color=f"C{i % 10}"))
        labels.append("resolution control" if rule == "control" else f"rule {rule}")
    for i, r in enumerate(radii):
        handles.append(Line2D([], [], ls="", marker=_MARKERS[i % len(_MARKERS)], color="0.3"))
        labels.append(f"R = {r * 1e3:g} mm")
    if report is not None and report.rule_errors:
        handles.append(Line2D([], [], ls="", marker="o", mfc="none", color="0.3"))
        labels.append("open: the rule's own error (against its control)")
    if clipped:
        handles.append(Line2D([], [], ls="", marker="^", color="0.3"))
        labels.append(f"arrow: interval beyond ±{CAP:g} %, unbounded (too few seeds)")
    handles.append(Line2D([], [], ls=":", color="black"))
    labels.append("reference run time")
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)), fontsize=7)
    fig.suptitle(KINDS["error_vs_runtime"], fontsize=10)


#: Largest error an error axis shows [%]: an interval end beyond it (a one-degree-of-freedom
#: interval reaches +1e8 %) is drawn to it with an arrow, and read as unbounded, as the
#: reports print it (engine.study.reasons.UNBOUNDED).
CAP = 1000.0


def _cap(ax, x: float, err: float, lo: float, hi: float, colour) -> tuple[float, float, float]:
    """(err, lo, hi) [%] within +-:data:`CAP`; an arrow at the edge for each end cut."""
    for end, sign, marker in ((hi, 1.0, "^"), (lo, -1.0, "v")):
        if not math.isfinite(end) or sign * end > CAP:
            ax.plot([x], [sign * CAP], marker=marker, color=colour, ms=6, ls="", zorder=5)
    return (
        float(np.clip(err, -CAP, CAP)),
        float(np.clip(lo, -CAP, CAP)) if math.isfinite(lo) else -CAP,
        float(np.clip(hi, -CAP, CAP)) if math.isfinite(hi) else CAP,
    )


def _symlog_locator(lin: float, top: float):
    """Ticks of a symmetric-log axis linear within ``lin`` and reaching ``top`` that stay
    apart: 0, then 1 and 3 per decade over up to three decades, one per decade up to six,
    and one every few decades beyond (about six a side); none crowding 0 inside ``lin``."""
    from matplotlib.ticker import FixedLocator

    decades = math.log10(max(top / lin, 10.0))
    step = max(1, math.ceil(decades / 6))
    subs = (1.0, 3.0) if decades <= 3 else (1.0,)
    k0 = math.floor(math.log10(lin))
    k0 = k0 + (-k0) % step  # powers of ten on a common grid: 10^0, 10^step, ...
    ticks = [
        m * 10.0**k
        for k in range(k0, math.floor(math.log10(top)) + 1, step)
        for m in subs
        if lin / 5 <= m * 10.0**k <= top
    ]
    return FixedLocator([-t for t in reversed(ticks)] + [0.0] + ticks)


def _pct(x: float) -> str:
    """A signed percentage that stays short: whole numbers below 10^4, else a power of ten
    (a 1-dof interval's end can be astronomically large)."""
    return f"{x:+.0f}" if abs(x) < 1e4 else f"{x:+.0e}"


def _span(lo: float, hi: float) -> str:
    """An interval of relative errors [-] in per cent, "[-31, -19] %", or, with an end beyond
    +-1000 % (too few seeds), the words the reports use (engine.study.reasons)."""
    from ..study.reasons import UNBOUNDED_WORDS, bounded

    if not bounded((lo, hi)):
        return UNBOUNDED_WORDS
    return f"[{_pct(100 * lo)}, {_pct(100 * hi)}] %"


def _resolution(fig, report, table: list[dict] | None = None) -> None:
    """One panel per property with a resolution curve (engine.study.resolution): each sample
    size's mean relative to the extrapolated bulk value against d / L, the fitted line, and
    the bulk value's interval at d / L = 0."""
    curve = report.resolution_curve if report is not None else None
    curves = curve.metrics if curve is not None else {}
    names = [n for n in _TITLES if n in curves]
    if not names:
        if report is not None and report.resolution:  # controls ran, too few seeds for a line
            _resolution_points(fig, report, table)
            return
        ax = fig.add_subplot()
        ax.text(
            0.5,
            0.5,
            "this study has no resolution controls (StudySpec.controls)",
            ha="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        fig.suptitle(KINDS["resolution"], fontsize=10)
        return
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, n in zip(axes, names):
        c = curves[n]
        bulk = c["bulk"]
        xs = np.array([s["d_over_L"] for s in c["sizes"]])
        grid = np.linspace(0.0, xs.max() * 1.05, 50)
        # the line is fitted to the log of the property (engine.study.resolution): a
        # straight line in d / L for the log, a curve in percent
        ax.plot(
            grid,
            100 * np.expm1(c["slope"] * grid),
            color="C0",
            lw=1.2,
            label="fit: log of the property linear in d / L",
        )
        lo, hi = c["bulk_interval"]
        ax.errorbar(
            [0.0],
            [0.0],
            yerr=[[100 * (1 - lo / bulk)], [100 * (hi / bulk - 1)]],
            fmt="s",
            color="C0",
            capsize=3,
            label="bulk (extrapolated)",
        )
        for s in c["sizes"]:
            ax.scatter(
                s["d_over_L"],
                100 * (s["mean"] / bulk - 1),
                s=34,
                zorder=3,
                color="black" if s["reference"] else "C3",
            )
            ax.annotate(
                f"{s['diameters_across']:.1f} d",
                (s["d_over_L"], 100 * (s["mean"] / bulk - 1)),
                fontsize=6,
                xytext=(3, 3),
                textcoords="offset points",
            )
        ax.axhline(0.0, color="0.6", lw=0.8)
        # the axis spans the size means and the line; a bulk interval wider than that runs
        # off the panel and is written out instead
        ys = [100 * (s["mean"] / bulk - 1) for s in c["sizes"]]
        ys += [100 * (s["fitted"] / bulk - 1) for s in c["sizes"]] + [0.0]
        pad = max(3.0, 0.5 * (max(ys) - min(ys)))
        ax.set_ylim(min(ys) - pad, max(ys) + pad)
        olo, ohi = c["reference_offset_interval"]
        ax.text(
            0.03,
            0.03,
            f"bulk: {_span(lo / bulk - 1, hi / bulk - 1)}\n"
            f"reference {100 * c['reference_offset']:+.1f} %\n{_span(olo, ohi)} from it",
            transform=ax.transAxes,
            fontsize=6,
            va="bottom",
            # the bulk's interval bar runs under it: the words on a white ground
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.85, "pad": 1.5},
            zorder=6,
        )
        ax.set_title(f"{_TITLES[n]} [%]", fontsize=9)
        ax.set_xlabel("d / L [-]", fontsize=8)  # the title says what d and L are
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("mean relative to the bulk value [%]", fontsize=8)
    from matplotlib.lines import Line2D

    handles, labels = axes[0].get_legend_handles_labels()
    handles += [
        Line2D([], [], ls="", marker="o", color="black"),
        Line2D([], [], ls="", marker="o", color="C3"),
    ]
    labels += ["references", "resolution controls"]
    fig.legend(handles, labels, loc="outside lower center", ncol=4, fontsize=7)
    conf = curve.confidence
    fig.suptitle(f"{KINDS['resolution']} (bulk interval {conf:.0%})", fontsize=10)


def _resolution_points(fig, report, table: list[dict]) -> None:
    """The resolution controls of a study whose sizes are too few, or too thinly seeded,
    for a line (engine.study.resolution.fit_curve wants two sizes of two seeds or more):
    per property, each control's signed error against the references [%] with its 95 %
    interval at its d / L, the references at theirs (zero), and why there is no line."""
    from matplotlib.ticker import FuncFormatter

    controls = report.resolution
    ref_d = [r["thickness_diameters"] for r in table if r["rule"] == "reference"]
    names = [n for n in _TITLES if any(_metric_bias(v.metric(n)) is not None for v in controls)]
    names = names or ["density"]
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, n in zip(axes, names):
        if ref_d:
            x_ref = 1.0 / float(np.mean(ref_d))
            ax.scatter([x_ref], [0.0], s=34, color="black", zorder=3)
            ax.annotate(
                f"{np.mean(ref_d):.1f} d",
                (x_ref, 0.0),
                fontsize=6,
                xytext=(3, 3),
                textcoords="offset points",
            )
        tol = report.tolerances.get(n)
        reach = [100 * (tol or 0.1)]  # the values the panel must show [%]
        xs = [1.0 / float(np.mean(ref_d))] if ref_d else []
        for v in controls:
            got = _metric_bias(v.metric(n))
            if got is None or not v.diameters_across:
                continue
            err, lo, hi = (100 * x for x in got)
            x = 1.0 / float(v.diameters_across)
            err, lo, hi = _cap(ax, x, err, lo, hi, "C3")
            reach += [abs(err), abs(lo), abs(hi)]
            xs.append(x)
            ax.errorbar(
                x,
                err,
                yerr=[[max(err - lo, 0.0)], [max(hi - err, 0.0)]],
                fmt="o",
                color="C3",
                capsize=3,
                zorder=3,
            )
            ax.annotate(
                f"{v.diameters_across:.1f} d",
                (x, err),
                fontsize=6,
                xytext=(3, 3),
                textcoords="offset points",
            )
        if tol is not None:
            for sign in (1, -1):
                ax.axhline(sign * 100 * tol, color="black", ls="--", lw=1)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_xlim(0.0, 1.2 * max(xs or [1.0]))
        top = 1.2 * max(reach)
        if top > 10 * reach[0]:  # a wide interval: logarithmic beyond the tolerance
            ax.set_yscale("symlog", linthresh=reach[0])
        ax.set_ylim(-top, top)
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:+g}" if v else "0"))
        ax.set_title(f"{_TITLES[n]} [%]", fontsize=9)
        ax.set_xlabel("d / L [-]", fontsize=8)  # the title says what d and L are
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("error against the references [%] (95 % interval)", fontsize=8)
    from matplotlib.lines import Line2D

    fig.legend(
        [
            Line2D([], [], ls="", marker="o", color="black"),
            Line2D([], [], ls="", marker="o", color="C3"),
            Line2D([], [], ls="--", color="black"),
        ],
        ["references", "resolution controls (mean over seeds)", "tolerance (±)"],
        loc="outside lower center",
        ncol=3,
        fontsize=7,
    )
    fig.suptitle(
        f"{KINDS['resolution']}\nno line to the bulk: it needs two sizes with two or more "
        "seeds each",
        fontsize=9,
    )


def discharge_rate(time, mass, window: float = RATE_WINDOW) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], rate [kg/s]) of a hopper's discharge curves: at each sample the slope of the
    discharged ``mass`` [kg] against ``time`` [s] between the samples ``window`` x the run's
    discharge time before and after it (at least one sample; cut at the curve's ends)."""
    t = np.asarray(time, dtype=float)
    m = np.asarray(mass, dtype=float)
    n = len(t)
    if n < 2:
        return t[:0], t[:0]
    h = max(1, round(window * (n - 1)))
    i = np.arange(n)
    lo, hi = np.maximum(i - h, 0), np.minimum(i + h, n - 1)
    return t, (m[hi] - m[lo]) / (t[hi] - t[lo])


def hopper_run_figure(result, title: str = ""):
    """A matplotlib Figure (Agg canvas, no pyplot) of one hopper run's discharge: its mass
    discharge rate [kg/s] against time since the gate began to open [s]
    (:func:`discharge_rate`), the steady window shaded and its rate dotted."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    c, s = result.curves, result.scalars
    fig = Figure(figsize=(7.0, 4.4), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    t, rate = discharge_rate(c["time"], c["discharged_mass"])
    ax.plot(t, rate, color="C0", lw=1.4, label="discharge rate")
    steady = s.get("discharge_rate", math.nan)
    if math.isfinite(steady):
        ax.axvspan(s["window_start"], s["window_end"], color="C0", alpha=0.12, lw=0)
        ax.axhline(steady, color="C0", ls=":", lw=1.2, label=f"steady window: {steady:.4g} kg/s")
    if s.get("arched"):
        ax.axvline(s["arch_time"], color="C3", ls="--", lw=1.0, label="arched")
    ax.set_xlabel("time since the gate began to open [s]")
    ax.set_ylabel("mass discharge rate [kg/s]")
    ax.set_ylim(bottom=0.0)
    ax.set_title(title or "hopper discharge")
    ax.legend(loc="best", fontsize=8)
    return fig


def _discharge(ax, runs: dict, table: list[dict]) -> None:
    """Every group's discharge rate against time (:func:`discharge_rate`; seeds as a mean
    with a band of 1 sd) and, dotted in its colour, its steady-window rate (the table's, the
    mean over the group's seeds)."""
    _plot_groups(
        ax,
        runs,
        table,
        lambda c: discharge_rate(c["time"], c["discharged_mass"]),
        (("discharge", True),),
        ("-",),
    )
    rows = {r["run"]: r for r in table}
    for i, (_, keys) in enumerate(_groups(runs, table).items()):
        rates = [rows[k].get("discharge_rate", math.nan) for k in keys if k in rows]
        rates = [r for r in rates if r is not None and math.isfinite(r)]
        if rates:
            st = _style(i, runs[keys[0]]["reference"])
            ax.axhline(float(np.mean(rates)), color=st["color"], ls=":", lw=1.2)
    ax.set_ylim(bottom=0.0)


def draw(ax, kind: str, runs: dict, table: list[dict]) -> None:
    """Draw plot ``kind`` (one of :data:`KINDS`) on the matplotlib Axes ``ax``."""
    if kind not in KINDS:
        raise ValueError(f"plot kind {kind!r} is not one of {sorted(KINDS)}")
    if kind == "stress_strain":
        _confined(ax, runs, table, "strain", None, 100.0, 1e-3)
        ax.set_xlabel("axial strain [%]")
        ax.set_ylabel("top platen stress [kPa]")
    elif kind == "stress_porosity":
        _confined(ax, runs, table, None, "porosity", 1e-3, 1.0)
        ax.set_xlabel("top platen stress [kPa]")
        ax.set_ylabel("porosity [-]")
    elif kind == "coordination":
        _confined(ax, runs, table, None, "coordination", 1e-3, 1.0)
        ax.set_xlabel("top platen stress [kPa]")
        ax.set_ylabel("coordination number [-]")
    elif kind == "unconfined":
        # the curve a strength is read from: the interior's contact-virial stress where every
        # run has it (the default protocol's strength_from), else the top platen's
        key = _unconfined_stress(runs)
        _plot_groups(
            ax,
            runs,
            table,
            lambda c: (np.asarray(c["strain"]) * 100, np.asarray(c[key]) * 1e-3),
            (("unconfined", True),),
            ("-",),
        )
        ax.set_xlabel("axial strain since release [%]")
        ax.set_ylabel(
            "interior axial stress (contact virial) [kPa]"
            if key == "stress_interior"
            else "top platen stress [kPa]"
        )
    elif kind == "yield_locus":
        _yield_loci(ax, runs, table)
    elif kind == "preshear":
        _plot_groups(
            ax,
            runs,
            table,
            lambda c: (np.asarray(c["shear_strain"]), np.asarray(c["shear_stress"]) * 1e-3),
            (("preshear", True),),
            ("-",),
        )
        ax.set_xlabel("shear strain (lid displacement / gap) [-]")
        ax.set_ylabel("shear stress on the lid [kPa]")
    elif kind == "discharge":
        _discharge(ax, runs, table)
        ax.set_xlabel("time since the gate began to open [s]")
        ax.set_ylabel("mass discharge rate [kg/s]")
    else:
        raise ValueError(f"{kind} is drawn on a whole figure: use figure()")
    titles = {
        "unconfined": None,
        "preshear": "at the pre-shear normal stress, to steady flow",
        "yield_locus": "lines: each seed's fitted locus, mean ± 1 sd",
        "discharge": f"slope over ± {RATE_WINDOW:.0%} of the discharge time; dotted: steady-"
        "window rate",
    }
    if ax.get_legend_handles_labels()[0]:
        ax.legend(
            fontsize=8,
            title=titles.get(kind, "solid: loading, dashed: unloading"),
            title_fontsize=7,
        )
    else:
        _placeholder(ax, _empty_words(kind, table))
    ax.set_title(KINDS[kind], fontsize=10)
    ax.grid(alpha=0.3)


def _empty_words(kind: str, table: list[dict]) -> str:
    """Why panel ``kind`` of the study of ``table`` is empty: a plot of the other kind of
    test (naming the study's own plots), or no run with the stage."""
    own = _table_type(table)
    if kind not in TEST_PLOTS[own]:
        other = next(t for t, kinds in TEST_PLOTS.items() if kind in kinds)
        return (
            f"a {TEST_NAMES[own]} study: this plot is of the {TEST_NAMES[other]} test\n"
            f"(its plots: {', '.join(kinds_of(table))})"
        )
    return "no run of this study has this stage"


def _placeholder(ax, words: str) -> None:
    """The one message of an empty panel, in its middle: any text drawn there before is
    removed first, so that two messages are never drawn over each other."""
    for t in list(ax.texts):
        t.remove()
    ax.text(0.5, 0.5, words, ha="center", va="center", transform=ax.transAxes)


def figure(kind: str, runs: dict, table: list[dict], report=None):
    """A new matplotlib Figure (Agg canvas, no pyplot) with plot ``kind`` (``report``: the
    study's :class:`engine.study.report.StudyReport`, for the kinds drawn from it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if kind in _WHOLE_FIGURE:
        fig = Figure(figsize=(12.0, 4.2), dpi=100, layout="constrained")
        FigureCanvasAgg(fig)
        if kind == "error_vs_runtime":
            _error_vs_runtime(fig, table, report)
        else:
            _resolution(fig, report, table)
        return fig
    fig = Figure(figsize=(7.0, 4.8), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    draw(fig.add_subplot(), kind, runs, table)
    return fig


def has_controls(table: list[dict]) -> bool:
    """Whether a study ran resolution controls (its resolution plot has something to show,
    a line to the bulk or the controls' points)."""
    return any(r.get("rule") == "control" for r in table)


def save_all(directory, runs: dict, table: list[dict], report=None) -> list[Path]:
    """Write ``<kind>.png`` for every kind of the study into ``directory``
    (:func:`kinds_of`: a uniaxial study's or a shear study's; ``resolution`` only for a
    study with resolution controls); returns the paths."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = []
    for kind in kinds_of(table):  # a study without resolution controls has no resolution plot
        path = d / f"{kind}.png"
        figure(kind, runs, table, report).savefig(path, format="png")
        out.append(path)
    return out


# ------------------------------------------------------------------ snapshot sections
def _signed_ticks(bar, norm) -> None:
    """Ticks on both sides of zero for a colour bar with a two-slope norm (matplotlib's
    default ticks leave the shorter side bare)."""
    from matplotlib.colors import TwoSlopeNorm

    if isinstance(norm, TwoSlopeNorm):
        ticks = np.unique(np.r_[np.linspace(norm.vmin, 0.0, 3), np.linspace(0.0, norm.vmax, 5)])
        bar.set_ticks(ticks, labels=[f"{t:.2g}" for t in ticks])


def section_figure(snap: Snapshot, title: str = ""):
    """A matplotlib Figure (Agg canvas, no pyplot) of a vertical section through the middle
    of the sample: left, the particles cut by the plane (true cross-section circles) coloured
    by their pressure [kPa] (1st to 99th percentile; red compression, blue tension when both
    occur); right, the force chains among the particles the plane cuts
    (line width and colour by the normal force [N]). The plane is normal to the shorter
    horizontal side of the cell, so the section shows the wider one."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.colors import ListedColormap, Normalize, TwoSlopeNorm
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    pos, rad = snap.positions, snap.radii
    lo, hi = pos.min(axis=0) - rad.max(), pos.max(axis=0) + rad.max()
    normal = 0 if hi[0] - lo[0] < hi[1] - lo[1] else 1  # cut across the shorter side
    across = 1 - normal
    mid = 0.5 * (lo[normal] + hi[normal])
    depth = pos[:, normal] - mid
    cut = np.abs(depth) < rad
    section = np.sqrt(np.maximum(rad[cut] ** 2 - depth[cut] ** 2, 0.0))
    pressure = particle_fields(snap)["pressure"]

    width = hi[across] - lo[across]
    height = max(hi[2], float(np.max(snap.platens))) - min(lo[2], float(np.min(snap.platens)))
    panel_h = max(2.4, min(5.2, 6.0 * height / width))  # a slumped sample: low and wide
    panel_w = float(np.clip(panel_h * width / height, 1.6, 6.0))
    fig = Figure(figsize=(2 * panel_w + 2.6, panel_h + 0.9), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax_p, ax_f = fig.subplots(1, 2, sharex=True, sharey=True)
    mm = 1e3

    kpa = pressure[cut] * 1e-3
    p_lo = float(np.percentile(kpa, 1)) if kpa.size else 0.0
    p_hi = float(np.percentile(kpa, 99)) if kpa.size else 1.0
    if p_lo < 0 < p_hi:  # adhesion holds some particles in tension: diverging, as the chains
        p_cmap, p_norm = "RdBu_r", TwoSlopeNorm(0.0, p_lo, p_hi)
    else:
        p_cmap, p_norm = "viridis", Normalize(min(p_lo, 0.0), max(p_hi, 1e-30))
    discs = PatchCollection(
        [
            Circle((x * mm, z * mm), r * mm)
            for x, z, r in zip(pos[cut, across], pos[cut, 2], section)
        ],
        cmap=p_cmap,
        norm=p_norm,
        edgecolor="0.25",
        linewidth=0.3,
    )
    discs.set_array(kpa)
    ax_p.add_collection(discs)
    bar = fig.colorbar(discs, ax=ax_p, label="particle pressure (Love-Weber) [kPa]", shrink=0.8)
    _signed_ticks(bar, p_norm)
    ax_p.set_title(f"section through the middle: {int(cut.sum())} particles", fontsize=9)

    # force chains: contacts whose two particles the plane cuts, drawn to the second
    # particle's nearest image (a chain through a periodic side stays short)
    i, j = snap.pairs[:, 0], snap.pairs[:, 1]
    keep = cut[i] & cut[j] if len(i) else np.zeros(0, dtype=bool)
    a = pos[i[keep]]
    b = a - snap.branches[keep]
    fn = snap.normal_forces[keep].astype(np.float64)
    ax_f.add_collection(
        PatchCollection(
            [
                Circle((x * mm, z * mm), r * mm)
                for x, z, r in zip(pos[cut, across], pos[cut, 2], section)
            ],
            facecolor="0.93",
            edgecolor="0.75",
            linewidth=0.3,
        )
    )
    if fn.size:
        f_lo, f_hi = float(fn.min()), float(fn.max())
        scale = max(abs(f_lo), abs(f_hi), 1e-30)
        if f_lo < 0 < f_hi:  # adhesive contacts too: blue pulls, red pushes
            cmap, norm = "RdBu_r", TwoSlopeNorm(0.0, f_lo, f_hi)
        else:  # one sign: the lower end of "Reds" cut off, so weak chains show on grey
            cmap = ListedColormap(colormaps["Reds"](np.linspace(0.3, 1.0, 256)))
            norm = Normalize(min(f_lo, 0.0), max(f_hi, 1e-30))
        chains = LineCollection(
            np.stack([a[:, [across, 2]], b[:, [across, 2]]], axis=1) * mm,
            cmap=cmap,
            norm=norm,
            linewidths=0.4 + 3.6 * np.abs(fn) / scale,
        )
        chains.set_array(fn)
        ax_f.add_collection(chains)
        bar = fig.colorbar(
            chains, ax=ax_f, label="normal contact force [N] (> 0 compressive)", shrink=0.8
        )
        _signed_ticks(bar, norm)
    ax_f.set_title(f"force chains: {int(keep.sum())} contacts in the section", fontsize=9)
    axis_name = "xy"[across]
    for ax in (ax_p, ax_f):
        for z in snap.platens:
            ax.axhline(z * mm, color="black", lw=2)
        ax.set_xlim(lo[across] * mm, hi[across] * mm)
        ax.set_ylim(
            min(lo[2], float(np.min(snap.platens))) * mm - 1,
            max(hi[2], float(np.max(snap.platens))) * mm + 1,
        )
        ax.set_aspect("equal")
        ax.set_xlabel(f"{axis_name} [mm]")
        ax.tick_params(labelsize=7)
    ax_p.set_ylabel("z [mm]")
    fig.suptitle(
        f"{title + ': ' if title else ''}{snap.stage} end, t = {snap.time:.4g} s, "
        f"section at {'xy'[normal]} = {mid * mm:.3g} mm",
        fontsize=10,
    )
    return fig


# ------------------------------------------------------------------ calibration
def _target_stress(name: str) -> float | None:
    """The stress [Pa] in a calibration quantity's name (``porosity@8000Pa:loading``,
    ``strength@20000Pa``), else None."""
    if "@" not in name:
        return None
    return float(name.split("@", 1)[1].split("Pa", 1)[0])


#: Units of a calibration target's kind (engine.calibration.calibrate.TARGET_UNITS), as
#: the figure writes them.
_TARGET_UNITS = {
    "porosity": "-",
    "loading_stiffness": "Pa",
    "unloading_stiffness": "Pa",
    "k0": "-",
    "strength": "Pa",
    "tau_pre": "Pa",
    "bulk_density": "kg/m^3",
}


def _locus_of(name: str) -> float:
    """The pre-shear normal stress [Pa] of a shear point target (``tau@<sn>Pa:<sp>Pa``)."""
    return float(name.split(":", 1)[1].split("Pa", 1)[0])


def _locus_panel(ax, checks: list, runs: list, curves: dict) -> None:
    """Yield loci: shear stress against normal stress [kPa], per pre-shear normal stress the
    laboratory points (1 sd), the check run at the laboratory's normal stresses, its fitted
    locus up to its pre-shear point, and the design and wave runs (faint)."""
    rows = [q for q in checks if q["name"].startswith("tau@")]
    loci = sorted({_locus_of(q["name"]) for q in rows})
    for r in runs:
        pts = [q for q in r.get("quantities", []) if q["name"].startswith("tau@")]
        ax.scatter(
            [_target_stress(q["name"]) * 1e-3 for q in pts],
            [q["value"] * 1e-3 for q in pts],
            s=8,
            color="0.75",
            zorder=1,
        )
    fitted = {c["sigma_pre"]: c for c in curves.get("yield_loci") or []}
    for i, sp in enumerate(loci):
        color = f"C{i % 10}"
        here = [q for q in rows if _locus_of(q["name"]) == sp]
        x = [_target_stress(q["name"]) * 1e-3 for q in here]
        ax.errorbar(
            x,
            [q["lab"] * 1e-3 for q in here],
            yerr=[q["sd"] * 1e-3 for q in here],
            fmt="o",
            color=color,
            capsize=3,
            zorder=3,
            label=f"laboratory, pre-shear {sp * 1e-3:g} kPa (1 sd)",
        )
        ax.scatter(
            x, [q["value"] * 1e-3 for q in here], marker="s", color=color, zorder=4, alpha=0.6
        )
        c = fitted.get(sp)
        if c is not None:
            top = max(c["preshear"]["sigma"], max(x) * 1e3)
            sig = np.linspace(0.0, top, 50)
            ax.plot(sig * 1e-3, (c["cohesion"] + c["slope"] * sig) * 1e-3, "-", color=color, lw=1)
            ax.scatter(
                [c["preshear"]["sigma"] * 1e-3],
                [c["preshear"]["tau"] * 1e-3],
                marker="^",
                color=color,
                zorder=4,
            )
    ax.scatter([], [], marker="s", color="0.3", label="calibrated law (check run)")
    ax.plot([], [], "-", color="0.3", lw=1, label="its yield locus; triangle: pre-shear")
    ax.scatter([], [], s=8, color="0.75", label="design and wave runs")
    ax.set_xlabel("normal stress [kPa]")
    ax.set_ylabel("shear stress [kPa]")
    ax.set_title("yield loci: shear stress [kPa] against normal stress [kPa]", fontsize=9)
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def calibration_status(summary: dict) -> str:
    """One line on whether the calibrated law's check run met its targets: "all 9 targets
    met", or "2 of 9 targets NOT met: ..." naming each with its z; first, where the data
    determine none of the parameters, that they are all free (a target met then says
    only that some law of the box meets it)."""
    from ..calibration.calibrate import determination

    det = summary.get("determination") or determination(summary)
    first = ""
    if det["all_free"]:
        first = f"the data determine none of its parameters ({', '.join(det['free'])} free): "
    checks = summary.get("targets_met") or []
    missed = [q for q in checks if not q.get("met")]
    if not missed:
        return f"{first}all {len(checks)} targets met (check run within 2 sd)"
    words = ", ".join(
        f"{q['name']} (z = {q['z']:+.1f})"
        if q.get("z") is not None
        else f"{q['name']} ({'no peak' if q.get('no_peak') else 'failed'})"
        for q in missed
    )
    return f"{first}{len(missed)} of {len(checks)} targets NOT met: {words}"


def calibration_figure(summary: dict):
    """The calibration (engine.Calibration.to_summary()) against the laboratory, one panel
    per kind of target it has (no empty panel): the compression curve, porosity against
    vertical stress on a log stress axis (compressibility is read against log stress); the
    flow function, strength against consolidation stress; a shear tester's yield loci,
    shear against normal stress (:func:`_locus_panel`); and the scalar targets (stiffness,
    K0, a locus's pre-shear stress and bulk density) as the check run over the laboratory
    value. The laboratory points with their 1-sd
    bars, the check run of the calibrated law and every run of the design and waves
    (faint); the title says whether every target was met."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    checks = summary["targets_met"]
    runs = summary.get("runs", [])
    kinds = [
        (prefix, sy)
        for prefix, sy in (("porosity@", 1.0), ("strength@", 1e-3))
        if any(q["name"].startswith(prefix) for q in checks)
    ]
    loci = any(q["name"].startswith("tau@") for q in checks)
    # scalar targets: those without a stress, and a locus's pre-shear stress and density
    scalars = [
        q
        for q in checks
        if "@" not in q["name"] or q["name"].split("@", 1)[0] in ("tau_pre", "bulk_density")
    ]
    n = len(kinds) + loci + bool(scalars)
    fig = Figure(figsize=(max(5.5, 4.6 * n), 4.6), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = list(fig.subplots(1, max(n, 1), squeeze=False)[0])
    for ax, (prefix, sy) in zip(axes, kinds):
        rows = [q for q in checks if q["name"].startswith(prefix)]
        for r in runs:
            pts = [
                (q["name"], q["value"])
                for q in r.get("quantities", [])
                if q["name"].startswith(prefix)
            ]
            ax.scatter(
                [_target_stress(n) * 1e-3 for n, _ in pts],
                [v * sy for _, v in pts],
                s=8,
                color="0.75",
                zorder=1,
            )
        x = [_target_stress(q["name"]) * 1e-3 for q in rows]
        ax.errorbar(
            x,
            [q["lab"] * sy for q in rows],
            yerr=[q["sd"] * sy for q in rows],
            fmt="o",
            color="black",
            capsize=3,
            label="laboratory (1 sd)",
            zorder=3,
        )
        ax.scatter(
            x,
            [q["value"] * sy for q in rows],
            marker="s",
            color="C3",
            zorder=4,
            label="calibrated law (check run)",
        )
        ax.scatter([], [], s=8, color="0.75", label="design and wave runs")
        curves = summary.get("curves") or {}
        if prefix == "porosity@":
            for part, style in (("loading", "-"), ("unloading", "--")):
                c = curves.get(part)
                if c:
                    stress = np.asarray(c["stress"]) * 1e-3
                    keep = stress > 0  # a log axis: the curve from the first loaded sample
                    ax.plot(
                        stress[keep],
                        np.asarray(c["porosity"])[keep],
                        style,
                        color="C3",
                        lw=1,
                        zorder=2,
                        label=f"check run, {part}",
                    )
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            ax.set_xlabel("vertical stress [kPa] (log scale)")
            ax.set_ylabel("porosity [-]")
            ax.set_title("compression curve: porosity [-] against stress [kPa]", fontsize=9)
        else:
            if curves.get("flow_function"):
                ff = curves["flow_function"]
                ax.plot(
                    [p["consolidation_stress"] * 1e-3 for p in ff],
                    [p["strength"] * sy for p in ff],
                    "-",
                    color="C3",
                    lw=1,
                    zorder=2,
                )
            ax.set_xlabel("consolidation stress [kPa]")
            ax.set_ylabel("unconfined strength [kPa]")
            ax.set_title("flow function: strength [kPa] against consolidation [kPa]", fontsize=9)
            ax.set_xlim(left=0)
            ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    if loci:
        _locus_panel(axes[len(kinds)], checks, runs, summary.get("curves") or {})
    if scalars:
        ax = axes[len(kinds) + loci]
        names = [
            q["name"].replace("@", "\n@")
            + f"\n{q['lab']:.3g} [{_TARGET_UNITS.get(q['name'].split('@', 1)[0], '-')}]"
            for q in scalars
        ]
        xs = np.arange(len(scalars))
        ax.errorbar(
            xs,
            np.ones(len(scalars)),
            yerr=[q["sd"] / q["lab"] for q in scalars],
            fmt="o",
            color="black",
            capsize=3,
            label="laboratory (1 sd)",
        )
        for i, q in enumerate(scalars):
            ok = q.get("met")
            ax.scatter(
                [i],
                [q["value"] / q["lab"]],
                marker="s",
                color="C3" if ok else "C1",
                zorder=4,
                label=("calibrated law (check run)" if i == 0 else None),
            )
            if not ok:
                ax.annotate(
                    "NOT met",
                    (i, q["value"] / q["lab"]),
                    fontsize=7,
                    color="C1",
                    xytext=(5, -3),
                    textcoords="offset points",
                )
        ax.axhline(1.0, color="0.6", lw=0.8)
        ax.set_xticks(xs, names, fontsize=7)
        ax.set_xlim(-0.6, len(scalars) - 0.4)
        ax.set_ylabel("check run / laboratory value [-]")
        ax.set_title("other targets: check run over the laboratory value [-]", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    # wrapped to the figure's width (about 12 characters an inch at 9 points), so that a
    # long list of targets not met is read whole, not cut at the edges
    title = f"Calibration against the laboratory: {calibration_status(summary)}"
    width = int(12 * fig.get_figwidth())
    fig.suptitle(textwrap.fill(title, width), fontsize=9)
    return fig
