"""demscale against LIGGGHTS 3.8: confined compression of one packing with the non-linear EEPA law.

    python -m benchmarks.liggghts_eepa               # everything (~1.5 h on 2 cores)
    python -m benchmarks.liggghts_eepa --cases 1 2   # some cases (the others from the cache)
    python -m benchmarks.liggghts_eepa --report      # table and figure from the cached curves

Cases 1 to 5 are the issue's; 1b, 2b, 2c, 2d are diagnostics that change one thing each;
"mpi" reruns LIGGGHTS case 2 on 2 ranks, "spread" reruns cases 1 and 2 with the bed moved by
1 nm (each code's own chaotic spread). LIGGGHTS takes 5 to 6 min a case (12 at dt = 5e-6 s),
demscale 30 to 40 s.

Both codes run the same protocol on the 2,025-sphere anchor bed of benchmarks/liggghts
(pack2k.data, R = 2.5 mm, density 2000, 0.05 x 0.05 m cell periodic in x and y, gravity):
a flat bottom platen at z = 0 and a top platen 0.1 R above the bed, a settle of ``NEQUIL``
steps with the platen at rest, then the platen down at 10 mm/s for 0.5 s, dt = 1e-5 s. The
top platen stress (force / cell area) is averaged over every 10th step of each 500-step
window (0.005 s, 100 points) in both codes; strain = platen travel / initial gap.

Pair law: EEPA (n, chi, K1, K2, f0, kadh = 0) in demscale, ``edinburgh/stiffness`` in
LIGGGHTS (LoadingStiffness = K1, UnloadingStiffness = K2/K1, overlapExponent = n,
adhesionExponent = chi, pullOffForce = f0, surfaceEnergy = 0 with fixKc off, so its computed
adhesive-branch stiffness is 0). Platens: Hertz-Mindlin in both (LIGGGHTS ``wall/gran model
hertz``, wall of atom type 1; demscale HertzMindlin with a WallMaterial of the particles' E
and nu), same restitution, friction and rolling friction as the pairs. The LIGGGHTS Verlet
skin is larger than the platen travel, so no neighbour list is rebuilt during the run (a
rebuild can hand an edinburgh contact to its other particle with its stored overlap negated);
the script checks the log for it. The metric is the relative RMS difference of the two
stress curves (module function :func:`rel_rms`). docs/LIGGGHTS_EEPA.md explains every
difference of the two implementations; this script writes its result table and the figure
docs/figures/liggghts_eepa.png.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

import engine
from benchmarks.checks import report, save_figure, write_marked
from benchmarks.engine_speed import (
    DT,
    PLATEN_SPEED,
    R,
    anchor_bed,
    scene_for,
    write_lammps_data,
)
from engine.io.liggghts import matched_restitution

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CACHE = HERE / ".cache" / "liggghts_eepa"
DOC = ROOT / "docs" / "LIGGGHTS_EEPA.md"
FIGURE = ROOT / "docs" / "figures" / "liggghts_eepa.png"
TABLE_BEGIN = "<!-- table:begin (written by python -m benchmarks.liggghts_eepa) -->"
TABLE_END = "<!-- table:end -->"

# step counts at dt = DT (1e-5 s); a case with a smaller dt takes DT/dt times as many
NEQUIL = 5000  # settle steps, platen at rest (0.05 s)
NSTEPS = 50_000  # compression steps (0.5 s at 10 mm/s: 5 mm of travel)
EVERY = 10  # stress sampled every EVERY steps ...
WINDOW = 500  # ... and averaged over each WINDOW-step window
GAP = 0.1 * R  # initial clearance between the bed top and the top platen [m]
#: LIGGGHTS Verlet skin [m]: its rebuild trigger (half the skin) exceeds the 5 mm platen
#: travel and, in these runs, every particle's displacement, so the list built at the start
#: is kept (atom sorting is off as well, so no rebuild could reorder a pair)
SKIN = 0.013
#: platen (wall) material, Hertz-Mindlin, for both codes: E [Pa], nu [-]
WALL_E = 1.0e8
WALL_NU = 0.25
TARGET = 5.0  # per cent, the criterion


@dataclass(frozen=True)
class Case:
    """One compression: the EEPA parameters shared by both codes and demscale's conventions."""

    key: str
    title: str
    n: float = 1.5
    chi: float = 1.5
    k1: float = 5e5  # N/m^n
    k2: float = 2.5e6  # N/m^n
    f0: float = 0.0  # N
    mu_s: float = 0.5
    mu_r: float = 0.001
    restitution: float = 0.5
    friction_cap: str = "normal"  # demscale's Coulomb cap convention ("normal": LIGGGHTS')
    kt_ratio: float = 1.0  # demscale kt / (n k1 d^(n-1)); LIGGGHTS: kt = k1 numerically
    #: diagnostic: LIGGGHTS' (and both codes' platen) restitution, if not ``restitution``
    lig_restitution: float | None = None
    dt: float = DT  # time step of both codes [s], DT / integer
    diagnostic: bool = False  # a variant that explains a difference, not one of the issue's

    @property
    def steps(self) -> tuple[int, int, int, int]:
        """(settle steps, compression steps, sampling interval, window) at this dt: the same
        times as NEQUIL, NSTEPS, EVERY, WINDOW at DT."""
        k = round(DT / self.dt)
        if not math.isclose(k * self.dt, DT):
            raise ValueError(f"case {self.key}: dt must be DT / an integer")
        return NEQUIL * k, NSTEPS * k, EVERY * k, WINDOW * k

    def eepa(self) -> engine.EEPA:
        fields = ("k1", "k2", "f0", "n", "chi", "kt_ratio", "mu_s", "mu_r", "restitution")
        return engine.EEPA(
            kadh=0.0, friction_cap=self.friction_cap, **{f: getattr(self, f) for f in fields}
        )

    def wall_law(self) -> engine.HertzMindlin:
        return engine.HertzMindlin(
            E=WALL_E, nu=WALL_NU, restitution=self.platen_restitution, mu=self.mu_s, mu_r=self.mu_r
        )

    @property
    def platen_restitution(self) -> float:
        """Restitution of the platen contacts (LIGGGHTS: one coefficient for every type pair,
        walls of type 1 included)."""
        return self.restitution if self.lig_restitution is None else self.lig_restitution


#: median pair overlap at the end of demscale's case 1 [m]: where case 1b matches the damping
D_REF = 3.7e-5
#: median pair overlap at the end of demscale's case 2 [m]: where case 2d's demscale tangential
#: stiffness kt_ratio n K1 d^(n-1) equals LIGGGHTS' K1 (numerically)
D_REF_FRICTION = 5.7e-5


CASES: dict[str, Case] = {
    c.key: c
    for c in (
        Case("1", "n = 1.5, frictionless, cohesionless", mu_s=0.0, mu_r=0.0),
        Case("2", "n = 1.5, friction, cohesionless"),
        Case("3", "n = 1.5, f0 = -0.4 N, adhesive cap", f0=-0.4, friction_cap="adhesive"),
        Case("4", "n = 1.5, f0 = -0.4 N, normal cap (LIGGGHTS')", f0=-0.4),
        Case("5", "n = 1 (K1 = 5e3 N/m), friction, cohesionless", n=1.0, chi=1.0, k1=5e3, k2=2.5e4),
        Case(
            "1b",
            "1, LIGGGHTS damping matched at 37 um",
            mu_s=0.0,
            mu_r=0.0,
            lig_restitution=round(matched_restitution(0.5, 1.5, D_REF), 3),
            diagnostic=True,
        ),
        Case("2b", "2 without rolling friction", mu_r=0.0, diagnostic=True),
        Case("2c", "2 at dt = 5e-6 s in both codes", dt=5e-6, diagnostic=True),
        Case(
            "2d",
            "2c, demscale kt = LIGGGHTS' at 57 um",
            dt=5e-6,
            kt_ratio=round(1.0 / (1.5 * math.sqrt(D_REF_FRICTION))),
            diagnostic=True,
        ),
    )
}
MPI_CASE = "2"
#: the chaotic spread of a run: cases rerun with every initial position moved by a random
#: vector of scale JITTER, seeds of demscale's and of LIGGGHTS' reruns
JITTER = 1e-9  # m
SPREAD = {"1": ((1, 2, 3, 4), (1,)), "2": ((1,), ())}
SPREAD_CODES = tuple(
    dict.fromkeys(
        f"{code}-jitter{seed}"
        for seeds in SPREAD.values()
        for code, ss in zip(("demscale", "liggghts"), seeds)
        for seed in ss
    )
)


# ---------------------------------------------------------------------------- metric
def rel_rms(strain_a, stress_a, strain_ref, stress_ref) -> float:
    """Relative RMS difference [%] of curve a against the reference curve:
    100 sqrt(mean((a - ref)^2)) / sqrt(mean(ref^2)) over the reference's strain points
    (curve a linearly interpolated onto them; only points inside both strain ranges)."""
    xa = np.asarray(strain_a, dtype=float)
    ya = np.asarray(stress_a, dtype=float)
    xr = np.asarray(strain_ref, dtype=float)
    yr = np.asarray(stress_ref, dtype=float)
    keep = (xr >= xa.min()) & (xr <= xa.max())
    if not keep.any():
        raise ValueError("the two curves share no strain range")
    a = np.interp(xr[keep], xa, ya)
    ref = yr[keep]
    norm = math.sqrt(float(np.mean(ref**2)))
    if norm == 0.0:
        raise ValueError("the reference curve is zero")
    return 100.0 * math.sqrt(float(np.mean((a - ref) ** 2))) / norm


# ---------------------------------------------------------------------------- the bed
def bed():
    """(positions, radii, box lengths, initial top-platen height [m]) of the anchor bed."""
    pos, rad, lengths = anchor_bed()
    top = float((pos[:, 2] + rad).max()) + GAP
    return pos, rad, lengths, top


# ---------------------------------------------------------------------------- demscale
def jittered(pos, jitter: float, seed: int):
    """``pos`` with every position moved by a normal random vector of scale ``jitter`` [m]."""
    if not jitter:
        return pos
    return pos + np.random.default_rng(seed).normal(scale=jitter, size=pos.shape)


def run_demscale(case: Case, threads: int = 1, jitter: float = 0.0, seed: int = 1) -> dict:
    """The compression in demscale: strain, stress [Pa] per window, and run statistics;
    ``jitter`` [m]: every initial position moved by a random vector of that scale (the
    chaotic spread of the run; the platen stays where the unmoved bed puts it)."""
    pos, rad, lengths, top = bed()
    pos = jittered(pos, jitter, seed)
    scene = scene_for(
        pos,
        rad,
        lengths,
        case.eepa(),
        top,
        platen_speed=0.0,  # the platen starts after the equilibration (set_wall_velocity)
        wall_law=case.wall_law(),
        wall_material=engine.WallMaterial(E=WALL_E, nu=WALL_NU),
    )
    t0 = time.perf_counter()
    nequil, nsteps, every, window = case.steps
    sim = engine.Simulation(scene, dt=case.dt, threads=threads)
    setup = time.perf_counter() - t0
    area = lengths[0] * lengths[1]
    t0 = time.perf_counter()
    sim.run(nequil)
    sim.set_wall_velocity(1, (0.0, 0.0, -PLATEN_SPEED))
    strain, stress, ke = [0.0], [float(sim.wall_forces[1, 2]) / area], [sim.kinetic_energy()]
    for w in range(nsteps // window):
        acc = 0.0
        for _ in range(window // every):
            sim.run(every)
            acc += float(sim.wall_forces[1, 2])
        stress.append(acc / (window // every) / area)
        strain.append(PLATEN_SPEED * (w + 1) * window * case.dt / top)
        ke.append(sim.kinetic_energy())
    wall = time.perf_counter() - t0
    c = sim.contacts()
    return {
        "strain": strain,
        "stress": stress,
        "ke": ke,
        "seconds": wall,
        "setup": setup,
        "threads": sim.threads,
        "rebuilds": sim.n_rebuilds,
        "dt_limit": sim.limit.dt,
        "dt_reason": sim.limit.reason,
        "contacts": len(c.overlaps),
        "overlap_median": float(np.median(c.overlaps)),
        "overlap_p90": float(np.percentile(c.overlaps, 90)),
    }


# ---------------------------------------------------------------------------- LIGGGHTS
def deck(case: Case, top: float, side: float = 0.05, data: str = "pack2k.data") -> str:
    """The LIGGGHTS 3.8 input deck of ``case`` (SI units): top platen (the unit STL square
    scaled to the ``side`` [m] of the cell) at ``top`` [m]."""
    e = case.platen_restitution
    nequil, nsteps, every, window = case.steps
    return f"""\
# demscale benchmarks/liggghts_eepa.py, case {case.key}: {case.title}
# edinburgh/stiffness (EEPA): K1 = {case.k1:g} N/m^n, K2 = {case.k2:g} N/m^n, n = {case.n:g},
# chi = {case.chi:g}, f0 = {case.f0:g} N, kadh = 0 (surfaceEnergy 0, fixKc off); platens Hertz
units           si
atom_style      granular
atom_modify     map array sort 0 0.0
boundary        p p f
newton          off
processors      * * 1
communicate     single vel yes
read_data       {data}
neighbor        {SKIN!r} bin
neigh_modify    delay 0

fix m1 all property/global youngsModulus peratomtype {WALL_E!r}
fix m2 all property/global poissonsRatio peratomtype {WALL_NU!r}
fix m3 all property/global coefficientRestitution peratomtypepair 1 {e!r}
fix m4 all property/global coefficientFriction peratomtypepair 1 {case.mu_s!r}
fix m5 all property/global coefficientRollingFriction peratomtypepair 1 {case.mu_r!r}
fix m6 all property/global LoadingStiffness peratomtypepair 1 {case.k1!r}
fix m7 all property/global UnloadingStiffness peratomtypepair 1 {case.k2 / case.k1!r}
fix m8 all property/global overlapExponent scalar {case.n!r}
fix m9 all property/global adhesionExponent scalar {case.chi!r}
fix m10 all property/global pullOffForce peratomtypepair 1 {case.f0!r}
fix m11 all property/global surfaceEnergy peratomtypepair 1 0.0
fix m12 all property/global coefficientAdhesionStiffness peratomtypepair 1 0.0

pair_style      gran model edinburgh/stiffness tangential history rolling_friction cdt
pair_coeff      * *

fix             topmesh all mesh/surface/stress file plate_unit.stl type 1 scale {side!r} &
                move 0.0 0.0 {top!r}
fix             wallb all wall/gran model hertz tangential history rolling_friction cdt &
                primitive type 1 zplane 0.0
fix             wallt all wall/gran model hertz tangential history rolling_friction cdt &
                mesh n_meshes 1 meshes topmesh
variable        vz equal -{PLATEN_SPEED!r}*(step>{nequil})
variable        zero equal 0.0
fix             movetop all move/mesh mesh topmesh linear/variable v_zero v_zero v_vz

fix             grav all gravity 9.81 vector 0.0 0.0 -1.0
fix             integr all nve/sphere
timestep        {case.dt!r}

fix             avg all ave/time {every} {window // every} {window} f_topmesh[3]
thermo_style    custom step atoms ke f_avg f_topmesh[3] cpu
thermo_modify   lost ignore norm no format float %.12g
thermo          {window}

run             {nequil + nsteps}
"""


def deck_id(case: Case) -> str:
    """Digest of the deck without its comments: cases with the same LIGGGHTS input (they
    differ only in a demscale option) share one LIGGGHTS run."""
    body = "\n".join(
        line for line in deck(case, *bed()[3:]).splitlines() if not line.startswith("#")
    )
    return hashlib.sha256(body.encode()).hexdigest()[:16]


def parse_log(text: str) -> dict:
    """Thermo rows (step, ke, averaged platen force), the loop time and the neighbour-list
    builds of a LIGGGHTS log."""
    rows = []
    on = False
    for line in text.splitlines():
        f = line.split()
        if f[:2] == ["Step", "Atoms"]:
            on = True
            continue
        if on:
            if line.startswith("Loop time"):
                on = False
                continue
            try:
                rows.append([float(v) for v in f[:5]])
            except ValueError:
                continue
    loop = re.findall(r"Loop time of (\S+) on (\d+) procs", text)
    builds = re.findall(r"Neighbor list builds = (\d+)", text)
    danger = re.findall(r"Dangerous builds = (\d+)", text)
    return {
        "rows": rows,
        "seconds": float(loop[-1][0]) if loop else None,
        "procs": int(loop[-1][1]) if loop else None,
        "builds": int(builds[-1]) if builds else None,
        "dangerous": int(danger[-1]) if danger else None,
    }


def run_liggghts(case: Case, ranks: int = 1, jitter: float = 0.0, seed: int = 1) -> dict | None:
    """The compression in LIGGGHTS (None if it is not installed or failed); ``jitter`` as
    :func:`run_demscale` (the moved bed is written as a new data file)."""
    exe = shutil.which("liggghts")
    if exe is None or (ranks > 1 and shutil.which("mpirun") is None):
        return None
    pos, rad, lengths, top = bed()
    assert lengths[0] == lengths[1]
    with tempfile.TemporaryDirectory() as tmp:
        for f in ("pack2k.data", "plate_unit.stl"):
            shutil.copy(HERE / "liggghts" / f, tmp)
        data = "pack2k.data"
        if jitter:
            data = "moved.data"
            write_lammps_data(Path(tmp, data), jittered(pos, jitter, seed), rad, lengths)
        Path(tmp, "in.eepa").write_text(deck(case, top, float(lengths[0]), data))
        cmd = [exe, "-in", "in.eepa", "-log", "lig.log"]
        if ranks > 1:
            cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks), *cmd]
        t0 = time.perf_counter()
        # LIGGGHTS crashes with screen output disabled: send it to a file instead
        with open(Path(tmp, "screen.txt"), "w") as screen:
            subprocess.run(
                cmd, cwd=tmp, stdout=screen, stderr=subprocess.STDOUT, timeout=3600, check=False
            )
        wall = time.perf_counter() - t0
        log = Path(tmp, "lig.log")
        if not log.exists():
            print(Path(tmp, "screen.txt").read_text()[-3000:])
            return None
        out = parse_log(log.read_text())
        out["deck"] = deck_id(case)
    rows = np.array(out.pop("rows"))
    nequil, nsteps, _, _ = case.steps
    if len(rows) == 0 or rows[-1, 0] < nequil + nsteps:
        print(f"LIGGGHTS case {case.key} did not finish: {len(rows)} thermo rows")
        return None
    area = lengths[0] * lengths[1]
    keep = rows[:, 0] >= nequil
    steps = rows[keep, 0] - nequil
    # the first row: instantaneous force (the window average there is the settle's)
    stress = rows[keep, 3] / area
    stress[0] = rows[keep, 4][0] / area
    return {
        "strain": list(PLATEN_SPEED * steps * case.dt / top),
        "stress": list(stress),
        "ke": list(rows[keep, 2]),
        "seconds": wall,
        "loop": out["seconds"],
        "ranks": ranks,
        "builds": out["builds"],
        "dangerous": out["dangerous"],
    }


# ---------------------------------------------------------------------------- cache
def cache_path(code: str, key: str) -> Path:
    return CACHE / f"{code}_{key}.json"


def save(code: str, key: str, result: dict, case: Case) -> None:
    CACHE.mkdir(parents=True, exist_ok=True)
    cache_path(code, key).write_text(json.dumps({"case": asdict(case), **result}))


def load(code: str, key: str, case: Case) -> dict | None:
    p = cache_path(code, key)
    if not p.exists():
        return None
    d = json.loads(p.read_text())
    stored = d.pop("case")
    defaults = {f.name: f.default for f in fields(Case)}
    if any(
        stored.get(k, defaults[k]) != v
        for k, v in asdict(case).items()
        if k not in ("title", "diagnostic")
    ):
        return None  # stale: the case's parameters changed since
    return d


def same_liggghts_run(case: Case) -> dict | None:
    """A cached 1-rank LIGGGHTS run of another case with the same deck, or None."""
    want = deck_id(case)
    for key, other in CASES.items():
        if key == case.key:
            continue
        r = load("liggghts", key, other)
        if r is not None and r.get("deck", deck_id(other)) == want:
            return {**r, "same_as": r.get("same_as") or key}
    return None


# ---------------------------------------------------------------------------- report
def table(results: dict) -> str:
    rows = [
        "| case | law | rel. RMS difference | within 5 % | stress at 5.7 % strain, "
        "demscale / LIGGGHTS [kPa] | run time demscale / LIGGGHTS [s] |",
        "|---|---|---:|---|---:|---:|",
    ]
    for key, case in CASES.items():
        dem, lig = results.get(("demscale", key)), results.get(("liggghts", key))
        name = f"{key} (diagnostic)" if case.diagnostic else key
        if dem is None or lig is None:
            rows.append(f"| {name} | {case.title} | not run | | | |")
            continue
        d = rel_rms(dem["strain"], dem["stress"], lig["strain"], lig["stress"])
        rows.append(
            f"| {name} | {case.title} | {d:.1f} % | {'yes' if d <= TARGET else 'no'} | "
            f"{dem['stress'][-1] / 1e3:.2f} / {lig['stress'][-1] / 1e3:.2f} | "
            f"{dem['seconds']:.0f} / {lig['seconds']:.0f} |"
        )
    for key, seeds in SPREAD.items():
        for code, name in (("demscale", "demscale"), ("liggghts", "LIGGGHTS")):
            base = results.get((code, key))
            runs = [
                results[f"{code}-jitter{s}", key]
                for s in seeds[code == "liggghts"]
                if (f"{code}-jitter{s}", key) in results
            ]
            if base is None or not runs:
                continue
            d = [rel_rms(a["strain"], a["stress"], base["strain"], base["stress"]) for a in runs]
            span = f"{d[0]:.1f} %" if len(d) == 1 else f"{min(d):.1f} to {max(d):.1f} %"
            ends = ", ".join(f"{a['stress'][-1] / 1e3:.2f}" for a in runs)
            rows.append(
                f"| {key} (spread) | {name} against itself, bed moved by "
                f"{JITTER * 1e9:g} nm ({len(runs)} seed(s)) | {span} | | {ends} / "
                f"{base['stress'][-1] / 1e3:.2f} ({name}) | |"
            )
        dem = [
            results[c, key]
            for c in ("demscale", *(f"demscale-jitter{s}" for s in seeds[0]))
            if (c, key) in results
        ]
        lig = [
            results[c, key]
            for c in ("liggghts", *(f"liggghts-jitter{s}" for s in seeds[1]))
            if (c, key) in results
        ]
        if len(dem) > 1 and len(lig) > 1:
            x = np.asarray(lig[0]["strain"])
            mean_d = np.mean([np.interp(x, r["strain"], r["stress"]) for r in dem], axis=0)
            mean_l = np.mean([np.interp(x, r["strain"], r["stress"]) for r in lig], axis=0)
            d = rel_rms(x, mean_d, x, mean_l)
            rows.append(
                f"| {key} (ensemble) | mean of {len(dem)} demscale runs against the mean "
                f"of {len(lig)} LIGGGHTS runs | {d:.1f} % | "
                f"{'yes' if d <= TARGET else 'no'} | {mean_d[-1] / 1e3:.2f} / "
                f"{mean_l[-1] / 1e3:.2f} | |"
            )
    one, two = results.get(("liggghts", MPI_CASE)), results.get(("liggghts-2ranks", MPI_CASE))
    if one is not None and two is not None:
        d = rel_rms(two["strain"], two["stress"], one["strain"], one["stress"])
        rows.append(
            f"| {MPI_CASE} (MPI) | LIGGGHTS 2 ranks against LIGGGHTS 1 rank | {d:.1f} % "
            f"| {'yes' if d <= TARGET else 'no'} | {two['stress'][-1] / 1e3:.2f} / "
            f"{one['stress'][-1] / 1e3:.2f} | {two['seconds']:.0f} / "
            f"{one['seconds']:.0f} |"
        )
    elif shutil.which("mpirun") is None:
        rows.append(f"| {MPI_CASE} (MPI) | LIGGGHTS 2 ranks | not run: no mpirun | | | |")
    notes = []
    for (code, key), r in sorted(results.items()):
        if code.startswith("liggghts"):
            same = f" (the run of case {r['same_as']}: the same deck)" if r.get("same_as") else ""
            moved = ", bed moved by 1 nm" if "jitter" in code else ""
            notes.append(
                f"LIGGGHTS case {key} ({r['ranks']} rank(s){moved}){same}: "
                f"{r['builds']} "
                "neighbour-list builds after the one at the start, "
                f"{r['dangerous']} dangerous"
            )
        elif code == "demscale":
            notes.append(
                f"demscale case {key}: {r['threads']} thread(s), dt limit "
                f"{r['dt_limit']:.3g} s ({r['dt_reason']})"
            )
    return "\n".join(rows) + "\n\n" + "\n".join(f"- {n}" for n in notes) + "\n"


def figure(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(CASES)
    ncol = 4
    nrow = -(-len(keys) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.9 * nrow), squeeze=False)
    for ax in axes.flat[len(keys) :]:
        ax.set_visible(False)
    for ax, key in zip(axes.flat, keys):
        case = CASES[key]
        for code, style, label in (
            ("liggghts", "k-", "LIGGGHTS 3.8"),
            ("liggghts-2ranks", "k:", "LIGGGHTS, 2 MPI ranks"),
            ("demscale", "C3--", "demscale"),
        ):
            r = results.get((code, key))
            if r is None:
                continue
            ax.plot(
                100 * np.asarray(r["strain"]),
                np.asarray(r["stress"]) / 1e3,
                style,
                lw=1.4,
                label=label,
            )
        first = {"demscale": True, "liggghts": True}
        for code in SPREAD_CODES:
            r = results.get((code, key))
            if r is None:
                continue
            kind = code.split("-")[0]
            label = (
                f"{'demscale' if kind == 'demscale' else 'LIGGGHTS'}, bed moved 1 nm"
                if first[kind]
                else None
            )
            first[kind] = False
            ax.plot(
                100 * np.asarray(r["strain"]),
                np.asarray(r["stress"]) / 1e3,
                "C3:" if kind == "demscale" else "C7-",
                lw=1.0,
                label=label,
            )
        dem, lig = results.get(("demscale", key)), results.get(("liggghts", key))
        sub = ""
        if dem is not None and lig is not None:
            sub = (
                f"\nrel. RMS difference "
                f"{rel_rms(dem['strain'], dem['stress'], lig['strain'], lig['stress']):.1f} %"
            )
        kind = " (diagnostic)" if case.diagnostic else ""
        ax.set_title(f"case {key}{kind}: {case.title}{sub}", fontsize=9)
        ax.set_xlabel("strain [%]")
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=8, loc="upper left")
    for row in axes:
        row[0].set_ylabel("top platen stress [kPa]")
    save_figure(fig, path, dpi=110)


def write_doc(text: str) -> None:
    """Put the table between the markers of docs/LIGGGHTS_EEPA.md (create it if absent)."""
    write_marked(DOC, TABLE_BEGIN, TABLE_END, text, "demscale against LIGGGHTS 3.8: the EEPA law")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--cases",
        nargs="*",
        default=None,
        choices=[*CASES, "mpi", "spread"],
        help="cases to (re)run; default: all, the MPI check and demscale's spread",
    )
    ap.add_argument(
        "--codes", nargs="*", default=["demscale", "liggghts"], choices=["demscale", "liggghts"]
    )
    ap.add_argument("--report", action="store_true", help="only the table and the figure")
    args = ap.parse_args(argv)
    todo = (
        [] if args.report else (args.cases if args.cases is not None else [*CASES, "mpi", "spread"])
    )
    if shutil.which("liggghts") is None:
        print("liggghts is not on the PATH: only cached LIGGGHTS curves can be compared")
    for key in todo:
        if key == "spread":
            for k, (dseeds, lseeds) in SPREAD.items():
                for code, seeds, run in (
                    ("demscale", dseeds, run_demscale),
                    ("liggghts", lseeds, run_liggghts),
                ):
                    if code not in args.codes:
                        continue
                    for seed in seeds:
                        print(
                            f"{code} case {k}, bed moved by {JITTER:g} m (seed {seed}) ...",
                            flush=True,
                        )
                        r = run(CASES[k], jitter=JITTER, seed=seed)
                        if r is not None:
                            save(f"{code}-jitter{seed}", k, r, CASES[k])
                            print(
                                f"  {r['seconds']:.0f} s, final stress {r['stress'][-1]:.4g} Pa",
                                flush=True,
                            )
            continue
        if key == "mpi":
            if "liggghts" not in args.codes:
                continue
            if shutil.which("mpirun") is None:
                print("no mpirun: the 2-rank LIGGGHTS run is skipped")
                continue
            case = CASES[MPI_CASE]
            print(f"LIGGGHTS case {MPI_CASE}, 2 MPI ranks ...", flush=True)
            r = run_liggghts(case, ranks=2)
            if r is not None:
                save("liggghts-2ranks", MPI_CASE, r, case)
                print(f"  {r['seconds']:.0f} s, {r['builds']} list builds", flush=True)
            continue
        case = CASES[key]
        if "demscale" in args.codes:
            print(f"demscale case {key}: {case.title} ...", flush=True)
            r = run_demscale(case)
            save("demscale", key, r, case)
            print(f"  {r['seconds']:.0f} s, final stress {r['stress'][-1]:.4g} Pa", flush=True)
        if "liggghts" in args.codes and shutil.which("liggghts"):
            print(f"LIGGGHTS case {key}: {case.title} ...", flush=True)
            r = same_liggghts_run(case)
            if r is not None:
                print(f"  the same deck as case {r['same_as']}: its run", flush=True)
            else:
                r = run_liggghts(case)
            if r is not None:
                save("liggghts", key, r, case)
                print(
                    f"  {r['seconds']:.0f} s, final stress {r['stress'][-1]:.4g} Pa, "
                    f"{r['builds']} list builds ({r['dangerous']} dangerous)",
                    flush=True,
                )
    results = {}
    for code in ("demscale", "liggghts", "liggghts-2ranks", *SPREAD_CODES):
        for key, case in CASES.items():
            r = load(code, key, case)
            if r is not None:
                results[code, key] = r
    text = table(results)
    print("\n" + text)
    write_doc(text)
    figure(results, FIGURE)
    print(f"wrote {DOC.relative_to(ROOT)} and {FIGURE.relative_to(ROOT)}")
    checks = []
    for k, case in CASES.items():
        if case.diagnostic:
            continue
        if ("demscale", k) in results and ("liggghts", k) in results:
            d = rel_rms(
                results["demscale", k]["strain"],
                results["demscale", k]["stress"],
                results["liggghts", k]["strain"],
                results["liggghts", k]["stress"],
            )
            checks.append(
                (
                    f"case {k} ({case.title}): stress-strain within {TARGET:g} % of "
                    f"LIGGGHTS: {d:.1f} % (docs/LIGGGHTS_EEPA.md explains the "
                    "differences)",
                    d <= TARGET,
                )
            )
        else:
            checks.append((f"case {k}: not compared (a code did not run)", False))
    return report(checks)


if __name__ == "__main__":
    sys.exit(main())
