"""Per-step speed of the paper-scale workload at one thread (issue 40 item 6).

    python -m benchmarks.paper_speed                 # about 20 minutes once the states exist
    python -m benchmarks.paper_speed --states        # only make the cached states
    python -m benchmarks.paper_speed --baseline REV --rounds 5 --steps 2000
    python -m benchmarks.paper_speed --stages [--baseline REV]   # whole runs, CPU by stage (hours)

States: the stored paper-scale cohesive reference (``b_cohesive/ref-s1``: 20,626 particles,
R = 2.5 mm) and its coarse b = 2 run (``r5mm-b2-s1``: 2,578 particles, R = 5 mm), each run
through the uniaxial driver (its stored test, the seed protocol) from the poured cloud to
``CONSOLIDATION_STEPS`` steps into consolidation, with the particle renumbering switched off
(``RENUMBER_STEPS`` out of reach): the particles keep the order of the cloud, as every stored
paper run had them. The Simulation is pickled when pre-compression begins (``fill``: the fill
just settled) and in consolidation (``consolidation``), under benchmarks/.cache/ (making them
takes about 2.6e9 particle-steps: half an hour to an hour on a shared core; cached).

Arms, each timed from the same pickled state, ``--steps`` steps at one thread, CPU time of
the thread per particle-step (the cost of a step whatever else runs on the machine):

- ``baseline``: the engine at git revision ``--baseline`` (default: the commit before issue
  40's speed work) on the state as it is (the cloud's order);
- ``as run``: this engine on the state as it is (renumbering off);
- ``renumbered``: this engine after renumbering the particles in cell order (and again every
  ``RENUMBER_STEPS``), as a run of this engine has them;
- ``shuffled``: this engine with the particles in a random order (seeded), renumbering off:
  what an order that no longer follows space costs.

``--stages``: the coarse run and the reference whole, through the stage driver at one thread
(this engine, or with ``--baseline`` the engine at that revision), the CPU time of each stage
per particle-step split into kernel calls, list builds and curve samples, with the number of
kernel calls and list builds; one JSON line per stage, written to
benchmarks/results/paper_speed/stages-<revision>.jsonl as they come (a run of the reference
is about 1.25e10 particle-steps: 35 minutes of a quiet core, hours on a shared one).

Rounds run every arm once in a fresh process each, in alternating order, so that a slow spell
of the shared machine falls on all of them; a figure is the median over rounds, a ratio the
median of the rounds' ratios. Printed: the order of each state (median and 90th percentile of
|i - j| over the neighbour list's pairs), ns per particle-step per arm, the ratios to the
baseline, and the target of issue 40: the reference within 1.5x of the coarse run's cost per
particle-step (this engine, renumbered; both states).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import pickle
import statistics
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.checks import ROOT, report, run_child, worktree

HERE = Path(__file__).resolve().parent
CACHE = HERE / ".cache"
RESULTS = HERE / "results" / "paper"
#: the stored runs whose tests the states are made with
RUNS = {
    "reference": RESULTS / "b_cohesive" / "ref-s1.h5",
    "coarse": RESULTS / "b_cohesive" / "r5mm-b2-s1.h5",
}
STATES = ("fill", "consolidation")
#: steps into consolidation of the second state
CONSOLIDATION_STEPS = 3000
#: the commit before issue 40's speed work (renumbering, the fused pass)
BASELINE = "51c2ccc"
#: issue 40: the reference within this factor of the coarse run's cost per particle-step
TARGET = 1.5


def _test(which: str):
    from engine.io.store import load_run

    return load_run(RUNS[which]).test


def state_path(which: str, state: str) -> Path:
    blob = json.dumps(_test(which).to_dict(), sort_keys=True, default=str).encode()
    return CACHE / f"paper_{which}_{hashlib.sha256(blob).hexdigest()[:12]}_{state}.pkl"


def make_states(which: str, log=print) -> None:
    """Run the stored test of ``which`` through the stage driver to ``CONSOLIDATION_STEPS``
    into consolidation with the renumbering off, pickling the Simulation when pre-compression
    begins and there; one log line per stage (steps, wall time, list builds, rate)."""
    import engine.simulation.simulation as simulation
    from engine.core.errors import StopRequested
    from engine.uniaxial.driver import _Driver

    if all(state_path(which, s).exists() for s in STATES):
        return
    simulation.RENUMBER_STEPS = 2**62  # the order of the cloud, as the stored runs had it
    CACHE.mkdir(exist_ok=True)
    seen: dict[str, tuple[int, float, int]] = {}
    d = None

    def save(state: str) -> None:
        path = state_path(which, state)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(pickle.dumps(d.sim, protocol=pickle.HIGHEST_PROTOCOL))
        os.replace(tmp, path)

    def progress(p) -> bool:
        sim = d.sim
        if p.stage not in seen:
            seen[p.stage] = (p.steps, time.perf_counter(), sim.n_rebuilds)
            if len(seen) > 1:
                prev = list(seen)[-2]
                s0, t0, b0 = seen[prev]
                dt = time.perf_counter() - t0
                log(
                    f"  {which} {prev}: {p.steps - s0} steps, {dt:.0f} s, "
                    f"{sim.n_rebuilds - b0} list builds, "
                    f"{sim.n * (p.steps - s0) / dt:.3e} particle-steps/s (shared core)"
                )
            if p.stage == "pre_compression":
                save("fill")
        if p.stage == "consolidation" and p.steps - seen[p.stage][0] >= CONSOLIDATION_STEPS:
            save("consolidation")
            return False
        return True

    d = _Driver(_test(which), progress)
    try:
        d.run()
    except StopRequested:
        pass


#: One arm in a fresh process (argv: pickled states, steps, the order: as run, renumbered or
#: shuffled): CPU ns per particle-step of the calling thread, the order statistics, the list
#: builds.
_CHILD = """
import json, pickle, sys, time
import numpy as np
import engine

def order(sim):
    lst, m = sim._list, sim._n_entries
    i = np.repeat(np.arange(sim.n), np.diff(lst.start))
    d = np.abs(lst.j[:m].astype(np.int64) - i)
    return [float(np.median(d)), float(np.percentile(d, 90))]

paths, steps, order_as = sys.argv[1].split(","), int(sys.argv[2]), sys.argv[3]
out = {}
for path in paths:
    sim = pickle.loads(open(path, "rb").read())
    sim._threads = 1
    if hasattr(sim, "_renumber"):
        if order_as == "renumbered":
            sim._renumber()  # cell order now, and every RENUMBER_STEPS from here
        else:
            sim._next_renumber = 2**62
        if order_as == "shuffled":
            sim.permute(np.random.default_rng(1).permutation(sim.n))
    ordered = order(sim)
    sim.run(20)  # every buffer touched once
    c0 = time.thread_time()
    b0 = sim.n_rebuilds
    sim.run(steps)
    ns = (time.thread_time() - c0) / (sim.n * steps) * 1e9
    out[path] = {"ns": ns, "order": ordered, "builds": sim.n_rebuilds - b0, "n": sim.n}
print(json.dumps(out))
"""


#: The stage profile of one whole run (argv: which, the stored run's path): the driver's
#: kernel calls, list builds and curve samples timed (CPU time of the thread) per stage.
_STAGES = """
import json, sys, time
import engine.simulation.simulation as simulation
from engine.io.store import load_run
from engine.uniaxial import driver as drv

which, path = sys.argv[1], sys.argv[2]
acc = {"kernel": 0.0, "rebuild": 0.0, "sample": 0.0, "calls": 0, "builds": 0}

def timed(name, fn, count=None):
    def w(*a, **k):
        t = time.thread_time()
        try:
            return fn(*a, **k)
        finally:
            acc[name] += time.thread_time() - t
            if count:
                acc[count] += 1
    return w

S = simulation.Simulation
S._call_kernel = timed("kernel", S._call_kernel, "calls")
S._rebuild = timed("rebuild", S._rebuild, "builds")
drv._Recorder.sample = timed("sample", drv._Recorder.sample)
state = {"stage": None, "steps": 0, "t": time.thread_time(), "w": time.perf_counter(),
         "acc": dict(acc)}
d = None

def flush(stage_next, steps):
    now, w = time.thread_time(), time.perf_counter()
    ds = steps - state["steps"]
    delta = {k: acc[k] - state["acc"][k] for k in acc}
    cpu = now - state["t"]
    if ds > 0:
        ps = d.sim.n * ds
        print(json.dumps({
            "which": which, "stage": state["stage"], "steps": ds, "cpu_s": round(cpu, 1),
            "wall_s": round(w - state["w"], 1), "ns_total": round(cpu / ps * 1e9, 1),
            "ns_kernel": round(delta["kernel"] / ps * 1e9, 1),
            "ns_rebuild": round(delta["rebuild"] / ps * 1e9, 1),
            "ns_sample": round(delta["sample"] / ps * 1e9, 1), "calls": delta["calls"],
            "builds": delta["builds"],
            "ms_per_build": round(delta["rebuild"] / max(1, delta["builds"]) * 1e3, 2),
            "threads": d.sim.threads}), flush=True)
    state.update(stage=stage_next, steps=steps, t=now, w=w, acc=dict(acc))

def progress(p):
    if p.stage != state["stage"]:
        flush(p.stage, p.steps)
    return True

d = drv._Driver(load_run(path).test, progress)
res = d.run()
flush(None, d.sim.steps)
print(json.dumps({"which": which, "particle_steps": res.scalars["particle_steps"],
                  "wall_time": res.scalars["wall_time"]}), flush=True)
"""


def stages(baseline: str | None) -> int:
    """``--stages``: the whole coarse run and reference, CPU time by stage (see the module
    doc), one process each at one thread, at low priority."""
    import subprocess

    out_dir = HERE / "results" / "paper_speed"
    out_dir.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as stack:
        tree = ROOT if baseline is None else stack.enter_context(worktree(baseline))
        rev = (
            baseline
            or subprocess.run(
                ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                capture_output=True,
                text=True,
                check=True,
            ).stdout.strip()
        )
        out = out_dir / f"stages-{rev}.jsonl"
        for which in ("coarse", "reference"):
            with open(out, "a") as fh:
                subprocess.run(
                    ["nice", "-n", "19", sys.executable, "-c", _STAGES, which, str(RUNS[which])],
                    cwd=tree,
                    env={**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"},
                    stdout=fh,
                    check=True,
                )
        print(out.read_text())
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--states", action="store_true", help="only make the cached states")
    ap.add_argument("--stages", action="store_true", help="whole runs, CPU time by stage")
    ap.add_argument(
        "--baseline",
        default=None,
        help=f"git revision of the baseline engine (default {BASELINE}; with --stages: none)",
    )
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=2000, help="timed steps of the reference")
    args = ap.parse_args(argv)
    if args.stages:
        return stages(args.baseline)
    for which in ("coarse", "reference"):
        make_states(which, log=lambda s: print(s, flush=True))
    if args.states:
        return 0
    # the same particle-steps for both sizes: the coarse state runs 8x the steps
    steps = {"reference": args.steps, "coarse": args.steps * 8}
    paths = {w: [str(state_path(w, s)) for s in STATES] for w in steps}
    every = [p for w in steps for p in paths[w]]
    arms = ("baseline", "as run", "renumbered", "shuffled")
    rows: dict[str, list[dict]] = {a: [] for a in arms}
    with worktree(args.baseline or BASELINE) as base, tempfile.TemporaryDirectory() as tmp:
        trees = {a: (ROOT, a) for a in arms}
        trees["baseline"] = (base, "as run")
        for r in range(args.rounds):
            order = arms if r % 2 == 0 else arms[::-1]
            for arm in order:
                tree, order_as = trees[arm]
                got = {}
                for which, n_steps in steps.items():
                    got.update(
                        run_child(
                            tree,
                            _CHILD,
                            (",".join(paths[which]), n_steps, order_as),
                            NUMBA_NUM_THREADS=1,
                            DEMSCALE_CACHE_DIR=Path(tmp) / arm.replace(" ", "_"),
                        )
                    )
                rows[arm].append(got)
            print(
                f"round {r + 1}: "
                + "; ".join(
                    f"{a} " + " ".join(f"{rows[a][-1][p]['ns']:.0f}" for p in every) for a in arms
                )
                + " ns",
                flush=True,
            )

    def med(arm, path):
        return statistics.median(x[path]["ns"] for x in rows[arm])

    def ratio(arm, path, other="baseline"):
        return statistics.median(
            a[path]["ns"] / b[path]["ns"] for a, b in zip(rows[arm], rows[other])
        )

    print(
        f"\none thread, CPU time of the thread per particle-step [ns], median of {args.rounds} "
        f"rounds; {steps['reference']} steps of the reference, {steps['coarse']} of the coarse run"
    )
    print(
        "| run | state | particles | order: median, p90 of abs(i - j) (as run -> renumbered) "
        "| baseline | as run | renumbered | shuffled | renumbered / baseline | shuffled / "
        "renumbered |"
    )
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for which in steps:
        for state, path in zip(STATES, paths[which]):
            a, b = rows["as run"][0][path], rows["renumbered"][0][path]
            print(
                f"| {which} | {state} | {a['n']} | {a['order'][0]:.0f}, {a['order'][1]:.0f} -> "
                f"{b['order'][0]:.0f}, {b['order'][1]:.0f} | {med('baseline', path):.1f} | "
                f"{med('as run', path):.1f} | {med('renumbered', path):.1f} | "
                f"{med('shuffled', path):.1f} | {ratio('renumbered', path):.3f} | "
                f"{ratio('shuffled', path, 'renumbered'):.3f} |"
            )
    checks = []
    for state, ref, coarse in zip(STATES, paths["reference"], paths["coarse"]):
        per = {
            arm: statistics.median(x[ref]["ns"] / x[coarse]["ns"] for x in rows[arm])
            for arm in arms
        }
        print(
            f"\n{state}: reference / coarse cost per particle-step: baseline "
            f"{per['baseline']:.2f}, as run {per['as run']:.2f}, renumbered "
            f"{per['renumbered']:.2f}, shuffled {per['shuffled']:.2f}"
        )
        checks.append(
            (
                f"{state}: the reference within {TARGET}x of the coarse run per particle-step "
                f"(this engine): {per['renumbered']:.2f}x",
                per["renumbered"] <= TARGET,
            )
        )
        for which, path in (("reference", ref), ("coarse", coarse)):
            q = ratio("renumbered", path)
            checks.append(
                (
                    f"{state}, {which}: not slower than the baseline: {q:.3f} <= 1.03 (the "
                    "spread of repeated measurements, benchmarks/README.md)",
                    q <= 1.03,
                )
            )
    return report(checks)


if __name__ == "__main__":
    sys.exit(main())
