"""The run protocol: a time step from the contact time and quasi-static loading at a stated
inertial number, measured against the seed's (issue 40, items 1, 2 and 4).

    python -m benchmarks.protocol fill      # the fill: steps to settle, blow-ups (paper scale)
    python -m benchmarks.protocol paper     # halving checks and the benchmark (hours; resumable)
    python -m benchmarks.protocol --report  # docs/PROTOCOL.md from the stored runs only

Every run is stored at once as ``benchmarks/results/paper/protocol/<sample>-<tag>-s<seed>.h5``
(:mod:`engine.io.store`; the fill cases as JSON in ``fill/``), one at a time on one engine
thread, with a checkpoint beside it (``.checkpoints/``, not tracked) so that a run cut off
resumes bit for bit; a rerun makes only what is not stored (a stored run made with another
test is made again). ``paper --only <sample>-<tag>-s<seed> ...`` runs a share of it
(``ref-default-s1``, ``ref-half-s2``, ``b2-I5e-4-f0.4-s3``, ``b2-seed-s4``); ``--commit``
commits each run it stores. The report recomputes everything from the stored runs.

What is measured, and why each candidate (stated before any was run):

- **The fill** (``fill``): the fill stage alone at the paper scale, free fall from the pour
  column (3.4 m/s at the platen) against the capped pour at 1 m/s (a free fall from 5 cm, the
  capped (b)'s) and 2 m/s (from 20 cm): steps to settle and whether it blows up, on the
  reference law and on experiment (b)'s b = 3 law at 5 mm (f0 = -6.4 N against K1 = 1e4 N/m,
  the law whose free-fall fill blew up on two seeds). A capped pour lasts at least H_pour /
  v_cap but lowers the impact speed that sets the platen Hertz limit of the time step, for
  the whole run (critical time ~ v^-1/5).
- **The time step** (``paper``, on the 5 mm b = 2 run): ``dt_fraction`` 0.4 against 0.2 of
  the critical time of the stiffest contact (the damped-oscillator limit
  2/w (sqrt(1 + z^2) - z) of the platen Hertz contact at the impact speed, or of the pair
  unloading stiffness K2). A contact lasts
  pi / w, 1.57 critical times: at a fraction f it is resolved by 1.57 / f steps (3.9 at 0.4,
  7.9 at 0.2, 15.7 at 0.1), and velocity Verlet's frequency error is (w dt)^2 / 24 = f^2 / 6
  (2.7 % at 0.4, 0.7 % at 0.2). A quasi-static bulk property depends on the contact forces,
  which the integrator reproduces exactly at rest, so the fraction should matter only through
  collisions (the fill's packing: the density); 0.2 is about the seed's dt = 1e-5 s
  (0.18 of the quick cell's critical time, 0.20 of the paper cell's). The default is the
  largest fraction whose halving leaves every verdict metric equivalent.
- **The inertial number** (``paper``, on the 5 mm run, then the reference): I* = 1e-3, the
  upper end of the quasi-static regime (GDR MiDi 2004; da Cruz et al. 2005: the friction of
  a sheared bed departs from its static value by (mu_2 - mu_s) I / I_0, about 0.1 % at I =
  1e-3), against 5e-4 and 2.5e-4; the seed held 5-9e-5 at the paper scale and up to 8e-4 at
  the quick scale (by the recorded definition). The default is the largest I* whose halving
  leaves every metric equivalent on samples that fail. The platen's bound, first a fixed 0.1
  m/s, became 100 I* m/s (:data:`CANDIDATES`) after the first 5 mm runs showed the unloading
  stiffness following the platen's speed rather than I*: a bound fixed in m/s would have
  left the reference's unloading at 0.1 m/s whatever I*, and no halving of I* would have
  halved it.
- **The benchmark** (``paper``): the seed's protocol (its stored cohesive references of
  experiment (b) and its 5 mm b = 2 runs, and one more seed of the latter) against the new
  default on the same tests (3 seeds each), each metric judged by the verdict rule of a
  study's protocol check (engine.study.judge.judge_protocol: the study's tolerances and
  confidence, paired by seed where that pays), and the
  default against its halved inertial number on the references (the paper-scale check of
  I*). The strength of the seed comparison is the top platen's on both sides (the seed's runs
  have no interior curve); the interior strength is reported beside it.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import engine
from benchmarks.checks import run_and_store
from benchmarks.report import CELL_WORDS
from engine.io.store import load_run
from engine.study.metrics import metric_names, metric_values
from engine.uniaxial.measures import failed_by_curve

ROOT = Path(__file__).resolve().parent.parent
STORE = {s: ROOT / "benchmarks" / "results" / s / "protocol" for s in ("quick", "paper")}
FILL_STORE = STORE["paper"] / "fill"
B_STORE = ROOT / "benchmarks" / "results" / "paper" / "b_cohesive"
REPORT = ROOT / "docs" / "PROTOCOL.md"
SEEDS = (1, 2, 3)
#: Wall time between two checkpoints of a run in flight [s].
CHECKPOINT_INTERVAL = 300.0


def b_study() -> engine.StudySpec:
    from benchmarks.experiments import experiments

    return experiments("paper")["b_cohesive"]


def b_test(key: str) -> engine.UniaxialTest:
    """The planned test of run ``key`` of experiment (b) at the paper scale (the seed's
    protocol), with its seed taken from the key for seeds the plan does not hold."""
    from engine.study.plan import plan

    runs = {p.key: p.test for p in plan(b_study()).runs}
    if key in runs:
        return runs[key]
    stem, seed = key.rsplit("-s", 1)
    base = next(t for k, t in runs.items() if k.rsplit("-s", 1)[0] == stem)
    return replace(base, seed=int(seed))


def protocol(
    inertial_number: float | None, dt_fraction: float, max_platen_speed: float = 0.1, **kw
) -> dict:
    """The fields of a protocol at ``inertial_number``, ``dt_fraction`` and
    ``max_platen_speed`` [m/s] (the strength from the interior virial stress; the rest as
    given)."""
    return {
        "dt": None,
        "dt_fraction": dt_fraction,
        "inertial_number": inertial_number,
        "max_platen_speed": max_platen_speed,
        "strength_from": "interior",
        **kw,
    }


# ---------------------------------------------------------------------------- the fill
#: Fill cases: name -> (the test's run key in experiment (b), pour speed [m/s] or None): the
#: reference's seed 1 and the b = 3 law's seed 1 at 5 mm in the three pours, and the 2 m/s
#: pour on the other b = 3 seeds, those whose free fall blew up at the seed's protocol
#: (r3.75mm-b3-s1, r5mm-b3-s1) or were left out of the free-fall study (s2, s4).
_POURS = {"free": None, "cap1": 1.0, "cap2": 2.0}
FILLS = {
    f"{key}-{name}": (key, _POURS[name])
    for key, names in (
        ("ref-s1", ("free", "cap1", "cap2")),
        ("r5mm-b3-s1", ("free", "cap1", "cap2")),
        ("r5mm-b3-s2", ("cap2",)),
        ("r5mm-b3-s4", ("cap2",)),
        ("r3.75mm-b3-s1", ("free", "cap2")),
    )
    for name in names
}
#: The time step of the fill cases: the fraction of each case's own critical time.
FILL_DT_FRACTION = 0.4


def fill_test(name: str) -> engine.UniaxialTest:
    key, v = FILLS[name]
    return replace(b_test(key), **protocol(5e-4, FILL_DT_FRACTION, pour_speed=v))


def run_fill(name: str) -> dict:
    """The fill stage of case ``name`` alone: steps, simulated and wall time, whether it
    settled or blew up, and the settled bed's whole-sample porosity."""
    from engine.uniaxial.driver import _Driver

    test = fill_test(name)
    out = {"case": name, "test": test.to_dict(), "particles": test.n_particles}
    t0 = time.perf_counter()
    d = _Driver(test, None)
    out["dt"], out["dt_critical"] = d.sim.dt, d.time_step.critical
    try:
        d.begin("fill")
        d.loop()
        d.end("fill")
        c = d.stages["fill"].curves
        out.update(
            steps=int(d.sim.steps),
            time=float(d.sim.time),
            bed_top=d.bed_top(),
            porosity=1.0 - d.solid_volume / (d.area * d.bed_top()),
            max_kinetic_energy=float(np.max(c["kinetic_energy"])),
            error=None,
        )
    except Exception as e:  # a blow-up is the measurement
        out.update(steps=int(d.sim.steps), time=float(d.sim.time), error=f"{type(e).__name__}: {e}")
    out["wall_time"] = time.perf_counter() - t0 - d.setup_time
    return out


def fills(names=None) -> None:
    FILL_STORE.mkdir(parents=True, exist_ok=True)
    for name in names or FILLS:
        path = FILL_STORE / f"{name}.json"
        if path.exists() and json.loads(path.read_text())["test"] == fill_test(name).to_dict():
            continue
        out = run_fill(name)
        path.write_text(json.dumps(out, indent=1) + "\n")
        print(f"{name}: {out['steps']} steps, {out['wall_time']:.0f} s, {out['error']}", flush=True)


# ---------------------------------------------------------------------------- groups of runs
#: The capped pour of every new-protocol run [m/s]: 2 m/s, of the fill's candidates the one
#: that settles in about the fewest steps (25,806 against 24,720 at 1 m/s and 41,820 in free
#: fall, the reference's seed 1) and leaves the free fall's bed (porosity 0.457 against
#: 0.458; 1 m/s leaves 0.474, the capped (b)'s looser bed, whose loading stiffness is 21 %
#: below the free fall's at the seed's protocol): see the fill table of docs/PROTOCOL.md.
POUR = 2.0
#: Candidate protocols: tag -> (I*, dt_fraction, max_platen_speed [m/s]). The platen's bound is
#: 100 I* m/s: the speed at which the seed's coarsest bed (5 mm, 30 diameters tall) holds I*
#: at the consolidation stress, I* (h / d) sqrt(sigma_c / rho) = 95 I* m/s; a taller bed of
#: finer grains would move faster at the same I* (v ~ h / d), while its elastic response
#: (the unloading branch) lags the platen by v / c, c the bed's wave speed, which does not
#: grow with h / d. Halving I* halves the bound, so that a halved protocol is slower in every
#: stage (engine.uniaxial.spec.halved_protocol). The halving checks run on experiment (b)'s
#: 5 mm b = 2 coarse run at the paper scale (2,578 particles in the seed's cell, 5 x 15 x 30
#: diameters: every one of its seed-protocol runs failed at a peak), the cheapest failing
#: sample of the paper scale; the reference (2.5 mm) checks the chosen I* (``half``).
CANDIDATES = {
    "I1e-3-f0.4": (1e-3, 0.4, 0.1),
    "I1e-3-f0.2": (1e-3, 0.2, 0.1),
    "I5e-4-f0.4": (5e-4, 0.4, 0.05),
    "I5e-4-f0.2": (5e-4, 0.2, 0.05),
    "I2.5e-4-f0.4": (2.5e-4, 0.4, 0.025),
}
#: The halving checks: (reference tag, halved tag, what is halved), the first of a pair the
#: reference of its verdict.
CHECKS = (
    ("I1e-3-f0.4", "I1e-3-f0.2", "dt halved at I* = 1e-3"),
    ("I1e-3-f0.4", "I5e-4-f0.4", "I* halved from 1e-3"),
    ("I5e-4-f0.4", "I5e-4-f0.2", "dt halved at I* = 5e-4"),
    ("I5e-4-f0.4", "I2.5e-4-f0.4", "I* halved from 5e-4"),
)
#: The samples: name -> experiment (b)'s run key stem (its test at the paper scale).
SAMPLES = {
    "ref": "ref",
    "b2": "r5mm-b2",
    "b2_375": "r3.75mm-b2",
    # the controls: the reference law at the coarse radius (docs/PHYSICS.md section 7.4)
    "ctl": "ctl-r5mm",
    "ctl_375": "ctl-r3.75mm",
}


def tag_of(t: engine.UniaxialTest) -> str:
    """The tag of a test's protocol: ``seed`` for the seed's, else I* and dt fraction (and
    the pour, where it is not :data:`POUR`)."""
    if t.inertial_number is None and t.dt is not None:
        return "seed"
    out = next(
        (
            k
            for k, v in CANDIDATES.items()
            if v == (t.inertial_number, t.dt_fraction, t.max_platen_speed)
        ),
        f"I{t.inertial_number:.3g}-f{t.dt_fraction:g}-v{t.max_platen_speed:g}",
    )
    return out if t.pour_speed == POUR else f"{out}-pour{t.pour_speed}"


def paper_test(sample: str, tag: str, seed: int) -> engine.UniaxialTest:
    """Experiment (b)'s test of ``sample`` at packing ``seed`` with protocol ``tag``
    (``seed``: the seed's, as stored in experiment (b); ``default``: the engine's defaults
    of a new test; else a :data:`CANDIDATES` tag)."""
    base = b_test(f"{SAMPLES[sample]}-s{seed}")
    if tag == "seed":
        return base
    if tag == "default":
        t = engine.UniaxialTest()
        keys = ("dt", "dt_fraction", "inertial_number", "max_platen_speed", "strength_from")
        return replace(base, **{k: getattr(t, k) for k in keys}, pour_speed=t.pour_speed)
    i_star, f, v = CANDIDATES[tag]
    return replace(base, **protocol(i_star, f, v, pour_speed=POUR))


def run_path(sample: str, tag: str, seed: int) -> Path:
    """Where a run is stored: the seed protocol's in experiment (b)'s store when it holds
    the run, else ``paper/protocol/<sample>-<tag>-s<seed>.h5`` (the default's under its
    candidate tag: one run, one file)."""
    if tag == "seed":
        p = B_STORE / f"{SAMPLES[sample]}-s{seed}.h5"
        if p.exists():
            return p
    if tag == "default":
        tag = tag_of(paper_test(sample, "default", seed))
    return STORE["paper"] / f"{sample}-{tag}-s{seed}.h5"


#: What the ``paper`` part runs, in order: the checks on the 5 mm sample first (they choose
#: the default), then the benchmark: the reference at the default and at its halved I*, the
#: 5 mm sample's third seed-protocol seed.
CHECK_SEEDS = (1, 2, 3, 4, 5, 6, 7, 8)
BENCHMARK = (
    [("b2", tag, s) for s in CHECK_SEEDS for tag in ("I5e-4-f0.4", "I5e-4-f0.2", "I2.5e-4-f0.4")]
    + [("b2", tag, s) for s in CHECK_SEEDS for tag in ("I1e-3-f0.4", "I1e-3-f0.2")]
    + [("ref", "default", s) for s in (1, 2, 3)]
    + [("ref", "half", s) for s in (1, 2, 3)]
    + [("b2", "seed", 4)]
    + [("b2_375", "default", s) for s in (1, 2, 3, 4, 5)]
    # the controls of the rule's runs, seed for seed (paired by packing)
    + [("ctl", "default", s) for s in CHECK_SEEDS]
    + [("ctl_375", "default", s) for s in (1, 2, 3, 4, 5)]
)


def half_test(sample: str, seed: int) -> engine.UniaxialTest:
    """The default at half its inertial number and platen bound (dt and all else equal)."""
    t = paper_test(sample, "default", seed)
    return replace(
        t, inertial_number=t.inertial_number / 2, max_platen_speed=t.max_platen_speed / 2
    )


def _stored(path: Path, test: engine.UniaxialTest):
    if not path.exists():
        return None
    out = load_run(path)
    return out if isinstance(out, str) or out.test == test else None


def job(sample: str, tag: str, seed: int) -> tuple[engine.UniaxialTest, Path]:
    if tag == "half":
        t = half_test(sample, seed)
        return t, STORE["paper"] / f"{sample}-{tag_of(t)}-s{seed}.h5"
    return paper_test(sample, tag, seed), run_path(sample, tag, seed)


def run_paper(jobs, commit: bool = False) -> None:
    STORE["paper"].mkdir(parents=True, exist_ok=True)
    for sample, tag, seed in jobs:
        test, path = job(sample, tag, seed)
        if _stored(path, test) is not None:
            continue
        print(time.strftime("%H:%M"), "running", path.stem, flush=True)
        print(
            "  stored",
            run_and_store(test, path, "Protocol benchmark", commit, CHECKPOINT_INTERVAL),
            flush=True,
        )


# ---------------------------------------------------------------------------- judging
def platen_view(result):
    """``result`` with its strength and failure read from the top platen's stress (the
    seed's estimator): the seed's runs have no interior curve, so a comparison with them
    reads both sides so."""
    s = dict(result.scalars)
    u = result.stages["unconfined"].curves
    s["unconfined_strength"] = s.get("unconfined_strength_platen", s["unconfined_strength"])
    failed = failed_by_curve(u["strain"], u["stress_top"], result.test.failure_strain)
    if result.test.strength_from == "platen":
        failed = failed or s["unconfined_failure"] == 1.0
    s["unconfined_failure"] = 1.0 if failed else 0.0
    return replace(result, scalars=s)


def load_group(sample: str, tag: str, seeds) -> list:
    """Stored runs of ``sample`` at protocol ``tag`` (``seed``, ``default``, ``half`` or a
    candidate) for ``seeds`` that exist and are made with the planned test (failed runs
    left out)."""
    out = []
    for seed in seeds:
        test, path = job(sample, tag, seed)
        r = _stored(path, test)
        if r is not None and not isinstance(r, str):
            out.append(r)
    return out


def judge(ref_runs: list, runs: list, name: str, platen: bool = False) -> dict:
    """``runs`` against ``ref_runs`` by the verdict rule of a study's protocol check
    (engine.study.judge.judge_protocol: every metric at the study's tolerances and
    confidence, paired by packing seed where that pays, docs/PHYSICS.md section 7.6), the
    reference's own metric values on its side; with ``platen`` both read their strength
    from the top platen."""
    from engine.study.judge import judge_protocol
    from engine.study.noise import StudyNoise

    view = platen_view if platen else (lambda r: r)
    test = ref_runs[0].test
    names = metric_names(test.unconfined)
    study = b_study()  # its tolerances and confidence; the consolidation stress is the test's
    spec = SimpleNamespace(reference=test, tolerances=study.tolerances, confidence=study.confidence)
    refs = {r.test.seed: metric_values(view(r)) for r in ref_runs}
    half = {r.test.seed: metric_values(view(r)) for r in runs}
    noise = StudyNoise(
        list(refs.values()),
        {(test.radius, "protocol"): list(half.values())},
        names,
        test.consolidation_stress,
    )
    return judge_protocol(spec, noise, test.radius, half, refs, names)


def strength_curve(runs: list, platen: bool = False) -> str:
    """The curve the strength of ``runs`` is read from, and their failure with it: the top
    platen's with ``platen`` (:func:`platen_view`), else each test's ``strength_from``."""
    where = {"platen" if platen else r.test.strength_from for r in runs}
    return " and ".join("top platen" if w == "platen" else f"{w} curve" for w in sorted(where))


def failed_cell(ref_runs: list, runs: list, platen: bool = False) -> str:
    """How many runs failed at a peak on the curve the compared strength is read from (the
    failure that decides which runs' strengths are compared, docs/PHYSICS.md section 7.3),
    and, where that is the top platen for runs that have an interior curve, how many fail on
    that too."""
    view = platen_view if platen else (lambda r: r)
    both = ref_runs + runs
    n = sum(view(r).scalars["unconfined_failure"] == 1.0 for r in both)
    text = f"{n} of {len(both)} ({strength_curve(both, platen)})"
    own = [r for r in both if r.test.strength_from != "platen"]
    if platen and own:
        k = sum(r.scalars["unconfined_failure"] == 1.0 for r in own)
        text += f"; on the interior curve {k} of the {len(own)} that have one"
    return text


def verdict_row(
    label: str, ref_runs: list, runs: list, platen: bool = False
) -> tuple[str, dict | None]:
    """A table row of ``runs`` judged against ``ref_runs`` (:func:`judge`; each cell as
    benchmarks.report.judged_text words it: no more than the verdict decided), and the
    judgement (None with fewer than two runs a side)."""
    from benchmarks.report import judged_text
    from engine.study.report import MetricVerdict

    if len(ref_runs) < 2 or len(runs) < 2:
        return f"| {label} | {len(ref_runs)} / {len(runs)} | not enough runs stored yet |", None
    v = judge(ref_runs, runs, label, platen)
    cells = []
    for m in v["metrics"]:
        if m["interval"] is None:
            cells.append(f"{100 * m['signed_error']:+.1f} %")
            continue
        cells.append(judged_text(MetricVerdict.from_dict(m)))
    row = (
        f"| {label} | {len(ref_runs)} / {len(runs)} | "
        + " | ".join(cells)
        + f" | {failed_cell(ref_runs, runs, platen)} | **{v['verdict']}** |"
    )
    return row, v


#: What a bias within the tolerance means, per kind of comparison.
HALVING_BIAS = (
    "halving moved each by that much; `equivalent` bounds such a move by the tolerance, it "
    "does not say that the protocol has converged in that metric, and a finer protocol "
    "could move it again (docs/PHYSICS.md section 7.6)"
)
PROTOCOL_BIAS = "the two protocols give values that far apart"
RULE_BIAS = "the runs are that far from those they are compared with"


def curve_lines(bench: list) -> list[str]:
    """Which curve each side's strength (and failure) is read from in the benchmark's
    comparisons ``bench`` ((label, reference runs, runs, platen, _)), and the runs of each
    side whose strength is compared: the runs that fail at a peak on that curve."""
    out = [
        "The strength of the comparisons with the seed's protocol is read from the top "
        "platen on both sides (the seed's runs have no interior curve): the seed's runs "
        "from their own (`strength_from = 'platen'`), the default's from the top platen's "
        "stress they store beside their interior curve (`unconfined_strength_platen`); "
        "whether a run failed at a peak is read from the same curve, and only failed runs' "
        "strengths are compared (docs/PHYSICS.md section 7.3). The comparison of the "
        "default with its halved I* reads both sides from the interior curve (the "
        "default's `strength_from`).",
        "",
    ]
    view = platen_view
    for label, a, b, platen, _ in bench:
        if not (platen and a and b):
            continue
        sides = []
        for name, runs in (("the seed's protocol", a), ("the default", b)):
            failed = [r.test.seed for r in runs if view(r).scalars["unconfined_failure"] == 1.0]
            hard = [r.test.seed for r in runs if r.test.seed not in failed]
            own = [r for r in runs if r.test.strength_from != "platen"]
            inner = sum(r.scalars["unconfined_failure"] == 1.0 for r in own)
            sides.append(
                f"{name} {len(failed)} of {len(runs)} on the top platen"
                + (
                    f" (seed{'s' if len(hard) > 1 else ''} {', '.join(map(str, hard))} "
                    f"harden{'' if len(hard) > 1 else 's'} there)"
                    if hard
                    else ""
                )
                + (f", {inner} of {len(own)} on the interior curve" if own else "")
            )
        out.append(
            f"- {label}: runs that fail at a peak: {'; '.join(sides)}. Its strength compares "
            "the failed runs only."
        )
    return out


def bias_line(label: str, v: dict | None, meaning: str) -> str | None:
    """One line naming the biased metrics of a comparison that is not ``differs`` (the
    interval of the mean over levels excludes 0), each with its own verdict, and what
    that ``meaning`` is."""
    if v is None or v["verdict"] == "differs" or not v.get("biased"):
        return None
    ms = {m["metric"]: m for m in v["metrics"]}

    def verdict(m):
        tol = f"{100 * m['tolerance']:g} %"
        return (
            f"equivalent within {tol}"
            if m["verdict"] == "equivalent"
            else (f"{m['verdict']} against ± {tol}")
        )

    moved = "; ".join(
        f"{b['metric']} {100 * b['error']:+.1f} [{100 * b['interval'][0]:+.1f}, "
        f"{100 * b['interval'][1]:+.1f}] % ({verdict(ms[b['metric']])})"
        for b in v["biased"]
    )
    return (
        f"- {label} ({v['verdict']}): biased in {moved}; 95 % intervals of the mean over "
        f"levels on each side's own spread: {meaning}."
    )


def cost_row(label: str, runs: list) -> str:
    if not runs:
        return f"| {label} | - | - | - | - | - | - |"
    s = [r.scalars for r in runs]
    ps = np.mean([x["particle_steps"] for x in s])
    # a run stored before the fraction was recorded: its step over its test's critical time
    fractions = [x.get("dt_fraction", r.test.time_step().fraction) for x, r in zip(s, runs)]
    return (
        f"| {label} | {len(runs)} | {np.mean([x['particles'] for x in s]):.0f} | "
        f"{np.mean([x['steps'] for x in s]):,.0f} | {ps:.3g} | "
        f"{np.mean([x['wall_time'] for x in s]):.0f} | "
        f"{np.mean([x['dt'] for x in s]):.3g} s ({np.mean(fractions):.2f}) |"
    )


HEADER = """| comparison | seeds (ref / runs) | density | K load | K unload | coordination | \
strength | failed | verdict |
|---|---|---|---|---|---|---|---|---|"""
COST_HEADER = """| runs | seeds | particles | steps | particle-steps | wall time [s] | \
dt (fraction) |
|---|---|---|---|---|---|---|"""


def held_rows(groups: dict[str, list]) -> list[str]:
    """Median inertial number held per loading stage (engine.uniaxial.measures
    .held_inertial_numbers, from the stored curves) of each group."""
    from engine.uniaxial.measures import held_inertial_numbers

    stages = ("pre_compression", "consolidation", "unloading", "unconfined")
    out = [
        "| runs | " + " | ".join(s.replace("_", "-") for s in stages) + " |",
        "|---|" + "---|" * len(stages),
    ]
    for label, runs in groups.items():
        if not runs:
            continue
        cells = []
        for st in stages:
            vals = np.concatenate(
                [held_inertial_numbers(r.stages[st].curves, r.test) for r in runs]
            )
            cells.append(f"{np.median(vals):.2e}" if vals.size else "-")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return out


def fill_rows() -> list[str]:
    rows = [
        "| case | particles | pour | dt [s] (critical) | steps | simulated [s] | wall [s] | "
        "outcome |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, (key, v) in FILLS.items():
        path = FILL_STORE / f"{name}.json"
        if not path.exists():
            rows.append(f"| {name} | - | - | - | - | - | - | not run yet |")
            continue
        f = json.loads(path.read_text())
        pour = "free fall" if v is None else f"capped at {v:g} m/s"
        what = "settled" if f["error"] is None else f"blew up: {f['error'].split(':')[0]}"
        if f["error"] is None:
            what += f", bed porosity {f['porosity']:.3f}"
        rows.append(
            f"| {key} | {f['particles']} | {pour} | {f['dt']:.3g} ({f['dt_critical']:.3g}) | "
            f"{f['steps']:,} | {f['time']:.3f} | {f['wall_time']:.0f} | {what} |"
        )
    return rows


#: Seeds of each stored group in the report.
ALL_SEEDS = tuple(range(1, 11))


def chosen(verdicts: dict) -> list[str]:
    """What the verdict rule chooses from the checks: the largest dt fraction whose halving
    is equivalent, and the largest I* whose halving is (computed, not written)."""
    out = []
    for what, pairs in (
        ("dt fraction", [c for c in CHECKS if "dt halved" in c[2]]),
        ("I*", [c for c in CHECKS if "I* halved" in c[2]]),
    ):
        ok = [a for a, b, _ in pairs if verdicts.get((a, b)) == "equivalent"]
        undecided = [a for a, b, _ in pairs if (a, b) not in verdicts]
        if ok:
            best = max(ok, key=lambda t: CANDIDATES[t][0 if what == "I*" else 1])
            out.append(f"- {what}: halving {best} is equivalent on every metric.")
        else:
            out.append(
                f"- {what}: no halving checked is equivalent on every metric yet"
                + (f" (not stored: {', '.join(undecided)})" if undecided else "")
                + "."
            )
    return out


def report() -> str:
    t = engine.UniaxialTest()
    lines = [
        "# The run protocol: the time step and the loading rate",
        "",
        "Generated by `python -m benchmarks.protocol --report` from the stored runs "
        "(benchmarks/results/paper/protocol/; the seed's runs of experiment (b) in "
        "benchmarks/results/paper/b_cohesive/). What each candidate is and why: the module's "
        "docstring, written before any run; the protocol itself: docs/PHYSICS.md sections 4 "
        "and 6. Verdicts: docs/PHYSICS.md section 7.1 at the study's tolerances (density 3 %, "
        "stiffnesses 15 %, coordination 10 %, strength 15 %) and 95 % confidence; intervals "
        "of the per-level error in per cent (a curve's worst level; for `differs`, the "
        "interval that lies outside the tolerance). Each cell says what its verdict decided "
        f"and no more: {CELL_WORDS} Column 'failed': the runs that fail at a peak on the "
        "curve the compared strength is read from (only those runs' strengths are compared, "
        "docs/PHYSICS.md section 7.3).",
        "",
        f"The engine's defaults of a new test: dt = {t.dt_fraction:g} of the critical time "
        f"of the stiffest contact, I* = {t.inertial_number:g}, at most "
        f"{t.max_platen_speed:g} m/s, the pour capped at {t.pour_speed:g} m/s, the strength "
        f"from the {t.strength_from} curve (engine.uniaxial.spec.DEFAULT_PROTOCOL). The "
        'seed\'s protocol stays one option away: `preset(name, protocol="seed")`, '
        "`engine.SEED_PROTOCOL` (dt = 1e-5 s, the platen at 10 mm/s, free fall, the top "
        "platen's strength).",
        "",
        "How the defaults were chosen: the fill is the pour of the three candidates that "
        "settles in about the fewest steps and leaves the free fall's bed (the table below); "
        "the time step and the inertial number are the largest candidates whose halving "
        "leaves every verdict metric equivalent on a failing sample at the seed's scale "
        "(the halving checks below, on experiment (b)'s 5 mm b = 2 run, whose every run "
        "fails at a peak), the inertial number then checked on the reference itself (the "
        "benchmark's last row). A metric judged `undecided` needs more seeds; the verdicts "
        "are the study's protocol check (engine.study.judge.judge_protocol), paired by seed "
        "where that pays. `equivalent` says that halving moves no metric beyond its "
        "tolerance at 95 %, not that the protocol has converged: a halving that moves a "
        "metric by less than its tolerance, but by more than its noise, is listed under its "
        "table as a bias (docs/PHYSICS.md section 7.6).",
        "",
        "## The fill (paper scale)",
        "",
        *fill_rows(),
        "",
        "## The halving checks (paper scale, experiment (b)'s 5 mm b = 2 run)",
        "",
        HEADER,
    ]
    b2 = {tag: load_group("b2", tag, ALL_SEEDS) for tag in CANDIDATES}
    verdicts, biases = {}, []
    for a, b, label in CHECKS:
        row, v = verdict_row(f"{label} ({b} against {a})", b2[a], b2[b])
        lines.append(row)
        if v is not None:
            verdicts[a, b] = v["verdict"]
        biases.append(bias_line(label, v, HALVING_BIAS))
    lines += ["", *chosen(verdicts), *[x for x in biases if x], "", COST_HEADER]
    lines += [cost_row(tag, runs) for tag, runs in b2.items()]
    lines += ["", "Median inertial number held per stage:", "", *held_rows(b2)]
    groups = {
        "ref, seed's protocol": load_group("ref", "seed", ALL_SEEDS),
        "ref, default": load_group("ref", "default", ALL_SEEDS),
        "ref, I* halved": load_group("ref", "half", ALL_SEEDS),
        "b2, seed's protocol": load_group("b2", "seed", ALL_SEEDS),
        "b2, default": load_group("b2", "default", ALL_SEEDS),
    }
    g = list(groups.values())
    bench = [
        ("reference: default against the seed's protocol", g[0], g[1], True, PROTOCOL_BIAS),
        ("5 mm b = 2: default against the seed's protocol", g[3], g[4], True, PROTOCOL_BIAS),
        ("reference: I* halved against the default", g[1], g[2], False, HALVING_BIAS),
    ]
    judged = [(label, *verdict_row(label, a, b, p), meaning) for label, a, b, p, meaning in bench]
    lines += [
        "",
        "## The benchmark (paper scale): the seed's protocol against the default",
        "",
        *curve_lines(bench),
        "",
        HEADER,
        *[row for _, row, _, _ in judged],
        "",
        *[x for label, _, v, meaning in judged if (x := bias_line(label, v, meaning))],
        "",
        COST_HEADER,
        *[cost_row(label, runs) for label, runs in groups.items()],
        "",
    ]
    for label, a, b in (("reference", g[0], g[1]), ("5 mm b = 2", g[3], g[4])):
        if a and b:
            ps = [np.mean([r.scalars["particle_steps"] for r in x]) for x in (a, b)]
            wall = [np.mean([r.scalars["wall_time"] for r in x]) for x in (a, b)]
            lines.append(
                f"- {label}: the seed's protocol takes {ps[0] / ps[1]:.1f} x the "
                f"particle-steps of the default ({wall[0] / wall[1]:.1f} x the mean wall "
                "time, on machines shared with other runs)."
            )
    lines += ["", "Median inertial number held per stage:", "", *held_rows(groups), ""]
    rule = {
        "5 mm b = 2": load_group("b2", "default", ALL_SEEDS),
        "3.75 mm b = 2": load_group("b2_375", "default", ALL_SEEDS),
    }
    controls = {
        "5 mm b = 2": load_group("ctl", "default", ALL_SEEDS),
        "3.75 mm b = 2": load_group("ctl_375", "default", ALL_SEEDS),
    }
    judged_rule = [
        (label, *verdict_row(label, g[1], runs))
        for label, runs in (
            (f"{lb} against the reference, default protocol", r) for lb, r in rule.items()
        )
    ]
    own = [
        (label, *verdict_row(label, a, b))
        for label, a, b in [
            (f"{lb} against its control, default protocol", controls[lb], r)
            for lb, r in rule.items()
        ]
        + [
            (f"control of {lb} against the reference, default protocol", g[1], c)
            for lb, c in controls.items()
        ]
    ]
    lines += [
        "## The seed's rule re-judged at the default protocol (paper scale)",
        "",
        "Experiment (b)'s quadratic rule (K ~ R, f0 ~ R^2) at each coarse radius against the "
        "20,626-particle reference, both at the default protocol (the interior strength on "
        "both sides), by the same verdict rule. At the seed's protocol the study's verdicts "
        "are in docs/VALIDATION.md.",
        "",
        HEADER,
        *[row for _, row, _ in judged_rule],
        "",
        "Against its control (the reference law in the coarse run's own packing and cell, "
        "seed for seed): for this law the quadratic rule is an exact similarity "
        "(docs/PHYSICS.md section 5.1), so a coarse run is its control in other units and "
        "this comparison is a check of units (the constants left in seconds and the runs' "
        "chaos), not evidence for the rule. The control against the reference is the "
        "resolution error of a sample that many diameters across (docs/PHYSICS.md section "
        "7.4).",
        "",
        HEADER,
        *[row for _, row, _ in own],
        "",
        *[x for label, _, v in judged_rule + own if (x := bias_line(label, v, RULE_BIAS))],
        "",
        *speedup_lines(g[1], rule),
    ]
    return "\n".join(lines)


def speedup_lines(ref_runs: list, rule: dict) -> list[str]:
    """The seed's speed-up claim at the default protocol: the reference's mean particle-steps
    and wall time over each coarse run's, every run at its own time step (a fraction of its
    own contact time), against s^3 (a fixed step) and s^4 (a step growing as s)."""
    if not ref_runs:
        return []
    out = [
        "The seed's speed-up claim at the default protocol (each run at its own time step, "
        "the mean over the stored seeds; wall times on machines shared with other runs, one "
        "engine thread):",
        "",
    ]
    ref_r = ref_runs[0].test.radius
    ps0 = np.mean([r.scalars["particle_steps"] for r in ref_runs])
    w0 = np.mean([r.scalars["wall_time"] for r in ref_runs])
    for label, runs in rule.items():
        if not runs:
            continue
        sc = runs[0].test.radius / ref_r
        ps = np.mean([r.scalars["particle_steps"] for r in runs])
        w = np.mean([r.scalars["wall_time"] for r in runs])
        out.append(
            f"- {label} (s = {sc:.3g}, {len(runs)} runs against {len(ref_runs)}): "
            f"{ps0 / ps:.1f} x fewer particle-steps and {w0 / w:.1f} x less wall time than the "
            f"reference; s^3 = {sc**3:.1f}, s^4 = {sc**4:.1f}."
        )
    return [*out, ""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("part", nargs="?", choices=("fill", "paper"))
    ap.add_argument("--only", nargs="*", help="fill cases, or <sample>-<tag>-s<seed> runs")
    ap.add_argument("--commit", action="store_true", help="commit each stored paper run")
    ap.add_argument("--report", action="store_true", help="only write docs/PROTOCOL.md")
    args = ap.parse_args(argv)
    if args.part == "fill":
        fills(args.only)
    elif args.part == "paper":
        jobs = BENCHMARK
        if args.only:
            jobs = [j for j in jobs if "-".join((j[0], j[1], f"s{j[2]}")) in args.only]
        run_paper(jobs, commit=args.commit)
    if args.report or args.part is None:
        REPORT.write_text(report())
        print(f"wrote {REPORT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
