"""Finite-size control of experiment (b) at the paper scale (issue 19, point 6).

    python -m benchmarks.finite_size [--seeds 1 2 3] [--threads N]   # run, store, report
    python -m benchmarks.finite_size --report                        # report from stored runs

Every coarse cohesive run at R = 5 mm (a bed 5 diameters thick) is weaker in unconfined
strength than the references (10 diameters thick). The control separates the finite-size
effect from the scaling rule: the 2.5 mm reference law of experiment (b), **unscaled**
(K1 = 5e3 N/m, K2 = 2.5e4 N/m, f0 = -0.8 N), in the reference test shrunk by
s = R_ref / R_coarse = 1/2 in every length of the cell, so that it holds the 5 mm coarse
run's particles per thickness, width and height (5 x 15 x 30 diameters, 2,578 particles):

- ``cell`` (50, 150, 300) mm -> (25, 75, 150) mm: the cell itself (the pour column, its
  height H solid_fraction / pour_fraction, and the top platen's start follow from it);
- ``interior_margin`` 20 mm -> 10 mm: the platen layer left out of the interior density and
  coordination is a length of the cell; scaled, it stays 1/15 of the sample height on
  each side as in the references and coarse runs, and 2 particle diameters as in the
  coarse runs (the references leave out 4 of their diameters);
- ``platen_speed`` 10 -> 5 mm/s: the same strain rate (speed / height) as both, so that
  every compression stage lasts the same simulated time and the same strain lies between
  two curve samples (``output_interval``, ``max_stage_time`` and ``release_time`` are
  times and stay).

What does not scale, and why: the particle radius (it is the reference's: the control is
the reference material in a smaller cell), gravity and the time step (the brief: the
control keeps the reference's particle-scale physics; its gravity stress rho g H is halved
against the references, as it is in no coarse run, which is one of the things "what the
rule leaves" measures), and every dimensionless field (solid and pour fractions, strains,
the failure criterion, ``settle_ke``, which is relative to N m g R). Not the thickness
alone: a 25 x 150 x 300 mm cell doubles the free-standing slab's slenderness (issue 19).

Against the full references (``b_cohesive/ref-s*``) the control measures the pure
finite-size effect (same particles and law, a bed with half as many diameters each way);
against the coarse 5 mm b2 runs (``b_cohesive/r5mm-b2-s*``: K ~ R, f0 ~ R^2, the same bed
in diameters, the same strain rate) what the rule leaves: the gravity stress (the coarse
bed stands in the full 300 mm cell, twice the control's overburden rho g H, and each
coarse particle weighs 8 times as much against 4 times the adhesion: twice the Bond
number), the particle-scale rate (the same strain rate on particles twice as large: twice
the inertial number) and the time step relative to the contact time (sqrt(m / K1) is
twice as long for a coarse particle, dt is the same), and the platen law (Hertz-Mindlin,
unscaled). Section (ii) of the report gives the coarse runs' error relative to the
control, so that coarse / reference = (control / reference) x (coarse / control) splits
the study's error into the two parts. Each finished run is stored at once as
``benchmarks/results/paper/e_finite_size/<key>.h5``; a rerun skips the stored ones.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.checks import Ticker
from engine.io.store import load_run, save_run
from engine.study.judge import error_rates, judge_values
from engine.study.metrics import METRICS, metric_names, metric_values
from engine.study.plan import reference_test as study_reference
from engine.uniaxial.driver import run_uniaxial
from engine.uniaxial.measures import overburden_ratio
from engine.uniaxial.spec import UniaxialTest

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "paper" / "e_finite_size"
B_STORE = ROOT / "benchmarks" / "results" / "paper" / "b_cohesive"
SEEDS = (1, 2, 3)
#: The coarse radius whose bed the control reproduces in particle diameters [m].
COARSE_RADIUS = 5e-3
#: The coarse variant of experiment (b) the control is set against (quadratic adhesion).
COARSE_RULE = "b2"
CONFIDENCE = 0.95


def reference_test() -> UniaxialTest:
    """The 2.5 mm reference test of experiment (b) at the paper scale, as its study runs it
    (interior margin set by the study: two diameters of its largest, 5 mm, particles)."""
    from benchmarks.experiments import experiments

    return study_reference(experiments("paper")["b_cohesive"])


def control_test(
    seed: int, reference: UniaxialTest | None = None, coarse_radius: float = COARSE_RADIUS
) -> UniaxialTest:
    """The control for ``seed``: ``reference`` (default :func:`reference_test`) with its law
    and particles unchanged and every length of the cell, and the platen speed, scaled by
    R_ref / ``coarse_radius`` (module docstring)."""
    ref = reference if reference is not None else reference_test()
    s = ref.radius / coarse_radius
    return replace(
        ref,
        seed=seed,
        cell=tuple(s * c for c in ref.cell),
        interior_margin=s * ref.margin,
        platen_speed=s * ref.platen_speed,
    )


def run_key(seed: int) -> str:
    return f"control-s{seed}"


def stored(directory: Path = STORE) -> dict:
    """Key -> stored outcome (UniaxialResult or error text) of every control run."""
    return {p.stem: load_run(p) for p in sorted(Path(directory).glob("control-s*.h5"))}


def _ticker(key: str) -> Ticker:
    """A progress line of run ``key`` at most once a minute."""
    return Ticker(
        lambda pr, took: (
            f"    [{took:6.0f} s] {key}: {pr.stage}, t = {pr.time:.3f} s simulated, "
            f"{pr.steps} steps, {100 * pr.fraction:.1f} % done"
        )
    )


def run(seeds=SEEDS, threads: int = 1, directory: Path = STORE) -> None:
    """Run the control for every seed not yet stored with exactly its test; store each at
    once (a failed run is stored as its error text)."""
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    ref = reference_test()
    for seed in seeds:
        test = control_test(seed, ref)
        key = run_key(seed)
        path = Path(directory) / f"{key}.h5"
        if path.exists():
            old = load_run(path)
            if isinstance(old, str) or old.test == test:
                print(f"{key}: stored, skipped", flush=True)
                continue
            print(f"{key}: stored with other parameters, will run again", flush=True)
        print(
            f"{key}: {test.n_particles} particles, cell "
            f"{' x '.join(f'{1e3 * c:g}' for c in test.cell)} mm, "
            f"{test.thickness_diameters:g} diameters thick, platen "
            f"{1e3 * test.platen_speed:g} mm/s, {numba.get_num_threads()} thread(s)",
            flush=True,
        )
        t0 = time.perf_counter()
        try:
            outcome = run_uniaxial(test, _ticker(key))
        except Exception as e:  # stored as the run's error, as the studies do
            outcome = f"{type(e).__name__}: {e}"
        save_run(path, outcome, keep_particles=False)
        what = outcome if isinstance(outcome, str) else _line(outcome)
        print(f"  [{time.perf_counter() - t0:7.0f} s] {key} stored: {what}", flush=True)


def _line(r) -> str:
    s = r.scalars
    kind = "fails" if s["unconfined_failure"] else "hardens"
    return (
        f"{s['particles']:.0f} particles, {s['steps']:.0f} steps, "
        f"{s['wall_time']:.0f} s, {kind} at {s['unconfined_strength'] / 1e3:.2f} kPa"
    )


# ---------------------------------------------------------------------------------- report


def _b_runs(prefix: str, directory: Path) -> dict:
    out = {}
    for p in sorted(Path(directory).glob(f"{prefix}-s*.h5")):
        r = load_run(p)
        if not isinstance(r, str):
            out[p.stem] = r
    return out


def _self_weight(r) -> float:
    """Weight per area of the consolidated sample, the stress its own weight adds at the
    bottom platen [Pa] (engine.uniaxial.measures.overburden_ratio times sigma_c)."""
    return overburden_ratio(r) * r.test.consolidation_stress


def _pct(x: float) -> str:
    if not np.isfinite(x):
        return "-inf" if x < 0 else "+inf"
    return f"{100 * x:+.1f} %"


def _interval(m: dict) -> str:
    if m["interval"] is None:
        return "spread unknown"
    lo, hi = m["interval"]
    at = "" if m["level"] is None else f" (level {m['level'] + 1})"
    return f"{_pct(m['level_error'])}{at} in [{_pct(lo)}, {_pct(hi)}]"


def _summed(m: dict) -> str:
    if m.get("differs_interval") is None:
        return ""
    lo, hi = m["differs_interval"]
    return f"{_pct(m['differs_error'])} in [{_pct(lo)}, {_pct(hi)}]"


def _judge(
    values: list[dict], against: list[dict], names, cons: float, confidence: float
) -> list[dict]:
    a_e, a_d = error_rates(confidence, len(names))
    return [judge_values(n, values, against, METRICS[n].tolerance, cons, a_e, a_d) for n in names]


def _table(
    title: str, what: str, judged: list[dict], n_side: int, n_against: int, confidence: float
) -> list[str]:
    a_e, a_d = judged[0]["alpha_equivalent"], judged[0]["alpha_differs"]
    lines = [
        f"### {title}",
        "",
        f"{what} ({n_side} against {n_against} seeds; equivalence interval at "
        f"{1 - a_e:.1%} one-sided per end, worst level; differs interval of the "
        f"level-summed ratio at {1 - a_d:.1%} one-sided, Bonferroni over "
        f"{len(judged)} metrics; confidence {confidence:.0%}).",
        "",
        "| metric | mean signed error | interval (equivalence) | "
        "summed (differs) | tolerance | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for m in judged:
        lines.append(
            f"| {m['metric']} | {_pct(m['signed_error'])} | {_interval(m)} | "
            f"{_summed(m)} | ± {m['tolerance']:.0%} | {m['verdict']} |"
        )
    return [*lines, ""]


def _split(v_ctrl: list[dict], v_ref: list[dict], v_coarse: list[dict], names) -> list[str]:
    """The study's error split in two: coarse / reference = (control / reference) x
    (coarse / control), ratios of the seed means summed over levels."""

    def total(values, n):
        return float(np.mean([np.sum(v[n]) for v in values]))

    lines = [
        "### Split of the coarse runs' error",
        "",
        "Ratios of seed means (summed over levels for density and coordination): "
        "coarse / reference = finite size (control / reference) x rule's remainder "
        "(coarse / control).",
        "",
        "| metric | coarse / reference | control / reference (finite size) | "
        "coarse / control (what the rule leaves) |",
        "|---|---|---|---|",
    ]
    for n in names:
        c, r, k = total(v_ctrl, n), total(v_ref, n), total(v_coarse, n)
        lines.append(f"| {n} | {k / r:.3f} | {c / r:.3f} | {k / c:.3f} |")
    return [*lines, ""]


def control_report(
    directory: Path = STORE, b_directory: Path = B_STORE, confidence: float = CONFIDENCE
) -> str:
    """Markdown: every stored control run (failed or hardened, strength, porosity, particles,
    steps, wall time) and the control judged per verdict metric, with the engine's verdict
    functions, against (i) the references of experiment (b) (the pure finite-size effect)
    and (ii) its coarse 5 mm b2 runs (what the rule leaves); (iii), for scale, the coarse
    runs against the references (what the study's verdict on them sees). From the stored
    runs alone."""
    controls = stored(directory)
    refs = _b_runs("ref", b_directory)
    coarse = _b_runs(f"r{COARSE_RADIUS * 1e3:g}mm-{COARSE_RULE}", b_directory)
    lines = ["## Finite-size control (experiment (b), R = 5 mm)", ""]
    ok = {k: r for k, r in controls.items() if not isinstance(r, str)}
    if ok:
        t = next(iter(ok.values())).test
        lines += [
            f"The 2.5 mm reference law, unscaled, in a "
            f"{' x '.join(f'{1e3 * c:g}' for c in t.cell)} mm cell "
            f"({t.thickness_diameters:g} diameters thick), platen "
            f"{1e3 * t.platen_speed:g} mm/s, interior margin "
            f"{1e3 * t.margin:g} mm: the coarse 5 mm bed in particle diameters.",
            "",
        ]
    lines += [
        "| run | particles | thickness [d] | height [d] | steps | wall time [s] | "
        "threads | unconfined | strength [kPa] | strain at peak | consolidated "
        "porosity (interior) | loading stiffness [kPa] | unloading stiffness [kPa] | "
        "self-weight at the base [kPa] | max inertial number |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    groups = (("control", controls), ("reference", refs), (f"coarse 5 mm {COARSE_RULE}", coarse))
    for label, runs in groups:
        for k, r in runs.items():
            if isinstance(r, str):
                lines.append(f"| {k} ({label}) | failed: {r} |" + " |" * 13)
                continue
            s = r.scalars
            kind = "fails (peak)" if s["unconfined_failure"] else "hardens (fallback)"
            threads = f"{s['threads']:.0f}" if "threads" in s else "?"
            lines.append(
                f"| {k} ({label}) | {s['particles']:.0f} | {s['thickness_diameters']:.1f} | "
                f"{s['height_diameters']:.1f} | {s['steps']:.0f} | {s['wall_time']:.0f} | "
                f"{threads} | {kind} | "
                f"{s['unconfined_strength'] / 1e3:.2f} | {s['strain_at_peak']:.4f} | "
                f"{s['consolidated_porosity']:.4f} ({s['consolidated_porosity_interior']:.4f})"
                f" | {s['loading_stiffness'] / 1e3:.0f} | {s['unloading_stiffness'] / 1e3:.0f} | "
                f"{_self_weight(r) / 1e3:.2f} | {s['max_inertial_number']:.2e} |"
            )
    lines.append("")
    for label, runs in groups:
        if len(runs) > 0:
            st = [r.scalars["unconfined_strength"] for r in runs.values() if not isinstance(r, str)]
            if st:
                sd = f" ± {np.std(st, ddof=1) / 1e3:.2f}" if len(st) > 1 else ""
                lines.append(
                    f"- {label}: strength {np.mean(st) / 1e3:.2f}{sd} kPa "
                    f"(mean ± sample SD of {len(st)})"
                )
    lines.append("")
    if not ok or not refs:
        return "\n".join([*lines, "No control or reference run stored yet: nothing judged."])
    t_ref = next(iter(refs.values())).test
    cons = t_ref.consolidation_stress
    names = metric_names(t_ref.unconfined)
    v_ctrl = [metric_values(r) for r in ok.values()]
    v_ref = [metric_values(r) for r in refs.values()]
    v_coarse = [metric_values(r) for r in coarse.values()]
    lines += _table(
        "(i) control against the references: the finite-size effect",
        "Error of the control relative to the full 2.5 mm references",
        _judge(v_ctrl, v_ref, names, cons, confidence),
        len(v_ctrl),
        len(v_ref),
        confidence,
    )
    if v_coarse:
        lines += _table(
            f"(ii) coarse 5 mm {COARSE_RULE} against the control: what the rule leaves",
            f"Error of the coarse 5 mm {COARSE_RULE} runs relative to the control "
            "(same bed in diameters)",
            _judge(v_coarse, v_ctrl, names, cons, confidence),
            len(v_coarse),
            len(v_ctrl),
            confidence,
        )
        lines += _table(
            f"(iii) coarse 5 mm {COARSE_RULE} against the references, for scale",
            "The study's own comparison (its verdict on this variant), recomputed "
            "with the same functions",
            _judge(v_coarse, v_ref, names, cons, confidence),
            len(v_coarse),
            len(v_ref),
            confidence,
        )
        lines += _split(v_ctrl, v_ref, v_coarse, names)
    lines += [
        "Signed errors are (mean of the first - mean of the second) / mean of the second "
        "(per level, then averaged, for density and coordination); intervals from "
        "engine.study.judge.judge_values (ratio of geometric means, t interval on mean "
        "logs, two one-sided tests).",
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=list(SEEDS))
    ap.add_argument(
        "--threads", type=int, default=1, help="engine threads (at most NUMBA_NUM_THREADS)"
    )
    ap.add_argument(
        "--report", action="store_true", help="only print the report from the stored runs"
    )
    ap.add_argument("--store", type=Path, default=STORE, help="folder of the control runs")
    args = ap.parse_args(argv)
    if not args.report:
        run(args.seeds, args.threads, args.store)
    print(control_report(args.store))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
