"""The outlet's N_req from the stored outlet series (:mod:`benchmarks.outlet_series`, whose
docstring fixes the series, the fits and the tolerances) and the Jenike series' two
gravities (:mod:`benchmarks.jenike_series`): the discharge number's and the arching width's
resolution curves, read by :mod:`benchmarks.size_report` into docs/RESOLUTION.md and the
planner's evidence (feature kind ``outlet``).

    python -m benchmarks.outlet_report        # print the section (size_report writes it)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from benchmarks import jenike_series as J
from benchmarks import outlet_series as O
from engine.study.intervals import t_quantile
from engine.study.resolution import diameters_needed, resolution_curves

CONFIDENCE = 0.95
FIGURE = Path(__file__).resolve().parent.parent / "docs" / "figures" / "outlet_series.png"
#: The Jenike series' gravities [m/s^2] with their stored kinds and widths [d].
JENIKE_GRAVITIES = {
    J.GRAVITY: ("hopper", J.WIDTHS, J.HOPPER_SEEDS),
    J.GRAVITY_2: ("hopper_g2", J.G2_WIDTHS, J.G2_SEEDS),
}


def _number(d) -> float | None:
    """A stored run's discharge number, None if it failed or had no steady window."""
    if d is None or not d.ok or not math.isfinite(d.scalars["discharge_number"]):
        return None
    return float(d.scalars["discharge_number"])


def sink_check() -> dict | None:
    """The sink against the runs made before it (:mod:`benchmarks.outlet_series`'
    docstring, rule fixed
    before the runs): per seed at :data:`~benchmarks.outlet_series.SINK_CHECK_WIDTH`, the
    discharge number with the sink over the stored run's, minus 1; their mean, its 90 %
    t-interval and the verdict against +- ``SINK_CHECK_MARGIN``. None before two pairs."""
    w, g = O.SINK_CHECK_WIDTH, O.G_FLOW
    pairs, parted, cpu = [], [], []
    for s in range(1, O.FLOW_SEEDS + 1):
        dd, ds = O.stored("flow", g, w, s), O.stored("sink", g, w, s)
        before, sink = _number(dd), _number(ds)
        if before is not None and sink is not None:
            pairs.append((s, before, sink))
            total = float(dd.scalars["total_mass"])
            parted.append(_parted(dd.extra.get("curve"), ds.extra.get("curve"), total))
            cpu.append((dd.extra.get("cpu_seconds"), ds.extra.get("cpu_seconds")))
    if len(pairs) < 2:
        return None
    r = np.array([b / a - 1.0 for _, a, b in pairs])
    half = t_quantile(0.95, len(r) - 1) * float(np.std(r, ddof=1)) / math.sqrt(len(r))
    lo, hi, m = float(r.mean()) - half, float(r.mean()) + half, O.SINK_CHECK_MARGIN
    verdict = (
        "equivalent"
        if -m <= lo and hi <= m
        else "different"
        if hi < -m or lo > m
        else ("undecided")
    )
    return {
        "pairs": pairs,
        "mean": float(r.mean()),
        "interval": (lo, hi),
        "verdict": verdict,
        "parted": parted,
        "cpu_seconds": cpu,
    }


def _parted(a: dict | None, b: dict | None, total: float) -> float | None:
    """The discharged fraction at which two stored (decimated) discharge curves (the mass
    discharged [kg] against time) of a fill of ``total`` [kg] first differ, None where they
    never do (NaN where a curve is missing or they were sampled differently)."""
    if not a or not b or len(a["discharged_mass"]) != len(b["discharged_mass"]):
        return math.nan
    x, y = np.asarray(a["discharged_mass"], float), np.asarray(b["discharged_mass"], float)
    differ = np.nonzero(x != y)[0]
    return None if not len(differ) else float(min(x[differ[0]], y[differ[0]])) / total


def _sink_gated(kind: str) -> bool:
    """Whether a discharge series' runs made with the sink (``extra.sink``) are kept out:
    the slot's until the sink check finds the sink equivalent to the runs made before it;
    never the cone's (made with the sink throughout, by its rule)."""
    if kind == "cone":
        return False
    check = sink_check()
    return check is None or check["verdict"] != "equivalent"


def flow_runs(kind: str = "flow") -> dict[float, list]:
    """The stored runs of a discharge series (``flow``, the slot; ``cone``) that discharged,
    per width [d], but those :func:`_sink_gated` keeps out."""
    gated = _sink_gated(kind)
    widths = O.FLOW_WIDTHS if kind == "flow" else O.CONE_WIDTHS
    out: dict[float, list] = {}
    for w in widths:
        ds = [O.stored(kind, O.G_FLOW, w, s) for s in range(1, O.FLOW_SEEDS + 1)]
        ok = [d for d in ds if _number(d) is not None and not (gated and "sink" in d.extra)]
        if ok:
            out[w] = ok
    return out


def sink_lines() -> list[str]:
    """The sink check's lines for docs/RESOLUTION.md."""
    c = sink_check()
    head = (
        f"The sink against the runs made before it (rule fixed before its runs: the "
        f"{O.SINK_CHECK_WIDTH:g} d discharge, stored from before the sink (its grains fell "
        "freely onto the floor's heap), made again with the sink, the same fills, paired by "
        "seed; equivalent if "
        "the 90 % t-interval of the mean relative difference of the discharge number lies "
        f"within +-{100 * O.SINK_CHECK_MARGIN:.0f} %; only then do runs made with the sink "
        "join the fit): "
    )
    if c is None:
        return [head + "not measured (fewer than two pairs stored)."]
    per = "; ".join(f"seed {s}: {a:.4f} -> {b:.4f}" for s, a, b in c["pairs"])
    lo, hi = c["interval"]

    def where(f):
        return "never" if f is None else "?" if math.isnan(f) else f"at {100 * f:.0f} %"

    apart = ", ".join(where(f) for f in c["parted"])
    end = O.flow_test(O.SINK_CHECK_WIDTH, 1).window_end
    known = [f for f in c["parted"] if f is not None and not math.isnan(f)]
    if any(f is not None and math.isnan(f) for f in c["parted"]):
        when = "(a curve missing: where they part not read for every seed)"
    elif not known:
        when = "(identical throughout)"
    elif all(f > end for f in known):
        when = "after the steady window"
    else:
        when = "within the steady window in some"
    cpu = ", ".join(f"{a:.0f} -> {b:.0f}" for a, b in c["cpu_seconds"])
    return [
        head + f"{per}: mean difference {100 * c['mean']:+.2f} % [{100 * lo:+.2f}, "
        f"{100 * hi:+.2f}] %, **{c['verdict']}**. The stored discharge curves (fraction "
        f"discharged against time) first part {apart} discharged, {when} (up to "
        f"{100 * end:.0f} %); "
        f"CPU seconds on one thread, before -> sink: {cpu}."
    ]


def flow_failures() -> list[str]:
    """Runs of the discharge series (slot and cone) that failed or did not discharge (left
    out), a line each."""
    out = []
    gated = {kind: _sink_gated(kind) for kind in ("flow", "cone")}
    keys = [("flow", w) for w in O.FLOW_WIDTHS] + [("cone", w) for w in O.CONE_WIDTHS]
    for kind, w in keys:
        for s in range(1, O.FLOW_SEEDS + 1):
            d = O.stored(kind, O.G_FLOW, w, s)
            if d is None:
                continue
            name = O.key_name(kind, O.G_FLOW, w, s)
            if d.ok and "sink" in d.extra and gated[kind]:
                out.append(
                    f"{name}: made with the sink, which the sink check has not found "
                    "equivalent to the runs made before it"
                )
            elif not d.ok:
                out.append(f"{name}: {d.outcome[:160]}")
            elif not math.isfinite(d.scalars["discharge_number"]):
                out.append(f"{name}: no steady discharge ({J.describe(d)[:120]})")
    return out


#: A run that failed after discharging at least this fraction of its fill without a stop
#: went on (``outlet_series.before_failure``: the failure is on the catch floor's heap).
WENT_ON_FRACTION = 0.5


def went_on(d) -> bool:
    """Whether a failed run had discharged :data:`WENT_ON_FRACTION` of its fill, unstopped."""
    b = d.extra.get("before_failure")
    return bool(b) and not b["stopped"] and b["discharged_fraction"] >= WENT_ON_FRACTION


def _arch_runs(g: float, seed: int) -> dict[float, bool]:
    """A seed's stored arching runs at gravity ``g``: width [d] -> whether the flow stopped
    (runs that failed left out, but those that had gone on: :func:`went_on`)."""
    if g in JENIKE_GRAVITIES:
        kind, widths, _ = JENIKE_GRAVITIES[g]
        got = {w: J.stored(kind, w, seed) for w in widths}
    else:
        got = {w: O.stored("arch", g, w, seed) for w in O.ARCH_WIDTHS[g]}
    out = {w: bool(d.scalars["stopped"]) for w, d in got.items() if d is not None and d.ok}
    out.update({w: False for w, d in got.items() if d is not None and not d.ok and went_on(d)})
    return out


def gravities() -> dict[float, int]:
    """Every gravity of the arching width's series [m/s^2] and its seeds."""
    out = {g: n for g, (_, _, n) in JENIKE_GRAVITIES.items()}
    out.update({g: O.ARCH_SEEDS for g in O.ARCH_GRAVITIES})
    return out


def critical_width(runs: dict[float, bool]) -> dict:
    """One seed's critical outlet width [d] from its runs at one gravity (width [d] ->
    whether the flow stopped: the mass discharged over the wait stayed under the arch
    fraction, :func:`_arch_runs`): the flow stopped at the
    widest width ``below`` and went on at the next width ``above``; B_crit their midpoint.
    Censored (``width`` None) where the flow stopped at every width or at none, or where a
    width below ``below`` went on (not monotone: said, and the bracket taken around the
    widest stop)."""
    widths = sorted(runs)
    stops = [w for w in widths if runs[w]]
    if not stops:
        return {"width": None, "why": f"discharged at every width ({widths[0]:g}-{widths[-1]:g} d)"}
    below = max(stops)
    above = [w for w in widths if w > below]
    if not above:
        return {"width": None, "why": f"stopped at every width up to {below:g} d", "below": below}
    monotone = all(runs[w] for w in widths if w < below)
    return {
        "width": 0.5 * (below + above[0]),
        "below": below,
        "above": above[0],
        "monotone": monotone,
    }


def arch_table() -> dict[float, list[dict]]:
    """Per gravity [m/s^2], per seed with runs stored: its critical width and G* = g B_crit
    [m^2/s^2]."""
    out = {}
    for g, n in sorted(gravities().items(), reverse=True):
        rows = []
        for seed in range(1, n + 1):
            runs = _arch_runs(g, seed)
            if not runs:
                continue
            c = critical_width(runs)
            c["seed"] = seed
            c["widths_run"] = len(runs)
            c["g_b"] = None if c["width"] is None else g * c["width"] * O.D
            rows.append(c)
        if rows:
            out[g] = rows
    return out


def _curve(groups: list[list[tuple[float, dict]]], name: str, tol: float) -> dict | None:
    """The resolution curve of ``name`` over groups of (diameters across, values) per run,
    the group the most diameters across as the reference; its need at ``tol``."""
    groups = [g for g in groups if len(g) >= 2]
    if len(groups) < 3:
        return None
    groups.sort(key=lambda g: np.mean([x for x, _ in g]))
    ref, rest = groups[-1], groups[:-1]
    controls = {float(np.mean([x for x, _ in g])): g for g in rest}
    c = resolution_curves(ref, controls, [name], CONFIDENCE, pooled=True)["metrics"].get(name)
    if c is not None:
        c["needed"] = diameters_needed(c, tol)
    return c


def outlet_curves() -> dict:
    """The outlet's curves in :func:`benchmarks.size_report.feature_need`'s form: the
    discharge number against B / d at the held g B; G* = g B_crit against B_crit / d. The
    per-property stress the series held [Pa]: rho_b G_FLOW (the discharge runs' mean bulk
    density) and rho_b G* at the widest critical width (the arching transition)."""
    flows, cones = flow_runs(), flow_runs("cone")
    metrics, stresses = {}, {}
    for runs, name in ((flows, "discharge_number"), (cones, "cone_discharge_number")):
        groups = [
            [(d.scalars["outlet_diameters"], {name: [d.scalars["discharge_number"]]}) for d in ds]
            for ds in runs.values()
        ]
        c = _curve(groups, name, O.TOLERANCES[name])
        if c is not None:
            metrics[name] = c
            rho = float(np.mean([d.scalars["bulk_density"] for ds in runs.values() for d in ds]))
            stresses[name] = rho * O.G_FLOW
    arch = arch_table()
    arch_groups = [
        [(r["width"], {"arching_g_b": [r["g_b"]]}) for r in rows if r["width"] is not None]
        for rows in arch.values()
    ]
    c = _curve(arch_groups, "arching_g_b", O.TOLERANCES["arching_g_b"])
    if c is not None:
        metrics["arching_g_b"] = c
        stresses["arching_g_b"] = None  # the law's own transition: matched by law, not stress
    sizes = sorted(set(flows) | set(cones) | {round(w, 3) for g in arch_groups for w, _ in g})
    return {"metrics": metrics, "sizes": sizes, "stresses": stresses}


def sizes_words() -> str:
    """The sizes each property of the outlet was measured at [d across], in words."""
    flows = ", ".join(f"{w:g}" for w in sorted(flow_runs()))
    cones = ", ".join(f"{w:g}" for w in sorted(flow_runs("cone")))
    crit = []
    for rows in arch_table().values():
        got = [r["width"] for r in rows if r["width"] is not None]
        if got:
            crit.append(float(np.mean(got)))
    arch = ", ".join(f"{w:.3g}" for w in sorted(crit))
    return (
        f"discharge {flows or 'none'}; conical discharge {cones or 'none'}; arching (mean "
        f"B_crit per gravity) {arch or 'none'}"
    )


def lines() -> list[str]:
    """docs/RESOLUTION.md's outlet section (below the heading)."""
    out = [
        "From `benchmarks/outlet_series.py` (the series, fits and tolerances fixed in its "
        "docstring before the runs) and the Jenike series' two gravities: the fine law "
        f"(bond1) in the slot hopper, every length in units of B, **g B held** (a coarse "
        "model at factor s of an outlet is exactly the fine law at B / (s d) across it with "
        "the same g B). Two properties: the discharge number W / (rho sqrt(g) B^1.5 D) at "
        f"g B = {O.G_FLOW:g} m^2/s^2 (tolerance {100 * O.TOLERANCES['discharge_number']:.0f} "
        "%), and G* = g B_crit, the g B below which the outlet stops in an arch (tolerance "
        f"{100 * O.TOLERANCES['arching_g_b']:.0f} %), read at four gravities whose critical "
        "widths lie at different B / d. A third: the discharge number of the same hopper "
        "made a cone, W / (rho sqrt(g) B^2.5), the same g B, tolerance and fit (series "
        "`cone`).",
    ]
    for kind, title in (("flow", "Discharge at the held g B"), ("cone", "Conical outlet")):
        out += [
            "",
            f"{title}:",
            "",
            "| B / d | particles | seeds | discharge number (mean) | se of the mean | "
            "bulk density [kg/m^3] | mass flow | CPU s (mean) |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for w, ds in sorted(flow_runs(kind).items()):
            q = np.array([d.scalars["discharge_number"] for d in ds])
            se = float(np.std(q, ddof=1) / math.sqrt(len(q))) if len(q) > 1 else math.nan
            out.append(
                f"| {w:g} | {int(ds[0].scalars['particles'])} | {len(ds)} | {q.mean():.4f} | "
                f"{se:.4f} | {np.mean([d.scalars['bulk_density'] for d in ds]):.0f} | "
                f"{sum(int(d.scalars['mass_flow']) for d in ds)} of {len(ds)} | "
                f"{np.mean([d.extra['cpu_seconds'] for d in ds]):.0f} |"
            )
    out += [
        "",
        "Arching: per seed, the critical width is the midpoint between the widest outlet at "
        "which the flow stopped and the next one run, at which it went on (the flow stopped: "
        "less than the arch fraction of the mass discharged over the wait, `HopperTest`).",
        "",
        "| g [m/s^2] | seed | stopped at [d] | went on at [d] | B_crit [d] | G* = g B_crit "
        "[m^2/s^2] |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    for g, rows in arch_table().items():
        for r in rows:
            if r["width"] is None:
                out.append(f"| {g:g} | {r['seed']} | {r['why']} | | | |")
                continue
            mono = "" if r["monotone"] else " (not monotone)"
            out.append(
                f"| {g:g} | {r['seed']} | {r['below']:g}{mono} | {r['above']:g} | "
                f"{r['width']:g} | {r['g_b']:.2f} |"
            )
    curves = outlet_curves()
    out += ["", f"![outlet series](figures/{FIGURE.name})", "", "Curves:", ""]
    for name in ("discharge_number", "cone_discharge_number", "arching_g_b"):
        c = curves["metrics"].get(name)
        if c is None:
            out.append(f"- {name}: no curve yet (fewer than three sizes with two seeds)")
            continue
        lo, hi = c["slope_interval"]
        bulk_lo, bulk_hi = c["bulk_interval"]
        sizes = ", ".join(f"{s['diameters_across']:.3g}" for s in c["sizes"])
        n = c["needed"]
        need = {
            "needs": f"needs {n['point']:.3g} d (95 % bound {n['diameters']:.3g} d)",
            "more_than": f"needs more than {n['diameters']:.3g} d (the finest run), point "
            f"estimate {n['point']:.3g} d",
            "at_most": f"within tolerance down to {n['diameters']:.3g} d (the coarsest fitted)",
            "not_linear": "the size means lie off the line: no need read",
        }[n["bound"]]
        out.append(
            f"- {name}: bulk {c['bulk']:.4g} [{bulk_lo:.4g}, {bulk_hi:.4g}], slope of log "
            f"value in d / B {c['slope']:+.2f} [{lo:+.2f}, {hi:+.2f}] (sizes {sizes} d): {need}"
        )
    out += censored_lines(curves["metrics"].get("arching_g_b"))
    out += ["", *sink_lines()]
    fails = flow_failures()
    if fails:
        out += ["", "Discharge runs left out:", ""] + [f"- {f}" for f in fails]
    arch_fails = arch_failures()
    if arch_fails:
        out += [
            "",
            "Arching runs that failed (`InstabilityError` on the catch floor's heap; counted "
            f"as gone on where they had discharged {100 * WENT_ON_FRACTION:.0f} % of their "
            "fill unstopped, else left out):",
            "",
        ] + [f"- {f}" for f in arch_fails]
    return out


def censored_lines(c: dict | None) -> list[str]:
    """The seeds whose flow stopped at every width run (no bracket, so not in the fit): each
    gives a lower bound on G*, g times the widest width at which it stopped, set beside the
    fitted line there and its 95 % band (the bulk's and the slope's intervals together). A
    bound above the band says the line falls too far at that size (wider outlets at that
    gravity would bracket it); not a verdict of its own."""
    rows = [
        (g, r)
        for g, rs in arch_table().items()
        for r in rs
        if r["width"] is None and r.get("below") is not None
    ]
    if not rows:
        return []
    out = ["", "Seeds that stopped at every width they ran (lower bounds on G*, not fitted):", ""]
    for g, r in rows:
        lo_g = g * r["below"] * O.D
        line = (
            f"- g = {g:g} m/s^2, seed {r['seed']}: stopped up to {r['below']:g} d: G* >= {lo_g:.2f}"
        )
        if c is not None:
            x = 1.0 / r["below"]
            fit = c["bulk"] * math.exp(c["slope"] * x)
            (b_lo, b_hi), (s_lo, s_hi) = c["bulk_interval"], c["slope_interval"]
            hi = b_hi * math.exp(max(s_lo * x, s_hi * x))
            low = b_lo * math.exp(min(s_lo * x, s_hi * x))
            where = "above the band" if lo_g > hi else "within the band" if lo_g >= low else ""
            line += f"; the fitted line there {fit:.2f} [{low:.2f}, {hi:.2f}]" + (
                f": {where}" if where else ""
            )
        out.append(line)
    return out


def arch_failures() -> list[str]:
    """The arching series' failed runs, a line each: how far each had got, and whether it
    counts (:func:`went_on`)."""
    out = []
    for g in O.ARCH_GRAVITIES:
        for w in O.ARCH_WIDTHS[g]:
            for seed in range(1, O.ARCH_SEEDS + 1):
                d = O.stored("arch", g, w, seed)
                if d is None or d.ok:
                    continue
                b = d.extra.get("before_failure")
                where = (
                    "before the gate opened"
                    if not b
                    else f"{b['time']:.3f} s after the opening, "
                    f"{100 * b['discharged_fraction']:.0f} % discharged, "
                    f"{'stopped' if b['stopped'] else 'not stopped'}"
                )
                counts = "counted as gone on" if went_on(d) else "left out"
                out.append(f"{O.key_name('arch', g, w, seed)}: failed {where}: {counts}")
    return out


def figure():
    """Three panels against d / B (the fit's variable): each run's discharge number at the
    held g B through the slot and through the cone, and each seed's G* = g B_crit; each with
    its fitted line exp(a + b d / B) and the tolerance band around the fitted bulk (matplotlib's
    object API on an Agg canvas). A panel without a curve shows its points and says so."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13.0, 4.0), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    curves = outlet_curves()["metrics"]
    ax_pts = []
    for kind in ("flow", "cone"):
        flows = flow_runs(kind)
        fx = [1.0 / d.scalars["outlet_diameters"] for ds in flows.values() for d in ds]
        fy = [d.scalars["discharge_number"] for ds in flows.values() for d in ds]
        ax_pts.append((fx, fy))
    arch = arch_table()
    ax_pts.append(
        (
            [1.0 / r["width"] for rows in arch.values() for r in rows if r["width"]],
            [r["g_b"] for rows in arch.values() for r in rows if r["width"]],
        )
    )
    titles = (
        f"slot: discharge at g B = {O.G_FLOW:g} m^2/s^2",
        f"cone: discharge at g B = {O.G_FLOW:g} m^2/s^2",
        "slot: arching, G* = g B_crit (one point per seed and gravity)",
    )
    ylabels = (
        "discharge number W / (rho sqrt(g) B^1.5 D) [-]",
        "discharge number W / (rho sqrt(g) B^2.5) [-]",
        "G* [m^2/s^2]",
    )
    # a seed that stopped at every width it ran bounds G* from below (the widest such
    # bound of each gravity: a seed not yet run at its wider widths says less)
    lower = []
    for g, rows in arch.items():
        bounds = [r["below"] for r in rows if r["width"] is None and r.get("below")]
        if bounds:
            lower.append((1.0 / max(bounds), g * max(bounds) * O.D))
    if lower:
        axes[2].plot(
            *zip(*lower),
            "^",
            ms=7,
            mfc="none",
            color="C4",
            label="stopped at every width run (G* above, d / B_crit below)",
        )
    for ax, name, (x, y), title, ylabel in zip(
        axes, ("discharge_number", "cone_discharge_number", "arching_g_b"), ax_pts, titles, ylabels
    ):
        ax.plot(x, y, "o", ms=4, color="C0", label="runs")
        c = curves.get(name)
        grid = np.linspace(0.0, max(x) * 1.05 if x else 0.2, 50)
        if c is not None:
            a, b = math.log(c["bulk"]), c["slope"]
            fitted = max(s["d_over_L"] for s in c["sizes"])
            inside = grid <= fitted * 1.0001
            ax.plot(
                grid[inside],
                np.exp(a + b * grid[inside]),
                "-",
                color="C1",
                label="fit (sizes fitted)",
            )
            if (~inside).any():
                why = "sizes left out: off its line" if c.get("left_out") else "extrapolated"
                ax.plot(
                    grid[~inside],
                    np.exp(a + b * grid[~inside]),
                    ":",
                    color="C1",
                    label=f"the fit beyond them ({why})",
                )
            tol = O.TOLERANCES[name]
            ax.axhspan(c["bulk"] * (1 - tol), c["bulk"] * (1 + tol), color="C2", alpha=0.15)
            ax.axhline(c["bulk"], color="C2", lw=0.8, label=f"bulk +- {100 * tol:.0f} %")
            n = c["needed"]
            if n["bound"] == "needs":
                ax.axvline(1.0 / n["diameters"], color="C3", ls="--", lw=0.8)
                ax.text(
                    1.0 / n["diameters"],
                    ax.get_ylim()[0],
                    f" 95 % bound: {n['diameters']:.3g} d",
                    color="C3",
                    fontsize=8,
                    va="bottom",
                )
        else:
            ax.text(0.5, 0.9, "no curve yet", transform=ax.transAxes, ha="center")
        ax.set_xlim(0.0, grid[-1])
        ax.set_xlabel("d / B [-]")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return fig


def write_figure(path: Path | None = None) -> str:
    """Draw :func:`figure` into ``path`` (default :data:`FIGURE`)."""
    path = Path(path or FIGURE)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure().savefig(path, format="png")
    return str(path)


if __name__ == "__main__":
    print("\n".join(lines()))
    print(write_figure())
