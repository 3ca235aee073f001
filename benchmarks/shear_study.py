"""A scaling study on the shear test (issue 41 item 5; docs/SHEAR.md, "Scaling judged in
shear"): the main job's rules and law on the shear test at the quick scale.

    NUMBA_NUM_THREADS=1 nohup nice -n 19 python -m benchmarks.shear_study > LOG 2>&1 &
    python -m benchmarks.shear_study --report        # the report, from the stored runs
    python -m benchmarks.shear_study --estimate      # the planned runs' cost, nothing run

The study (:data:`SPEC`): the reference is the default shear test (docs/SHEAR.md: the
10 x 5 x 15-diameter cell at R = 2.5 mm, inertial number 1e-3, sigma_pre = 10 kPa,
sigma_n = 2, 4, 6, 8 kPa) with the main job's cohesive law (engine.default_study: K1 = 5e3,
K2 = 2.5e4 N/m, f0 = -0.4 N, mu_s = 0.5, mu_r = 0.001, restitution 0.4); coarse radii
3.125 and 3.75 mm (the main job's: 8 and 6.7 diameters across the cell's 50 mm) and 5 mm
(5 x 2.5 diameters across); the main job's rules, ``paper`` (K ~ R, f0 ~ R^2) and
``unscaled``; a resolution control per coarse radius and seed; the protocol check (five
reference seeds at half the inertial number and half the time step; two in the first pass,
raised to five when two left it undecided); a pilot of five
seeds a side, then one round of added seeds (up to ten a variant and ten references,
within 3e9 particle-steps: docs/PHYSICS.md section 7.2) at 95 % confidence. The shear
metrics and their tolerances (engine.study.metrics.SHEAR_METRICS, docs/PHYSICS.md
section 11.1) were fixed before any of these runs.

Each run is stored the moment it ends under ``benchmarks/results/quick/shear_study/`` as
``<key>.json`` (test, scalars, points, locus) with its shear stages' curves in ``<key>.npz``
(engine.shear.results.save_shear), or ``<key>.failed`` (its error), and committed with
``--commit``; the study resumes with the runs it lacks (a run cut off starts again: this script
passes no checkpoint to its runs). The summary (table, verdicts, report) is written to
``summary.json`` there when the study ends and by ``--report``.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import engine
from engine.shear.results import load_shear, save_shear
from engine.study.plan import final_look, plan, plan_runs
from engine.study.results import assemble

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "quick" / "shear_study"

#: The main job's cohesive law (engine.default_study's reference law).
LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)

SPEC = engine.StudySpec(
    reference=engine.ShearTest(pair_law=LAW),
    coarse_radii=(3.125e-3, 3.75e-3, 5e-3),
    rules=(engine.ScalingRule.named("paper"), engine.ScalingRule.named("unscaled")),
    seeds=(1, 2, 3, 4, 5),
    reference_seeds=(1, 2, 3, 4, 5),
    decide=True,
    rounds=1,
    max_seeds=10,
    max_reference_seeds=10,
    budget=3e9,
    protocol_check=True,
    # five reference seeds at half the rate and step: raised from two after the first pass,
    # where two (one degree of freedom) left every metric of the check undecided
    protocol_seeds=5,
)


def stored() -> dict:
    """Key -> ShearResult (or error text) of every stored run."""
    out: dict = {}
    if not STORE.exists():
        return out
    for p in sorted(STORE.glob("*.json")):
        if p.name == "summary.json":
            continue
        out[p.stem] = load_shear(p)
    for p in sorted(STORE.glob("*.failed")):
        out[p.stem] = p.read_text().strip()
    return out


def commit(paths: list[Path], message: str) -> None:
    """Commit ``paths`` alone (``git commit -- paths``), waiting for another engineer's
    commit that holds the index."""
    rel = [str(p.resolve().relative_to(ROOT)) for p in paths]
    for _ in range(30):
        if not (ROOT / ".git" / "index.lock").exists():
            break
        time.sleep(2)
    subprocess.call(["git", "add", *rel], cwd=ROOT)
    subprocess.call(["git", "commit", "-q", "-m", message, "--", *rel], cwd=ROOT)


def run(do_commit: bool) -> engine.StudyResult:
    STORE.mkdir(parents=True, exist_ok=True)
    started = {"t": time.perf_counter()}

    def on_run(key: str, outcome) -> None:
        took = time.perf_counter() - started["t"]
        if isinstance(outcome, str):
            path = STORE / f"{key}.failed"
            path.write_text(outcome + "\n")
            paths, line = [path], f"FAILED {outcome}"
        else:
            path = STORE / f"{key}.json"
            save_shear(path, outcome, engine=engine.__version__)
            paths = [path.with_suffix(".npz"), path]
            s = outcome.scalars
            line = (
                f"{s['particles']:.0f} grains, {s['steps']:.0f} steps, "
                f"c = {s['cohesion']:.0f} Pa, phi = {s['friction_angle']:.1f} deg, "
                f"sigma_c = {s['sigma_c']:.0f} Pa, ffc = {s['ffc']:.3g}, "
                f"rho_b = {s['bulk_density']:.0f} kg/m^3"
            )
        print(f"{key}: {took:.0f} s, {line}", flush=True)
        if do_commit:
            commit(paths, f"Shear study: {key} stored ({took:.0f} s)")
        started["t"] = time.perf_counter()

    done = stored()
    print(f"{len(done)} runs stored; running the rest", flush=True)
    res = engine.run_study(plan(SPEC), completed=done, on_run=on_run)
    write_summary(res, do_commit)
    return res


def result() -> engine.StudyResult:
    """The study judged from the stored runs (as run_study would at this point)."""
    outcomes = stored()
    runs, added, stopped = plan_runs(plan(SPEC), outcomes)
    from engine.study.plan import adaptive_summary

    adaptive = adaptive_summary(SPEC, runs, added, stopped)
    return assemble(SPEC, runs, outcomes, final_look(SPEC, added, stopped), adaptive)


def write_summary(res: engine.StudyResult, do_commit: bool = False) -> Path:
    path = STORE / "summary.json"
    path.write_text(json.dumps(res.to_summary(), indent=1, default=_json))
    if do_commit:
        commit([path], "Shear study: summary written")
    return path


def _json(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:+.1f}"


def _metric(m) -> str:
    """A judged metric (engine.study.report.MetricVerdict): its error and interval [%]."""
    if m.interval is None:
        return f"{_pct(m.signed_error)} %"
    lo, hi = m.interval
    return f"{_pct(m.level_error)} [{_pct(lo)}, {_pct(hi)}]"


def report() -> str:
    """The report in docs/SHEAR.md's words: verdicts with each metric's error and interval
    (at the level furthest out), the rules against their controls, the resolution errors,
    the protocol check, errors against run time, the reference's values."""
    res = result()
    write_summary(res)
    rep = res.report
    names = list(engine.study.metrics.SHEAR_METRICS)
    lines = []
    ad = rep.adaptive
    lines.append(
        f"Runs stored: {len(res.runs)} (failed: "
        f"{sum(t != 'not run' for t in res.failed.values())}); look {ad and ad.look} of "
        f"{ad and ad.looks}; stopped: {ad and ad.stopped}; added runs: "
        f"{len(ad.added_runs) if ad else 0}"
    )
    missing = [k for k, t in res.failed.items() if t == "not run"]
    if missing:
        lines.append(f"Not run yet: {len(missing)} planned runs.")
    for k, t in res.failed.items():
        if t != "not run":
            lines.append(f"- {k} failed: {t[:300]}")
    lines.append(reproduced(res))
    lines.append(similarity(res))
    head = "| R [mm] | against | verdict | seeds | " + " | ".join(names) + " |"
    lines += ["", head, "|" + "---|" * (4 + len(names))]

    def rows(verdicts, against):
        for v in sorted(verdicts, key=lambda v: (v.radius, v.rule)):
            cells = [_metric(m) if (m := v.metric(n)) is not None else "-" for n in names]
            who = v.rule if against is None else f"{v.rule} vs {against}"
            lines.append(
                f"| {v.radius * 1e3:g} | {who} | {v.verdict} | {v.seeds} | "
                + " | ".join(cells)
                + " |"
            )

    rows(rep.verdicts, None)
    rows(rep.rule_errors, "control")
    rows(rep.resolution, "reference")
    if rep.protocol is not None:
        rows([rep.protocol], "reference")
    lines.append("")
    lines.append(
        "Errors are the ratio of geometric means less 1 [%] with the 95 % interval of the "
        "level furthest out (yield_locus: the normal stress where it is furthest)."
    )
    # errors against run time
    lines += [
        "",
        "| R [mm] | group | runs | particles | wall time [s] | speed-up | particle-step "
        "speed-up | " + " | ".join(f"err {n}" for n in names) + " |",
        "|" + "---|" * (7 + len(names)),
    ]
    groups: dict = {}
    for r in res.runs.values():
        groups.setdefault((r.radius, r.label), []).append(r)
    for (radius, label), rs in sorted(groups.items()):
        err = [
            f"{np.mean([x.errors[engine.study.metrics.metric_column(n)] for x in rs]):.3f}"
            for n in names
        ]
        wall = [x.result.scalars["wall_time"] for x in rs]
        lines.append(
            f"| {radius * 1e3:g} | {label} | {len(rs)} | "
            f"{np.mean([x.result.scalars['particles'] for x in rs]):.0f} | "
            f"{np.mean(wall):.1f} | {np.mean([x.speedup for x in rs]):.2f} | "
            f"{np.mean([x.speedup_steps for x in rs]):.2f} | " + " | ".join(err) + " |"
        )
    ref = rep.reference
    lines.append("")
    lines.append(
        "Reference (seeds "
        + ", ".join(str(s) for s in ref.seeds)
        + "): "
        + ", ".join(
            f"{k} {ref.mean(k):.4g} +- {ref.std(k):.2g}"
            for k in ("cohesion", "friction_angle", "sigma_1", "sigma_c", "ffc", "bulk_density")
            if ref.has(k) and math.isfinite(ref.mean(k))
        )
    )
    lines.append("")
    lines.append("Noise floor: " + ", ".join(f"{k} {v:.3f}" for k, v in rep.noise_floor.items()))
    lines.append("")
    lines.append("Advisor: " + rep.message)
    return "\n".join(lines)


def reproduced(res: engine.StudyResult) -> str:
    """Whether each reference run's scalars (but its wall time and those added since) equal
    those of the same test stored by benchmarks/shear_cell.py (cohesive-h15-s<seed>: the same
    law, cell, rate and seed): a run of the study is the shear test as it was measured."""
    from benchmarks.shear_cell import path_for

    same, differ = [], []
    for key, r in res.runs.items():
        if not r.is_reference:
            continue
        p = path_for("cohesive", 15, r.seed)
        if not p.exists():
            continue
        old = load_shear(p)
        if old.test != r.result.test:
            continue
        skip = {"wall_time", "particle_steps", "thickness_diameters"}
        new = {k: v for k, v in r.result.scalars.items() if k not in skip}
        (same if new == {k: old.scalars[k] for k in new} else differ).append(key)
    return (
        f"References equal to the stored shear_cell runs of the same test in every scalar but "
        f"the wall time: {', '.join(same) or 'none'}; differing: {', '.join(differ) or 'none'}."
    )


def similarity(res: engine.StudyResult) -> str:
    """How alike a paper-rule run and the control of its seed are before the shear (a coarse
    run under K ~ R, f0 ~ R^2 is its control scaled, clock included, docs/PHYSICS.md 11.1):
    per radius the largest relative difference of the bulk density when the platens were
    glued, and the ratio of their time steps (s = R_c / R_ref where the similarity holds)."""
    out = []
    for radius in SPEC.coarse_radii:
        pairs = [
            (r.result.scalars, c.result.scalars)
            for r in res.runs.values()
            if r.rule is not None and r.rule.name == "paper" and r.radius == radius
            for c in res.runs.values()
            if c.control and c.radius == radius and c.seed == r.seed
        ]
        if not pairs:
            continue
        dens = [
            abs(a["bulk_density_consolidated"] / b["bulk_density_consolidated"] - 1)
            for a, b in pairs
        ]
        dts = [a["dt"] / b["dt"] for a, b in pairs]
        out.append(
            f"{radius * 1e3:g} mm ({len(pairs)} pairs): consolidated bulk density within "
            f"{100 * max(dens):.2f} % (median {100 * float(np.median(dens)):.3f} %), time steps "
            f"{min(dts):.4g}-{max(dts):.4g} x the control's "
            f"(s = {radius / SPEC.reference.radius:g})"
        )
    return "Paper runs against the controls of their seeds: " + "; ".join(out) + "."


def estimate() -> str:
    p = plan(SPEC)
    lines = [f"{len(p.runs)} planned runs"]
    for r in p.runs:
        lines.append(f"{r.key}: {r.test.n_particles} grains, {r.particle_steps:.3g} particle-steps")
    lines.append(
        f"planned {sum(r.particle_steps for r in p.runs):.3g} particle-steps; at most "
        f"{p.estimated_particle_steps():.3g} with the added round"
    )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--report", action="store_true", help="the report from the stored runs")
    ap.add_argument("--estimate", action="store_true", help="the planned runs' cost")
    ap.add_argument("--commit", action="store_true", help="commit each stored run")
    a = ap.parse_args(argv)
    if a.estimate:
        print(estimate())
    elif a.report:
        print(report())
    else:
        run(a.commit)
        print(report())
    return 0


if __name__ == "__main__":
    sys.exit(main())
