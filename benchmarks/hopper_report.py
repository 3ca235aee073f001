"""The Beverloo section of docs/HOPPER.md from the stored digests of the hopper series
(``python -m benchmarks.hopper_report``; the runs: :mod:`benchmarks.hopper_series`).

What decides, fixed before the runs (2026-12-06):

- **The quantity**: each run's steady discharge rate per unit depth W (kg/(s m), the
  HopperTest's batch-means window) over rho_b sqrt(g), rho_b the run's own **bulk density of
  the settled fill** (its lower half, ``scalars["bulk_density"]``), in units of d^(3/2):
  y = W / (rho_b sqrt(g) d^(3/2)), d the mean diameter. Beverloo's slot form is then
  y = C (B/d - k)^(3/2).
- **Width means**: per outlet width the mean of y over its seeds, with its standard error:
  the seeds' standard deviation over sqrt(n) (n >= 2 seeds), but no less than the runs'
  mean batch-means error over sqrt(n) (two or three seeds that agree by chance would
  otherwise weigh a width without bound); a single seed's own batch-means error otherwise.
- **The fit**: C and k by weighted least squares over the width means (weights 1 / SE^2):
  for a fixed k the best C is linear, so chi^2 is minimised over a fine grid of k
  (step 1e-3 of a diameter, k from -3 to just below the narrowest B/d) and C follows.
- **Intervals (95 %)**: profile likelihood: the k (or C) whose profiled chi^2 lies within
  3.84 s^2 of the minimum, s^2 = max(1, chi^2_min / dof) (the scatter inflated where the
  width means scatter more than their errors say). Beside them a bootstrap over seeds
  (each width's seeds resampled with replacement, the fit repeated 2000 times, 2.5-97.5
  percentiles; with three seeds per width it understates the spread by about
  sqrt(2/3)): reported, not the verdict's.
- **Published ranges** (:data:`PUBLISHED`) and **the verdict**: "within" where the
  whole 95 % profile interval lies inside the range, "outside" where it does not meet the
  range, "undecided" otherwise; no tolerance beyond the range's own width. A verdict needs
  five widths with three seeds each (the issue's "done when"); with fewer the fit is
  shown only when five widths have two seeds at least, and the verdict is "undecided".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from benchmarks import hopper_series as S

ROOT = S.ROOT
REPORT = ROOT / "docs" / "HOPPER.md"
#: The Beverloo figure, drawn by :func:`write_report` beside the section.
FIGURE = ROOT / "docs" / "figures" / "hopper_beverloo.png"
BEGIN = "<!-- beverloo:begin (benchmarks/hopper_report.py) -->"
END = "<!-- beverloo:end -->"
#: Beverloo's exponent for a slot (plane flow).
EXPONENT = 1.5
#: Published ranges: name -> (low, high, source).
PUBLISHED = {
    "C": (
        0.55,
        0.65,
        "Beverloo, Leniger & van de Velde, Chem. Eng. Sci. 15 (1961) 260-269; Nedderman, "
        "Statics and kinematics of granular materials (1992): circular orifices in flat "
        "bottoms (3D)",
    ),
    "k": (
        1.3,
        2.9,
        "Nedderman (1992); Nedderman, Tüzün, Savage & Houlsby, Chem. Eng. Sci. 37 (1982) "
        "1597-1609: circular orifices (3D)",
    ),
}
WIDTHS_NEEDED = 5
SEEDS_NEEDED = 3
BOOTSTRAP = 2000
Z95 = 3.841458820694124  # the 95 % quantile of chi^2 with one degree of freedom


@dataclass
class Point:
    """One stored run: outlet width B/d, y = W / (rho_b sqrt(g) d^1.5) and its batch-means
    standard error, the run's rho_b [kg/m^3], W per depth [kg/(s m)], flow mode, seconds."""

    width: float
    seed: int
    y: float
    y_se: float
    rho_b: float
    rate_per_depth: float
    flow_mode: str
    particles: int
    cpu_seconds: float
    wall_seconds: float
    drift: float = math.nan


def drift_of(curve: dict, total: float, start: float, end: float) -> float:
    """How the rate changed over the steady window, from a digest's decimated curve: the
    least-squares rate over the window's second half in discharged mass less that over its
    first half, over their mean [-] (NaN with fewer than four samples in a half). A rate set
    by the outlet alone, not by the head above it, drifts by no more than its noise."""
    t = np.asarray(curve.get("time", ()), dtype=float)
    m = np.asarray(curve.get("discharged_mass", ()), dtype=float)
    mid = 0.5 * (start + end)
    rates = []
    for a, b in ((start, mid), (mid, end)):
        sel = (m >= a * total) & (m <= b * total)
        if sel.sum() < 4:
            return math.nan
        rates.append(np.polyfit(t[sel], m[sel], 1)[0])
    return float((rates[1] - rates[0]) / (0.5 * (rates[0] + rates[1])))


def point_of(width: float, seed: int, digest) -> Point | None:
    """The run's point (None for a run without a steady window or that failed)."""
    if digest is None or not digest.ok:
        return None
    s = digest.scalars
    g = float(digest.test["gravity"])
    depth = float(digest.test["depth"])
    d = 2.0 * float(digest.test["radius"])
    w = s.get("discharge_rate_per_depth", math.nan)
    rho_b = s.get("bulk_density", math.nan)
    if not (math.isfinite(w) and math.isfinite(rho_b)):
        return None
    scale = rho_b * math.sqrt(g) * d**EXPONENT
    return Point(
        width=width,
        seed=seed,
        y=w / scale,
        y_se=s["discharge_rate_se"] / depth / scale,
        rho_b=rho_b,
        rate_per_depth=w,
        flow_mode=digest.extra.get("flow_mode", "unknown"),
        particles=int(s["particles"]),
        cpu_seconds=float(digest.extra.get("cpu_seconds", math.nan)),
        wall_seconds=float(digest.extra.get("wall_seconds", math.nan)),
        drift=drift_of(
            digest.extra.get("curve", {}),
            float(s.get("total_mass", math.nan)),
            float(digest.test["window_start"]),
            float(digest.test["window_end"]),
        ),
    )


def points(store=None) -> list[Point]:
    """Every stored run's point, in the series' order."""
    out = []
    for w, seed in S.keys():
        p = point_of(w, seed, S.stored(w, seed, store))
        if p is not None:
            out.append(p)
    return out


def width_means(pts: list[Point]) -> list[dict]:
    """Per width: B/d, n, the mean y, its standard error (``pooled``: False where a single
    seed's own error stands in)."""
    out = []
    for w in sorted({p.width for p in pts}):
        ys = np.array([p.y for p in pts if p.width == w])
        own = float(np.mean([p.y_se for p in pts if p.width == w])) / math.sqrt(len(ys))
        if len(ys) >= 2:
            # no lower than the runs' own errors say: two or three seeds that agree by
            # chance would otherwise weigh a width without bound
            se, from_seeds = max(float(np.std(ys, ddof=1) / math.sqrt(len(ys))), own), True
        else:
            se, from_seeds = own, False
        out.append(
            {"width": w, "n": len(ys), "mean": float(ys.mean()), "se": se, "seeds": from_seeds}
        )
    return out


def _k_grid(x: np.ndarray) -> np.ndarray:
    return np.arange(-3.0, float(np.min(x)) - 1e-3, 1e-3)


def _profile(x, y, se, ks):
    """chi^2 minimised over C at each k of ``ks``: (chi2, C_hat, sum x^2/se^2)."""
    X = np.clip(x[None, :] - ks[:, None], 0.0, None) ** EXPONENT
    wgt = 1.0 / se**2
    sxx = (X * X * wgt).sum(axis=1)
    c = (X * y * wgt).sum(axis=1) / sxx
    chi2 = (((y - c[:, None] * X) ** 2) * wgt).sum(axis=1)
    return chi2, c, sxx


def fit(x, y, se) -> dict:
    """Weighted least squares of y = C (x - k)^1.5 (module docstring): C, k, their 95 %
    profile intervals, chi^2, dof, the residuals."""
    x, y, se = (np.asarray(a, dtype=float) for a in (x, y, se))
    if len(x) < 3:
        raise ValueError(f"a fit of C and k takes three widths at least, not {len(x)}")
    if np.any(se <= 0) or not np.all(np.isfinite(se)):
        raise ValueError("every width's standard error must be finite and positive")
    ks = _k_grid(x)
    chi2, c, sxx = _profile(x, y, se, ks)
    i = int(np.argmin(chi2))
    dof = len(x) - 2
    s2 = max(1.0, chi2[i] / dof) if dof > 0 else 1.0
    thr = chi2[i] + Z95 * s2
    inside = chi2 <= thr
    k_lo, k_hi = float(ks[inside].min()), float(ks[inside].max())
    # C's profile: at each k, chi^2 is quadratic in C with curvature sxx
    half = np.sqrt(np.clip(thr - chi2[inside], 0.0, None) / sxx[inside])
    c_lo, c_hi = float((c[inside] - half).min()), float((c[inside] + half).max())
    k, cc = float(ks[i]), float(c[i])
    model = cc * (x - k) ** EXPONENT
    return {
        "C": cc,
        "k": k,
        "C_interval": (c_lo, c_hi),
        "k_interval": (k_lo, k_hi),
        "k_at_edge": bool(inside[0] or inside[-1]),
        "chi2": float(chi2[i]),
        "dof": dof,
        "s2": s2,
        "model": model.tolist(),
        "residual": (y - model).tolist(),
        "residual_sigma": ((y - model) / se).tolist(),
    }


def bootstrap(pts: list[Point], means: list[dict], n: int = BOOTSTRAP, seed: int = 52) -> dict:
    """95 % percentile intervals of C and k from resampling each width's seeds with
    replacement (the widths' standard errors held)."""
    rng = np.random.default_rng(seed)
    x = np.array([m["width"] for m in means])
    se = np.array([m["se"] for m in means])
    groups = [np.array([p.y for p in pts if p.width == m["width"]]) for m in means]
    ks = _k_grid(x)
    X = np.clip(x[None, :] - ks[:, None], 0.0, None) ** EXPONENT  # (k, width)
    wgt = 1.0 / se**2
    sxx = (X * X * wgt).sum(axis=1)
    ys = np.stack(
        [g[rng.integers(0, len(g), (n, len(g)))].mean(axis=1) for g in groups], axis=1
    )  # (resample, width)
    cs, kk = [], []
    for chunk in np.array_split(ys, max(1, n // 200)):
        sxy = chunk @ (X * wgt).T  # (resample, k)
        # chi^2 minimised over C at each k: sum w y^2 - sxy^2 / sxx
        chi2 = (chunk**2 * wgt).sum(axis=1)[:, None] - sxy**2 / sxx[None, :]
        i = np.argmin(chi2, axis=1)
        kk += ks[i].tolist()
        cs += (sxy[np.arange(len(i)), i] / sxx[i]).tolist()
    q = (2.5, 97.5)
    return {
        "C_interval": tuple(float(v) for v in np.percentile(cs, q)),
        "k_interval": tuple(float(v) for v in np.percentile(kk, q)),
        "n": n,
    }


def verdict(interval: tuple[float, float], published: tuple[float, float]) -> str:
    """ "within", "outside" or "undecided" (module docstring)."""
    lo, hi = interval
    a, b = published
    if a <= lo and hi <= b:
        return "within"
    if hi < a or lo > b:
        return "outside"
    return "undecided"


def fit_band(f: dict, x: np.ndarray, y: np.ndarray, se: np.ndarray, grid: np.ndarray):
    """The 95 % band of the fitted curve at widths ``grid`` [-]: the lowest and highest
    C (B/d - k)^1.5 over every (C, k) inside the fit's joint profile region (chi^2 within
    3.84 s^2 of its minimum: the region :func:`fit`'s intervals are read from)."""
    ks = _k_grid(x)
    chi2, c, sxx = _profile(x, y, se, ks)
    thr = float(chi2.min()) + Z95 * f["s2"]
    inside = chi2 <= thr
    half = np.sqrt(np.clip(thr - chi2[inside], 0.0, None) / sxx[inside])
    shape = np.clip(grid[None, :] - ks[inside][:, None], 0.0, None) ** EXPONENT  # (k, grid)
    lo = np.minimum((c[inside] - half)[:, None] * shape, (c[inside] + half)[:, None] * shape)
    hi = np.maximum((c[inside] - half)[:, None] * shape, (c[inside] + half)[:, None] * shape)
    return lo.min(axis=0), hi.max(axis=0)


def figure(store=None):
    """The Beverloo figure (matplotlib's object API on an Agg canvas, as
    engine/io/figures.py draws): y = W / (rho_b sqrt(g) d^1.5) against B/d on log-log
    axes, each run's point
    (small), each width's mean with its standard error, the fit C (B/d - k)^1.5 with its 95 %
    band, and the mean rate per unit depth in kg/(s m) on the right axis (at the runs' mean
    bulk density); below, the same against the fit [%] (where the band can be seen). Without five
    widths of two seeds the points only, and the panel says why."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pts = points(store)
    means = [m for m in width_means(pts) if m["n"] >= 2]
    fig = Figure(figsize=(7.0, 6.2), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax, res = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (3, 1)})
    ax.plot(
        [p.width for p in pts],
        [p.y for p in pts],
        "o",
        ms=3,
        color="0.55",
        label=f"each run ({len(pts)})",
    )
    if means:
        ax.errorbar(
            [m["width"] for m in means],
            [m["mean"] for m in means],
            yerr=[m["se"] for m in means],
            fmt="s",
            ms=5,
            color="black",
            capsize=3,
            label="mean over seeds ± 1 SE",
        )
    top = max([p.width for p in pts], default=float(max(S.WIDTHS)))
    if len(means) >= WIDTHS_NEEDED:
        x = np.array([m["width"] for m in means])
        y = np.array([m["mean"] for m in means])
        se = np.array([m["se"] for m in means])
        f = fit(x, y, se)
        grid = np.geomspace(0.8 * float(x.min()), 1.15 * top, 300)
        lo, hi = fit_band(f, x, y, se, grid)
        ax.fill_between(grid, lo, hi, color="C0", alpha=0.2, lw=0, label="fit's 95 % band")
        cl, ch = f["C_interval"]
        kl, kh = f["k_interval"]
        ax.plot(
            grid,
            f["C"] * np.clip(grid - f["k"], 0.0, None) ** EXPONENT,
            color="C0",
            lw=1.8,
            label=f"C (B/d - k)^1.5: C = {f['C']:.3g} [{cl:.3g}, {ch:.3g}], "
            f"k = {f['k']:.3g} [{kl:.3g}, {kh:.3g}]",
        )

        # below: each point against the fit [%], the band the same way
        def model(b):
            return f["C"] * np.clip(np.asarray(b, dtype=float) - f["k"], 0.0, None) ** EXPONENT

        mid = model(grid)
        res.fill_between(grid, 100 * (lo / mid - 1), 100 * (hi / mid - 1), color="C0", alpha=0.2)
        res.axhline(0.0, color="C0", lw=1.2)
        res.plot(
            [p.width for p in pts],
            [100 * (p.y / model(p.width) - 1) for p in pts],
            "o",
            ms=3,
            color="0.55",
        )
        res.errorbar(
            x,
            100 * (y / model(x) - 1),
            yerr=100 * se / model(x),
            fmt="s",
            ms=4,
            color="black",
            capsize=3,
        )
        res.set_ylabel("against the fit [%]")
    else:
        res.text(
            0.5,
            0.5,
            f"no fit: {len(means)} widths with two seeds or more, the fit takes {WIDTHS_NEEDED}",
            ha="center",
            va="center",
            transform=res.transAxes,
        )
    if pts:  # the right axis: the rate per unit depth at the runs' mean bulk density
        scale = float(np.mean([p.rate_per_depth / p.y for p in pts]))
        right = ax.secondary_yaxis("right", functions=(lambda v: v * scale, lambda w: w / scale))
        right.set_ylabel("W at the mean rho_b [kg/(s m)]")
    # log-log: the widths from 6 to 40 diameters and their rates spread evenly, and the
    # bend of (B/d - k)^1.5 away from a power law at small widths (k) shows
    ax.set_xscale("log")
    ax.set_yscale("log")
    low = min([p.width for p in pts], default=float(min(S.WIDTHS)))
    ax.set_xlim(0.8 * low, 1.15 * top)
    ticks = sorted({float(w) for w in S.WIDTHS})
    ax.set_xticks(ticks, [f"{w:g}" for w in ticks])
    ax.set_xticks([], minor=True)
    ax.set_ylabel("W / (rho_b sqrt(g) d^1.5) [-]")
    ax.set_title(
        f"Slot hopper discharge against Beverloo's law ({S.HALF_ANGLE:g} deg walls, "
        f"depth {S.DEPTH / S.D:g} d)",
        fontsize=10,
    )
    ax.legend(fontsize=8, loc="upper left", title="intervals 95 % (profile)", title_fontsize=7)
    res.set_xlabel("outlet width B / d [-]")
    for a in (ax, res):
        a.grid(alpha=0.3)
    return fig


def write_figure(path=None, store=None) -> str:
    """Draw :func:`figure` into ``path`` (default :data:`FIGURE`; its folder made)."""
    from pathlib import Path

    path = Path(path or FIGURE)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure(store).savefig(path, format="png")
    return str(path)


def _f(v, nd=3) -> str:
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.{nd}g}"


def section(store=None) -> str:
    """The generated Markdown between the markers."""
    pts = points(store)
    means = width_means(pts)
    runs = {w: [p for p in pts if p.width == w] for w in S.WIDTHS}
    stored_all = [(w, s, S.stored(w, s, store)) for w, s in S.keys()]
    failed = [(w, s, d.outcome) for w, s, d in stored_all if d is not None and not d.ok]
    no_window = [
        (w, s) for w, s, d in stored_all if d is not None and d.ok and point_of(w, s, d) is None
    ]
    L = [
        BEGIN,
        "",
        "## Beverloo's law: the slot's cohesionless discharge (generated)",
        "",
        "Generated by `python -m benchmarks.hopper_report` from the digests in",
        "`benchmarks/results/hopper_series/` (the runs: `python -m benchmarks.hopper_series`;",
        "the choices, fixed before the runs, in the docstrings of `benchmarks/hopper_series.py`",
        "and `benchmarks/hopper_report.py`). Slot hopper, half-angle "
        f"{S.HALF_ANGLE:g} deg, periodic depth {S.DEPTH * 1e3:g} mm = {S.DEPTH / S.D:g} d, "
        f"d = {S.D * 1e3:g} mm (radii +-{S.POLYDISPERSITY:.0%}), the bilinear law without "
        "adhesion (mu_s = 0.5, mu_r = 0.001, e = 0.4), Hertz walls (mu = 0.3), fill height "
        "max(1.5 B, 20 d). y = W / (rho_b sqrt(g) d^1.5), W the steady rate per unit depth, "
        "rho_b the run's settled bulk density; Beverloo's slot form y = C (B/d - k)^1.5.",
        "",
        f"![Beverloo fit](figures/{FIGURE.name}) (drawn from the same digests: each run, the "
        "widths' means, the fit with its 95 % band; below, the same against the fit)",
        "",
        f"**Stored**: {len(pts)} runs with a steady window of {len(S.keys())} planned "
        f"({len(S.WIDTHS)} widths x {S.SEEDS} seeds); per width: "
        + ", ".join(f"{w:g} d: {len(runs[w])}" for w in S.WIDTHS)
        + ".",
        "",
    ]
    left = [k for k, (_, _, d) in zip(S.keys(), stored_all) if d is None]
    if left:
        L += [
            f"**Left to run**: {len(left)} runs ("
            + ", ".join(S.key_name(*k) for k in left)
            + f"), about {sum(S.estimate(*k) for k in left) / 60:.0f} min of CPU on one "
            "engine thread by `hopper_series.estimate` (wall time more on a shared machine); "
            "`python -m benchmarks.hopper_series` runs them, then "
            "`python -m benchmarks.hopper_report` rewrites this.",
            "",
        ]
    if failed:
        L += ["Failed runs: " + "; ".join(f"{S.key_name(w, s)}: {o[:120]}" for w, s, o in failed)]
        L += [""]
    if no_window:
        L += ["Runs without a steady window: " + ", ".join(S.key_name(*k) for k in no_window)]
        L += [""]
    if pts:
        L += [
            "| B/d | seed | particles | rho_b (kg/m^3) | W (kg/(s m)) | y | y's SE (batch means) "
            "| drift | flow | CPU s | wall s |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for p in sorted(pts, key=lambda p: (p.width, p.seed)):
            L.append(
                f"| {p.width:g} | {p.seed} | {p.particles} | {p.rho_b:.0f} | "
                f"{p.rate_per_depth:.4g} | {p.y:.4g} | {p.y_se:.2g} | {p.drift:+.1%} | "
                f"{p.flow_mode} | "
                f"{p.cpu_seconds:.0f} | {p.wall_seconds:.0f} |"
            )
        L += [
            "",
            "(drift: the rate over the second half of the steady window, in discharged mass, "
            "less that over its first half, over their mean, from the stored curve: a rate set "
            "by the outlet, not the head, drifts by its noise only. "
            "CPU and wall seconds of the whole run on one engine thread of a 2-core VM shared "
            "with other jobs, the kernels' compilation included where the run compiled them.)",
            "",
        ]
        parts, headed = [], []
        for w in S.WIDTHS:
            dr = np.array([p.drift for p in runs[w] if math.isfinite(p.drift)])
            if len(dr) == 0:
                continue
            parts.append(f"{w:g} d {dr.mean():+.1%}")
            if len(dr) >= 2 and abs(dr.mean()) > 2.0 * dr.std(ddof=1) / math.sqrt(len(dr)):
                headed.append(f"{w:g} d")
        L += [
            "Drift, the mean over seeds per width: "
            + ", ".join(parts)
            + ". "
            + (
                "It exceeds twice its standard error over seeds at "
                + ", ".join(headed)
                + ": there the rate is not constant over the window to within the seeds' noise "
                "(by about the drift's size; the head, the fill falling, is the candidate "
                "cause, not tested here); the rate reported is the window's mean."
                if headed
                else "Within twice its standard error over seeds at every width."
            ),
            "",
        ]
    full = [m for m in means if m["n"] >= SEEDS_NEEDED]
    twos = [m for m in means if m["n"] >= 2]
    if len(twos) < WIDTHS_NEEDED:
        L += [
            f"**Fit: not measured** ({len(twos)} widths with two seeds or more; the fit takes "
            f"{WIDTHS_NEEDED}). **Verdict: undecided.**",
            "",
        ]
    else:
        use = twos
        x = np.array([m["width"] for m in use])
        y = np.array([m["mean"] for m in use])
        se = np.array([m["se"] for m in use])
        f = fit(x, y, se)
        b = bootstrap(pts, use)
        decided = len(full) >= WIDTHS_NEEDED
        L += [
            "| B/d | seeds | mean y | SE | fit | residual | residual / SE |",
            "|---|---|---|---|---|---|---|",
        ]
        for m, mod, r, rs in zip(use, f["model"], f["residual"], f["residual_sigma"]):
            L.append(
                f"| {m['width']:g} | {m['n']} | {m['mean']:.4g} | {m['se']:.2g} | {mod:.4g} | "
                f"{r:+.3g} ({r / mod:+.1%}) | {rs:+.2f} |"
            )
        L += [
            "",
            f"chi^2 = {f['chi2']:.3g} with {f['dof']} degrees of freedom (s^2 = "
            f"{f['s2']:.3g} scales the intervals).",
            "",
            "| | fit | 95 % profile interval | 95 % bootstrap over seeds | published | verdict |",
            "|---|---|---|---|---|---|",
        ]
        for name in ("C", "k"):
            lo, hi, _src = PUBLISHED[name]
            iv = f[f"{name}_interval"]
            bi = b[f"{name}_interval"]
            v = verdict(iv, (lo, hi)) if decided else "undecided (fewer than 5 x 3 runs)"
            if decided and max(x) < max(S.WIDTHS):
                v += f" (widths {min(x):g}-{max(x):g} d fitted; {max(S.WIDTHS):g} d not stored)"
            L.append(
                f"| {name} | {f[name]:.3g} | [{iv[0]:.3g}, {iv[1]:.3g}] | "
                f"[{bi[0]:.3g}, {bi[1]:.3g}] | {lo:g}-{hi:g} | **{v}** |"
            )
        if f["k_at_edge"]:
            L += ["", "k's interval reaches the edge of the searched range (-3 to B_min/d)."]
        L += [""]
    L += [
        "Published ranges:",
        "",
        f"- C {PUBLISHED['C'][0]:g}-{PUBLISHED['C'][1]:g}: {PUBLISHED['C'][2]}.",
        f"- k {PUBLISHED['k'][0]:g}-{PUBLISHED['k'][1]:g}: {PUBLISHED['k'][2]}.",
        "",
        "These are the issue's ranges, for circular orifices in flat bottoms (the 5/2 law),",
        "not re-checked against the papers here. No published range of C and k for a slot",
        "(plane flow, the 3/2 law) was found: the sources the search gave (Mankoc et al.,",
        "Granular Matter 9 (2007) 407, 2D and 3D silos fitted with their own law in place of",
        "k; Janda, Zuriguel & Maza, PRL 108 (2012) 248001, a 2D silo's rate from its density",
        "and velocity profiles, without k) state no slot range of C and k. A slot's C is not a",
        "circle's (the geometry factor differs), and a hopper of 30-degree walls discharges",
        "faster than a flat bottom (the converging walls), so C is set against the 3D range",
        "as the issue asks, not as a like-for-like check; k, the empty annulus in diameters,",
        "is the more comparable of the two.",
        "",
        END,
    ]
    return "\n".join(L)


def write_report(path=None, store=None) -> str:
    """Write the section into docs/HOPPER.md between :data:`BEGIN` and :data:`END` (before
    "## Not measured / not done yet" the first time); the path written."""
    path = path or REPORT
    text = path.read_text()
    body = section(store)
    if BEGIN in text and END in text:
        a = text.index(BEGIN)
        z = text.index(END) + len(END)
        text = text[:a] + body + text[z:]
    else:
        anchor = "## Not measured / not done yet"
        if anchor in text:
            text = text.replace(anchor, body + "\n\n" + anchor, 1)
        else:
            text = text.rstrip("\n") + "\n\n" + body + "\n"
    path.write_text(text)
    return str(path)


if __name__ == "__main__":
    print(write_report())
    print(write_figure())
