"""A calibration to shear-tester data on the real shear test, end to end, at the smallest
scale (issue 41 item 2: the shear targets' route through ``engine.calibrate``).

    python -m benchmarks.calibration_shear             # runs not yet stored, then the report
    python -m benchmarks.calibration_shear --report    # the report of what is stored

A twin experiment, as the uniaxial benchmark (benchmarks/calibration.py): the "laboratory"
is the engine with a law the calibration is not told (:data:`TRUTH`: mu_s = 0.5, f0 = -0.2
N), run in the shear cell of tests/engine/test_shear.py (6 x 3 x 6 diameters, about 120
grains, inertial number 2e-3; stages bounded at 5 s) at three packing seeds; each target
is the seeds' mean and its sd (the repeatability a tester would report) at two yield loci,
sigma_pre = 10 and 20 kPa, three points each, with tau_pre and the bulk density. The
calibration is given the boxes :data:`BOX` for mu_s and f0, 8 design runs and one wave of
4 (and the check run), every run stored in ``benchmarks/results/calibration_shear_tiny/``
as it ends; a rerun goes on from there. Its result (``result.json``) and the report's
numbers (``report.json``) are stored beside the runs.

What it can show: that a calibration to shear data runs through the real shear test and
what it recovers in a cell this small. It is not a check of the shear test's physics
(docs/SHEAR.md) and not a calibration to real data (issue 41 item 6: not done).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import engine
from engine.calibration import LabTargets, calibrate
from engine.calibration.forward import (
    check_shear_cell,
    measure_shear,
    run_shear_tests,
    shear_tests,
)

ROOT = Path(__file__).resolve().parent.parent


def stored(name: str) -> tuple[Path, Path, Path]:
    """A shear calibration's folder ``benchmarks/results/<name>`` and its result and report
    files in it."""
    store = ROOT / "benchmarks" / "results" / name
    return store, store / "result.json", store / "report.json"


STORE, RESULT, REPORT = stored("calibration_shear_tiny")
TRUTH = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.2, mu_s=0.5, mu_r=0.001, restitution=0.4)
#: the law the calibration starts from (its other fields are the truth's: not calibrated)
START = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.1, mu_s=0.3, mu_r=0.001, restitution=0.4)
BOX = {"mu_s": (0.2, 0.8), "f0": (-0.4, -0.05)}
#: pre-shear stress [Pa] -> normal stresses of its points [Pa]
#: (at 5 kPa the truth's pre-shear did not reach steady flow in this cell: its shear stress
#: still changed by 18 % between the last two windows at 1.5 strain, seed 101)
LOCI = {1e4: (3e3, 5e3, 7e3), 2e4: (6e3, 1e4, 1.4e4)}
LAB_SEEDS = (101, 102, 103)
RUNS, WAVES, WAVE_RUNS = 8, 1, 4


def shear_cell(seed: int = 1) -> engine.ShearTest:
    """tests/engine/test_shear.py's cell (about 120 grains, seconds a locus) with the
    shear test's default bound on a stage's time, 5 s (the tests' 2 s stopped a cohesive
    pre-shear at 5 kPa at strain 1.27, before its steady-state check had passed)."""
    return engine.ShearTest(
        cell=(0.03, 0.015, 0.03),
        inertial_number=2e-3,
        pair_law=START,
        seed=seed,
    )


def base_test() -> engine.UniaxialTest:
    """The law and material the calibration is given (its uniaxial test is not run: the
    targets are a shear tester's alone)."""
    return engine.UniaxialTest(pair_law=START)


def _draft(loci: dict | None = None) -> LabTargets:
    """The loci's shape (stresses; :data:`LOCI` by default) with placeholder values: what
    runs are read by (:func:`engine.calibration.forward.measure_shear`)."""
    pt = lambda s: {"sigma_n": s, "sigma_n_sd": 0.0, "tau": s, "tau_sd": 0.0}  # noqa: E731
    loci = [
        {
            "sigma_pre": s,
            "points": [pt(x) for x in sn],
            "tau_pre": s,
            "tau_pre_sd": 0.0,
            "bulk_density": 1000.0,
            "bulk_density_sd": 0.0,
        }
        for s, sn in (LOCI if loci is None else loci).items()
    ]
    return LabTargets.from_dict({"tester": "ring_shear", "shear": loci})


def _locus_targets(s: float, sn: tuple, values: np.ndarray) -> dict:
    """A locus's targets from runs' values (a row per run, measure_shear's columns: its
    points' tau, tau_pre, bulk density): their mean and sd (ddof 1)."""
    mean, sd = values.mean(axis=0), values.std(axis=0, ddof=1)
    k = len(sn)
    return {
        "sigma_pre": s,
        "points": [
            {"sigma_n": x, "sigma_n_sd": 0.0, "tau": float(mean[i]), "tau_sd": float(sd[i])}
            for i, x in enumerate(sn)
        ],
        "tau_pre": float(mean[k]),
        "tau_pre_sd": float(sd[k]),
        "bulk_density": float(mean[k + 1]),
        "bulk_density_sd": float(sd[k + 1]),
    }


def lab() -> LabTargets:
    """The truth's loci at :data:`LAB_SEEDS`, each stored as it is made, as targets: the
    seeds' mean and sd of each quantity."""
    draft = _draft()
    values = []
    for seed in LAB_SEEDS:
        path = STORE / f"lab-s{seed}.json"
        if path.exists():
            shear = {float(k): v for k, v in json.loads(path.read_text()).items()}
        else:
            tests = shear_tests(check_shear_cell(base_test(), shear_cell(seed)), draft, TRUTH)
            shear = run_shear_tests(tests)
            STORE.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps({str(k): v for k, v in shear.items()}))
        values.append([q["value"] for q in measure_shear(shear, draft)])
    v = np.array(values)
    loci, start = [], 0
    for s, sn in LOCI.items():  # measure_shear's columns, locus by locus
        width = len(sn) + 2
        loci.append(_locus_targets(s, sn, v[:, start : start + width]))
        start += width
    material = (
        f"synthetic: engine.run_shear of mu_s = {TRUTH.mu_s}, f0 = {TRUTH.f0} N in a 6 x 3 x 6 "
        f"diameter cell, mean and sd of seeds {list(LAB_SEEDS)}"
    )
    return LabTargets.from_dict({"tester": "ring_shear", "material": material, "shear": loci})


def run() -> dict:
    targets = lab()
    (STORE / "lab.json").write_text(json.dumps(targets.to_dict(), indent=1))
    return calibrate_twin(
        base_test(),
        targets,
        BOX,
        (RUNS, WAVES, WAVE_RUNS),
        STORE,
        shear_cell(),
        on_run=lambda i, q: print(f"run {i} done", flush=True),
    )


def calibrate_twin(test, targets, box, sizes, store: Path, shear_test, on_run, **kw) -> dict:
    """Calibrate ``test``'s pair law within ``box`` to ``targets`` measured on a twin (the
    same model made the data: no discrepancy to widen by), design seed 0, with ``sizes`` =
    (design runs, waves, runs per wave) and ``shear_test`` the shear cell; its runs go to
    ``store/runs``, its summary (returned) to ``store/result.json``; ``kw``: more of
    :func:`engine.calibration.calibrate`'s arguments."""
    runs, waves, wave_runs = sizes
    cal = calibrate(
        test,
        targets,
        box,
        runs=runs,
        waves=waves,
        wave_runs=wave_runs,
        store=store / "runs",
        seed=0,
        shear_test=shear_test,
        discrepancy=False,
        on_run=on_run,
        **kw,
    )
    summary = cal.to_summary()
    (store / "result.json").write_text(json.dumps(summary, indent=1))
    return summary


def summary_report(summary: dict, parameter) -> dict:
    """The report of a calibration's summary: each parameter as ``parameter(name, p)``
    describes it (``p`` its entry in the summary: median, 90 % interval, status), each
    target against the laboratory's with its z, the failed runs' errors, whether every
    target was met, the check run's yield loci."""
    return {
        "parameters": {name: parameter(name, p) for name, p in summary["parameters"].items()},
        "targets": [
            {k: q[k] for k in ("name", "lab", "sd", "value", "z", "met", "unit") if k in q}
            for q in summary["targets_met"]
        ],
        "failed_runs": [r["error"] for r in summary["runs"] if "error" in r],
        "all_targets_met": summary["all_targets_met"],
        "yield_loci": summary["curves"].get("yield_loci", []),
    }


def report(summary: dict) -> dict:
    """Each parameter against the truth (inside its 90 % interval?), each target met."""

    def parameter(name: str, p: dict) -> dict:
        truth = getattr(TRUTH, name)
        lo, hi = p["interval"]
        return {
            "truth": truth,
            "median": p["median"],
            "interval": [lo, hi],
            "truth_inside": lo <= truth <= hi,
            "status": p["status"],
        }

    out = summary_report(summary, parameter)
    REPORT.write_text(json.dumps(out, indent=1))
    return out


def truth_aside(p: dict) -> str:
    """A parameter's truth and whether its interval holds it, for :func:`print_report`."""
    return f"truth {p['truth']:g}, {'inside' if p['truth_inside'] else 'OUTSIDE'}"


def print_report(rep: dict, aside) -> None:
    """Print a report: each parameter's median and interval (with ``aside(p)`` of its
    entry ``p``) and status, each target against the laboratory's with its z, whether
    every target was met and how many runs failed."""
    for name, p in rep["parameters"].items():
        lo, hi = p["interval"]
        print(f"{name}: {p['median']:.4g} [{lo:.4g}, {hi:.4g}] ({aside(p)}), {p['status']}")
    for q in rep["targets"]:
        z = "-" if q["z"] is None else f"{q['z']:+.2f}"
        print(f"  {q['name']}: {q['value']:.4g} against {q['lab']:.4g} +- {q['sd']:.2g}, z {z}")
    print(f"all targets met: {rep['all_targets_met']}; failed runs: {len(rep['failed_runs'])}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true", help="report what is stored; run nothing")
    args = ap.parse_args()
    if args.report:
        summary = json.loads(RESULT.read_text())
    else:
        summary = run()
    rep = report(summary)
    print_report(rep, truth_aside)


if __name__ == "__main__":
    main()
