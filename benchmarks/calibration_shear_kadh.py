"""Twin recovery on the shear test with consolidation-dependent adhesion (issue 41's
done-when: "a ring-shear flow function at three sigma_pre made by an untold law (kadh > 0)
is recovered, the truth inside each 90 % interval, targets met; and the calibrated law
predicts a fourth yield locus it was not fitted to within its uncertainty").

    python -m benchmarks.calibration_shear_kadh             # runs not yet stored, then the report
    python -m benchmarks.calibration_shear_kadh --report    # the report of what is stored

The "laboratory" is the engine with a law the calibration is not told (:data:`TRUTH`: the
tiny twin's law, benchmarks/calibration_shear.py, with an adhesive branch kadh = 2.5e3 N/m
= K1 / 2, a contact consolidation coefficient kappa = kadh (K2 - K1) / (K1 (K2 + kadh)) =
0.36), run in the tiny twin's shear cell (6 x 3 x 6 diameters, about 124 grains, inertial
number 2e-3, stages bounded at 5 s) at five packing seeds (:data:`LAB_SEEDS`); each target
is the seeds' mean and its sd (a tester's repeatability). Three yield loci are fitted
(:data:`FITTED`: sigma_pre = 10, 20 and 40 kPa, three points each at 0.3, 0.5 and 0.7
sigma_pre, with tau_pre and the bulk density); the calibration is told the truth's K1, K2,
mu_r and restitution and searches mu_s, f0 and kadh in :data:`BOX`, 15 design runs, two
waves of 6 and the check run, each run stored in
``benchmarks/results/calibration_shear_kadh/runs/`` as it ends.

**The fourth locus** (:data:`HELD_OUT`, sigma_pre = 30 kPa, between the fitted 20 and 40
kPa) is never shown to the calibration. Its prediction: :data:`PREDICT_SAMPLES` laws drawn
evenly from the calibration's posterior samples, each run at that locus with its own
packing seed (:data:`PREDICT_SEEDS`), so that the spread of their values holds the
parameters' uncertainty and one test's seed scatter; the median law's run (the
calibration's cell seed) is reported beside it. **Criterion, stated before the run:** the
fourth locus is predicted within its uncertainty when every one of its quantities (tau at
its three sigma_n, tau_pre, bulk density) has |z| <= 2, z = (mean of the predictions - lab
mean) / sqrt(sd of the predictions^2 + lab sd^2), the lab sd being the five seeds' sd as for
every fitted target. :data:`EXTRA` (sigma_pre = 50 kPa, 1.25 times the highest fitted) is an
extrapolation predicted and judged the same way, reported beside it and not part of the
done-when.

Cost (measured on the truth's runs, ``particle_steps`` of each result): about 7e6
particle-steps and 2-3 s per locus on one free core; 5 seeds x 5 loci + 28 parameter sets x
3 loci + 2 x 10 predictions + 2 median runs, about 130 locus runs, about 1e9 particle-steps.
Every result is stored as it ends (lab per seed, the calibration's runs, each prediction),
and a rerun goes on from there.

``--vary-seed`` (added after the first run's diagnosis, ``--diagnose``: every calibration
run had packed with one seed, whose sample is looser than the laboratory seeds' mean) runs
the same twin, targets and criterion with ``calibrate(..., vary_seed=True)``, each run
packing its own sample, into ``vary_seed/``; the first run's result stands beside it.

What it can show: that kadh (with f0 and mu_s) is recovered from a ring-shear flow function
on the real shear test in a cell this small, and whether the recovered law carries to a
locus it was not fitted to. It is one twin (the targets come from the same code, cell and
estimator, no model discrepancy), not a calibration to real data.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

import engine
from benchmarks.calibration_shear import (
    _draft,
    _locus_targets,
    calibrate_twin,
    print_report,
    stored,
    truth_aside,
)
from benchmarks.calibration_shear import shear_cell as _tiny_cell
from engine.calibration import LabTargets
from engine.calibration.forward import (
    check_shear_cell,
    measure_shear,
    run_shear_tests,
    shear_tests,
)
from engine.shear.locus import yield_locus

STORE, RESULT, REPORT = stored("calibration_shear_kadh")
#: where the calibration's runs, result, report and predictions go (``--vary-seed``: the
#: ``vary_seed`` folder; the laboratory's runs are shared)
OUT = STORE
VARY_SEED = False
TRUTH = engine.BilinearAdhesive(
    k1=5e3, k2=2.5e4, f0=-0.2, kadh=2.5e3, mu_s=0.5, mu_r=0.001, restitution=0.4
)
#: the law the calibration starts from (K1, K2, mu_r, restitution are the truth's: not
#: calibrated; kadh 0 as every calibration so far)
START = replace(TRUTH, kadh=0.0, f0=-0.1, mu_s=0.3)
#: kadh up to 0.4 K2 = 2 K1 (kappa up to 0.57), well inside the 10 K2 bound
BOX = {"mu_s": (0.2, 0.8), "f0": (-0.4, -0.05), "kadh": (0.0, 1e4)}
#: fitted loci: pre-shear stress [Pa] -> normal stresses of its points [Pa]
FITTED = {1e4: (3e3, 5e3, 7e3), 2e4: (6e3, 1e4, 1.4e4), 4e4: (1.2e4, 2e4, 2.8e4)}
#: the fourth locus, not fitted: predicted (the done-when's)
HELD_OUT = {3e4: (9e3, 1.5e4, 2.1e4)}
#: an extrapolation, not fitted: predicted and reported (at 60 kPa a truth's run at one
#: seed of two stopped on a 0.5 R overlap: K1 = 5e3 N/m is soft for it)
EXTRA = {5e4: (1.5e4, 2.5e4, 3.5e4)}
LAB_SEEDS = (101, 102, 103, 104, 105)
RUNS, WAVES, WAVE_RUNS = 15, 2, 6
PREDICT_SAMPLES = 10
PREDICT_SEEDS = tuple(201 + i for i in range(PREDICT_SAMPLES))
#: |z| at most this for a predicted quantity to be within its uncertainty (stated before)
Z_MAX = 2.0


def base_test() -> engine.UniaxialTest:
    """The law and material the calibration is given (its uniaxial test is not run)."""
    return engine.UniaxialTest(pair_law=START)


def cell(seed: int = 1) -> engine.ShearTest:
    """The tiny twin's cell (benchmarks/calibration_shear.py) at packing ``seed``."""
    return replace(_tiny_cell(seed), pair_law=START)


def _run_loci(path: Path, loci: dict, law, seed: int) -> dict | str:
    """The shear results of ``law`` at ``loci`` (sigma_pre -> JSON form), stored at
    ``path`` as they end (a failed run: its error text, stored too)."""
    if path.exists():
        got = json.loads(path.read_text())
        return got["error"] if "error" in got else {float(k): v for k, v in got.items()}
    try:
        tests = shear_tests(check_shear_cell(base_test(), cell(seed)), _draft(loci), law)
        out = run_shear_tests(tests)
        text = json.dumps({str(k): v for k, v in out.items()})
    except (
        engine.ParameterError,
        engine.StageError,
        engine.InstabilityError,
        FloatingPointError,
    ) as e:
        out = f"{type(e).__name__}: {e}"
        text = json.dumps({"error": out})
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    return out


#: fewest seeds whose runs of a locus must have finished for its targets (a failed test
#: is repeated in a laboratory, not averaged in)
MIN_LAB_SEEDS = 3


def lab() -> tuple[dict[str, LabTargets], dict]:
    """The truth's loci (fitted, held out, extra) at :data:`LAB_SEEDS`, each run stored as
    it ends (one file per seed and locus); per group the targets, each locus's the mean and
    sd over the seeds whose run of it finished (at least :data:`MIN_LAB_SEEDS`), and the
    seeds that failed, per locus, with their errors."""
    material = (
        f"synthetic: engine.run_shear of mu_s = {TRUTH.mu_s}, f0 = {TRUTH.f0} N, kadh = "
        f"{TRUTH.kadh} N/m in a 6 x 3 x 6 diameter cell, mean and sd of seeds "
        f"{list(LAB_SEEDS)} (less any listed as failed)"
    )
    out, failed = {}, {}
    for name, loci in (("fitted", FITTED), ("held_out", HELD_OUT), ("extra", EXTRA)):
        rows = []
        for s, sn in loci.items():
            draft = _draft({s: sn})
            values = []
            for seed in LAB_SEEDS:
                r = _run_loci(STORE / "lab" / f"s{seed}-{s:g}Pa.json", {s: sn}, TRUTH, seed)
                if isinstance(r, str):
                    failed.setdefault(f"{s:g}", []).append({"seed": seed, "error": r})
                else:
                    values.append([q["value"] for q in measure_shear(r, draft)])
            if len(values) < MIN_LAB_SEEDS:
                raise RuntimeError(
                    f"the truth's locus at {s:g} Pa finished at {len(values)} seeds of "
                    f"{len(LAB_SEEDS)}: {failed.get(f'{s:g}')}"
                )
            rows.append(_locus_targets(s, sn, np.array(values)))
        out[name] = LabTargets.from_dict(
            {"tester": "ring_shear", "material": material, "shear": rows}
        )
    return out, failed


def run_calibration(targets: LabTargets) -> dict:
    return calibrate_twin(
        base_test(),
        targets,
        BOX,
        (RUNS, WAVES, WAVE_RUNS),
        OUT,
        cell(),
        on_run=lambda i, q: print(
            f"run {i} done" + (f": {q}" if isinstance(q, str) else ""), flush=True
        ),
        vary_seed=VARY_SEED,
    )


def _laws(summary: dict) -> list[dict]:
    """:data:`PREDICT_SAMPLES` posterior samples, evenly spaced over the stored ones."""
    post = summary["posterior"]
    rows = post["samples"]
    idx = np.linspace(0, len(rows) - 1, PREDICT_SAMPLES).astype(int)
    return [dict(zip(post["parameters"], rows[i])) for i in idx]


def predict(summary: dict, name: str, loci: dict, targets: LabTargets) -> dict:
    """The calibrated law's prediction of ``loci`` (not fitted): a run per posterior
    sample (its own seed) and the median law's run; per quantity the predictions' mean and
    sd, the lab's mean and sd, z and whether |z| <= :data:`Z_MAX`."""
    draft = _draft(loci)
    values, runs = [], []
    for i, (params, seed) in enumerate(zip(_laws(summary), PREDICT_SEEDS)):
        law = replace(START, **params)
        r = _run_loci(OUT / "predict" / f"{name}-{i:02d}.json", loci, law, seed)
        row = {"parameters": params, "seed": seed}
        if isinstance(r, str):
            row["error"] = r
        else:
            row["quantities"] = measure_shear(r, draft)
            row["loci"] = _loci_of(r)
            values.append([q["value"] for q in row["quantities"]])
        runs.append(row)
    law = summary["law"]
    median = replace(START, **{k: law[k] for k in BOX})
    med = _run_loci(OUT / "predict" / f"{name}-median.json", loci, median, 1)
    v = np.array(values)
    quantities = []
    # the columns of v are measure_shear's order: per locus its points, tau_pre, density
    for j, (qname, lab_value, lab_sd) in enumerate(_lab_values(targets)):
        mean = float(v[:, j].mean()) if len(v) else math.nan
        sd = float(v[:, j].std(ddof=1)) if len(v) > 1 else math.nan
        comb = math.hypot(sd, lab_sd)
        z = (mean - lab_value) / comb if comb > 0 else math.nan
        quantities.append(
            {
                "name": qname,
                "unit": "kg/m^3" if qname.startswith("bulk_density") else "Pa",
                "lab": lab_value,
                "lab_sd": lab_sd,
                "predicted": mean,
                "predicted_sd": sd,
                "z": z,
                "within": bool(abs(z) <= Z_MAX),
                "median_law": None
                if isinstance(med, str)
                else next(m["value"] for m in measure_shear(med, draft) if m["name"] == qname),
            }
        )
    return {
        "loci": list(loci),
        "runs": runs,
        "failed": sum("error" in r for r in runs),
        "quantities": quantities,
        "predicted": all(q["within"] for q in quantities) and len(values) >= 2,
        "median_law_run": med if isinstance(med, str) else _loci_of(med),
        "lab_loci": _lab_loci(targets),
    }


def _lab_values(targets: LabTargets) -> list[tuple[str, float, float]]:
    """(name, value, sd) of each quantity of ``targets``, named as measure_shear names them."""
    out = []
    for locus in targets.shear:
        s = locus.sigma_pre
        for k, p in enumerate(locus.points):
            out.append((f"tau@{p.sigma_n:g}Pa:{s:g}Pa", p.tau, locus.tau_sd(k)))
        out.append((f"tau_pre@{s:g}Pa", locus.tau_pre, locus.tau_pre_sd))
        out.append((f"bulk_density@{s:g}Pa", locus.bulk_density, locus.bulk_density_sd))
    return out


def _loci_of(shear: dict) -> list[dict]:
    """Per sigma_pre: c [Pa], tan(phi), sigma_c, sigma_1 [Pa], ffc of a run's loci."""
    return [
        {
            "sigma_pre": float(s),
            **{k: r["locus"][k] for k in ("cohesion", "slope", "sigma_c", "sigma_1", "ffc")},
        }
        for s, r in sorted(shear.items())
    ]


def _lab_loci(targets: LabTargets) -> list[dict]:
    """The lab's loci (its mean points) as a tester reports them: the line through the
    points and the Mohr construction with (sigma_pre, tau_pre) (engine.shear.locus)."""
    out = []
    for locus in targets.shear:
        loc = yield_locus(
            [p.sigma_n for p in locus.points],
            [p.tau for p in locus.points],
            locus.sigma_pre,
            locus.tau_pre,
        )
        out.append(
            {
                "sigma_pre": locus.sigma_pre,
                **{k: getattr(loc, k) for k in ("cohesion", "slope", "sigma_c", "sigma_1", "ffc")},
            }
        )
    return out


def report(summary: dict, groups: dict, predictions: dict, lab_failed: dict) -> dict:
    """Each parameter against the truth (inside its 90 % interval?), each target met, the
    loci (lab and check run), each prediction (module docstring's criterion)."""
    out = {"parameters": {}, "targets": [], "failed_runs": []}
    for name, p in summary["parameters"].items():
        truth = getattr(TRUTH, name)
        lo, hi = p["interval"]
        out["parameters"][name] = {
            "truth": truth,
            "median": p["median"],
            "interval": [lo, hi],
            "truth_inside": lo <= truth <= hi,
            "status": p["status"],
            "spread_ratio": p["spread_ratio"],
        }
    for q in summary["targets_met"]:
        out["targets"].append(
            {
                k: q[k]
                for k in ("name", "lab", "sd", "seed_sd", "value", "z", "met", "unit")
                if k in q
            }
        )
    out["failed_runs"] = [r["error"] for r in summary["runs"] if "error" in r]
    out["runs"] = len(summary["runs"])
    out["all_targets_met"] = summary["all_targets_met"]
    out["all_truths_inside"] = all(p["truth_inside"] for p in out["parameters"].values())
    out["lab_loci"] = _lab_loci(groups["fitted"])
    out["check_loci"] = summary["curves"].get("yield_loci", [])
    out["correlation"] = summary["posterior"]["correlation"]
    out["sensitivity"] = summary["sensitivity"]
    out["predictions"] = predictions
    out["lab_failed"] = lab_failed
    out["criterion"] = (
        f"each quantity of a predicted locus within {Z_MAX:g} combined sd: |mean of the "
        "posterior-sample runs - lab mean| <= 2 sqrt(sd of those runs^2 + lab sd^2)"
    )
    out["vary_seed"] = VARY_SEED
    (OUT / "report.json").write_text(json.dumps(out, indent=1))
    return out


def diagnose(groups: dict) -> dict:
    """After the verdict, not part of it: the truth's own runs in the calibration's cell
    (packing seed 1, the seed of every calibration run) against the lab's targets, beside
    the check run's values: whether one packing's offset from the five seeds' mean is what
    the calibration read as a lower mu_s (``diagnosis.json``)."""
    targets = groups["fitted"]
    rows = []
    check = {q["name"]: q for q in json.loads(RESULT.read_text())["targets_met"]}
    for s, sn in FITTED.items():
        r = _run_loci(STORE / "diagnosis" / f"truth-s1-{s:g}Pa.json", {s: sn}, TRUTH, 1)
        if isinstance(r, str):
            rows.append({"sigma_pre": s, "error": r})
            continue
        lab_values = {n: (v, sd) for n, v, sd in _lab_values(targets)}
        for q in measure_shear(r, _draft({s: sn})):
            v, sd = lab_values[q["name"]]
            rows.append(
                {
                    "name": q["name"],
                    "lab": v,
                    "lab_sd": sd,
                    "truth_seed1": q["value"],
                    "z_truth_seed1": (q["value"] - v) / sd if sd > 0 else None,
                    "check_run": check[q["name"]]["value"],
                }
            )
    (STORE / "diagnosis.json").write_text(json.dumps(rows, indent=1))
    return {"rows": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true", help="report what is stored; run nothing")
    ap.add_argument(
        "--vary-seed",
        action="store_true",
        help="each calibration run packs its own sample (calibrate(vary_seed=True)); stored "
        "in vary_seed/",
    )
    ap.add_argument(
        "--diagnose",
        action="store_true",
        help="after the report: the truth at the calibration's packing seed against the lab",
    )
    args = ap.parse_args()
    global OUT, VARY_SEED
    if args.vary_seed:
        OUT, VARY_SEED = STORE / "vary_seed", True
        OUT.mkdir(parents=True, exist_ok=True)
    groups, lab_failed = lab()
    if args.diagnose:
        for row in diagnose(groups)["rows"]:
            print(row)
        return
    if args.report:
        summary = json.loads((OUT / "result.json").read_text())
    else:
        (STORE / "lab.json").write_text(json.dumps(groups["fitted"].to_dict(), indent=1))
        (STORE / "lab_held_out.json").write_text(
            json.dumps(
                {k: groups[k].to_dict() for k in ("held_out", "extra")},
                indent=1,
            )
        )
        summary = run_calibration(groups["fitted"])
    predictions = {
        "held_out": predict(summary, "held_out", HELD_OUT, groups["held_out"]),
        "extra": predict(summary, "extra", EXTRA, groups["extra"]),
    }
    rep = report(summary, groups, predictions, lab_failed)
    print_report(rep, truth_aside)
    for name, pr in predictions.items():
        print(f"{name} ({pr['loci']} Pa): predicted {pr['predicted']}; failed {pr['failed']}")
        for q in pr["quantities"]:
            print(
                f"  {q['name']}: {q['predicted']:.4g} +- {q['predicted_sd']:.2g} against "
                f"{q['lab']:.4g} +- {q['lab_sd']:.2g}, z {q['z']:+.2f}"
            )


if __name__ == "__main__":
    main()
