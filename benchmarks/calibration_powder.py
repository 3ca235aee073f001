"""Calibrations to real materials' shear-tester data (issue 41 item 6), at the smallest
scale: the materials of docs/POWDER_DATA.md, one :class:`Material` each.

    python -m benchmarks.calibration_powder                   # runs not yet stored, then the report
    python -m benchmarks.calibration_powder --report          # the report of what is stored
    python -m benchmarks.calibration_powder --cell default    # docs/SHEAR.md's default cell
    python -m benchmarks.calibration_powder --material wet_glass_beads         # the cohesive one
    python -m benchmarks.calibration_powder --material wet_glass_beads --cost  # one set, timed
    python -m benchmarks.calibration_powder --material wet_glass_beads --report --figure

``calcium_carbonate`` (the default, unchanged since its run): the calcium carbonate of
examples/calibration/calcium_carbonate_ring_shear.json: three yield loci (sigma_pre = 2949,
6045, 8982 Pa), three points each, and each locus's tau_pre. The source's own analysis
reports cohesion 0 at every level, so f0 = 0 and the calibration varies the sliding and
the rolling friction alone, with 10 design runs, one wave of 5 and the check run, every
run packing the cell with one seed.

``wet_glass_beads``: the 0.5 mm glass beads wetted with 0.5 % water of
examples/calibration/wet_glass_beads_ring_shear.json: five yield loci (sigma_pre = 1949 to
9953 Pa), five points each, and each locus's tau_pre; cohesive by the source's own
analysis at four of the five levels. The law is the bilinear adhesive law with
consolidation-dependent adhesion: the calibration varies mu_s, mu_r, the pull-off force f0
and the adhesive branch's slope kadh in boxes set before any run (:data:`WET_BOX`, the
reasons beside it), with 16 design runs, two waves of 6 and the check run, each run
packing its own sample (``calibrate(..., vary_seed=True)``: the kadh twin of
docs/CALIBRATION.md showed that one packing's offset can place a parameter).

Both run in tests/engine/test_shear.py's shear cell: 6 x 3 x 6 diameters of 5 mm spheres
(about 120 grains, the base test's radius 2.5 mm), inertial number 2e-3. Every run is
stored under ``benchmarks/results/calibration_powder/`` (the material's folder:
:attr:`Material.stores`) as it ends, and a rerun goes on from there. The result
(``result.json``) and the report's numbers (``report.json``) are stored beside the runs.
``--cell default`` runs the same calibration in docs/SHEAR.md's default cell instead (10 x
5 x 15 diameters, the shear test's default inertial number 1e-3), in the material's
``default_cell/`` folder. ``--cost`` runs one parameter set (the middle of each box) on
every locus, timed, and stores its time and targets in ``cost.json`` (measured before a
calibration is started). ``--figure`` writes the engine's calibration figure (the lab's
yield loci and tau_pre beside the check run's) and a flow-function figure (the lab's
sigma_c against sigma_1, from the transcribed points by the engine's own locus
construction and as the source prints them, beside the check run's) to docs/figures/.

What it can show: whether spheres in this small cell, with sliding and rolling friction
(and, for the wet beads, adhesion that grows with the preload), can meet a real
material's loci, and at which parameters. The grains are 5 mm spheres, not the material's
particles (the calcium carbonate's size is not given; the beads are 0.5 mm). The cell is
far smaller than a converged one (docs/SHEAR.md). So the calibrated values are those of
this model and cell, not of the material's particles, and no claim rests on them beyond
that.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import engine
from benchmarks.calibration_shear import print_report, summary_report
from benchmarks.calibration_shear import shear_cell as tiny_cell
from engine.calibration import LabTargets, calibrate
from engine.calibration.forward import check_shear_cell, measure_shear, run_shear_tests, shear_tests

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "calibration_powder"
FIGURES = ROOT / "docs" / "figures"

# --- the calcium carbonate (its names kept as they were when its result was stored) ---
LAB = ROOT / "examples" / "calibration" / "calcium_carbonate_ring_shear.json"
#: cell name -> where its runs, result and report are stored
STORES = {"tiny": RESULTS, "default": RESULTS / "default_cell"}
#: the law the calibration starts from; f0 = 0: the source reports cohesion 0 Pa at all
#: three levels (its linearised loci cut the tau axis below zero)
START = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.5, mu_r=0.05, restitution=0.4)
#: wide boxes, set before any run (not tuned after): sliding friction 0.1 to 1, rolling
#: friction 0 to 0.3 (the rolling torque mu_r |f| R of docs/PHYSICS.md)
BOX = {"mu_s": (0.1, 1.0), "mu_r": (0.0, 0.3)}
RUNS, WAVES, WAVE_RUNS = 10, 1, 5

# --- the wet glass beads: set before any run of this material, not tuned after ---
WET_LAB = ROOT / "examples" / "calibration" / "wet_glass_beads_ring_shear.json"
#: the calcium carbonate's law (stiffnesses, restitution) with a small pull-off to start from
WET_START = replace(START, f0=-0.01, kadh=0.0)
#: mu_s and mu_r: the calcium carbonate's boxes. f0 in [-0.1, 0] N: a pull-off F between
#: grains of diameter d gives a cohesion of order F / d^2, and 0.1 N on d = 5 mm is 4 kPa,
#: above the largest cohesion the source reports (2636 Pa), so the box spans from none to
#: more than the data show. kadh in [0, 1e4] N/m: the kadh twin's box (docs/CALIBRATION.md;
#: 0.4 K2, kappa up to 1.14 N of pull-off per N of preload with K1 = 5e3, K2 = 2.5e4 N/m),
#: within calibrate's bound of 10 K2.
WET_BOX = {"mu_s": (0.1, 1.0), "mu_r": (0.0, 0.3), "f0": (-0.1, 0.0), "kadh": (0.0, 1e4)}


@dataclass(frozen=True)
class Material:
    """A material's calibration: its lab file, starting law, boxes (in the law's units),
    run counts, whether each run packs its own sample, and where each cell's runs and
    result are stored."""

    lab: Path
    start: engine.BilinearAdhesive
    box: dict
    runs: int
    waves: int
    wave_runs: int
    vary_seed: bool
    stores: dict


MATERIALS = {
    "calcium_carbonate": Material(LAB, START, BOX, RUNS, WAVES, WAVE_RUNS, False, STORES),
    "wet_glass_beads": Material(
        WET_LAB,
        WET_START,
        WET_BOX,
        16,
        2,
        6,
        True,
        {
            "tiny": RESULTS / "wet_glass_beads",
            "default": RESULTS / "wet_glass_beads" / "default_cell",
        },
    ),
}


def shear_cell(name: str = "tiny", seed: int = 1, law=START) -> engine.ShearTest | None:
    """``tiny``: the cell of benchmarks/calibration_shear.py (tests/engine/test_shear.py's,
    about 120 grains, stages bounded at the shear test's default 5 s) with ``law``.
    ``default``: None, the calibration's default cell (docs/SHEAR.md: 10 x 5 x 15
    diameters)."""
    if name == "default":
        return None
    return replace(tiny_cell(seed), pair_law=law)


def base_test(law=START) -> engine.UniaxialTest:
    """The law and material the calibration is given (its uniaxial test is not run: the
    targets are a shear tester's alone). Density 2000 kg/m^3 is the base test's default,
    not the material's: the targets are stresses, and the bulk density is left out."""
    return engine.UniaxialTest(pair_law=law)


def targets(material: str = "calcium_carbonate") -> LabTargets:
    return LabTargets.from_dict(json.loads(MATERIALS[material].lab.read_text()))


def run(cell: str, material: str = "calcium_carbonate") -> dict:
    m = MATERIALS[material]
    store = m.stores[cell]
    cal = calibrate(
        base_test(m.start),
        targets(material),
        m.box,
        runs=m.runs,
        waves=m.waves,
        wave_runs=m.wave_runs,
        store=store / "runs",
        seed=0,
        shear_test=shear_cell(cell, law=m.start),
        vary_seed=m.vary_seed,
        on_run=lambda i, q: print(f"run {i} done", flush=True),
    )
    summary = cal.to_summary()
    store.mkdir(parents=True, exist_ok=True)
    (store / "result.json").write_text(json.dumps(summary, indent=1))
    return summary


def cost(cell: str, material: str) -> dict:
    """One parameter set (the middle of each box) on every locus of the material, timed
    (wall time, on whatever load the machine has); stored in the material's ``cost.json``."""
    m = MATERIALS[material]
    params = {k: 0.5 * (lo + hi) for k, (lo, hi) in m.box.items()}
    law = replace(m.start, **params)
    lab = targets(material)
    t0 = time.perf_counter()
    tests = shear_tests(check_shear_cell(base_test(m.start), shear_cell(cell, law=law)), lab, law)
    out = run_shear_tests(tests)
    wall = time.perf_counter() - t0
    runs = 1 + m.runs + m.waves * m.wave_runs
    rec = {
        "parameters": params,
        "wall_s": wall,
        "loci": len(lab.shear),
        "points": sum(len(lo.points) for lo in lab.shear),
        "calibration_runs": runs,
        "estimated_calibration_wall_s": wall * runs,
        "targets": measure_shear(out, lab),
    }
    store = m.stores[cell]
    store.mkdir(parents=True, exist_ok=True)
    (store / "cost.json").write_text(json.dumps(rec, indent=1))
    return rec


def report(summary: dict, cell: str, material: str = "calcium_carbonate") -> dict:
    """Each parameter's interval (and whether it sits on a box edge), each target against
    the laboratory's with its z, the failed runs."""
    box = MATERIALS[material].box
    out = summary_report(
        summary,
        lambda name, p: {
            "median": p["median"],
            "interval": list(p["interval"]),
            "box": list(box[name]),
            "status": p["status"],
        },
    )
    if material != "calcium_carbonate":  # the calcium carbonate's stored report stays as it was
        out["lab_yield_loci"] = lab_loci(material)
        out["sensitivity"] = summary.get("sensitivity")
    (MATERIALS[material].stores[cell] / "report.json").write_text(json.dumps(out, indent=1))
    return out


def lab_loci(material: str) -> list[dict]:
    """Each of the lab's loci by the engine's own construction (engine.shear.locus: the
    least-squares line through the transcribed points and the Mohr circles through the
    pre-shear point): sigma_pre, cohesion, slope, sigma_1, sigma_c, ffc [Pa, -]."""
    from engine.shear.locus import yield_locus

    out = []
    for lo in targets(material).shear:
        y = yield_locus(
            [p.sigma_n for p in lo.points], [p.tau for p in lo.points], lo.sigma_pre, lo.tau_pre
        )
        out.append(
            {
                "sigma_pre": lo.sigma_pre,
                "cohesion": y.cohesion,
                "slope": y.slope,
                "sigma_1": y.sigma_1,
                "sigma_c": y.sigma_c,
                "ffc": y.ffc if math.isfinite(y.ffc) else None,
            }
        )
    return out


#: the source's own (sigma_1, sigma_c) per level [Pa], as printed (docs/POWDER_DATA.md)
PRINTED_FLOW_FUNCTION = {
    "wet_glass_beads": [(2297, 1000), (4965, 0), (7411, 1509), (11560, 4906), (13390, 6401)],
}


def figures(summary: dict, material: str) -> list[Path]:
    """The engine's calibration figure (yield loci, tau_pre) and a flow-function figure:
    sigma_c against sigma_1 [kPa], the lab's (the engine's construction on the transcribed
    points, and the source's printed values) beside the check run's."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from engine.io.figures import calibration_figure

    FIGURES.mkdir(parents=True, exist_ok=True)
    paths = [FIGURES / f"calibration_{material}.png", FIGURES / f"calibration_{material}_ffc.png"]
    fig = calibration_figure(summary)
    fig.savefig(paths[0])
    fig = Figure(figsize=(5.5, 4.6), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()

    def flow_function(loci: list[dict], style: str, color: str, label: str) -> None:
        # sigma_c against sigma_1 of yield loci (summary rows, in Pa), in kPa
        ax.plot(
            [c["sigma_1"] * 1e-3 for c in loci],
            [c["sigma_c"] * 1e-3 for c in loci],
            style,
            color=color,
            label=label,
        )

    lab = lab_loci(material)
    flow_function(lab, "o-", "black", "laboratory: engine's construction on its points")
    printed = PRINTED_FLOW_FUNCTION.get(material, [])
    if printed:
        ax.scatter(
            [a * 1e-3 for a, _ in printed],
            [b * 1e-3 for _, b in printed],
            marker="x",
            color="0.4",
            zorder=3,
            label="laboratory: the source's printed values",
        )
    model = summary["curves"].get("yield_loci") or []
    flow_function(model, "s-", "C3", "calibrated law (check run)")
    top = max([c["sigma_1"] for c in lab + model] + [1.0]) * 1e-3
    for ffc in (1, 2, 4, 10):
        ax.plot([0, top], [0, top / ffc], ":", color="0.7", lw=0.8)
        ax.annotate(f"ffc {ffc}", (top, top / ffc), fontsize=7, color="0.5", ha="right")
    ax.set_xlabel("major consolidation stress sigma_1 [kPa]")
    ax.set_ylabel("unconfined yield strength sigma_c [kPa]")
    ax.set_title(f"flow function ({material.replace('_', ' ')})", fontsize=9)
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.savefig(paths[1])
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true", help="report what is stored; run nothing")
    ap.add_argument("--cell", choices=sorted(STORES), default="tiny", help="the shear cell")
    ap.add_argument(
        "--material", choices=sorted(MATERIALS), default="calcium_carbonate", help="the data set"
    )
    ap.add_argument("--cost", action="store_true", help="time one parameter set; store cost.json")
    ap.add_argument("--figure", action="store_true", help="write the figures to docs/figures/")
    args = ap.parse_args()
    if args.cost:
        rec = cost(args.cell, args.material)
        print(f"one parameter set: {rec['wall_s']:.1f} s wall ({rec['loci']} loci, ", end="")
        print(f"{rec['points']} points); {rec['calibration_runs']} runs: about ", end="")
        print(f"{rec['estimated_calibration_wall_s'] / 60:.0f} min")
        for q in rec["targets"]:
            print(f"  {q['name']}: {q['value']:.4g} against {q['lab']:.4g}")
        return
    store = MATERIALS[args.material].stores[args.cell]
    summary = (
        json.loads((store / "result.json").read_text())
        if args.report
        else run(args.cell, args.material)
    )
    rep = report(summary, args.cell, args.material)
    print_report(rep, lambda p: f"box {p['box']}")
    if args.figure:
        for p in figures(summary, args.material):
            print(f"figure: {p.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
