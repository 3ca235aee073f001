"""A calibration to a real powder's shear-tester data (issue 41 item 6), at the smallest
scale: the calcium carbonate of docs/POWDER_DATA.md
(examples/calibration/calcium_carbonate_ring_shear.json).

    python -m benchmarks.calibration_powder                   # runs not yet stored, then the report
    python -m benchmarks.calibration_powder --report          # the report of what is stored
    python -m benchmarks.calibration_powder --cell default    # docs/SHEAR.md's default cell

The targets are the transcribed laboratory's: three yield loci (sigma_pre = 2949, 6045,
8982 Pa), three points each, and each locus's tau_pre. Their sds are the doc's rules: the
source states none. The law is the engine's bilinear adhesive law (:data:`START`). f0 = 0
because the source's own analysis reports cohesion 0 at every level. The calibration
varies the sliding and the rolling friction in :data:`BOX`, with the other fields kept at
:data:`START`'s. It uses :data:`RUNS` design runs, one wave of :data:`WAVE_RUNS` and the
check run, in tests/engine/test_shear.py's shear cell: 6 x 3 x 6 diameters of 5 mm spheres
(about 120 grains, the base test's radius 2.5 mm), inertial number 2e-3. Every run is
stored in ``benchmarks/results/calibration_powder/runs/`` as it ends, and a rerun goes on
from there. The result (``result.json``) and the report's numbers (``report.json``) are
stored beside the runs. ``--cell default`` runs the same calibration in docs/SHEAR.md's
default cell instead (10 x 5 x 15 diameters, the shear test's default inertial number
1e-3), stored in ``benchmarks/results/calibration_powder/default_cell/``: about 2 minutes
a parameter set on this shared 2-core machine, half an hour in all (not run yet:
docs/POWDER_DATA.md).

What it can show: whether spheres with sliding and rolling friction in this small cell can
meet this powder's loci, and at which frictions. The grains are 5 mm spheres, not the
powder's particles: the source names the powder only "CaCO3- 40-200" and gives no size or
particle density. The cell is far smaller than a converged one (docs/SHEAR.md). So the
calibrated values are those of this model and cell, not of the powder's particles, and no
claim rests on them beyond that.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import engine
from benchmarks.calibration_shear import shear_cell as tiny_cell
from engine.calibration import LabTargets, calibrate

ROOT = Path(__file__).resolve().parent.parent
LAB = ROOT / "examples" / "calibration" / "calcium_carbonate_ring_shear.json"
#: cell name -> where its runs, result and report are stored
STORES = {
    "tiny": ROOT / "benchmarks" / "results" / "calibration_powder",
    "default": ROOT / "benchmarks" / "results" / "calibration_powder" / "default_cell",
}
#: the law the calibration starts from; f0 = 0: the source reports cohesion 0 Pa at all
#: three levels (its linearised loci cut the tau axis below zero)
START = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.5, mu_r=0.05, restitution=0.4)
#: wide boxes, set before any run (not tuned after): sliding friction 0.1 to 1, rolling
#: friction 0 to 0.3 (the rolling torque mu_r |f| R of docs/PHYSICS.md)
BOX = {"mu_s": (0.1, 1.0), "mu_r": (0.0, 0.3)}
RUNS, WAVES, WAVE_RUNS = 10, 1, 5


def shear_cell(name: str = "tiny", seed: int = 1) -> engine.ShearTest | None:
    """``tiny``: the cell of benchmarks/calibration_shear.py (tests/engine/test_shear.py's,
    about 120 grains, stages bounded at the shear test's default 5 s) with this powder's
    starting law. ``default``: None, the calibration's default cell (docs/SHEAR.md: 10 x 5 x
    15 diameters)."""
    if name == "default":
        return None
    return replace(tiny_cell(seed), pair_law=START)


def base_test() -> engine.UniaxialTest:
    """The law and material the calibration is given (its uniaxial test is not run: the
    targets are a shear tester's alone). Density 2000 kg/m^3 is the base test's default,
    not the powder's: the targets are stresses, and the bulk density is left out."""
    return engine.UniaxialTest(pair_law=START)


def targets() -> LabTargets:
    return LabTargets.from_dict(json.loads(LAB.read_text()))


def run(cell: str) -> dict:
    store = STORES[cell]
    cal = calibrate(
        base_test(),
        targets(),
        BOX,
        runs=RUNS,
        waves=WAVES,
        wave_runs=WAVE_RUNS,
        store=store / "runs",
        seed=0,
        shear_test=shear_cell(cell),
        on_run=lambda i, q: print(f"run {i} done", flush=True),
    )
    summary = cal.to_summary()
    store.mkdir(parents=True, exist_ok=True)
    (store / "result.json").write_text(json.dumps(summary, indent=1))
    return summary


def report(summary: dict, cell: str) -> dict:
    """Each parameter's interval (and whether it sits on a box edge), each target against
    the laboratory's with its z, the failed runs."""
    out = {"parameters": {}, "targets": [], "failed_runs": []}
    for name, p in summary["parameters"].items():
        lo, hi = p["interval"]
        b_lo, b_hi = BOX[name]
        out["parameters"][name] = {
            "median": p["median"],
            "interval": [lo, hi],
            "box": [b_lo, b_hi],
            "status": p["status"],
        }
    for q in summary["targets_met"]:
        out["targets"].append(
            {k: q[k] for k in ("name", "lab", "sd", "value", "z", "met", "unit") if k in q}
        )
    out["failed_runs"] = [r["error"] for r in summary["runs"] if "error" in r]
    out["all_targets_met"] = summary["all_targets_met"]
    out["yield_loci"] = summary["curves"].get("yield_loci", [])
    (STORES[cell] / "report.json").write_text(json.dumps(out, indent=1))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true", help="report what is stored; run nothing")
    ap.add_argument("--cell", choices=sorted(STORES), default="tiny", help="the shear cell")
    args = ap.parse_args()
    stored = STORES[args.cell] / "result.json"
    summary = json.loads(stored.read_text()) if args.report else run(args.cell)
    rep = report(summary, args.cell)
    for name, p in rep["parameters"].items():
        lo, hi = p["interval"]
        print(f"{name}: {p['median']:.4g} [{lo:.4g}, {hi:.4g}] (box {p['box']}), {p['status']}")
    for q in rep["targets"]:
        z = "-" if q["z"] is None else f"{q['z']:+.2f}"
        print(f"  {q['name']}: {q['value']:.4g} against {q['lab']:.4g} +- {q['sd']:.2g}, z {z}")
    print(f"all targets met: {rep['all_targets_met']}; failed runs: {len(rep['failed_runs'])}")


if __name__ == "__main__":
    main()
