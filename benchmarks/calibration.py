"""Calibrating the seed's cohesive law to laboratory-like targets at the quick scale, then
coarsening it (issue 30's benchmark).

    python -m benchmarks.calibration --workers 2     # runs not yet stored, then the report
    python -m benchmarks.calibration --report        # docs/CALIBRATION_quick.md so far

The "laboratory" is the engine itself, with a law the calibration is not told
(:data:`TRUTH`: K1 = 6.5e3 N/m, K2 = 3.5e4 N/m, f0 = -0.55 N; the seed's law is 5e3, 2.5e4,
-0.8): three packing seeds of its flow function at the quick scale (2,292 particles, 10
diameters thick) give each target's mean and its seed-to-seed sd, as a tester's
repeatability would; the tester is a lambda tester (K0). The calibration starts from the
seed's law and is given the box :data:`BOX` for K1, K2 and f0, with 25 design runs and two
waves of 15 (``engine.calibrate``'s defaults); every run is stored in
``benchmarks/results/quick/calibration/`` as it finishes, and a rerun goes on from there.
Each run is a quick-scale flow function (one fill, three consolidation stresses), about ten
minutes on one core, so the whole takes several sessions on 2 cores; the report says how
far it has come. When done it reports the runs used, the parameters recovered (the truth
inside each determined parameter's 90 % interval?), the targets met and which target
moves with which parameter, then the coarsened law: the paper rule applied to the
calibrated law at 3.75 and 5 mm. The finished calibration's summary is stored as
``result.json`` beside the runs and drawn as docs/calibration_quick.png, so ``--report``
rebuilds the whole report without a run.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import multiprocessing as mp
from dataclasses import replace
from pathlib import Path

import numpy as np

import engine
from benchmarks.checks import publish
from engine.calibration import LabTargets, StrengthPoint, calibrate
from engine.calibration.calibrate import DETERMINED, branch_stresses, measure
from engine.contact.registry import LAWS
from engine.core.records import from_dict

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "quick" / "calibration"
REPORT = ROOT / "docs" / "CALIBRATION_quick.md"
#: the finished calibration's summary (``Calibration.to_summary()``), so ``--report`` needs no run
RESULT = STORE / "result.json"
FIGURE = ROOT / "docs" / "calibration_quick.png"
TRUTH = engine.BilinearAdhesive(k1=6.5e3, k2=3.5e4, f0=-0.55, mu_s=0.5, mu_r=0.001, restitution=0.4)
SEED_LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.8, mu_s=0.5, mu_r=0.001, restitution=0.4)
BOX = {"k1": (2e3, 2e4), "k2": (2.1e4, 1e5), "f0": (-2.0, -0.1)}
#: consolidation stresses of the flow function [Pa]; the base test's is 20 kPa
STRESSES = (1e4, 2e4, 4e4)
#: stresses of the compression-curve targets [Pa]
POROSITY_AT = (8e3, 1.5e4, 3e4)
LAB_SEEDS = (101, 102, 103)


def base_test(seed: int = 1) -> engine.UniaxialTest:
    """The calibrated test at packing ``seed``: the quick preset with the seed's protocol
    (``protocol="seed"``), as the stored calibration was made."""
    return engine.preset("quick", protocol="seed", pair_law=SEED_LAW, seed=seed)


def _lab_run(seed: int):
    """The truth's flow function at packing ``seed``, each branch stored as it is made
    (``STORE / lab-s<seed>-<stress>Pa.h5``) and found again on a rerun."""
    from engine.calibration.calibrate import _run_point
    from engine.io.store import load_run, save_run

    t = replace(base_test(seed), pair_law=TRUTH)
    paths = {s: STORE / f"lab-s{seed}-{s:g}Pa.h5" for s in STRESSES}
    if all(p.exists() for p in paths.values()):
        got = {s: load_run(p) for s, p in paths.items()}
        if all(
            not isinstance(r, str) and r.test == replace(t, consolidation_stress=s)
            for s, r in got.items()
        ):
            return got
    out = _run_point(t, STRESSES)
    if isinstance(out, str):
        raise RuntimeError(f"the laboratory run of seed {seed} failed: {out}")
    STORE.mkdir(parents=True, exist_ok=True)
    for s, r in out.items():
        save_run(paths[s], r, keep_particles=False)
    return out


def lab_targets(workers: int) -> LabTargets:
    """The targets: the truth's flow function at three seeds, mean and sd of each quantity
    (stored in ``STORE / lab.json`` once made)."""
    path = STORE / "lab.json"
    if path.exists():
        return LabTargets.from_dict(json.loads(path.read_text()))
    draft = LabTargets(
        tester="lambda",
        compression=tuple({"stress": s, "porosity": 0.45} for s in POROSITY_AT),
        loading_stiffness=1.0,
        unloading_stiffness=1.0,
        k0=0.5,
        strength=tuple(StrengthPoint(consolidation_stress=s, strength=1.0) for s in STRESSES),
    )
    draft = LabTargets.from_dict(draft.to_dict())
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        runs = list(ex.map(_lab_run, LAB_SEEDS))
    qs = [measure(r, base_test(), draft) for r in runs]
    vals = np.array([[q["value"] for q in x] for x in qs])
    mean, sd = vals.mean(0), vals.std(0, ddof=1)
    names = [q["name"] for q in qs[0]]
    by = dict(zip(names, zip(mean, sd)))
    comp = [
        {
            "stress": s,
            "porosity": by[f"porosity@{s:g}Pa:loading"][0],
            "sd": by[f"porosity@{s:g}Pa:loading"][1],
        }
        for s in POROSITY_AT
    ]
    body = {
        "tester": "lambda",
        "material": "the engine's TRUTH law, 3 seeds (benchmarks/calibration.py)",
        "compression": comp,
        "loading_stiffness": by["loading_stiffness"][0],
        "loading_stiffness_sd": by["loading_stiffness"][1],
        "unloading_stiffness": by["unloading_stiffness"][0],
        "unloading_stiffness_sd": by["unloading_stiffness"][1],
        "k0": by["k0"][0],
        "k0_sd": by["k0"][1],
        "strength": [
            {
                "consolidation_stress": s,
                "strength": by[f"strength@{s:g}Pa"][0],
                "sd": by[f"strength@{s:g}Pa"][1],
            }
            for s in STRESSES
        ],
    }
    targets = LabTargets.from_dict(body)
    STORE.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(targets.to_dict(), indent=1))
    return targets


def run(workers: int) -> engine.calibration.Calibration:
    targets = lab_targets(workers)
    assert branch_stresses(base_test(), targets) == STRESSES
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        return calibrate(
            base_test(),
            targets,
            BOX,
            store=STORE / "runs",
            executor=ex,
            # a twin: the same model made the data, no discrepancy to widen by
            discrepancy=False,
            on_run=lambda i, q: print(f"run {i + 1} done", flush=True),
        )


def _coarsened(law_json: dict) -> list[str]:
    """The calibrated law coarsened by the paper rule at 3.75 and 5 mm."""
    body = dict(law_json)
    law = from_dict(LAWS[body.pop("type")], body)
    rule = engine.ScalingRule.named("paper")
    test = replace(base_test(), pair_law=law)
    out = []
    for r in (3.75e-3, 5e-3):
        c = rule.apply(test, r, test.dt).pair_law
        out.append(
            f"- R = {r * 1e3:g} mm: K1 = {c.k1:.4g} N/m, K2 = {c.k2:.4g} N/m, f0 = {c.f0:.4g} N"
        )
    return out


def _result_lines(summary: dict) -> list[str]:
    """The finished calibration (``Calibration.to_summary()``, stored as ``RESULT``) in words
    and tables: the runs used, the parameters against the untold truth, the targets met, the
    sensitivities and the coarsened law."""
    runs = summary["runs"]
    failed = [r for r in runs if "error" in r]
    waves = sorted({r["wave"] for r in runs})
    per_wave = ", ".join(
        f"{'design' if w == 0 else f'wave {w}'}: {sum(r['wave'] == w for r in runs)}" for w in waves
    )
    checked = all(q["z"] is not None for q in summary["targets_met"])
    lines = [
        "",
        "## Result",
        "",
        f"Runs used: {len(runs) + 1} ({per_wave}, and the check run of the calibrated law"
        f"{'' if checked else ', which failed'}). Stopped with an error, and left out of the "
        f"emulators: {len(failed)}" + (":" if failed else "."),
        "",
    ]
    for r in failed:
        p = ", ".join(f"{k} = {v:.4g}" for k, v in r["parameters"].items())
        lines.append(
            f"- {'design' if r['wave'] == 0 else 'wave ' + str(r['wave'])}: {p}: "
            f"{r['error'].splitlines()[0].split('; dt')[0]}"
        )
    lines += [
        "",
        "The parameters (posterior median and 90 % credible interval; `determined` where the "
        f"posterior's spread is under {DETERMINED:g} of the box's; the truth is the law the "
        "targets were made with, which the calibration was not told):",
        "",
        "| parameter | truth | median | 90 % interval | status | truth inside |",
        "|---|---|---|---|---|---|",
    ]
    for n, p in summary["parameters"].items():
        lo, hi = p["interval"]
        truth = getattr(TRUTH, n)
        inside = min(lo, hi) <= truth <= max(lo, hi)
        lines.append(
            f"| {n} | {truth:.4g} | {p['median']:.4g} | {lo:.4g} to {hi:.4g} | {p['status']} | "
            f"{'yes' if inside else 'no'} |"
        )
    lines += [
        "",
        "The targets, met by the check run of the calibrated law when |z| <= 2 (z against the "
        "laboratory's sd, the emulator's seed noise and any resolution correction together):",
        "",
        "| target | lab | check run | z | met |",
        "|---|---|---|---|---|",
    ]
    for q in summary["targets_met"]:
        z = "-" if q["z"] is None else f"{q['z']:+.1f}"
        lines.append(
            f"| {q['name']} | {q['lab']:.4g} +/- {q['sd']:.2g} | {q['value']:.4g} | {z} | "
            f"{'yes' if q['met'] else 'no'} |"
        )
    if summary["not_met"]:
        lines += ["", "Not met:", ""] + [f"- {m}" for m in summary["not_met"]]
    names = list(summary["parameters"])
    lines += [
        "",
        "Which target moves with which parameter (first-order Sobol index of the emulator):",
        "",
        "| target | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for q, s in summary["sensitivity"].items():
        lines.append(f"| {q} | " + " | ".join(f"{s[n]:.2f}" for n in names) + " |")
    lines += ["", "Coarsened by the paper rule (K ~ R, f0 ~ R^2):", ""]
    lines += _coarsened(summary["law"])
    lines += ["", f"![calibration]({FIGURE.name})"]
    return lines


def report(summary: dict | None) -> str:
    """docs/CALIBRATION_quick.md: the targets, how far the runs have come and, once the
    calibration has finished (``summary``: the stored ``RESULT``), its result."""
    done = sorted((STORE / "runs").glob("cal-*.h5")) if (STORE / "runs").exists() else []
    points = {p.name.split("-")[1] for p in done}
    lines = [
        "# Calibration benchmark (quick scale)",
        "",
        "Generated by `python -m benchmarks.calibration` (docs/CALIBRATION.md; "
        "`--report` from the stored runs and result). The seed's cohesive law calibrated to "
        "targets the engine made from a law it is not told "
        f"(K1 = {TRUTH.k1:g} N/m, K2 = {TRUTH.k2:g} N/m, f0 = {TRUTH.f0:g} N; three seeds), "
        f"over K1, K2, f0 in {BOX}, 25 design runs and two waves of 15.",
        "",
        f"Runs stored so far: {len(points)} of 55 (each a flow function at "
        f"{', '.join(f'{s / 1e3:g}' for s in STRESSES)} kPa; a run that stopped with an "
        "error is stored with it).",
    ]
    lab = STORE / "lab.json"
    if lab.exists():  # the targets, made once from the untold law
        t = LabTargets.from_dict(json.loads(lab.read_text()))
        lines += [
            "",
            "The laboratory (the untold law at three packing seeds: mean +/- sd):",
            "",
            "| target | value | sd |",
            "|---|---|---|",
        ]
        lines += [
            f"| porosity at {p.stress / 1e3:g} kPa ({p.branch}) | {p.porosity:.4f} | {p.sd:.4f} |"
            for p in t.compression
        ]
        for name, unit, scale in (
            ("loading_stiffness", "MPa", 1e-6),
            ("unloading_stiffness", "MPa", 1e-6),
            ("k0", "", 1.0),
        ):
            v = getattr(t, name)
            if v is not None:
                sd = getattr(t, f"{name}_sd")
                lines.append(f"| {name} [{unit or '-'}] | {v * scale:.4g} | {sd * scale:.2g} |")
        lines += [
            f"| strength at {p.consolidation_stress / 1e3:g} kPa [kPa] | {p.strength / 1e3:.4g} | "
            f"{p.sd / 1e3:.2g} |"
            for p in t.strength
        ]
    if summary is not None:
        lines += _result_lines(summary)
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--report", action="store_true")
    args = ap.parse_args(argv)
    if not args.report:
        RESULT.write_text(json.dumps(run(args.workers).to_summary(), separators=(",", ":")))
    summary = json.loads(RESULT.read_text()) if RESULT.exists() else None
    if summary is not None:
        from engine.io.figures import calibration_figure

        calibration_figure(summary).savefig(FIGURE)
    publish(REPORT, report(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
