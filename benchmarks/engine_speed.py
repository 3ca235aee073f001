"""Engine speed benchmark: particle-steps per second on a settled bed under a moving platen.

    python -m benchmarks.engine_speed            # full run (a few minutes)
    python -m benchmarks.engine_speed --quick    # 2k bed only, shorter runs

Scene (issue 2): R = 2.5 mm spheres, density 2000, periodic x and y, bottom platen and a top
platen moving down at 10 mm/s, dt = 1e-5 s; law K1 = 5e3, K2 = 2.5e4 N/m, f0 = -0.4 N,
mu_s = 0.5, mu_r = 0.001, restitution 0.4. Beds of about 2,000 and 16,000 particles are built
with engine.packing and settled once (cached under benchmarks/.cache). Every configuration
starts from the same settled state; each figure is the median of ``--repeats`` timed runs.
If ``liggghts`` is on the PATH, its hooke/hysteresis model runs the same 2,025-particle
packing (benchmarks/liggghts, the LIGGGHTS 3.8 deck) in the same session, as the baseline.
"""

from __future__ import annotations

import argparse
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
from engine import packing

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


def scene_for(pos, rad, lengths, law, top: float | None, platen_speed: float = PLATEN_SPEED):
    walls = [engine.Plane((0, 0, 0), (0, 0, 1))]
    if top is not None:
        walls.append(engine.Plane((0, 0, top), (0, 0, -1), velocity=(0, 0, -platen_speed)))
    return engine.Scene(pos, rad, RHO, box=[(0, lengths[0]), (0, lengths[1]),
                                            (0, lengths[2])],
                        periodic=(True, True, False), walls=walls, gravity=(0, 0, -9.81),
                        pair_law=law, wall_law=WALL_LAW, wall_material=WALL)


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
    print(f"  settled {n} particles in {steps} steps ({time.perf_counter() - t0:.0f} s), "
          f"bed height {pos[:, 2].max() + R:.4f} m, max speed {vmax:.1e} m/s", flush=True)
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
    """Median particle-steps per second, plus the last simulation for its statistics."""
    numba.set_num_threads(threads)
    top = float((pos[:, 2] + rad).max()) + 0.1 * R
    rates = []
    sim = None
    for _ in range(repeats):
        sim = engine.Simulation(scene_for(pos, rad, lengths, law, top), dt=DT)
        sim.run(200)  # warm-up: the first steps also touch every buffer once
        t0 = time.perf_counter()
        sim.run(steps)
        rates.append(sim.n * steps / (time.perf_counter() - t0))
    return statistics.median(rates), sim


def compile_times() -> tuple[float, float]:
    """Seconds from interpreter start to a ready full-law Simulation, with empty caches and
    then with the caches they left (two fresh processes)."""
    code = ("import time; t = time.perf_counter(); import numpy as np; import engine;"
            "from benchmarks.engine_speed import scene_for, FULL;"
            "pos = np.array([[0.01, 0.01, 0.003], [0.02, 0.01, 0.003]]);"
            "sim = engine.Simulation(scene_for(pos, np.full(2, 2.5e-3), [0.05, 0.05, 0.1],"
            " FULL, top=0.01), dt=1e-5); sim.run(2); print(time.perf_counter() - t)")
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "DEMSCALE_CACHE_DIR": tmp + "/k", "NUMBA_CACHE_DIR": tmp + "/n"}
        out = []
        for _ in range(2):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], env=env, check=True,
                           capture_output=True, cwd=HERE.parent)
            out.append(time.perf_counter() - t0)
    return out[0], out[1]


def liggghts(ranks: int, steps: int) -> float | None:
    """LIGGGHTS hooke/hysteresis particle-steps per second on the anchor packing, or None."""
    exe = shutil.which("liggghts")
    if exe is None or (ranks > 1 and shutil.which("mpirun") is None):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        for f in ("in.liggghts_bench", "pack2k.data", "plate_unit.stl"):
            shutil.copy(HERE / "liggghts" / f, tmp)
        cmd = [exe, "-in", "in.liggghts_bench", "-var", "data", "pack2k.data", "-var", "model",
               "hysteresis", "-var", "nsteps", str(steps), "-var", "nequil", "1000", "-log",
               "lig.log"]
        if ranks > 1:
            cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks), *cmd]
        # LIGGGHTS crashes with screen output disabled: send it to /dev/null instead
        subprocess.run(cmd, cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       timeout=1200, check=False)
        log = Path(tmp, "lig.log")
        if not log.exists():
            return None
        loops = re.findall(r"Loop time of (\S+) on \d+ procs for (\d+) steps with (\d+) atoms",
                           log.read_text())
        if not loops:
            return None
        t, n_steps, atoms = loops[-1]
        return int(atoms) * int(n_steps) / float(t)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2k bed only, shorter runs")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    steps2k = 4000 if args.quick else 10_000
    steps16k = 1500

    print(f"demscale engine benchmark: {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, numba {numba.__version__} "
          f"({numba.config.NUMBA_NUM_THREADS} threads), numpy {np.__version__}")
    print("building / loading settled beds ...", flush=True)
    beds = {"bed-2k": settled_bed(2025, 0.05)}
    if not args.quick:
        beds["bed-16k"] = settled_bed(16200, 0.1)
    beds["anchor-2k"] = anchor_bed()

    rows = []
    stats = {}
    for name, (pos, rad, lengths) in beds.items():
        steps = steps16k if len(pos) > 5000 else steps2k
        for law_name, law in (("full", FULL), ("cohesionless-frictionless", PLAIN)):
            if name == "anchor-2k" and law is PLAIN:
                continue
            for threads in (1, 2):
                rate, sim = time_run(pos, rad, lengths, law, threads, steps, args.repeats)
                rows.append((name, len(pos), law_name, threads, rate, sim.threads))
                if law is FULL and threads == 1:
                    stats[name] = (len(sim.contacts().pairs) * 2 / sim.n,
                                   sim.memory_bytes() / sim.n, sim.n_rebuilds)
                print(f"  {name:10s} {len(pos):6d}  {law_name:26s} {threads} thread(s) "
                      f"({sim.threads} used) {rate:10.3e} particle-steps/s", flush=True)

    lig = {}
    if shutil.which("liggghts"):
        print("LIGGGHTS 3.8 hooke/hysteresis on anchor-2k ...", flush=True)
        for ranks in (1, 2):
            lig[ranks] = liggghts(ranks, steps2k)
    first, cached = compile_times()

    def rate(name, law, threads):
        return next(r[4] for r in rows if r[0] == name and r[2] == law and r[3] == threads)

    print("\n| scene | particles | law | numba threads (used) | particle-steps/s | ratio |")
    print("|---|---:|---|---:|---:|---|")
    for name, n, law_name, threads, r, used in rows:
        base = rate(name, "full", 1)
        note = ("baseline" if (law_name, threads) == ("full", 1)
                else f"{r / base:.2f} x full 1-thread")
        if name == "anchor-2k" and lig.get(threads):
            note += f"; {r / lig[threads]:.2f} x LIGGGHTS {threads} rank(s)"
        print(f"| {name} | {n} | {law_name} | {threads} ({used}) | {r:.3e} | {note} |")
    for ranks, r in lig.items():
        print(f"| anchor-2k | 2025 | LIGGGHTS hooke/hysteresis | {ranks} MPI | "
              f"{r:.3e} | same deck, same session |" if r else
              f"| anchor-2k | 2025 | LIGGGHTS | {ranks} MPI | failed | |")
    print("\n| scene | contacts per particle | engine memory per particle | list builds |")
    print("|---|---:|---:|---:|")
    for name, (cpp, mem, builds) in stats.items():
        print(f"| {name} | {cpp:.2f} | {mem:.0f} B | {builds} |")
    print(f"\ncompile: first {first:.1f} s (empty caches, includes interpreter start and "
          f"imports), cached {cached:.2f} s")

    big = "bed-16k" if "bed-16k" in stats else "bed-2k"
    checks = [
        ("1 thread full law >= 2.5e6", min(rate(n, "full", 1) for n in beds) >= 2.5e6),
        ("2 threads full law >= 4.5e6", min(rate(n, "full", 2) for n in beds) >= 4.5e6),
        ("cohesionless frictionless clearly faster (>= 1.2x)",
         all(rate(n, "cohesionless-frictionless", t) >= 1.2 * rate(n, "full", t)
             for n in beds if n != "anchor-2k" for t in (1, 2))),
        (f"memory < 1 KB per particle ({big})", stats[big][1] < 1024),
        ("first compile < 20 s", first < 20.0),
        ("cached start < 2 s", cached < 2.0),
    ]
    return report(checks)


if __name__ == "__main__":
    sys.exit(main())
