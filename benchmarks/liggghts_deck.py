"""demscale against LIGGGHTS 3.8 on the seed's cohesive test, through the exported deck (issue 43).

    python -m benchmarks.liggghts_deck                  # every run not yet stored, the report
    python -m benchmarks.liggghts_deck --cases b_elastic # some cases (stored runs are kept)
    python -m benchmarks.liggghts_deck --report         # docs/LIGGGHTS_DECK.md from the store

Every run is one uniaxial test of the quick preset with the seed's protocol, as experiment
(b) is run (engine.preset("quick", protocol="seed"): dt = 1e-5 s, the platen at a constant
10 mm/s, the free-fall fill, the strength from the top platen; the stored test says which
preset it was), seeds 1 to 3: demscale runs it here
(engine.run_uniaxial, one thread), LIGGGHTS runs the deck engine.io.liggghts_deck writes
for it, unmodified (``liggghts -in in.demscale`` in the deck folder under
benchmarks/.cache/liggghts_deck/), and engine.io.liggghts_read stores its output in the same
HDF5 layout. Each run is stored the moment it ends under
benchmarks/results/quick/liggghts_deck/<code>/<case>-s<seed>.h5 (a run whose stored test
differs from the current one is run again), so the script resumes where it stopped.

Cases:

- ``b``: experiment (b)'s reference (the bilinear law K1 = 5e3, K2 = 2.5e4 N/m,
  f0 = -0.8 N, kt = 2/7 K1, mu_s 0.5, mu_r 0.001, restitution 0.4), both codes;
- ``b_coarse``: its 5 mm run under the seed's rule (K ~ R, f0 ~ R^2), both codes, seed 1;
- ``b_elastic``: (b) without plastic unloading (K2 = K1), both codes, and its 5 mm run;
- ``b_elastic_kt1``, ``b_elastic_cap``, ``b_elastic_kt1_cap``: demscale alone, with one or
  both of LIGGGHTS' tangential conventions (kt = K1: ``kt_ratio`` 1; the Coulomb cap mu |F_n|:
  EEPA n = chi = 1 with ``friction_cap="normal"``), the runs that remove a named model
  difference;
- the handover probe (``probe``): LIGGGHTS' pair forces on demscale's settled (b) bed,
  summed over every pair: zero for a momentum-conserving contact law; run for (b), for (b)
  with K2 = K1, for (b) with f0 = 0 and for (b) in a box walled instead of periodic.

docs/LIGGGHTS_DECK.md explains what each case shows; the report judges LIGGGHTS' runs of a
case against demscale's with the study's verdict rule (engine.study.judge.judge_groups),
and against each demscale run with a difference removed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

import engine
from benchmarks.checks import save_figure, write_marked
from engine.io.liggghts_deck import write_deck
from engine.io.liggghts_read import save_output
from engine.io.store import load_run, save_run

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
STORE = HERE / "results" / "quick" / "liggghts_deck"
WORK = HERE / ".cache" / "liggghts_deck"
DOC = ROOT / "docs" / "LIGGGHTS_DECK.md"
SEEDS = (1, 2, 3)
CODES = ("demscale", "liggghts")
#: the coarse radius of the coarse cases [m], and the seed's rule there (K ~ R, f0 ~ R^2)
COARSE_RADIUS = 5e-3
COARSE_RULE = engine.ScalingRule("b2", 1.0, 2.0)
#: the interior window's margin of every run [m]: experiment (b)'s, two diameters of its
#: largest particle (R = 5 mm), so that fine and coarse runs are measured over one window
INTERIOR_MARGIN = 4 * COARSE_RADIUS
#: a LIGGGHTS run longer than this is stopped [s] (the quick runs take 5 to 20 min)
LIGGGHTS_TIMEOUT = 4 * 3600


def b_law(**changes) -> engine.BilinearAdhesive:
    """Experiment (b)'s reference law (benchmarks.experiments), with ``changes``."""
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.8, mu_s=0.5, mu_r=0.001, restitution=0.4)
    return replace(law, **changes)


def normal_cap(law: engine.BilinearAdhesive, kt_ratio: float) -> engine.EEPA:
    """``law`` as EEPA n = chi = 1 (the same law to the last bit) with LIGGGHTS' Coulomb cap
    mu |F_n| and the tangential stiffness ``kt_ratio`` K1."""
    return engine.EEPA(
        k1=law.k1,
        k2=law.k2,
        f0=law.f0,
        kadh=law.kadh,
        n=1.0,
        chi=1.0,
        kt_ratio=kt_ratio,
        mu_s=law.mu_s,
        mu_r=law.mu_r,
        restitution=law.restitution,
        friction_cap="normal",
    )


@dataclass(frozen=True)
class Case:
    """One test run by one or both codes over some seeds."""

    key: str
    title: str
    law: object
    codes: tuple[str, ...] = CODES
    seeds: tuple[int, ...] = SEEDS
    coarse: bool = False  # the 5 mm run of the law under COARSE_RULE
    removes: str = ""  # the model difference a demscale-only case removes

    def test(self, seed: int) -> engine.UniaxialTest:
        ref = engine.preset(
            "quick",
            protocol="seed",
            pair_law=self.law,
            seed=seed,
            interior_margin=INTERIOR_MARGIN,
        )
        if not self.coarse:
            return ref
        return COARSE_RULE.apply(ref, COARSE_RADIUS, ref.resolved_dt())


_ELASTIC = b_law(k2=5e3)
CASES = {
    c.key: c
    for c in (
        Case("b", "experiment (b)'s reference law", b_law()),
        Case("b_elastic", "(b) without plastic unloading (K2 = K1)", _ELASTIC),
        Case(
            "b_elastic_kt1",
            "(b), K2 = K1, kt = K1",
            replace(_ELASTIC, kt_ratio=1.0),
            codes=("demscale",),
            removes="tangential stiffness",
        ),
        Case(
            "b_elastic_cap",
            "(b), K2 = K1, Coulomb cap mu |F_n|",
            normal_cap(_ELASTIC, _ELASTIC.kt_ratio),
            codes=("demscale",),
            removes="Coulomb cap",
        ),
        Case(
            "b_elastic_kt1_cap",
            "(b), K2 = K1, kt = K1 and the cap mu |F_n|",
            normal_cap(_ELASTIC, 1.0),
            codes=("demscale",),
            removes="tangential stiffness and Coulomb cap",
        ),
        Case("b_coarse", "(b) at R = 5 mm, K ~ R, f0 ~ R^2", b_law(), seeds=(1,), coarse=True),
        Case(
            "b_elastic_coarse",
            "(b), K2 = K1, at R = 5 mm, K ~ R, f0 ~ R^2",
            _ELASTIC,
            seeds=(1,),
            coarse=True,
        ),
    )
}
#: the order the runs are made in when all are due: the verdicts and the runs that trace
#: them first, (b) in LIGGGHTS last (each runs its fill to the stage bound, about 50 min)
ORDER = (
    ("b_elastic", "demscale"),
    ("b_elastic", "liggghts"),
    ("probe", "liggghts"),
    ("b_elastic_kt1_cap", "demscale"),
    ("b_elastic_coarse", "liggghts"),
    ("b_elastic_coarse", "demscale"),
    ("b_elastic_kt1", "demscale"),
    ("b_elastic_cap", "demscale"),
    ("b_coarse", "liggghts"),
    ("b_coarse", "demscale"),
    ("b", "demscale"),
    ("b", "liggghts"),
)


def run_path(code: str, case: str, seed: int) -> Path:
    return STORE / code / f"{case}-s{seed}.h5"


#: demscale's stored runs of experiment (b) at the quick scale (benchmarks/reproduce.py):
#: its references are case b's demscale runs wherever their test is the case's
EXPERIMENT_B = HERE / "results" / "quick" / "b_cohesive"


def source(code: str, case: Case, seed: int) -> Path | None:
    """Where this run with the current test is stored, or None: this benchmark's store, or
    for case b's demscale runs experiment (b)'s stored references (the same test)."""
    paths = [run_path(code, case.key, seed)]
    if code == "demscale" and case.key == "b":
        paths.append(EXPERIMENT_B / f"ref-s{seed}.h5")
    import h5py

    for path in paths:
        if not path.exists():
            continue
        with h5py.File(path, "r") as f:
            test = f.attrs.get("test")
        if test is not None and engine.UniaxialTest.from_stored(json.loads(test)) == case.test(
            seed
        ):
            return path
    return None


def stored(code: str, case: Case, seed: int):
    """The stored outcome (a UniaxialResult or an error text) of this run with the current
    test, or None (:func:`source`)."""
    path = source(code, case, seed)
    return None if path is None else load_run(path)


# ---------------------------------------------------------------------------- runs
def run_demscale(case: Case, seed: int) -> Path:
    """demscale's run of the case's test, stored at once (a stage error stored as text)."""
    test = case.test(seed)
    t0 = time.perf_counter()
    try:
        outcome = engine.run_uniaxial(test)
    except (engine.StageError, engine.InstabilityError) as e:
        outcome = f"{type(e).__name__}: {e}"
    path = save_run(run_path("demscale", case.key, seed), outcome)
    if isinstance(outcome, str):
        import h5py

        with h5py.File(path, "r+") as f:
            f.attrs["test"] = json.dumps(test.to_dict())
    print(f"  demscale {case.key} s{seed}: {time.perf_counter() - t0:.0f} s", flush=True)
    return path


def run_liggghts(case: Case, seed: int) -> Path | None:
    """LIGGGHTS' run of the deck of the case's test (written under WORK), stored at once."""
    exe = shutil.which("liggghts")
    if exe is None:
        print("  liggghts is not on the PATH: skipped", flush=True)
        return None
    folder = WORK / f"{case.key}-s{seed}"
    if folder.exists():
        shutil.rmtree(folder)
    write_deck(case.test(seed), folder)
    t0 = time.perf_counter()
    # LIGGGHTS loses its screen output on an abort unless it is unbuffered
    with open(folder / "screen.txt", "w") as screen:
        rc = subprocess.run(
            ["stdbuf", "-o0", "-e0", exe, "-in", "in.demscale"],
            cwd=folder,
            stdout=screen,
            stderr=subprocess.STDOUT,
            timeout=LIGGGHTS_TIMEOUT,
            check=False,
        ).returncode
    wall = time.perf_counter() - t0
    if rc != 0:
        tail = (folder / "screen.txt").read_text()[-2000:]
        print(f"  LIGGGHTS exited with {rc} after {wall:.0f} s:\n{tail}", flush=True)
        return None
    path = save_output(folder, run_path("liggghts", case.key, seed))
    import h5py

    with h5py.File(path, "r+") as f:
        f.attrs["liggghts_wall_seconds"] = wall
    print(f"  LIGGGHTS {case.key} s{seed}: {wall:.0f} s", flush=True)
    return path


# ---------------------------------------------------------------------------- the probe
PROBE = STORE / "probe.json"
#: the probe's steps and sampling (0.3 s of the fill from the poured cloud, a sample every
#: 5 ms): long enough for demscale's fill of the same cloud to have its bed on the floor
PROBE_STEPS, PROBE_EVERY = 30_000, 500
#: the probe's variants: (law, periodic in x and y)
PROBE_VARIANTS = {
    "b, periodic": (b_law(), True),
    "b, walled in x and y": (b_law(), False),
    "b with K2 = K1, periodic": (_ELASTIC, True),
    "b with f0 = 0, periodic": (b_law(f0=0.0), True),
}


def run_probe() -> None:
    """LIGGGHTS' pair forces on seed 1's poured cloud, summed over every pair after every
    sample, for each of :data:`PROBE_VARIANTS`: zero (to rounding) for a contact law whose
    pair forces are equal and opposite. Stored in probe.json (skipped when stored with the
    same variants, steps and test)."""
    from engine.io.liggghts_deck import COLUMNS, probe_deck

    if shutil.which("liggghts") is None:
        print("  liggghts is not on the PATH: the probe is skipped", flush=True)
        return
    base = CASES["b"].test(1)
    want = {
        "steps": PROBE_STEPS,
        "every": PROBE_EVERY,
        "test": base.to_dict(),
        "variants": {
            k: [type(v[0]).__name__, asdict(v[0]), v[1]] for k, v in PROBE_VARIANTS.items()
        },
    }
    want = json.loads(json.dumps(want))  # as it reads back (tuples as lists)
    if PROBE.exists():
        old = json.loads(PROBE.read_text())
        if all(old.get(k) == v for k, v in want.items()):
            return
    pos, rad = base.initial_packing()
    weight = float(base.density * np.sum(4 / 3 * np.pi * rad**3) * base.gravity)
    out = {**want, "weight": weight, "results": {}}
    for i, (name, (law, periodic)) in enumerate(PROBE_VARIANTS.items()):
        print(f"probe: {name} ...", flush=True)
        test = replace(base, pair_law=law)
        folder = WORK / f"probe-{i}"
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        for fname, text in probe_deck(test, pos, rad, PROBE_STEPS, PROBE_EVERY, periodic).items():
            (folder / fname).write_text(text)
        t0 = time.perf_counter()
        with open(folder / "screen.txt", "w") as screen:
            subprocess.run(
                ["stdbuf", "-o0", "-e0", "liggghts", "-in", "in.probe"],
                cwd=folder,
                stdout=screen,
                stderr=subprocess.STDOUT,
                timeout=LIGGGHTS_TIMEOUT,
                check=True,
            )
        rows = [
            [float(v) for v in line.split()]
            for line in (folder / "probe.txt").read_text().splitlines()
            if not line.startswith("#")
        ]
        a = np.array(rows)
        c = {k: a[:, i] for i, k in enumerate([*COLUMNS, "fx", "fy", "fz", "wx", "wy", "wz"])}
        pair = np.sqrt(
            (c["fx"] - c["wx"]) ** 2 + (c["fy"] - c["wy"]) ** 2 + (c["fz"] - c["wz"] + weight) ** 2
        )
        out["results"][name] = {
            "time": list(c["step"] * test.resolved_dt()),
            "pair_force_sum": list(pair),
            "kinetic_energy": list(c["ke_trans"] + c["ke_rot"]),
            "bottom_force": list(c["fbot"]),
            "seconds": time.perf_counter() - t0,
        }
        print(f"  largest pair-force sum {pair.max() / weight:.3g} x the bed's weight", flush=True)
    PROBE.parent.mkdir(parents=True, exist_ok=True)
    PROBE.write_text(json.dumps(out) + "\n")


def run_all(keys) -> None:
    """Every due run of the cases ``keys``, one at a time, in :data:`ORDER`."""
    for key, code in ORDER:
        if key not in keys:
            continue
        if key == "probe":
            run_probe()
            continue
        case = CASES[key]
        if code not in case.codes:
            continue
        for seed in case.seeds:
            if stored(code, case, seed) is not None:
                continue
            print(f"{code} {key} seed {seed}: {case.title} ...", flush=True)
            if code == "demscale":
                run_demscale(case, seed)
            else:
                run_liggghts(case, seed)


# ---------------------------------------------------------------------------- the report
TABLE_BEGIN = "<!-- results:begin (written by python -m benchmarks.liggghts_deck --report) -->"
TABLE_END = "<!-- results:end -->"
FIGURE = ROOT / "docs" / "figures" / "liggghts_deck.png"
#: the metrics' names in the tables
METRIC_TITLES = {
    "density": "interior density",
    "loading_stiffness": "loading stiffness",
    "unloading_stiffness": "unloading stiffness",
    "coordination": "interior coordination",
    "strength": "unconfined strength",
}


def outcomes(code: str, key: str) -> list:
    """The stored outcomes of a case's runs by ``code`` (results and error texts), in seed
    order; runs not stored left out."""
    case = CASES[key]
    return [r for r in (stored(code, case, s) for s in case.seeds) if r is not None]


def _pct(x) -> str:
    return "" if x is None else f"{100 * x:+.1f} %"


def _interval(m: dict) -> str:
    iv = m.get("interval")
    return "" if iv is None else f"{100 * iv[0]:+.1f} to {100 * iv[1]:+.1f} %"


def verdict_table(title: str, judged: dict) -> list[str]:
    """A verdict (engine.io.liggghts_read.judge_runs) as markdown lines."""
    out = [
        f"**{title}**: {judged['verdict']} ({judged['seeds']} run(s) against "
        f"{judged['reference_seeds']}; {len(judged['failed'])} stopped)",
        "",
    ]
    if not judged["metrics"]:
        return [*out, f"- {judged['reason']}", ""]
    out += [
        "| metric | signed error | 95 % interval (at the metric's worst stress level) | "
        "tolerance | verdict |",
        "|---|---:|---:|---:|---|",
    ]
    for m in judged["metrics"]:
        out.append(
            f"| {METRIC_TITLES.get(m['metric'], m['metric'])} | {_pct(m['signed_error'])} | "
            f"{_interval(m)} | {100 * m['tolerance']:g} % | {m['verdict']} |"
        )
    return [*out, ""]


def runs_table() -> list[str]:
    out = [
        "| case | code | seed | outcome | steps | loop time [s] | interior density at "
        "sigma_c | loading stiffness [MPa] | unloading stiffness [MPa] | strength [kPa] "
        "(failed) |",
        "|---|---|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for key, case in CASES.items():
        for code in case.codes:
            for seed in case.seeds:
                path = source(code, case, seed)
                if path is None:
                    out.append(f"| {key} | {code} | {seed} | not run | | | | | | |")
                    continue
                r = load_run(path)
                where = "" if path.parent.parent == STORE else f" ({path.parent.name} store)"
                if isinstance(r, str):
                    out.append(
                        f"| {key} | {code} | {seed} | stopped: {r[:90]}{where} | | | | | | |"
                    )
                    continue
                sc = r.scalars
                dens = 1 - sc["consolidated_porosity_interior"]
                strength = sc.get("unconfined_strength")
                st = (
                    ""
                    if strength is None
                    else f"{strength / 1e3:.2f} ({sc['unconfined_failure']:.0f})"
                )
                out.append(
                    f"| {key} | {code} | {seed} | finished{where} | {sc['steps']:.0f} | "
                    f"{sc['wall_time']:.0f} | {dens:.4f} | {sc['loading_stiffness'] / 1e6:.3f} | "
                    f"{sc['unloading_stiffness'] / 1e6:.3f} | {st} |"
                )
    return [*out, ""]


def probe_table() -> list[str]:
    if not PROBE.exists():
        return ["The probe has not run.", ""]
    p = json.loads(PROBE.read_text())
    w = p["weight"]
    out = [
        f"Seed 1's poured cloud ({p['test']['cell']} m cell, {PROBE_STEPS} steps, a sample "
        f"every {PROBE_EVERY}); the bed weighs {w:.3g} N.",
        "",
        "| variant | largest sum of the pair forces / bed weight | kinetic energy at the end [J] "
        "| largest kinetic energy [J] |",
        "|---|---:|---:|---:|",
    ]
    for name, r in p["results"].items():
        out.append(
            f"| {name} | {max(r['pair_force_sum']) / w:.3g} | {r['kinetic_energy'][-1]:.3g} | "
            f"{max(r['kinetic_energy']):.3g} |"
        )
    return [*out, ""]


def report() -> str:
    """The results section of docs/LIGGGHTS_DECK.md, from the stored runs."""
    from engine.io.liggghts_read import judge_runs

    lines = ["### Runs", "", *runs_table(), "### Verdicts: LIGGGHTS against demscale", ""]
    for key in ("b_elastic", "b"):
        lig, dem = outcomes("liggghts", key), outcomes("demscale", key)
        finished = [r for r in dem if not isinstance(r, str)]
        if lig and len(finished) >= 2:
            lines += verdict_table(f"{key}: {CASES[key].title}", judge_runs(lig, dem))
    coarse = outcomes("liggghts", "b_elastic_coarse")
    fine = outcomes("demscale", "b_elastic")
    if coarse and len([r for r in fine if not isinstance(r, str)]) >= 2:
        lines += verdict_table(
            "b_elastic_coarse: LIGGGHTS at R = 5 mm (K ~ R, f0 ~ R^2) against demscale's "
            "R = 2.5 mm runs (a coarse model in the user's code against the fine reference)",
            judge_runs(coarse, fine),
        )
    for code in ("liggghts", "demscale"):
        coarse = outcomes(code, "b_elastic_coarse")
        fine = outcomes(code, "b_elastic")
        if coarse and len([r for r in fine if not isinstance(r, str)]) >= 2:
            lines += verdict_table(
                f"b_elastic_coarse against b_elastic, both by {code}: the seed's rule judged "
                f"within {code}",
                judge_runs(coarse, fine),
            )
    lines += ["### The model differences, each removed from demscale", ""]
    lig = outcomes("liggghts", "b_elastic")
    base = outcomes("demscale", "b_elastic")
    for key in ("b_elastic_kt1", "b_elastic_cap", "b_elastic_kt1_cap"):
        dem = outcomes("demscale", key)
        if len([r for r in dem if not isinstance(r, str)]) < 2:
            lines += [f"- {key}: not run yet", ""]
            continue
        case = CASES[key]
        if lig:
            lines += verdict_table(
                f"LIGGGHTS against demscale without the {case.removes} difference ({key})",
                judge_runs(lig, dem),
            )
        if len([r for r in base if not isinstance(r, str)]) >= 1:
            lines += verdict_table(
                f"demscale without the {case.removes} difference against demscale ({key} "
                "against b_elastic): the difference's own size",
                judge_runs(dem, base),
            )
    lines += ["### The probe: do LIGGGHTS' pair forces sum to zero?", "", *probe_table()]
    return "\n".join(lines) + "\n"


def figure(path: Path) -> None:
    """Stress against strain of both codes (b_elastic: confined and unconfined) and the
    probe's pair-force sums."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for code, style in (("demscale", "C3-"), ("liggghts", "k-")):
        for i, r in enumerate(outcomes(code, "b_elastic")):
            if isinstance(r, str):
                continue
            label = code if i == 0 else None
            for stage in ("pre_compression", "consolidation", "unloading"):
                c = r.stages[stage].curves
                h = r.stages["pre_compression"].curves["platen_gap"][0]
                e = 1 - c["platen_gap"] / h
                axes[0].plot(100 * e, c["stress_top"] / 1e3, style, lw=0.8, label=label)
                label = None
            u = r.stages["unconfined"].curves
            axes[1].plot(
                100 * u["strain"],
                u["stress_top"] / 1e3,
                style,
                lw=0.8,
                label=code if i == 0 else None,
            )
    axes[0].set(
        xlabel="strain from the pre-compression's start [%]",
        ylabel="top stress [kPa]",
        title="b_elastic: confined loading and unloading",
    )
    axes[1].set(
        xlabel="unconfined strain [%]",
        ylabel="top stress [kPa]",
        title="b_elastic: unconfined compression",
    )
    if PROBE.exists():
        p = json.loads(PROBE.read_text())
        for name, r in p["results"].items():
            axes[2].semilogy(
                r["time"],
                np.maximum(np.array(r["pair_force_sum"]) / p["weight"], 1e-16),
                label=name,
            )
        axes[2].set(
            xlabel="time [s]",
            ylabel="|sum of pair forces| / bed weight",
            title="LIGGGHTS' pair forces from the poured cloud",
        )
    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=8)
    save_figure(fig, path, dpi=100)


def write_doc(text: str) -> None:
    """Put the results between the markers of docs/LIGGGHTS_DECK.md."""
    write_marked(DOC, TABLE_BEGIN, TABLE_END, text, "LIGGGHTS deck")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", choices=[*CASES, "probe"], default=None)
    ap.add_argument("--report", action="store_true", help="only the report, from the store")
    args = ap.parse_args(argv)
    keys = [*CASES, "probe"] if args.cases is None else args.cases
    if not args.report:
        os.environ.setdefault("NUMBA_NUM_THREADS", "1")
        run_all(keys)
    text = report()
    print(text)
    write_doc(text)
    figure(FIGURE)
    print(f"wrote {DOC.relative_to(ROOT)} and {FIGURE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
