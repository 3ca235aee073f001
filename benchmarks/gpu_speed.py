"""The CUDA backend's targets (issue 21), each against the same scene on the CPU of the same
host, in one call:

    python -m benchmarks.engine_speed --backend cuda [--deadline 480]
    python -m benchmarks.engine_speed --backend cuda --batch 15    # target 4 alone

1. particle-steps/s on a settled bed (the 2,025-particle LIGGGHTS anchor packing, periodic
   in x and y, tiled 3x3, 8x8, 22x22 and 63x63: 18k, 130k, 980k and 8.0M particles, the
   full bilinear law, a bottom and a moving top platen) on the GPU and on the CPU (all
   cores; fewer steps at the large sizes);
2. the paper-scale reference of experiment (b) (``ref-s1``, 20,626 particles) on the GPU,
   its wall time against the target; the CPU's time for it is projected from the CPU rate
   measured in 1 on the 18k bed (the full run on the CPU takes about 7 minutes on 16 cores);
3. its bulk curves against the stored CPU run of the same test
   (benchmarks/results/paper/b_cohesive/ref-s1.h5): each verdict metric's relative
   difference against the bound a second seed of the same reference would keep
   (:func:`same_physics_bound`; the GPU's last bits differ, which makes a long run another
   realisation of the same packing, not a copy of the CPU's); the same for the
   reference at the default protocol (``benchmarks/results/paper/protocol/ref-I5e-4-f0.4``,
   the test new studies run), which is timed first. The GPU runs are stored under
   benchmarks/results/gpu/ so that their metrics can be recomputed;
4. experiment (b)'s 15 runs side by side on the card (one process per run, each stored as
   it finishes): a call of its own, ``--batch 15`` (its target alone is 15 minutes); the
   default call reports it as not measured.

Issue 54's figures, a call of their own (``--runs``, within ``--deadline``): (a) the
paper-scale reference at the default protocol alone, its wall time against 30 s (curve
samples measured on the device, engine.cuda.measures); (b) experiment (b)'s runs at the
default protocol side by side in this process through engine.cuda.batch (a thread and a CUDA
stream each, ``--workers`` at once, default all), the card's aggregate particle-steps/s:

    python -m benchmarks.engine_speed --backend cuda --runs [--workers N] [--deadline 480]
    NUMBA_ENABLE_CUDASIM=1 python -m benchmarks.engine_speed --backend cuda --runs --smoke \
        --deadline 30    # tiny tests under the simulator: the code path, no figures

Without a usable CUDA device every GPU figure is printed as "not measured" and the exit
status is 1. No figure is ever estimated where it says measured. ``--deadline`` [s] skips
what would start after it (reported as not measured).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np

import engine
from benchmarks.checks import report

HERE = Path(__file__).resolve().parent
STORED_REF = HERE / "results" / "paper" / "b_cohesive"
GPU_STORE = HERE / "results" / "gpu"
TILES = {"18k": 3, "130k": 8, "980k": 22, "8.0M": 63}
#: steps timed per size (after 50 warm-up steps): GPU, CPU
STEPS = {"18k": (4000, 400), "130k": (2000, 100), "980k": (1000, 30), "8.0M": (300, 10)}
TARGET_RATE_1M = 5e8
TARGET_REFERENCE_S = 120.0
TARGET_BATCH_S = 900.0
#: issue 54: the paper-scale reference at the default protocol on one GPU [s]
TARGET_DEFAULT_REF_S = 30.0


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def tiled_bed(k: int):
    """The anchor bed tiled k x k in x and y (periodic there, so the tiles join without a
    seam): positions [m], radii [m], box lengths [m]."""
    from benchmarks.engine_speed import anchor_bed

    pos, rad, lengths = anchor_bed()
    shifts = np.array(
        [(ix * lengths[0], iy * lengths[1], 0.0) for ix in range(k) for iy in range(k)]
    )
    big = (pos[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    return big, np.tile(rad, k * k), np.array([k * lengths[0], k * lengths[1], lengths[2]])


def rate(backend: str, k: int, steps: int) -> tuple[float, float, object]:
    """Particle-steps per second over ``steps`` steps after a warm-up, and the set-up time
    (kernel compile or load, first list build) [s]."""
    from benchmarks.engine_speed import DT, FULL, R, scene_for

    pos, rad, lengths = tiled_bed(k)
    top = float((pos[:, 2] + rad).max()) + 0.1 * R
    t0 = time.perf_counter()
    sim = engine.Simulation(
        scene_for(pos, rad, lengths, FULL, top),
        dt=DT,
        backend=backend,
        threads=os.cpu_count() if backend == "cpu" else None,
    )
    sim.run(50)
    _ = sim.positions  # the device has finished (a copy waits for it)
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    sim.run(steps)
    _ = sim.wall_forces
    return sim.n * steps / (time.perf_counter() - t0), setup, sim


def profile_passes(sim, reps: int = 20) -> dict[str, float]:
    """Where a step's time goes on the device [s per call]: each pass of the four-launch
    step timed alone (``reps`` times, synchronised; the pair pass and the particle pass in
    force-only mode, which leave the positions as they are), a neighbour-list build, and the
    host's cost of one launch (kernels that return at once: the control record says stop)."""
    from numba import cuda

    from engine.cuda.kernels import RED_T, THREADS
    from engine.cuda.simulation import _blocks

    sim.run(1)
    d, dk = sim._dev, sim._dk
    n, nchunk, forces = sim.n, len(d.cdisp), dk.cpu.FORCES
    P, L, W, prm = d.P, d.L, d.W, d.prm
    calls = {
        "pair pass": lambda: dk.pair_kernel[_blocks(n), THREADS](d.ctl, P, L, prm, d.stat),
        "particle pass": lambda: dk.particle_kernel[_blocks(n), THREADS](
            d.ctl, forces, P, L, W, prm, d.stat, d.wpart, d.disp
        ),
        "chunk reductions": lambda: dk.chunk_kernel[_blocks(nchunk), THREADS](
            d.ctl, forces, d.stat, d.wpart, d.disp, d.cstat, d.cdisp, W.acc
        ),
        "end of step": lambda: dk.finish_kernel[1, RED_T](
            d.ctl, 0, 1, 0, W, prm, d.cstat, d.cdisp, W.acc, d.info
        ),
        "list build": sim._rebuild,
    }
    out = {}
    for name, call in calls.items():
        dk.reset_ctl[1, 1](d.ctl)
        call()
        cuda.synchronize()
        t0 = time.perf_counter()
        for _ in range(reps):
            dk.reset_ctl[1, 1](d.ctl)
            call()
        cuda.synchronize()
        out[name] = (time.perf_counter() - t0) / reps
    d.ctl.copy_to_device(np.array([1, 0, 0, 0], dtype=np.int64))  # stopped: kernels return
    cuda.synchronize()
    t0 = time.perf_counter()
    for _ in range(reps * 10):
        calls["pair pass"]()
    t1 = time.perf_counter()
    cuda.synchronize()
    out["host time of one launch (pair kernel)"] = (t1 - t0) / (reps * 10)
    dk.reset_ctl[1, 1](d.ctl)
    return out


def reference_test():
    """Experiment (b)'s paper-scale reference ``ref-s1`` (20,626 particles) at the seed's
    protocol, as stored in benchmarks/results/paper/b_cohesive."""
    from benchmarks.experiments import experiments

    spec = experiments("paper")["b_cohesive"]
    return next(p.test for p in engine.plan(spec).runs if p.key == "ref-s1")


def default_reference_paths() -> list[Path]:
    """The stored CPU runs of the paper-scale reference at the default protocol, seeds 1-3
    (benchmarks/protocol.py)."""
    from benchmarks.protocol import job

    return [job("ref", "default", s)[1] for s in (1, 2, 3)]


def default_reference_test():
    """The same reference at the default protocol (time step from the contact time, loading
    at the default inertial number): the test a new study runs (docs/PROTOCOL.md)."""
    from benchmarks.protocol import job

    return job("ref", "default", 1)[0]


def run_reference(test, cap_s: float):
    """``test`` on the GPU, stopped at ``cap_s`` of wall time [s]: (result or None, wall
    time [s])."""
    t0 = time.perf_counter()

    def progress(p):
        return time.perf_counter() - t0 < cap_s

    try:
        res = engine.run_uniaxial(test, progress, backend="cuda")
    except engine.StopRequested:
        return None, time.perf_counter() - t0
    return res, time.perf_counter() - t0


def same_physics_bound(sd: float, seeds: int, metrics: int, alpha: float = 0.05) -> float:
    """The largest difference [-] between the GPU's run and the CPU's run of the same test
    that a second realisation of the same physics keeps with probability 1 - ``alpha``
    jointly over ``metrics`` metrics (Bonferroni), given the seed-to-seed standard deviation
    ``sd`` [-] estimated from ``seeds`` stored reference seeds.

    A long GPU run is not a copy of the CPU's: its last bits differ (NVVM may fuse
    multiply-adds), and a granular packing amplifies them until the run is another realisation of
    the same packing (the simulator's short runs are bit-identical, tests/engine/test_cuda.py).
    The difference of two realisations has standard deviation sqrt(2) sd, and with ``sd``
    estimated from ``seeds`` seeds the bound is Student's t quantile on seeds - 1 degrees of
    freedom: t(1 - alpha / (2 metrics), seeds - 1) sqrt(2) sd. Its coverage and power are
    checked by simulation in tests/engine/test_gpu_rule.py; with 3 seeds it rules out only
    gross differences (some 10 sd), which is all 3 seeds can tell."""
    from engine.study.intervals import t_quantile

    if seeds < 2:
        raise ValueError("same_physics_bound: an sd needs at least 2 seeds")
    return t_quantile(1.0 - alpha / (2 * metrics), seeds - 1) * np.sqrt(2.0) * sd


def curve_check(res, ref_paths, label: str) -> list[tuple[str, bool | None]]:
    """Each verdict metric of the GPU run ``res`` against the stored CPU run of the same
    test (``ref_paths[0]``), within :func:`same_physics_bound` of the stored seeds' spread."""
    from engine.io.store import load_run
    from engine.study.metrics import metric_names, metric_values, noise_floor, relative_error

    if not all(p.exists() for p in ref_paths):
        return [
            (f"GPU and CPU {label}: not measured (stored CPU runs missing)", None),
        ]
    refs = [load_run(p) for p in ref_paths]
    test = res.test
    if refs[0].test != test:
        return [(f"GPU and CPU {label}: not measured (stored CPU run of another test)", None)]
    names = metric_names(test.unconfined)
    floor = noise_floor([metric_values(r) for r in refs], names, test.consolidation_stress)
    gpu, cpu = metric_values(res), metric_values(refs[0])
    out = []
    for n in names:
        err = relative_error(n, gpu[n], cpu[n], test.consolidation_stress)
        sd = floor[n]["noise"]
        bound = same_physics_bound(sd, len(refs), len(names))
        out.append(
            (
                f"GPU vs CPU {label} {n}: relative difference {err:.2e} = {err / sd:.2f} seed "
                f"sd <= {bound:.2e} (a second seed's bound, {len(refs)} seeds)",
                err <= bound,
            )
        )
    return out


def reference_item(test, ref_paths, label: str, cap_s: float, cpu_rate, checks) -> None:
    """Run ``test`` on the GPU, store it under :data:`GPU_STORE`, time it against the
    target and check its curves against the stored CPU runs ``ref_paths``."""
    from engine.io.store import save_run

    res, wall = run_reference(test, cap_s)
    if res is None:
        checks.append(
            (f"{label} <= {TARGET_REFERENCE_S:.0f} s: stopped unfinished after {wall:.0f} s", False)
        )
        checks.append((f"GPU and CPU {label}: not measured (unfinished)", False))
        return
    GPU_STORE.mkdir(parents=True, exist_ok=True)
    save_run(GPU_STORE / f"{ref_paths[0].stem}.h5", res, keep_particles=False)
    s = res.scalars
    proj = (
        f"; CPU of this host projected from its 18k rate: {s['particle_steps'] / cpu_rate:.0f} s"
        if cpu_rate
        else ""
    )
    print(
        f"\n{label}: {test.n_particles} particles, {s['steps']:.0f} steps: GPU wall time "
        f"{s['wall_time']:.1f} s (set-up {s['setup_time']:.1f} s, {wall:.1f} s in all; "
        f"{s['particle_steps'] / s['wall_time']:.3e} particle-steps/s){proj}",
        flush=True,
    )
    checks.append(
        (
            f"{label} <= {TARGET_REFERENCE_S:.0f} s on the GPU: {s['wall_time']:.1f} s",
            s["wall_time"] <= TARGET_REFERENCE_S,
        )
    )
    checks += curve_check(res, ref_paths, label)


def run_batch(workers: int, store: Path) -> tuple[float, dict]:
    """Experiment (b)'s planned runs (3 references, 12 coarse) side by side on the card: one
    process per run (``workers`` at a time, one engine thread each, every one on the GPU),
    each stored under ``store`` as it finishes. Returns the wall time [s] and the outcomes."""
    import concurrent.futures as cf
    import multiprocessing as mp

    from benchmarks.experiments import experiments
    from engine.io.store import save_run

    spec = experiments("paper")["b_cohesive"]
    spec = replace(spec, decide=False)  # the 15 planned runs, no added seeds
    store.mkdir(parents=True, exist_ok=True)
    outcomes: dict = {}

    def on_run(key, outcome) -> None:
        outcomes[key] = outcome
        if not isinstance(outcome, str):
            save_run(store / f"{key}.h5", outcome, keep_particles=False)
        print(
            f"  {key}: {'failed: ' + outcome if isinstance(outcome, str) else 'stored'} "
            f"at {time.perf_counter() - t0:.0f} s",
            flush=True,
        )

    t0 = time.perf_counter()
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
        engine.run_study(spec, executor=pool, on_run=on_run, task_threads=1, backend="cuda")
    return time.perf_counter() - t0, outcomes


def timed_run(test, cap_s: float) -> dict:
    """:func:`timed_any`'s record of ``test`` alone (the result left out)."""
    return timed_any(test, cap_s)[1]


def smoke_tests(k: int) -> list:
    """``k`` tiny uniaxial tests (about 30 particles, seeds 1..k; the smallest configuration
    of ``--runs --smoke``, which checks the code path, under the simulator as well)."""
    return [
        engine.UniaxialTest(cell=(0.015, 0.015, 0.015), output_interval=1e-3, seed=s)
        for s in range(1, k + 1)
    ]


def runs_item(args, simulated: bool, deadline: float) -> list[tuple[str, bool]]:
    """Issue 54's GPU figures in one call: (a) the paper-scale reference at the default
    protocol, alone, its wall time against :data:`TARGET_DEFAULT_REF_S`; (b) experiment (b)'s
    runs at the default protocol side by side through :func:`engine.cuda.batch.run_together`
    (a thread and a stream each, ``--workers`` at once), the card's aggregate
    particle-steps/s (steps made by all runs over the batch's wall time, set-up included)
    and, if it ends before the cap, its wall time. Each part stops at its share of
    ``deadline`` [s] and reports what it made. ``--smoke``: tiny tests instead (the code path
    only; under the simulator no figure is one)."""
    from benchmarks.experiments import experiments
    from engine.cuda.batch import run_together

    t_start = time.perf_counter()
    checks: list[tuple[str, bool]] = []
    label = " (smoke: tiny tests, not figures)" if args.smoke else ""
    if simulated:
        label = " (simulator: not figures)"
    if args.smoke:
        ref, batch = smoke_tests(1)[0], smoke_tests(3)
    else:
        ref = default_reference_test()
        spec = replace(experiments("paper", protocol="default")["b_cohesive"], decide=False)
        batch = [p.test for p in engine.plan(spec).runs]
    cap_a = max(10.0, 0.35 * deadline)
    # the wall time of (a)'s curve samples (measured on the device since issue 54; docs/GPU.md
    # bounded them at about 250 s of the seed protocol's 344 s when they copied the state)
    import engine.uniaxial.driver as drv

    sampling = {"s": 0.0, "n": 0}
    plain = drv._Recorder.sample

    def sample(rec):
        t = time.perf_counter()
        try:
            return plain(rec)
        finally:
            sampling["s"] += time.perf_counter() - t
            sampling["n"] += 1

    drv._Recorder.sample = sample
    try:
        a = timed_run(ref, cap_a)
    finally:
        drv._Recorder.sample = plain
    rate_a = a["particles"] * a["steps"] / a["wall"]
    print(
        f"\n(a) reference at the default protocol{label}: {a['particles']} particles, "
        f"{a['steps']} steps, {'finished' if a['finished'] else 'stopped at the cap'} in "
        f"{a['wall']:.1f} s (set-up {a['setup'] if a['setup'] is None else round(a['setup'], 1)} "
        f"s), {rate_a:.3e} particle-steps/s; {sampling['n']} curve samples took "
        f"{sampling['s']:.1f} s ({1e3 * sampling['s'] / max(1, sampling['n']):.2f} ms each)",
        flush=True,
    )
    wall_a = a.get("run_wall", a["wall"])
    checks.append(
        (
            f"(a) paper-scale reference, default protocol, <= {TARGET_DEFAULT_REF_S:.0f} s on "
            f"the GPU{label}: "
            + (
                f"{wall_a:.1f} s (set-up left out)"
                if a["finished"]
                else f"unfinished at {a['wall']:.0f} s"
            ),
            a["finished"] and wall_a <= TARGET_DEFAULT_REF_S and not simulated,
        )
    )
    cap_b = max(10.0, deadline - (time.perf_counter() - t_start))
    workers = min(args.workers or len(batch), len(batch))
    t0 = time.perf_counter()
    outs = run_together([lambda t=t: timed_run(t, cap_b) for t in batch], max_workers=workers)
    wall_b = time.perf_counter() - t0
    total = sum(o["particles"] * o["steps"] for o in outs)
    finished = sum(o["finished"] for o in outs)
    print(
        f"(b) {len(batch)} runs side by side{label}, {workers} at once, launch "
        f"{os.environ.get('DEMSCALE_CUDA_LAUNCH', 'persistent')}: "
        f"{sum(o['particles'] for o in outs)} particles, {finished} finished in {wall_b:.1f} s, "
        f"{total:.3e} particle-steps, aggregate {total / wall_b:.3e} particle-steps/s",
        flush=True,
    )
    for o, t in zip(outs, batch):
        print(
            f"  {t.n_particles} particles seed {t.seed}: {o['steps']} steps, "
            f"{'finished' if o['finished'] else 'stopped'} at {o['wall']:.1f} s"
        )
    checks.append(
        (
            f"(b) experiment (b)'s {len(batch)} runs side by side{label}: aggregate "
            f"{total / wall_b:.3e} particle-steps/s, "
            + (f"all done in {wall_b:.0f} s" if finished == len(outs) else f"{finished} finished"),
            finished == len(outs) and not simulated,
        )
    )
    return checks


#: issue 54's third point: the series' runs on the GPU, each against the stored CPU seeds of
#: the same test; (series, run key of the series' module, the scalar compared)
SERIES_RUNS = (
    ("outlet", ("flow", 30.0, 64.0, 1), "discharge_number"),
    ("size", ("column", "bond1", 20.0, 1), "unconfined_strength"),
)


def series_runs(smoke: bool) -> list[tuple[str, object, dict[int, Path], str]]:
    """(label, test, {seed: stored CPU digest of the same test at that seed}, scalar) of
    :data:`SERIES_RUNS` (the test is seed 1's); ``smoke``: tiny tests of the same kinds
    (the code path only)."""
    from benchmarks import outlet_series, size_series

    if smoke:
        return [
            ("hopper (smoke)", engine.HopperTest(outlet_width=0.03, particles=100), {}, ""),
            ("column (smoke)", smoke_tests(1)[0], {}, ""),
        ]
    out = []
    for series, key, scalar in SERIES_RUNS:
        mod = outlet_series if series == "outlet" else size_series
        test = mod.test_of(*key)
        seeds = {s: (*key[:-1], s) for s in range(1, 5)}
        paths = {s: mod.path_of(*k) for s, k in seeds.items() if mod.stored(*k) is not None}
        out.append((f"{series} series {mod.key_name(*key)}", test, paths, scalar))
    return out


def timed_any(test, cap_s: float) -> tuple[object | None, dict]:
    """A uniaxial or hopper ``test`` on the GPU, stopped at ``cap_s`` of wall time [s]:
    (result or None, {particles, steps made, wall [s] (set-up included), finished, setup [s]
    and run_wall [s] (the run's own wall time) where it finished, error: why it failed or
    None}); a run that fails (instability, a stage's limit) is reported, not raised."""
    t0 = time.perf_counter()
    done = {"steps": 0}

    def progress(p):
        done["steps"] = p.steps
        return time.perf_counter() - t0 < cap_s

    run = engine.run_hopper if isinstance(test, engine.HopperTest) else engine.run_uniaxial
    out = {"particles": test.n_particles, "finished": False, "setup": None, "error": None}
    try:
        res = run(test, progress, backend="cuda")
    except engine.StopRequested:
        out.update(steps=done["steps"], wall=time.perf_counter() - t0)
        return None, out
    except (engine.InstabilityError, engine.StageError, FloatingPointError) as e:
        out.update(steps=done["steps"], wall=time.perf_counter() - t0)
        out["error"] = f"{type(e).__name__}: {e}"
        return None, out
    s = res.scalars
    out.update(
        steps=int(s["steps"]),
        wall=time.perf_counter() - t0,
        run_wall=s["wall_time"],
        setup=s.get("setup_time"),
        finished=True,
    )
    return res, out


def series_item(args, simulated: bool, deadline: float) -> list[tuple[str, bool]]:
    """Issue 54's third point: (c) one run of the outlet series (the 64 d discharge, 36,651
    particles) and (d) one 20-diameter size of the resolution series (the released column,
    55,004 particles) on the GPU, one after the other, each stopped at half of ``deadline``
    [s]: its wall time beside the seconds its stored run took on one thread of the 2-core
    VM (CPU seconds where the digest has them, else wall seconds; another machine: a cost,
    not a speed-up), and its scalar against seed 1's stored CPU run within
    :func:`same_physics_bound` of the stored seeds' spread (a GPU run is another
    realisation of the same fill; with two seeds the bound is wide: t on one degree of
    freedom). ``--smoke``: tiny tests (the code path only)."""
    from engine.io.digest import read_digest

    t_start = time.perf_counter()
    checks: list[tuple[str, bool]] = []
    note = " (simulator: not figures)" if simulated else (" (smoke)" if args.smoke else "")
    items = series_runs(args.smoke)
    for i, (label, test, paths, scalar) in enumerate(items):
        left = deadline - (time.perf_counter() - t_start)
        cap = max(10.0, left / (len(items) - i))
        res, o = timed_any(test, cap)
        rate = o["particles"] * o["steps"] / o["wall"]
        digests = {seed: read_digest(p) for seed, p in paths.items()}
        first = digests.get(1)
        took = ""
        if first is not None:
            cpu = first.extra.get("cpu_seconds")
            took = (
                f"; its stored CPU run took {cpu:.0f} CPU s on one thread"
                if cpu
                else f"; its stored CPU run took {first.scalars['wall_time']:.0f} wall s on "
                "one thread of a loaded 2-core VM"
            )
        ended = "finished" if o["finished"] else (o["error"] or "stopped at the cap")
        print(
            f"\n{label}{note}: {o['particles']} particles, {o['steps']} steps, {ended} after "
            f"{o['wall']:.1f} s (set-up included), {rate:.3e} particle-steps/s{took}",
            flush=True,
        )
        what = f"{label} on the GPU{note}: " + (
            f"{o['wall']:.1f} s"
            if o["finished"]
            else (f"failed: {o['error']}" if o["error"] else f"unfinished at {o['wall']:.0f} s")
        )
        checks.append((what, o["finished"] and not simulated))
        if res is None or not scalar:
            continue
        if not args.smoke:  # stored, so that its measures can be recomputed
            from engine.io.digest import make_digest, write_digest

            name = label.split()[0] + "-" + label.split()[-1].replace("/", "-")
            extra = {"gpu_wall_seconds": o["wall"], "backend": "cuda"}
            write_digest(GPU_STORE / "series" / f"{name}.json", make_digest(res, test, None, extra))
        gpu = float(res.scalars[scalar])
        vals = np.array([d.scalars[scalar] for d in digests.values() if scalar in d.scalars], float)
        if len(vals) < 2 or first is None or scalar not in first.scalars:
            checks.append(
                (
                    f"{label} {scalar}: GPU {gpu:.4g} against {len(vals)} stored CPU seed(s): "
                    "not judged (a seed sd needs two, seed 1 among them)",
                    False,
                )
            )
            continue
        sd = float(np.std(vals, ddof=1) / abs(vals.mean()))
        cpu1 = float(first.scalars[scalar])
        err = abs(gpu - cpu1) / abs(cpu1)
        bound = same_physics_bound(sd, len(vals), 1)
        checks.append(
            (
                f"{label} {scalar}: GPU {gpu:.4g} against seed 1 on the CPU {cpu1:.4g}: "
                f"{err:.2e} <= {bound:.2e} (a second seed's bound, {len(vals)} seeds)",
                err <= bound and not simulated,
            )
        )
    return checks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="issue 21 targets of the CUDA backend")
    ap.add_argument(
        "--deadline", type=float, default=480.0, help="seconds after which nothing new starts [s]"
    )
    ap.add_argument("--sizes", default=",".join(TILES), help="bed sizes to time")
    ap.add_argument(
        "--batch",
        type=int,
        default=0,
        metavar="WORKERS",
        help="only experiment (b)'s 15 runs side by side on the card, WORKERS "
        "processes at a time (a call of its own: the target is 15 minutes)",
    )
    ap.add_argument(
        "--runs",
        action="store_true",
        help="only issue 54's figures: the reference at the default protocol alone, then "
        "experiment (b)'s runs side by side through engine.cuda.batch (within --deadline)",
    )
    ap.add_argument(
        "--series",
        action="store_true",
        help="only issue 54's series runs: one outlet-series hopper and one 20-diameter "
        "column on the GPU against their stored CPU seeds (within --deadline)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=0,
        help="with --runs: runs side by side at once (0, the default: all of them)",
    )
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="with --runs: tiny tests instead (the code path; runs under the simulator)",
    )
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    from engine.simulation.backend import cuda_status

    ok, device = cuda_status()
    print(
        f"demscale CUDA benchmark: GPU {device}; CPU {cpu_model()}, {os.cpu_count()} "
        f"cores, numba {numba.__version__} ({numba.config.NUMBA_NUM_THREADS} threads), "
        f"numpy {np.__version__}"
    )
    simulated = ok and "simulator" in device
    if args.runs and (ok and (not simulated or args.smoke)):
        return report(runs_item(args, simulated, args.deadline))
    if args.series and (ok and (not simulated or args.smoke)):
        return report(series_item(args, simulated, args.deadline))
    if not ok or "simulator" in device:
        why = "no CUDA device" if not ok else "the simulator is no GPU"
        print(f"{why}: not measured ({device})")
        if args.series:
            return report(
                [(f"{label} on the GPU: {why}: not measured", False) for label, *_ in SERIES_RUNS]
            )
        if args.runs:
            return report(
                [
                    (f"(a) reference at the default protocol: {why}: not measured", False),
                    (f"(b) experiment (b)'s runs side by side: {why}: not measured", False),
                ]
            )
        return report(
            [
                (
                    f"GPU >= {TARGET_RATE_1M:.0e} particle-steps/s at 1M particles: {why}: not "
                    "measured",
                    False,
                ),
                (
                    f"paper-scale reference <= {TARGET_REFERENCE_S:.0f} s: {why}: not measured",
                    False,
                ),
                (f"experiment (b)'s 15 runs <= {TARGET_BATCH_S:.0f} s: {why}: not measured", False),
                (
                    f"GPU and CPU bulk curves within a second seed's bound: {why}: not measured",
                    False,
                ),
            ]
        )
    from numba import cuda

    try:
        from importlib.metadata import version

        ncv = version("numba-cuda")
    except Exception:
        ncv = "?"
    print(
        f"numba-cuda {ncv}, driver/runtime "
        f"{cuda.runtime.get_version() if hasattr(cuda, 'runtime') else '?'}",
        flush=True,
    )

    def late() -> bool:
        return time.perf_counter() - t_start > args.deadline

    if args.batch:
        wall, outcomes = run_batch(args.batch, HERE / "results" / "gpu" / "b_cohesive")
        failed = [k for k, v in outcomes.items() if isinstance(v, str)]
        return report(
            [
                (
                    f"experiment (b)'s {len(outcomes)} runs side by side on the card "
                    f"({args.batch} processes) <= {TARGET_BATCH_S:.0f} s: {wall:.0f} s"
                    f"{', failed: ' + ', '.join(failed) if failed else ''}",
                    wall <= TARGET_BATCH_S and not failed,
                )
            ]
        )

    checks: list[tuple[str, bool | None]] = []
    rates: dict[tuple[str, str], float] = {}
    print("\n| bed | particles | backend | particle-steps/s | set-up [s] | steps |")
    print("|---|---:|---|---:|---:|---:|")

    def measure(sizes) -> None:
        for name in sizes:
            for backend, steps in zip(("cuda", "cpu"), STEPS[name]):
                if late():
                    print(f"| {name} | | {backend} | not measured (deadline) | | |")
                    continue
                try:
                    r, setup, sim = rate(backend, TILES[name], steps)
                except Exception as e:  # e.g. out of device memory: reported, go on
                    print(f"| {name} | | {backend} | failed: {type(e).__name__}: {e} | | |")
                    continue
                rates[name, backend] = r
                print(
                    f"| {name} | {sim.n} | {backend} | {r:.3e} | {setup:.1f} | {steps} |",
                    flush=True,
                )
                del sim

    sizes = args.sizes.split(",")
    measure([s for s in sizes if s != "8.0M"])  # 8M last: after the reference
    g1 = rates.get(("980k", "cuda"))
    checks.append(
        (
            f"GPU >= {TARGET_RATE_1M:.0e} particle-steps/s at 1M particles (980k bed): {g1:.3e}"
            if g1
            else "GPU rate at 1M: not measured",
            (g1 >= TARGET_RATE_1M) if g1 else False,
        )
    )

    for label, test, paths in (
        (
            "paper-scale reference, default protocol",
            default_reference_test,
            default_reference_paths,
        ),
        (
            "paper-scale reference, seed's protocol",
            reference_test,
            lambda: [STORED_REF / f"ref-s{s}.h5" for s in (1, 2, 3)],
        ),
    ):
        if late():
            checks.append((f"{label}: not measured (deadline)", False))
            continue
        cap = max(60.0, args.deadline - (time.perf_counter() - t_start))
        reference_item(test(), paths(), label, cap, rates.get(("18k", "cpu")), checks)
    if "8.0M" in sizes:
        measure(["8.0M"])
    if not late():  # the closing note's profile: the 980k bed, one launch per pass
        from benchmarks.engine_speed import DT, FULL, R, scene_for

        os.environ["DEMSCALE_CUDA_LAUNCH"] = "passes"
        try:
            pos, rad, lengths = tiled_bed(TILES["980k"])
            top = float((pos[:, 2] + rad).max()) + 0.1 * R
            sim = engine.Simulation(scene_for(pos, rad, lengths, FULL, top), dt=DT, backend="cuda")
            print(f"\nprofile, {sim.n} particles, one launch per pass [ms per call]:")
            for what, sec in profile_passes(sim).items():
                print(f"  {what}: {sec * 1e3:.3f} ms")
            del sim
        except Exception as e:
            print(f"profile failed: {type(e).__name__}: {e}")
        finally:
            os.environ.pop("DEMSCALE_CUDA_LAUNCH", None)
    for name in TILES:
        g, c = rates.get((name, "cuda")), rates.get((name, "cpu"))
        if g and c:
            print(f"  {name}: GPU {g:.3e} / CPU {c:.3e} particle-steps/s = {g / c:.1f}x")
    checks.append(
        (
            f"experiment (b)'s 15 runs side by side <= {TARGET_BATCH_S:.0f} s: not "
            "measured in this call (a call of its own: --batch 15)",
            False,
        )
    )
    print(f"\nelapsed {time.perf_counter() - t_start:.0f} s")
    return report([(w, bool(o)) for w, o in checks])


if __name__ == "__main__":
    raise SystemExit(main())
