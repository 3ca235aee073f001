"""Why do the cohesive samples not fail in unconfined compression? (issue 8, item 5)

    python -m benchmarks.failure_sweep            # runs what is not stored, then the report
    python -m benchmarks.failure_sweep --report   # report from the stored runs only

The cohesive reference of the reproduction (experiment (b) at the ``quick`` scale: R = 2.5 mm,
K1 = 5e3, K2 = 2.5e4 N/m, f0 = -0.8 N, platen friction 0.3, a 50 x 50 x 100 mm sample), seed
1, and one change at a time to what could keep a sample from failing:

- ``base``: as the reproduction;
- ``frictionless_platens``: platen friction 0 (end restraint, the cause of barrelling);
- ``adhesion_x4`` and ``adhesion_x0.25``: f0 = -3.2 N and -0.2 N (adhesion against the
  20 kPa consolidation);
- ``tall``: a 50 x 50 x 200 mm sample, height / width 4 instead of 2 (aspect ratio);
- ``strain_25``: the strain limit 25 % instead of 10 % (a peak beyond the limit);
- ``wide``: a 50 x 150 x 100 mm sample, the seed's cross-section of 10 x 30 diameters at the
  quick height (room for a shear band across the wide side);
- ``wide_tall``: a 50 x 150 x 200 mm sample, that cross-section and twice the quick height.

How a run is judged was fixed before any was looked at: it *fails* when the driver's failure
detector (engine.uniaxial.measures.FailureDetector: the stress falls ``failure_drop`` = 20 % below
its peak, the peak past ``failure_strain`` = 0.5 %) fires within the 10 % strain limit; otherwise it
*hardens*, and its strength is the documented fallback (the largest stress up to the limit;
``strain_25`` was added after the first five, to look past the 10 % limit, and ``wide`` after the
paper-scale references (10 x 30 x 60 diameters) were seen to fail, to tell whether their width or
their height makes the difference, and ``wide_tall`` after ``wide`` hardened, with the same
judgement). Runs are stored in ``benchmarks/results/quick/failure_sweep/<variant>.h5``; the report
(docs/FAILURE.md and docs/figures/failure_sweep.png) is recomputed from them.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import engine
from engine.io.store import load_run, save_run

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "quick" / "failure_sweep"
LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.8, mu_s=0.5, mu_r=0.001, restitution=0.4)


def variants() -> dict[str, engine.UniaxialTest]:
    base = engine.preset("quick", protocol="seed", pair_law=LAW)
    return {
        "base": base,
        "frictionless_platens": replace(base, wall_law=replace(base.wall_law, mu=0.0)),
        "adhesion_x4": replace(base, pair_law=replace(LAW, f0=-3.2)),
        "adhesion_x0.25": replace(base, pair_law=replace(LAW, f0=-0.2)),
        "tall": replace(base, cell=(0.05, 0.05, 0.2)),
        "strain_25": replace(base, max_unconfined_strain=0.25),
        "wide": replace(base, cell=(0.05, 0.15, 0.1)),
        "wide_tall": replace(base, cell=(0.05, 0.15, 0.2)),
    }


def stored(name: str, test: engine.UniaxialTest):
    """The stored outcome of variant ``name`` (a result, or the error text), or None when it
    is not stored or was stored with other parameters (it runs again)."""
    path = STORE / f"{name}.h5"
    if not path.exists():
        return None
    out = load_run(path)
    return out if isinstance(out, str) or out.test == test else None


#: The law of the main job's default study (engine.default_study: f0 = -0.4 N at 2.5 mm),
#: whose quick runs must fail at a peak (issue 39, item 4).
DEFAULT_LAW = replace(LAW, f0=-0.4)

#: The protocol the candidates run at, stated with each so that a stored candidate stays
#: itself when the defaults move: the default protocol of this change
#: (engine.uniaxial.spec.DEFAULT_PROTOCOL, docs/PROTOCOL.md).
CANDIDATE_PROTOCOL = {
    "dt": None,
    "dt_fraction": 0.4,
    "inertial_number": 5e-4,
    "max_platen_speed": 0.05,
    "strength_from": "interior",
    "pour_speed": 2.0,
}

#: Candidate cells for the quick preset, in diameters of the reference's 2.5 mm particles,
#: with the gravity [m/s^2] that sets their overburden. Chosen before any was run, from the
#: stored runs: every paper-cell run fails (10 x 30 x 60 diameters at 2.5 mm, 5 x 15 x 30 at
#: 5 mm, and the 5 mm controls, 5 x 15 x 30 at 2 g), every quick-cell one hardens (10 x 10 x 20,
#: 5 x 5 x 10, at g, 2 g or 3 g), and neither the seed's cross-section nor twice the quick
#: height alone (overburden ratio 0.12) made a quick sample fail; the failing ones share the
#: seed's slenderness (height 6 x the thinnest side) and overburden (rho_b g H = 3.5 kPa,
#: 0.18 of the consolidation stress). The candidates keep the 10-diameter thickness (the
#: 5 mm variants of the default study are then 5 diameters thick, the seed's minimum) and hold
#: the seed's overburden, raising the slenderness from the quick sample's 2 to the seed's 6.
CANDIDATES = {
    "h20_g1": ((0.05, 0.05, 0.10), 9.81),  # the quick cell at the candidate protocol
    "h30_g2": ((0.05, 0.05, 0.15), 19.62),  # slenderness 3, the seed's overburden
    "h40_g1.5": ((0.05, 0.05, 0.20), 14.715),  # slenderness 4, the seed's overburden
    "h60_g1": ((0.05, 0.05, 0.30), 9.81),  # slenderness 6, the seed's overburden
}


def candidate(name: str, seed: int, law=None) -> engine.UniaxialTest:
    """Candidate ``name`` of :data:`CANDIDATES` at packing ``seed`` with the default study's
    law (or ``law``) at :data:`CANDIDATE_PROTOCOL`."""
    cell, g = CANDIDATES[name]
    return engine.preset(
        "quick",
        protocol="seed",
        **CANDIDATE_PROTOCOL,
        cell=cell,
        gravity=g,
        pair_law=law or DEFAULT_LAW,
        seed=seed,
    )


def _run_and_store(key: str, test: engine.UniaxialTest) -> tuple[dict, float]:
    """Run ``test`` and store it as ``STORE/<key>.h5`` (an exception is stored as the run's
    error, so that the other runs go on); returns the run's scalars (empty for an error)
    and the wall time of the run [s]."""
    t0 = time.perf_counter()
    try:
        res = engine.run_uniaxial(test)
    except Exception as e:  # stored as the run's error, the others go on
        res = f"{type(e).__name__}: {e}"
    save_run(STORE / f"{key}.h5", res, keep_particles=False)
    return (res.scalars if not isinstance(res, str) else {}), time.perf_counter() - t0


def run_candidates(names, seeds) -> None:
    """Run (one at a time) and store each candidate run not stored yet:
    ``STORE/<name>-s<seed>.h5``."""
    for seed in seeds:
        for name in names:
            key = f"{name}-s{seed}"
            test = candidate(name, seed)
            if not isinstance(stored(key, test) or "", str):
                print(f"{key}: stored")
                continue
            s, seconds = _run_and_store(key, test)
            print(
                f"{key}: {seconds:.0f} s, failed {s.get('unconfined_failure')}, "
                f"strength {s.get('unconfined_strength', float('nan')):.0f} Pa at "
                f"{100 * s.get('strain_at_peak', float('nan')):.1f} %, "
                f"{s.get('particle_steps', float('nan')):.3g} particle-steps",
                flush=True,
            )


def candidate_rows() -> list[str]:
    """The candidates' table from the stored runs (each judged by its stored
    ``unconfined_failure``: the documented failure of its strength curve, the interior
    virial stress at the candidate protocol)."""
    rows = [
        "| candidate | cell [diameters] | gravity [m/s^2] | overburden rho_b g H [kPa] | "
        "seeds | failed at a peak | strength [kPa] | strain at peak [%] | particles | "
        "particle-steps | wall time [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    d = 2 * 2.5e-3
    for name, (cell, g) in CANDIDATES.items():
        runs = []
        for path in sorted(STORE.glob(f"{name}-s*.h5")):
            seed = int(path.stem.rsplit("-s", 1)[1])
            r = stored(path.stem, candidate(name, seed))
            if r is not None and not isinstance(r, str):
                runs.append(r)
        dims = " x ".join(f"{c / d:.0f}" for c in cell)
        over = 2000 * 0.6 * g * cell[2] / 1e3
        if not runs:
            rows.append(f"| {name} | {dims} | {g:g} | {over:.2f} | 0 | - | - | - | - | - | - |")
            continue
        s = [r.scalars for r in runs]
        fails = sum(x["unconfined_failure"] == 1.0 for x in s)
        rows.append(
            f"| {name} | {dims} | {g:g} | {over:.2f} | {len(runs)} | {fails} of {len(runs)} | "
            f"{np.mean([x['unconfined_strength'] for x in s]) / 1e3:.2f} | "
            f"{100 * np.mean([x['strain_at_peak'] for x in s]):.1f} | "
            f"{s[0]['particles']:.0f} | {np.mean([x['particle_steps'] for x in s]):.3g} | "
            f"{np.mean([x['wall_time'] for x in s]):.0f} |"
        )
    return rows


#: Reference seeds of the main job's reference run here (at least 90 % must fail), and the
#: seeds of its paper-rule coarse runs (whose failures the main job's verdicts need too).
MAIN_REFERENCE_SEEDS = tuple(range(1, 11))
MAIN_COARSE_SEEDS = (1, 2, 3)


def main_job_runs() -> dict[str, engine.UniaxialTest]:
    """The main job's runs (engine.default_study() planned by engine.plan, its reference at
    more seeds): key ``main-<run key>`` -> test. Stored runs count only while the default
    study plans the same tests."""
    spec = engine.default_study()
    runs = {p.key: p.test for p in engine.plan(spec).runs}
    ref = runs["ref-s1"]
    out = {f"main-ref-s{n}": replace(ref, seed=n) for n in MAIN_REFERENCE_SEEDS}
    for r in spec.coarse_radii:
        stem = f"r{1e3 * r:g}mm-paper"
        for n in MAIN_COARSE_SEEDS:
            key = f"{stem}-s{n}"
            base = runs.get(key) or replace(runs[f"{stem}-s1"], seed=n)
            out[f"main-{key}"] = base
    return out


def run_main_job(keys=None) -> None:
    """Run (one at a time) and store the main job's runs not stored yet."""
    for key, test in main_job_runs().items():
        if keys and key not in keys:
            continue
        if not isinstance(stored(key, test) or "", str):
            continue
        s, seconds = _run_and_store(key, test)
        print(
            f"{key}: {seconds:.0f} s, failed {s.get('unconfined_failure')}, "
            f"{s.get('particle_steps', float('nan')):.3g} particle-steps",
            flush=True,
        )


def main_job_rows() -> list[str]:
    """The main job's runs stored so far: per kind, how many failed at a peak, their
    strength and cost."""
    rows = [
        "| runs | stored | failed at a peak | strength [kPa] (interior; platen) | "
        "self-weight stress [kPa] | particles | steps | particle-steps | wall time [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[str, list] = {}
    for key, test in main_job_runs().items():
        r = stored(key, test)
        stem = key.rsplit("-s", 1)[0]
        groups.setdefault(stem, [])
        if r is not None and not isinstance(r, str):
            groups[stem].append(r)
    for stem, runs in groups.items():
        if not runs:
            rows.append(f"| {stem} | 0 | - | - | - | - | - | - | - |")
            continue
        sc = [r.scalars for r in runs]

        def mean(k, sc=sc):
            return float(np.mean([x[k] for x in sc]))

        fails = sum(x["unconfined_failure"] == 1.0 for x in sc)
        rows.append(
            f"| {stem} | {len(runs)} | {fails} of {len(runs)} | "
            f"{mean('unconfined_strength') / 1e3:.2f}; "
            f"{mean('unconfined_strength_platen') / 1e3:.2f} | "
            f"{mean('self_weight_stress') / 1e3:.2f} | {mean('particles'):.0f} | "
            f"{mean('steps'):,.0f} | {mean('particle_steps'):.3g} | {mean('wall_time'):.0f} |"
        )
    return rows


def failing_section() -> list[str]:
    """The candidates of the quick preset and the main job's runs (issue 39, item 4), with
    what they say (computed from the stored runs, not written)."""
    out = [
        "## The sample that fails (issue 39)",
        "",
        "Every stored run in the seed's cell failed at a peak (10 x 30 x 60 diameters at "
        "2.5 mm, 5 x 15 x 30 at 5 mm, the 5 mm controls at 5 x 15 x 30 diameters and 2 g), "
        "every one in the quick cell hardened (10 x 10 x 20, 5 x 5 x 10; at g, 2 g or 3 g), "
        "and above neither the seed's cross-section nor twice the quick height (overburden "
        "0.12 of the consolidation stress) made a quick sample fail. The failing ones share "
        "the seed's slenderness (height six times the thinnest side) and its overburden "
        "(rho_b g H = 3.5 kPa, 0.18 of the consolidation stress). The candidates keep the "
        "10-diameter thickness (the 5 mm runs of the default study are then 5 diameters "
        "thick, the seed's minimum), hold the seed's overburden and raise the slenderness "
        "from 2 to 6; the law is the default study's (f0 = -0.4 N), the protocol the default "
        "(docs/PROTOCOL.md):",
        "",
        *candidate_rows(),
        "",
        *_candidate_reading(),
        "",
        "### The main job's runs at the quick preset",
        "",
        "`engine.default_study()` planned by `engine.plan` (its reference at ten seeds, its "
        "paper-rule coarse runs at three), each judged by its stored `unconfined_failure` "
        "(the documented failure of the interior virial stress, docs/PHYSICS.md section 7.3):",
        "",
        *main_job_rows(),
        "",
        *_main_job_reading(),
        "",
    ]
    return out


def _candidate_runs() -> dict[str, list]:
    out = {}
    for name in CANDIDATES:
        runs = []
        for path in sorted(STORE.glob(f"{name}-s*.h5")):
            r = stored(path.stem, candidate(name, int(path.stem.rsplit("-s", 1)[1])))
            if r is not None and not isinstance(r, str):
                runs.append(r)
        out[name] = runs
    return out


def _candidate_reading() -> list[str]:
    runs = {k: v for k, v in _candidate_runs().items() if v}
    if not runs:
        return ["No candidate stored yet."]

    def all_fail(rs):
        return all(r.scalars["unconfined_failure"] == 1.0 for r in rs)

    failing = [k for k, rs in runs.items() if all_fail(rs)]
    hardening = [k for k, rs in runs.items() if not all_fail(rs)]
    text = (
        "Failing at a peak in every stored seed: "
        + (", ".join(f"`{k}`" for k in failing) or "none")
        + "; hardening in at least one: "
        + (", ".join(f"`{k}`" for k in hardening) or "none")
        + "."
    )
    if failing:
        cheapest = min(failing, key=lambda k: runs[k][0].scalars["particles"])
        text += f" The cheapest failing candidate: `{cheapest}`."
    return [text]


def _main_job_reading() -> list[str]:
    refs, coarse = [], []
    for key, test in main_job_runs().items():
        r = stored(key, test)
        if r is None or isinstance(r, str):
            continue
        (refs if key.startswith("main-ref") else coarse).append(r)
    if not refs:
        return ["No main-job run stored yet."]
    n = sum(r.scalars["unconfined_failure"] == 1.0 for r in refs)
    m = sum(r.scalars["unconfined_failure"] == 1.0 for r in coarse)
    cost = np.mean([r.scalars["particle_steps"] for r in refs])
    wall = np.mean([r.scalars["wall_time"] for r in refs])
    return [
        f"{n} of {len(refs)} references ({100 * n / len(refs):.0f} %) and {m} of "
        f"{len(coarse)} paper-rule coarse runs fail at a peak. A reference costs "
        f"{cost:.3g} particle-steps ({wall:.0f} s of wall time on one engine thread, on a "
        "2-core machine shared with other runs)."
    ]


def run(names) -> None:
    tests = variants()
    for name in names:
        path = STORE / f"{name}.h5"
        if not isinstance(stored(name, tests[name]) or "", str):
            print(f"{name}: stored")
            continue
        t0 = time.perf_counter()
        try:
            res = engine.run_uniaxial(tests[name])
        except Exception as e:  # stored as the run's error, the others go on
            res = f"{type(e).__name__}: {e}"
        save_run(path, res, keep_particles=False)
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)


def report() -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tests = variants()
    rows = [
        "| variant | particles | failed | peak [kPa] at strain [%] | stress at the limit "
        "[kPa] | strength [kPa] |",
        "|---|---|---|---|---|---|",
    ]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    missing = []
    strengths: dict[str, float] = {}
    fails: dict[str, bool] = {}
    for name, test in tests.items():
        res = stored(name, test)
        if res is None:
            missing.append(name)
            continue
        if isinstance(res, str):
            rows.append(f"| {name} | - | error: {res} | - | - | - |")
            continue
        strain, stress, k = _peak(res)
        s = res.scalars
        rows.append(
            f"| {name} | {s['particles']:.0f} | {_outcome(s)} | "
            f"{stress[k] / 1e3:.2f} at {100 * strain[k]:.1f} | "
            f"{stress[-1] / 1e3:.2f} | {s['unconfined_strength'] / 1e3:.2f} |"
        )
        ax.plot(100 * strain, stress / 1e3, label=name)
        strengths[name] = s["unconfined_strength"]
        fails[name] = bool(s["unconfined_failure"])
    reading = _reading(strengths, fails)
    paper_rows = _paper_references(ax)
    ax.set_xlabel("unconfined strain [%]")
    ax.set_ylabel("platen stress [kPa]")
    ax.set_title("Unconfined compression after consolidation to 20 kPa")
    ax.legend()
    fig.tight_layout()
    fig_path = ROOT / "docs" / "figures" / "failure_sweep.png"
    fig_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(fig_path, dpi=110)
    plt.close(fig)
    text = [
        "# Why the cohesive samples hardened, and the quick sample that fails",
        "",
        "Generated by `python -m benchmarks.failure_sweep` from the runs stored in "
        "`benchmarks/results/quick/failure_sweep/` (how a run is judged: the module's "
        "docstring, fixed before any run was looked at).",
        "",
        "## The seed's quick sample hardens (issue 8)",
        "",
        "The quick preset as the seed's experiments were reproduced "
        '(`preset("quick", protocol="seed")`: 50 x 50 x 100 mm, the seed\'s protocol), '
        "the cohesive law of experiment (b), one change at a time:",
        "",
        *([f"**Incomplete**: not stored yet: {', '.join(missing)}.", ""] if missing else []),
        *rows,
        "",
        *reading,
        "",
        *paper_rows,
        "![unconfined curves](figures/failure_sweep.png)",
        "",
        *failing_section(),
    ]
    path = ROOT / "docs" / "FAILURE.md"
    path.write_text("\n".join(text) + "\n")
    return path


def _peak(res) -> tuple[np.ndarray, np.ndarray, int]:
    """Strain, platen stress [Pa] of the unconfined stage and the index of the peak."""
    c = res.stages["unconfined"].curves
    return c["strain"], c["stress_top"], int(np.argmax(c["stress_top"]))


def _outcome(scalars: dict) -> str:
    return "yes" if scalars["unconfined_failure"] else "no (hardens)"


PAPER_REFERENCES = ROOT / "benchmarks" / "results" / "paper" / "b_cohesive"


def _paper_references(ax) -> list[str]:
    """The same judgement on the cohesive references of the paper-scale reproduction
    (``python -m benchmarks.reproduce --scale paper``, experiment (b): the same law in the
    seed's filled 50 x 150 x 300 mm cuboid) when they are stored; their curves join the
    figure (dashed)."""
    paths = sorted(PAPER_REFERENCES.glob("ref-s*.h5"))
    if not paths:
        return []
    rows = [
        "At the seed's scale (the cohesive references of experiment (b) of "
        "`python -m benchmarks.reproduce --scale paper`, the same law and platens in the "
        "seed's filled 50 x 150 x 300 mm cuboid; the same failure detector):",
        "",
        "| reference | particles | cross-section x height [diameters] | failed | "
        "peak [kPa] at strain [%] | strength [kPa] |",
        "|---|---|---|---|---|---|",
    ]
    for path in paths:
        res = load_run(path)
        s = res.scalars
        strain, stress, k = _peak(res)
        cell = np.asarray(res.test.cell) / (2 * res.test.radius)
        rows.append(
            f"| {path.stem} | {s['particles']:.0f} | {cell[0]:.0f} x {cell[1]:.0f} x "
            f"{s['height_diameters']:.0f} | {_outcome(s)} | "
            f"{stress[k] / 1e3:.2f} at {100 * strain[k]:.1f} | "
            f"{s['unconfined_strength'] / 1e3:.2f} |"
        )
        ax.plot(100 * strain, stress / 1e3, "--", label=f"paper {path.stem}")
    rows += ["", _width_or_height(), ""]
    return rows


def _width_or_height() -> str:
    """What the stored ``tall``, ``wide`` and ``wide_tall`` variants say about the seed's
    sample failing where the quick one hardens (computed, not written)."""
    tests = variants()
    names = ("tall", "wide", "wide_tall")
    out = {n: stored(n, tests[n]) for n in names}
    fails = {
        n: bool(r.scalars["unconfined_failure"])
        for n, r in out.items()
        if r is not None and not isinstance(r, str)
    }
    d = 2 * tests["base"].radius

    def dims(n: str) -> str:
        c = tests[n].cell
        return f"`{n}` ({c[0] / d:.0f} x {c[1] / d:.0f} x {c[2] / d:.0f} diameters)"

    base = tests["base"].cell
    paper = engine.preset("paper").cell
    text = (
        f"The quick sample is {base[0] / d:.0f} x {base[1] / d:.0f} x {base[2] / d:.0f} "
        f"diameters; the paper preset differs from it in the cell alone "
        f"({paper[0] / d:.0f} x {paper[1] / d:.0f} x {paper[2] / d:.0f}). "
    )
    missing = [n for n in names if n not in fails]
    if missing:
        return text + f"Not stored yet: {', '.join(missing)}."
    failing = [dims(n) for n in names if fails[n]]
    if failing:
        return (
            text
            + "Failing within the limit: "
            + ", ".join(failing)
            + "; hardening: "
            + (", ".join(dims(n) for n in names if not fails[n]) or "none")
            + "."
        )
    tallest = max(tests[n].cell[2] for n in names)
    return text + (
        "None of " + ", ".join(dims(n) for n in names) + " fails. So the seed's cross-section and "
        "a doubled height, alone or together, do not make a sample fail; what is left is the "
        f"height itself: the seed's sample is {paper[2] / d:.0f} diameters tall, "
        f"{paper[2] / paper[0]:.0f} times its {paper[0] / d:.0f}-diameter thickness, against "
        f"at most {tallest / d:.0f} ({tallest / base[0]:.0f} times) here. The quick "
        "cross-section at the seed's height: the next section."
    )


def _reading(strengths: dict[str, float], fails: dict[str, bool]) -> list[str]:
    """What the stored runs say, each change against ``base`` (computed, not written)."""
    if "base" not in strengths:
        return []
    base = strengths["base"]
    out = [
        "What changes the outcome (strength: the peak, or the largest stress up to the "
        "limit; against `base`):",
        "",
    ]
    what = {
        "frictionless_platens": "platen friction 0.3 -> 0",
        "tall": "height / width 2 -> 4",
        "adhesion_x4": "adhesion f0 x 4",
        "adhesion_x0.25": "adhesion f0 x 0.25",
        "strain_25": "strain limit 10 % -> 25 %",
        "wide": "cross-section 10 x 10 -> 10 x 30 diameters",
        "wide_tall": "cross-section 10 x 30 and height / width 2 -> 4",
    }
    for name, text in what.items():
        if name in strengths:
            out.append(
                f"- {text}: strength x {strengths[name] / base:.2f}, "
                f"{'fails' if fails[name] else 'hardens'}."
            )
    n = sum(fails.values())
    out += ["", f"{n} of {len(fails)} samples fail within the strain limit."]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", action="store_true", help="only the report from stored runs")
    ap.add_argument("--only", nargs="*", choices=list(variants()), help="variants to run")
    ap.add_argument(
        "--candidates", nargs="*", choices=list(CANDIDATES), help="quick-preset candidates to run"
    )
    ap.add_argument("--seeds", nargs="*", type=int, default=[1, 2, 3], help="their seeds")
    ap.add_argument(
        "--main-job", nargs="*", help="the main job's runs (main-<key>; none named: all)"
    )
    args = ap.parse_args(argv)
    if args.main_job is not None and not args.report:
        run_main_job(args.main_job)
    elif args.candidates is not None and not args.report:
        run_candidates(args.candidates or list(CANDIDATES), args.seeds)
    elif not args.report:
        run(args.only or list(variants()))
    print(f"wrote {report()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
