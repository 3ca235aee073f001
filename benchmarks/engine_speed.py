"""Engine speed benchmark: particle-steps per second on a settled bed under a moving platen.

    python -m benchmarks.engine_speed            # full run (a few minutes)
    python -m benchmarks.engine_speed --quick    # 2k beds only, shorter runs
    python -m benchmarks.engine_speed --profile  # also a profile of the hot loop per pass
    python -m benchmarks.engine_speed --pairs 3 [--baseline REV]  # against LIGGGHTS, interleaved
    python -m benchmarks.engine_speed --backend cuda  # the GPU targets (benchmarks/gpu_speed.py)

Scene (issue 2): R = 2.5 mm spheres, density 2000, periodic x and y, bottom platen and a top platen
moving down at 10 mm/s, dt = 1e-5 s; law K1 = 5e3, K2 = 2.5e4 N/m, f0 = -0.4 N, mu_s = 0.5, mu_r =
0.001, restitution 0.4. Beds of about 2,000 and 16,000 particles are built with
engine.simulation.packing and settled once (cached under benchmarks/.cache). Every configuration
starts from the same settled state; each figure is the median of ``--repeats`` timed runs. If
``liggghts`` is on the PATH, its hooke/hysteresis model runs the same packings (the 2,025-particle
anchor bed of benchmarks/liggghts and the settled 16k bed, written as a LAMMPS data file) with the
LIGGGHTS 3.8 deck in the same session, as the baseline of the targets.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import engine
from benchmarks.checks import report
from engine.simulation import packing
from engine.simulation.simulation import run_team

HERE = Path(__file__).resolve().parent
CACHE = HERE / ".cache"
R = 2.5e-3
RHO = 2000.0
DT = 1e-5
PLATEN_SPEED = 0.01

FULL = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)
PLAIN = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.0, mu_r=0.0, restitution=0.4)
WALL_LAW = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.3)
WALL = engine.WallMaterial(E=2e11, nu=0.3)


def scene_for(
    pos,
    rad,
    lengths,
    law,
    top: float | None,
    platen_speed: float = PLATEN_SPEED,
    wall_law=WALL_LAW,
    wall_material=WALL,
    velocities=None,
    periodic: bool = True,
):
    """The bed ``pos``, ``rad`` [m] (``velocities`` [m/s], None: at rest) in a cell of
    ``lengths`` [m] periodic in x and y (unless ``periodic`` is False), on a floor at z = 0
    and (``top`` [m] not None) under a top platen moving down at ``platen_speed`` [m/s],
    under gravity, with the pair law ``law`` and the walls' ``wall_law`` and
    ``wall_material``. The engine tests' beds too (tests/engine/helpers.py)."""
    walls = [engine.Plane((0, 0, 0), (0, 0, 1))]
    if top is not None:
        walls.append(engine.Plane((0, 0, top), (0, 0, -1), velocity=(0, 0, -platen_speed)))
    return engine.Scene(
        pos,
        rad,
        RHO,
        velocities=velocities,
        box=[(0, lengths[0]), (0, lengths[1]), (0, lengths[2])],
        periodic=(periodic, periodic, False),
        walls=walls,
        gravity=(0, 0, -9.81),
        pair_law=law,
        wall_law=wall_law,
        wall_material=wall_material,
    )


def settled_bed(n: int, side: float, seed: int = 1):
    """Positions and radii of ``n`` spheres poured into a ``side`` x ``side`` periodic cell and
    settled under gravity with the full law (cached)."""
    path = CACHE / f"bed_{n}_{side:g}_{seed}.npz"
    if path.exists():
        d = np.load(path)
        return d["pos"], d["rad"], d["lengths"]
    t0 = time.perf_counter()
    rad = np.full(n, R)
    height = n * packing.sphere_volume(R) / (0.30 * side * side) + 2 * R
    lengths = np.array([side, side, height])
    pos = packing.loose_packing(rad, [(0, side), (0, side), (0, height)], seed=seed)
    sim = engine.Simulation(scene_for(pos, rad, lengths, FULL, top=None), dt=DT)
    steps = 0
    while True:
        sim.run(2000)
        steps += 2000
        vmax = float(np.linalg.norm(sim.velocities, axis=1).max())
        if (steps * DT > math.sqrt(2 * height / 9.81) and vmax < 5e-3) or steps >= 400_000:
            break
    pos = sim.positions
    CACHE.mkdir(exist_ok=True)
    np.savez(path, pos=pos, rad=rad, lengths=lengths)
    print(
        f"  settled {n} particles in {steps} steps ({time.perf_counter() - t0:.0f} s), "
        f"bed height {pos[:, 2].max() + R:.4f} m, max speed {vmax:.1e} m/s",
        flush=True,
    )
    return pos, rad, lengths


def anchor_bed():
    """The 2,025-particle settled packing of the LIGGGHTS deck (LAMMPS data file)."""
    text = (HERE / "liggghts" / "pack2k.data").read_text().splitlines()
    box = []
    for line in text[:20]:
        m = re.match(r"\s*(\S+)\s+(\S+)\s+[xyz]lo", line)
        if m:
            box.append((float(m.group(1)), float(m.group(2))))
    start = next(i for i, t in enumerate(text) if t.startswith("Atoms")) + 2
    rows = []
    for line in text[start:]:
        if not line.strip():
            break
        rows.append([float(v) for v in line.split()])
    a = np.array(rows)
    return a[:, 4:7].copy(), a[:, 2] / 2, np.array([b[1] - b[0] for b in box])


def time_run(pos, rad, lengths, law, threads: int, steps: int, repeats: int):
    """Median particle-steps per second with ``threads`` threads, the median CPU time of the
    process per particle-step [ns] (all threads together: with 1 thread the cost of a step
    whatever else runs on the machine; with 2 the excess over it is parallel overhead), and
    the last simulation for its statistics."""
    numba.set_num_threads(threads)
    top = float((pos[:, 2] + rad).max()) + 0.1 * R
    rates = []
    cpu = []
    sim = None
    for _ in range(repeats):
        sim = engine.Simulation(scene_for(pos, rad, lengths, law, top), dt=DT, threads=threads)
        sim.run(200)  # warm-up: the first steps also touch every buffer once
        c0 = time.process_time()
        t0 = time.perf_counter()
        sim.run(steps)
        rates.append(sim.n * steps / (time.perf_counter() - t0))
        cpu.append((time.process_time() - c0) / (sim.n * steps) * 1e9)
    return statistics.median(rates), statistics.median(cpu), sim


def compile_times() -> tuple[float, float]:
    """Seconds from interpreter start to a ready full-law Simulation, with empty caches and
    then with the caches they left (two fresh processes)."""
    code = (
        "import time; t = time.perf_counter(); import numpy as np; import engine;"
        "from benchmarks.engine_speed import scene_for, FULL;"
        "pos = np.array([[0.01, 0.01, 0.003], [0.02, 0.01, 0.003]]);"
        "sim = engine.Simulation(scene_for(pos, np.full(2, 2.5e-3), [0.05, 0.05, 0.1],"
        " FULL, top=0.01), dt=1e-5); sim.run(2); print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "DEMSCALE_CACHE_DIR": tmp + "/k", "NUMBA_CACHE_DIR": tmp + "/n"}
        out = []
        for _ in range(2):
            t0 = time.perf_counter()
            subprocess.run(
                [sys.executable, "-c", code],
                env=env,
                check=True,
                capture_output=True,
                cwd=HERE.parent,
            )
            out.append(time.perf_counter() - t0)
    return out[0], out[1]


def write_lammps_data(path: Path, pos, rad, lengths) -> None:
    """A settled bed as a LAMMPS ``atom_style granular`` data file (id type diameter density
    x y z), for the LIGGGHTS deck."""

    def f(x) -> str:
        return repr(float(x))

    lines = [
        "LAMMPS data file written by benchmarks.engine_speed",
        "",
        f"{len(pos)} atoms",
        "1 atom types",
        "",
        f"0 {f(lengths[0])} xlo xhi",
        f"0 {f(lengths[1])} ylo yhi",
        f"0 {f(lengths[2])} zlo zhi",
        "",
        "Atoms # sphere",
        "",
    ]
    lines += [
        f"{i + 1} 1 {f(2 * r)} {f(RHO)} {f(x)} {f(y)} {f(z)}"
        for i, (r, (x, y, z)) in enumerate(zip(rad, pos))
    ]
    path.write_text("\n".join(lines) + "\n")


def liggghts(ranks: int, steps: int, bed=None) -> float | None:
    """LIGGGHTS hooke/hysteresis particle-steps per second on the anchor packing (or on
    ``bed`` = (pos, rad, lengths)), or None."""
    exe = shutil.which("liggghts")
    if exe is None or (ranks > 1 and shutil.which("mpirun") is None):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        for f in ("in.liggghts_bench", "pack2k.data", "plate_unit.stl"):
            shutil.copy(HERE / "liggghts" / f, tmp)
        data = "pack2k.data"
        if bed is not None:
            data = "bed.data"
            write_lammps_data(Path(tmp, data), *bed)
        cmd = [
            exe,
            "-in",
            "in.liggghts_bench",
            "-var",
            "data",
            data,
            "-var",
            "model",
            "hysteresis",
            "-var",
            "nsteps",
            str(steps),
            "-var",
            "nequil",
            "1000",
            "-log",
            "lig.log",
        ]
        if ranks > 1:
            cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks), *cmd]
        # LIGGGHTS crashes with screen output disabled: send it to /dev/null instead
        subprocess.run(
            cmd,
            cwd=tmp,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            timeout=1200,
            check=False,
        )
        log = Path(tmp, "lig.log")
        if not log.exists():
            return None
        loops = re.findall(
            r"Loop time of (\S+) on \d+ procs for (\d+) steps with (\d+) atoms", log.read_text()
        )
        if not loops:
            return None
        t, n_steps, atoms = loops[-1]
        return int(atoms) * int(n_steps) / float(t)


def profile(name: str, pos, rad, lengths, threads: int, steps: int) -> None:
    """Where a step's time goes (full law, ``threads`` threads): a force evaluation (both
    passes by the thread team, with its barriers and the start of its threads)
    and the neighbour-list builds, each timed alone over many calls [us per step], against
    the whole step measured by a run; and the pair pass and the particle pass (gather,
    walls) on one thread. Wall-clock and the process's CPU time (robust to other load on
    the machine with one thread)."""
    numba.set_num_threads(threads)
    top = float((pos[:, 2] + rad).max()) + 0.1 * R
    sim = engine.Simulation(scene_for(pos, rad, lengths, FULL, top), dt=DT, threads=threads)
    sim.run(200)
    b0 = sim.n_rebuilds
    t0 = time.perf_counter()
    c0 = time.process_time()
    sim.run(steps)
    step = (time.perf_counter() - t0) / steps
    step_cpu = (time.process_time() - c0) / steps
    builds = sim.n_rebuilds - b0
    k = sim._k
    args = (sim._particles, sim._list, sim._walls, sim._params, sim._scratch)
    tiny = engine.Simulation(
        scene_for(
            np.array([[0.01, 0.01, 0.003], [0.02, 0.01, 0.003]]),
            np.full(2, R),
            [0.05, 0.05, 0.1],
            FULL,
            top=0.01,
        ),
        dt=DT,
        threads=threads,
    )
    targs = (tiny._particles, tiny._list, tiny._walls, tiny._params, tiny._scratch)
    reps = max(50, steps // 4)

    def per_call(fn, a):
        """(wall, process CPU) seconds per call."""
        fn(a)
        t = time.perf_counter()
        c = time.process_time()
        for _ in range(reps):
            fn(a)
        return (time.perf_counter() - t) / reps, (time.process_time() - c) / reps

    def pair(a):
        k.serial_pass(np.int64(0), np.int64(k.FORCES), *a)

    def particle(a):
        k.serial_pass(np.int64(1), np.int64(k.FORCES), *a)

    def forces(a):
        a[-1].sync[:] = 0
        run_team(k.run_member, threads, (threads, 0, 0, 0, *a))

    numba.set_num_threads(threads)
    call = per_call(pair, targs)  # the Python call itself, on a 2-particle scene
    t_pair = [a - b for a, b in zip(per_call(pair, args), call)]
    t_part = [a - b for a, b in zip(per_call(particle, args), call)]
    t_forces = [a - b for a, b in zip(per_call(forces, args), per_call(forces, targs))]
    t = time.perf_counter()
    for _ in range(5):
        sim.rebuild_neighbour_list()
    t_build = (time.perf_counter() - t) / 5
    build = t_build * builds / steps
    rest = step - t_forces[0] - build
    us = 1e6
    print(
        f"  profile {name:10s} {threads} thread(s): step {step * us:7.1f} us (CPU "
        f"{step_cpu * us:7.1f}) = force evaluation {t_forces[0] * us:7.1f} (CPU "
        f"{t_forces[1] * us:7.1f}; both passes on {threads} thread(s), one team) "
        f"+ list builds {build * us:5.1f} ({builds} x {t_build * 1e3:.2f} ms) + rest "
        f"{rest * us:6.1f}; one thread: pair pass {t_pair[0] * us:7.1f}, particle pass "
        f"{t_part[0] * us:6.1f}; {step / sim.n * 1e9:.0f} ns per particle-step",
        flush=True,
    )


#: One engine measurement in a fresh process (argv: threads, steps): particle-steps per
#: second of the full law on the anchor bed (the engine of the tree it runs in).
_ANCHOR_CHILD = """
import json, sys
import numba
from benchmarks.engine_speed import FULL, anchor_bed, time_run
threads, steps = int(sys.argv[1]), int(sys.argv[2])
pos, rad, lengths = anchor_bed()
time_run(pos, rad, lengths, FULL, threads, 10, 1)  # compiled (or loaded) before timing
print(json.dumps(time_run(pos, rad, lengths, FULL, threads, steps, 1)[0]))
"""


def liggghts_pairs(pairs: int, steps: int, threads: int, baseline: str | None) -> int:
    """``--pairs``: the engine against LIGGGHTS 3.8 on the anchor bed, ``threads`` engine
    threads against as many MPI ranks, in ``pairs`` interleaved pairs (the engine first in
    odd pairs, LIGGGHTS first in even ones, so that a slow spell of a shared machine falls on
    both); with ``baseline``, the engine at that git revision runs in each pair too. Each
    engine runs in a fresh process of its own tree. The figure: the median over pairs of each
    pair's ratio (particle-steps per second, engine / LIGGGHTS)."""
    import tempfile

    from benchmarks.checks import ROOT, run_child, worktree

    if shutil.which("liggghts") is None:
        print("LIGGGHTS is not installed (apt-get install -y liggghts)")
        return 1
    with contextlib.ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
        engines = {"this": ROOT}
        if baseline:
            engines["baseline " + baseline] = stack.enter_context(worktree(baseline))
        ratios: dict[str, list[float]] = {e: [] for e in engines}
        for k in range(pairs):
            rates = {}
            order = [*engines, "LIGGGHTS"]
            for who in order if k % 2 == 0 else order[::-1]:
                if who == "LIGGGHTS":
                    rates[who] = liggghts(threads, steps)
                else:
                    rates[who] = run_child(
                        engines[who],
                        _ANCHOR_CHILD,
                        (threads, steps),
                        NUMBA_NUM_THREADS=threads,
                        DEMSCALE_CACHE_DIR=tmp / who.replace(" ", "_"),
                    )
            lig = rates["LIGGGHTS"]
            if not lig:
                print(f"pair {k + 1}: LIGGGHTS failed")
                continue
            for e in engines:
                ratios[e].append(rates[e] / lig)
            print(
                f"pair {k + 1}: LIGGGHTS {lig:.3e}; "
                + "; ".join(f"{e} {rates[e]:.3e} ({rates[e] / lig:.2f}x)" for e in engines),
                flush=True,
            )
    print(
        f"\nanchor bed, full law, {threads} engine thread(s) against {threads} LIGGGHTS "
        f"rank(s), {steps} steps, median of {pairs} interleaved pairs; load at the end "
        + " ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    for e, r in ratios.items():
        if r:
            print(
                f"  {e}: {statistics.median(r):.2f}x LIGGGHTS (pairs: "
                + " ".join(f"{x:.2f}" for x in r)
                + ")"
            )
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2k beds only, shorter runs")
    ap.add_argument(
        "--pairs",
        type=int,
        default=0,
        help="only the engine against LIGGGHTS on the anchor bed, in this many interleaved pairs",
    )
    ap.add_argument("--threads", type=int, default=2, help="with --pairs: threads and ranks")
    ap.add_argument("--baseline", default=None, help="with --pairs: also this git revision")
    ap.add_argument("--profile", action="store_true", help="profile of the hot loop per pass")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--backend",
        choices=("cpu", "cuda"),
        default="cpu",
        help="cuda: the GPU targets of issue 21 (benchmarks/gpu_speed.py)",
    )
    args, rest = ap.parse_known_args(argv)
    if args.backend == "cuda":
        # handed over as a command line, not imported: gpu_speed builds on this module's beds
        import runpy
        import sys

        sys.argv = ["benchmarks.gpu_speed", *rest]
        try:
            runpy.run_module("benchmarks.gpu_speed", run_name="__main__", alter_sys=True)
        except SystemExit as e:
            return int(e.code or 0)
        return 0
    if rest:
        ap.error(f"unrecognised arguments: {' '.join(rest)}")
    if args.pairs:
        return liggghts_pairs(args.pairs, 10_000, args.threads, args.baseline)
    steps2k = 4000 if args.quick else 10_000
    steps16k = 1500

    print(
        f"demscale engine benchmark: {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, numba {numba.__version__} "
        f"({numba.config.NUMBA_NUM_THREADS} threads), numpy {np.__version__}, "
        f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}, "
        f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    print("building / loading settled beds ...", flush=True)
    beds = {"anchor-2k": anchor_bed(), "bed-2k": settled_bed(2025, 0.05)}
    if not args.quick:
        beds["bed-16k"] = settled_bed(16200, 0.1)

    if args.profile:
        for name in ("anchor-2k", "bed-16k"):
            if name in beds:
                for threads in (1, 2):
                    steps = steps16k if name == "bed-16k" else steps2k // 2
                    profile(name, *beds[name], threads, steps)

    rows = []
    stats = {}
    for name, (pos, rad, lengths) in beds.items():
        steps = steps16k if len(pos) > 5000 else steps2k
        for law_name, law in (("full", FULL), ("cohesionless-frictionless", PLAIN)):
            if name == "anchor-2k" and law is PLAIN:
                continue
            for threads in (1, 2):
                rate, cpu, sim = time_run(pos, rad, lengths, law, threads, steps, args.repeats)
                rows.append((name, len(pos), law_name, threads, rate, sim.threads, cpu))
                if law is FULL and threads == 1:
                    stats[name] = (
                        len(sim.contacts().pairs) * 2 / sim.n,
                        sim.memory_bytes() / sim.n,
                        sim.n_rebuilds,
                    )
                print(
                    f"  {name:10s} {len(pos):6d}  {law_name:26s} {threads} thread(s) "
                    f"({sim.threads} used) {rate:10.3e} particle-steps/s, CPU {cpu:.0f} ns "
                    "per particle-step",
                    flush=True,
                )

    lig: dict[tuple[str, int], float | None] = {}
    if shutil.which("liggghts"):
        for name in ("anchor-2k", "bed-16k"):
            if name not in beds:
                continue
            print(f"LIGGGHTS 3.8 hooke/hysteresis on {name} ...", flush=True)
            for ranks in (1, 2):
                lig[name, ranks] = liggghts(
                    ranks,
                    steps16k if name == "bed-16k" else steps2k,
                    None if name == "anchor-2k" else beds[name],
                )
    first, cached = compile_times()
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())

    def rate(name, law, threads):
        return next(r[4] for r in rows if r[0] == name and r[2] == law and r[3] == threads)

    print(
        "\n| scene | particles | law | threads (used) | particle-steps/s | CPU ns per "
        "particle-step | ratio |"
    )
    print("|---|---:|---|---:|---:|---:|---|")
    for name, n, law_name, threads, r, used, cpu in rows:
        base = rate(name, "full", 1)
        note = (
            "baseline" if (law_name, threads) == ("full", 1) else f"{r / base:.2f} x full 1-thread"
        )
        if law_name == "full" and lig.get((name, threads)):
            note += f"; {r / lig[name, threads]:.2f} x LIGGGHTS {threads} rank(s)"
        print(f"| {name} | {n} | {law_name} | {threads} ({used}) | {r:.3e} | {cpu:.0f} | {note} |")
    for (name, ranks), r in lig.items():
        print(
            f"| {name} | {len(beds[name][0])} | LIGGGHTS hooke/hysteresis | {ranks} MPI | "
            f"{r:.3e} | | same packing, same session |"
            if r
            else f"| {name} | {len(beds[name][0])} | LIGGGHTS | {ranks} MPI | failed | | |"
        )
    print("\n| scene | contacts per particle | engine memory per particle | list builds |")
    print("|---|---:|---:|---:|")
    for name, (cpp, mem, builds) in stats.items():
        print(f"| {name} | {cpp:.2f} | {mem:.0f} B | {builds} |")
    print(
        f"\ncompile: first {first:.1f} s (empty caches, includes interpreter start and "
        f"imports), cached {cached:.2f} s; load at the end: {load}"
    )

    big = "bed-16k" if "bed-16k" in stats else "bed-2k"
    checks: list[tuple[str, bool | None]] = []
    for name in ("anchor-2k", "bed-16k"):
        if name not in beds:
            continue
        r2 = rate(name, "full", 2)
        lg2, lg1 = lig.get((name, 2)), lig.get((name, 1))
        if lg2:
            # on a loaded machine LIGGGHTS's 2 MPI ranks can run slower than its 1 (MPI polls
            # while it waits): then the faster of the two is the baseline, never the collapse
            lg = max(lg2, lg1 or 0.0)
            which = "2 ranks" if lg == lg2 else "1 rank (faster than its 2 ranks here)"
            checks.append(
                (
                    f"{name} full law 2 threads >= 2x LIGGGHTS on 2 ranks: {r2:.3e} vs "
                    f"{lg:.3e} (LIGGGHTS {which}) = {r2 / lg:.2f}x",
                    r2 >= 2.0 * lg,
                )
            )
        else:
            checks.append(
                (
                    f"{name} full law 2 threads >= 2x LIGGGHTS on 2 ranks: {r2:.3e}, "
                    "LIGGGHTS not measured (not installed or failed)",
                    None,
                )
            )
        r1 = rate(name, "full", 1)
        checks.append(
            (
                f"{name} full law 2 threads >= 1.7x 1 thread: {r2:.3e} / {r1:.3e} = {r2 / r1:.2f}x",
                r2 >= 1.7 * r1,
            )
        )
    lo1 = min(rate(n, "full", 1) for n in beds)
    lo2 = min(rate(n, "full", 2) for n in beds)
    plain = [
        rate(n, "cohesionless-frictionless", t) / rate(n, "full", t)
        for n in beds
        if n != "anchor-2k"
        for t in (1, 2)
    ]
    checks += [
        (f"1 thread full law >= 2.5e6 (issue 2): lowest {lo1:.3e}", lo1 >= 2.5e6),
        (f"2 threads full law >= 4.5e6 (issue 2): lowest {lo2:.3e}", lo2 >= 4.5e6),
        (
            f"cohesionless frictionless >= 1.2x full law (issue 2): {min(plain):.2f}x to "
            f"{max(plain):.2f}x",
            min(plain) >= 1.2,
        ),
        (f"memory <= 1 KB per particle ({big}): {stats[big][1]:.0f} B", stats[big][1] <= 1024),
        (f"compile <= 20 s cold: {first:.1f} s", first <= 20.0),
        (f"compile <= 2 s cached: {cached:.2f} s", cached <= 2.0),
        ("16 threads >= 12x 1 thread at 128k particles: not measured (no 16-core machine)", None),
        (
            "cost per particle-step at 1M within 30 % of 16k, 16 threads: not measured (no "
            "16-core machine)",
            None,
        ),
    ]
    print("\nthread team: the calling thread and the engine's pool (no numba parallel region)")
    for what, ok in checks:
        if ok is None:
            print(f"----  {what}")
    return report([(what, ok) for what, ok in checks if ok is not None])


if __name__ == "__main__":
    sys.exit(main())
