"""The shear cell's height: the default shear test (docs/SHEAR.md) in cells 10, 15 and 20
mean diameters tall, six packing seeds each (1-3 first, then 4-6), cohesionless and
cohesive; and the 10 and 15 d cells at half the default inertial number (5e-4), the rate
check.

    nice -n 19 env NUMBA_NUM_THREADS=1 python -m benchmarks.shear_cell   # runs not yet stored
    python -m benchmarks.shear_cell --report                              # the table
    nice -n 19 env NUMBA_NUM_THREADS=1 python -m benchmarks.shear_cell --steady
    python -m benchmarks.shear_cell --steady --report   # long pre-shears, per 0.1 of strain
    python -m benchmarks.shear_cell --figure            # docs/figures/shear_cell.png

Each run is stored the moment it ends as ``benchmarks/results/quick/shear/<law>-h<H>-s<seed>
.json`` (the test, its scalars and shear points; the curves beside it as ``.npz``), so the
benchmark resumes with the runs it lacks. The cross-section is the default's, 10 x 5 mean
diameters (R = 2.5 mm); the heights are those of the cell the bed fills at solid fraction
0.6 before consolidation. The report gives per law and height the mean and the seeds'
standard deviation of the pre-shear point, the yield locus (c, phi), the effective angle,
sigma_1, sigma_c, ffc and the bulk density: a height is converged for a quantity when its
mean lies within the seeds' spread of the next taller cell's.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import engine

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "quick" / "shear"
HEIGHTS = (10, 15, 20)  # mean diameters
#: The default inertial number, and the rate check's half of it (in the 10 and 15 d cells).
RATES = (1e-3, 5e-4)
#: Every (height [d], inertial number [-]) run per law and seed, in the order they run.
VARIANTS = (*((h, RATES[0]) for h in HEIGHTS), (HEIGHTS[0], RATES[1]), (HEIGHTS[1], RATES[1]))
SEEDS = (1, 2, 3, 4, 5, 6)
#: The seeds of the long pre-shears (--steady).
LONG_SEEDS = (1, 2, 3)
LAWS = {
    "cohesionless": engine.ShearTest().pair_law,
    # tests/engine/test_shear.py's cohesive law: pull-off 0.4 N, about the contact force
    # sigma d^2 at the pre-shear stress of 10 kPa
    "cohesive": engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001),
}
#: The quantities reported, with their units.
REPORTED = {
    "preshear_tau": "Pa",
    "cohesion": "Pa",
    "cohesion_se": "Pa",
    "friction_angle": "deg",
    "effective_friction_angle": "deg",
    "sigma_1": "Pa",
    "sigma_c": "Pa",
    "ffc": "1",
    "bulk_density": "kg/m^3",
    "height_diameters": "1",
}


def test_for(law: str, height: int, seed: int, inertial: float = RATES[0]) -> engine.ShearTest:
    base = engine.ShearTest()
    d = 2 * base.radius
    cell = (base.cell[0], base.cell[1], height * d)
    # a stage's bound on simulated time grows as the rate falls (the same strains)
    return replace(
        base,
        cell=cell,
        seed=seed,
        pair_law=LAWS[law],
        inertial_number=inertial,
        max_stage_time=base.max_stage_time * RATES[0] / inertial,
    )


def path_for(law: str, height: int, seed: int, inertial: float = RATES[0]) -> Path:
    rate = "" if inertial == RATES[0] else f"-I{inertial:g}"
    return STORE / f"{law}-h{height}{rate}-s{seed}.json"


def store(path: Path, res: engine.ShearResult) -> None:
    """The run's test, scalars and points as JSON, its curves as .npz, each written whole
    (temporary file, then rename)."""
    STORE.mkdir(parents=True, exist_ok=True)
    curves = {f"{name}/{k}": v for name, st in res.stages.items() for k, v in st.curves.items()}
    tmp = path.with_suffix(".npz.tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **curves)
    tmp.replace(path.with_suffix(".npz"))
    data = {
        "test": res.test.to_dict(),
        "scalars": {k: float(v) for k, v in res.scalars.items()},
        "points": res.yield_points(),
        "locus": res.locus.to_dict(),
        "engine": engine.__version__,
    }
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    tmp.replace(path)


def run(laws) -> None:
    for law in laws:
        for seed in SEEDS:
            for h, rate in VARIANTS:
                p = path_for(law, h, seed, rate)
                if p.exists() or p.with_suffix(".failed").exists():
                    continue
                t0 = time.time()
                print(f"{p.name}: running", flush=True)
                try:
                    res = engine.run_shear(test_for(law, h, seed, rate))
                except (engine.StageError, FloatingPointError, engine.InstabilityError) as e:
                    print(f"{p.name}: FAILED {type(e).__name__}: {e}", flush=True)
                    p.with_suffix(".failed").write_text(f"{type(e).__name__}: {e}\n")
                    continue
                store(p, res)
                s = res.scalars
                print(
                    f"{p.name}: {time.time() - t0:.0f} s, {s['particles']:.0f} grains, "
                    f"c = {s['cohesion']:.0f} Pa, phi = {s['friction_angle']:.1f} deg, "
                    f"ffc = {s['ffc']:.3g}",
                    flush=True,
                )


class _Until:
    """A stage criterion (engine.shear.driver's kind): shear strain ``strain`` reached."""

    def __init__(self, strain: float):
        self.strain = strain

    def __call__(self, rows) -> bool:
        return rows[-1][2] >= self.strain

    def fraction(self, rows) -> float:
        return rows[-1][2] / self.strain


def steady(laws) -> None:
    """Long pre-shears (to shear strain ``LONG_STRAIN``, no steady-state stop) of the
    10-diameter cell, seeds 1-3 per law: the curves that the pre-shear's defaults
    (``preshear_min_strain``, ``steady_window``, ``steady_tolerance``) are judged on, stored
    as ``<law>-long-s<seed>.npz``. Runs the shear driver's stages directly (the public
    run_shear stops at steady flow)."""
    from engine.shear.driver import _Shear

    for law in laws:
        for seed in LONG_SEEDS:
            p = STORE / f"{law}-long-s{seed}.npz"
            if p.exists():
                continue
            t0 = time.time()
            t = test_for(law, HEIGHTS[0], seed)
            sh = _Shear(t, None)
            sh.cell = cell = sh.glue(sh.consolidate())
            _, gap = cell.heights()
            c, _ = sh.stage(
                "preshear",
                t.preshear_stress,
                sh.shear_speed(gap, t.preshear_stress),
                _Until(LONG_STRAIN),
                (0.0, 1.0),
            )
            STORE.mkdir(parents=True, exist_ok=True)
            tmp = p.with_suffix(".tmp")
            with open(tmp, "wb") as f:
                np.savez_compressed(f, test=json.dumps(t.to_dict()), **c)
            tmp.replace(p)
            print(f"{p.name}: {time.time() - t0:.0f} s", flush=True)


def steady_report() -> str:
    """Mean shear stress, normal stress and bulk density of the long pre-shears per window
    of 0.1 shear strain, and how far each 0.2-strain window's mean lies from the previous
    one's (the steady-state check's quantity)."""
    lines = []
    for law in LAWS:
        for seed in LONG_SEEDS:
            p = STORE / f"{law}-long-s{seed}.npz"
            if not p.exists():
                continue
            c = np.load(p)
            g, tau = c["shear_strain"], c["shear_stress"]
            sig, rho = c["normal_stress"], c["bulk_density"]
            lines.append(f"\n{law}, seed {seed} (10 d cell):\n")
            lines.append(
                "| strain | tau [Pa] | sigma [Pa] | bulk density [kg/m^3] | 0.2-window change [-] |"
            )
            lines.append("|---|---|---|---|---|")
            for a in np.arange(0.0, LONG_STRAIN - 1e-9, 0.1):
                m = (g >= a) & (g < a + 0.1)
                last = (g > a - 0.1) & (g <= a + 0.1)
                prev = (g > a - 0.3) & (g <= a - 0.1)
                ch = (
                    f"{abs(tau[last].mean() - tau[prev].mean()) / tau[last].mean():.3f}"
                    if a >= 0.3
                    else "-"
                )
                lines.append(
                    f"| {a:.1f}-{a + 0.1:.1f} | {tau[m].mean():.0f} | {sig[m].mean():.0f} | "
                    f"{rho[m].mean():.1f} | {ch} |"
                )
            w = [(g >= a) & (g < a + 0.1) for a in np.arange(0.4, LONG_STRAIN - 1e-9, 0.1)]
            taus = np.array([tau[m].mean() for m in w])
            rhos = np.array([rho[m].mean() for m in w])
            lines.append(
                f"\nPast 0.4 strain, per 0.1 window: tau {taus.mean():.0f} +- "
                f"{taus.std(ddof=1):.0f} Pa (range {taus.min():.0f}-{taus.max():.0f}), "
                f"tau / sigma {taus.mean() / sig[g >= 0.4].mean():.3f}, bulk density "
                f"{rhos.mean():.1f} +- {rhos.std(ddof=1):.1f} kg/m^3."
            )
    return "\n".join(lines)


#: Shear strain of the long pre-shears [-].
LONG_STRAIN = 2.0


def report() -> str:
    lines = [
        "| law | H [d] | I | runs | "
        + " | ".join(f"{k} [{u}]" for k, u in REPORTED.items())
        + " | servo miss [-] | peaked |",
        "|---" * (6 + len(REPORTED)) + "|",
    ]
    for law in LAWS:
        for h, rate in VARIANTS:
            paths = [path_for(law, h, s, rate) for s in SEEDS]
            runs = [json.loads(p.read_text()) for p in paths if p.exists()]
            failed = [p for p in paths if p.with_suffix(".failed").exists()]
            if not runs and not failed:
                continue
            cells = []
            for k in REPORTED:
                v = np.array([r["scalars"][k] for r in runs], dtype=float)
                if v.size == 0:
                    cells.append("-")
                elif not np.all(np.isfinite(v)):
                    cells.append("inf" if np.all(np.isinf(v)) else "some inf")
                elif v.size > 1:
                    cells.append(f"{v.mean():.4g} +- {v.std(ddof=1):.2g}")
                else:
                    cells.append(f"{v.mean():.4g}")
            # the servo's largest miss of a point's target, and the points that peaked
            miss = [
                max(abs(q["sigma"] - q["target"]) / q["target"] for q in r["points"][1:])
                for r in runs
            ]
            peaked = sum(q["peaked"] for r in runs for q in r["points"][1:])
            total = sum(len(r["points"]) - 1 for r in runs)
            cells.append(f"{max(miss):.3f}" if miss else "-")
            cells.append(f"{peaked}/{total}")
            n = f"{len(runs)}" + (f" ({len(failed)} failed)" if failed else "")
            lines.append(f"| {law} | {h} | {rate:g} | {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


FIGURE = ROOT / "docs" / "figures" / "shear_cell.png"


def figure(height: int = HEIGHTS[1], seed: int = SEEDS[0]) -> Path:
    """docs/figures/shear_cell.png from the stored runs of one height and seed: per law the
    shear stress and the lid height against shear strain (the pre-shear, then each point's
    shear to failure from the stored state, drawn from the pre-shear's end), and the yield
    loci with their Mohr circles."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 7.5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    for row, law in enumerate(LAWS):
        p = path_for(law, height, seed)
        if not p.exists():
            continue
        data = json.loads(p.read_text())
        c = np.load(p.with_suffix(".npz"))
        ax_t, ax_h, ax_l = axes[row]
        g0 = c["preshear/shear_strain"]
        ax_t.plot(g0, c["preshear/shear_stress"], color="k", lw=0.8, label="pre-shear")
        ax_h.plot(g0, c["preshear/lid_height"] * 1e3, color="k", lw=0.8)
        end = g0[-1]
        for k, pt in enumerate(data["points"][1:]):
            g = end + c[f"point{k}_shear/shear_strain"]
            ax_t.plot(g, c[f"point{k}_shear/shear_stress"], lw=0.8, label=f"{pt['target']:g} Pa")
            ax_h.plot(g, c[f"point{k}_shear/lid_height"] * 1e3, lw=0.8)
        title = f"{law}, H = {height} d, seed {seed}"
        ax_t.set(xlabel="shear strain [-]", ylabel="shear stress [Pa]", title=title)
        ax_t.legend(fontsize=7)
        ax_h.set(xlabel="shear strain [-]", ylabel="lid height [mm]")
        loc = data["locus"]
        pts = data["points"]
        sig = np.array([q["sigma"] for q in pts[1:]])
        tau = np.array([q["tau"] for q in pts[1:]])
        ax_l.plot(sig, tau, "o", color="C0", label="failure points")
        ax_l.plot(pts[0]["sigma"], pts[0]["tau"], "s", color="k", label="pre-shear point")
        s1, s2, sc = loc["sigma_1"], loc["sigma_2"], loc["sigma_c"]
        x = np.linspace(0, s1, 100)
        ax_l.plot(x, loc["cohesion"] + loc["slope"] * x, color="C0", lw=0.8, label="locus")
        th = np.linspace(0, np.pi, 100)
        for a, b in ((s2, s1), (0.0, sc)):
            if b > a:
                ax_l.plot(
                    0.5 * (a + b) + 0.5 * (b - a) * np.cos(th), 0.5 * (b - a) * np.sin(th), "C1"
                )
        ax_l.set(
            xlabel="normal stress [Pa]",
            ylabel="shear stress [Pa]",
            title=f"ffc = {loc['ffc']:.3g}, phi = {loc['friction_angle']:.1f} deg",
        )
        ax_l.set_aspect("equal")
        ax_l.legend(fontsize=7)
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=90)
    return FIGURE


def convergence() -> str:
    """Per law, each height against the next taller one (and the 10 d cell at half the rate
    against the default rate): per quantity the difference of the seeds' means, relative to
    the compared cell's mean, its Welch t, and OUT where it lies beyond the standard
    deviation of the compared cell's seeds (the module docstring's criterion, stated before
    the runs; it flags a difference of pure noise about a third of the time), and SIG where
    Welch's test finds a difference at 95 % (two-sided, Welch-Satterthwaite degrees of
    freedom); a quantity with an infinite value in any run is left out."""
    from scipy.stats import t as student_t

    keys = [k for k in REPORTED if k not in ("height_diameters", "cohesion_se")]
    lines = [
        "| law | cell | against | " + " | ".join(keys) + " |",
        "|---" * (3 + len(keys)) + "|",
    ]
    pairs = [((h, RATES[0]), (h2, RATES[0])) for h, h2 in itertools.pairwise(HEIGHTS)]
    pairs += [((h, RATES[1]), (h, RATES[0])) for h in HEIGHTS[:2]]
    for law in LAWS:
        for a, b in pairs:
            va, vb = (
                [
                    json.loads(p.read_text())["scalars"]
                    for p in (path_for(law, x[0], s, x[1]) for s in SEEDS)
                    if p.exists()
                ]
                for x in (a, b)
            )
            if len(va) < 2 or len(vb) < 2:
                continue
            cells = []
            for k in keys:
                xa = np.array([r[k] for r in va], dtype=float)
                xb = np.array([r[k] for r in vb], dtype=float)
                if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(xb))):
                    cells.append("-")
                    continue
                diff = xa.mean() - xb.mean()
                sd = xb.std(ddof=1)
                # Welch's t of the difference and its two-sided 95 % critical value
                ea, eb = xa.var(ddof=1) / xa.size, xb.var(ddof=1) / xb.size
                se = math.sqrt(ea + eb)
                t = diff / se if se > 0 else math.inf
                df = (ea + eb) ** 2 / (ea**2 / (xa.size - 1) + eb**2 / (xb.size - 1) or 1e-300)
                sig = abs(t) > student_t.ppf(0.975, df)
                cells.append(
                    f"{diff:+.3g} ({diff / abs(xb.mean()):+.1%}, t {t:+.1f}"
                    f"{', SIG' if sig else ''}{', OUT' if abs(diff) > sd else ''})"
                )
            lines.append(
                f"| {law} | {a[0]} d, I {a[1]:g} | {b[0]} d, I {b[1]:g} | "
                + " | ".join(cells)
                + " |"
            )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true", help="print the table of stored runs")
    ap.add_argument("--law", choices=tuple(LAWS), action="append", help="only this law")
    ap.add_argument(
        "--steady", action="store_true", help="the long pre-shears (with --report: their table)"
    )
    ap.add_argument("--figure", action="store_true", help=f"draw {FIGURE.relative_to(ROOT)}")
    a = ap.parse_args()
    if a.figure:
        print(figure())
        return
    if a.report:
        print(steady_report() if a.steady else report() + "\n\n" + convergence())
        return
    if a.steady:
        steady(a.law or tuple(LAWS))
        print(steady_report())
        return
    run(a.law or tuple(LAWS))
    print(report())


if __name__ == "__main__":
    main()
