"""Issue 41 item 1: demscale's shear test against a ring shear cell in LIGGGHTS 3.8
(docs/SHEAR.md, "Against a ring shear cell (LIGGGHTS)").

    python -m benchmarks.annular_shear              # every run not yet stored, then --report
    python -m benchmarks.annular_shear --cost       # one short ring run: its cost, stored
    python -m benchmarks.annular_shear --demscale   # demscale's six seeds only
    python -m benchmarks.annular_shear --liggghts   # the ring's pre-shear and points only
    python -m benchmarks.annular_shear --report     # the comparison from what is stored,
                                                    # written into docs/SHEAR.md

Everything runs one simulation at a time, niced; each run (a demscale seed, the ring's
pre-shear, each ring point) is stored the moment it ends under
benchmarks/results/annular_shear/ and skipped when present, so a rerun resumes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from engine.io.liggghts_deck import resolved_dt
from engine.shear.driver import SMOOTHING_STRAIN, _smoothed
from engine.shear.locus import fit_line

from . import demscale_side as ds
from .ring import COLUMNS, Ring

STORE = ds.STORE
RING_DIR = STORE / "liggghts"
COST_DIR = STORE / "cost"
DOC = Path(__file__).resolve().parents[2] / "docs" / "SHEAR.md"

#: the ring's size in particle diameters: radial width, fill height (demscale's 15), mean radius
WIDTH_D = 5.0
HEIGHT_D = 15.0
MEAN_RADIUS_D = 25.0

#: the tolerance stated before the runs (docs/SHEAR.md): allowance A and the seed spreads s
#: of one demscale run (six stored default-law runs of the default cell, same points)
ALLOWANCE = 0.10
SPREAD = {"tau_2000": 53.0, "tau_4000": 143.0, "tau_8000": 235.0, "tau_pre": 264.0}
SPREAD_SLOPE = 0.030
SPREAD_COHESION = 68.0
Z = 1.96


def liggghts() -> str | None:
    return shutil.which("liggghts")


def ring(**over) -> Ring:
    """The ring of this benchmark: demscale's test's radius, density, law and time step,
    its servo's gain and relaxation time (means of the stored demscale runs'
    ``servo_gain``, ``servo_time``)."""
    t = ds.test_for(1)
    runs = ds.load_all()
    if not runs:
        raise SystemExit("run the demscale side first (--demscale): the ring takes its servo gain")
    gain = float(np.mean([r.scalars["servo_gain"] for r in runs]))
    servo_time = float(np.mean([r.scalars["servo_time"] for r in runs]))
    d = 2 * t.radius
    kw = dict(
        law=t.pair_law,
        radius=t.radius,
        density=t.density,
        mean_radius=MEAN_RADIUS_D * d,
        width=WIDTH_D * d,
        height=HEIGHT_D * d,
        dt=resolved_dt(t),
        servo_gain=gain,
        servo_time=servo_time,
        preshear_stress=t.preshear_stress,
        normal_stresses=tuple(t.normal_stresses),
        inertial_number=t.inertial_number,
        max_speed=t.max_shear_speed,
        wall_E=t.wall_law.E,
        wall_nu=t.wall_law.nu,
        wall_material_E=t.wall_material.E,
        wall_material_nu=t.wall_material.nu,
        wall_restitution=t.wall_law.restitution,
        plate_mu=t.wall_law.mu,
        output_interval=t.output_interval,
    )
    kw.update(over)
    return Ring(**kw)


def _liggghts(directory: Path, deck: str) -> float:
    """Run ``deck`` (a file in ``directory``) niced; its wall time [s]."""
    t0 = time.time()
    cmd = ["nice", "-n", "19", "stdbuf", "-o0", liggghts(), "-in", deck, "-log", f"log.{deck}"]
    with open(directory / f"screen.{deck}", "w") as out:
        rc = subprocess.call(cmd, cwd=directory, stdout=out, stderr=subprocess.STDOUT)
    if rc:
        raise RuntimeError(f"liggghts {deck} in {directory} exited {rc}")
    return time.time() - t0


def loop_times(log: str) -> tuple[int, float, int]:
    """(steps, seconds, atoms) summed over a LIGGGHTS log's 'Loop time' lines."""
    steps = secs = atoms = 0
    for m in re.finditer(r"Loop time of (\S+) on \d+ procs for (\d+) steps with (\d+) atoms", log):
        secs += float(m.group(1))
        steps += int(m.group(2))
        atoms = int(m.group(3))
    return steps, secs, atoms


def cost() -> dict:
    """A short ring run at the benchmark's size (the whole fill and consolidation, then
    0.02 of pre-shear strain): LIGGGHTS' seconds per particle-step on this machine in the
    dense pre-shear (its last 'Loop time'), and the whole run's, stored."""
    path = STORE / "cost.json"
    if path.exists():
        return json.loads(path.read_text())
    r = ring(preshear_strain=0.02)
    COST_DIR.mkdir(parents=True, exist_ok=True)
    _write_inputs(COST_DIR, r)
    wall = _liggghts(COST_DIR, "in.preshear")
    log = (COST_DIR / "log.in.preshear").read_text()
    steps, secs, atoms = loop_times(log)
    last = re.findall(r"Loop time of (\S+) on \d+ procs for (\d+) steps", log)[-1]
    out = {
        "particles": atoms,
        "steps": steps,
        "loop_seconds": secs,
        "wall_seconds": wall,
        "seconds_per_particle_step": secs / (steps * atoms),
        "preshear_steps": int(last[1]),
        "preshear_seconds_per_particle_step": float(last[0]) / (int(last[1]) * atoms),
        "width_d": WIDTH_D,
        "height_d": HEIGHT_D,
        "mean_radius_d": MEAN_RADIUS_D,
        "load_average": os.getloadavg()[0],
    }
    path.write_text(json.dumps(out, indent=1))
    for f in COST_DIR.glob("*.restart"):
        f.unlink()
    return out


def _write_inputs(directory: Path, r: Ring) -> None:
    (directory / "ring.data").write_text(r.data_file())
    (directory / "plate.stl").write_text(r.plate())
    (directory / "in.preshear").write_text(r.preshear_deck())
    (directory / "ring.json").write_text(json.dumps(ring_record(r), indent=1))


def ring_record(r: Ring) -> dict:
    return {
        "ri": r.ri,
        "ro": r.ro,
        "mean_radius": r.mean_radius,
        "width": r.width,
        "height": r.height,
        "particles": r.particles,
        "radius": r.radius,
        "dt": r.dt,
        "servo_gain": r.servo_gain,
        "area": r.area,
        "lever": r.lever,
        "normal_stresses": list(r.normal_stresses),
        "preshear_stress": r.preshear_stress,
        "preshear_strain": r.preshear_strain,
        "law": repr(r.law),
    }


def curves(path: Path) -> dict[str, np.ndarray]:
    a = np.loadtxt(path, comments="#", ndmin=2)
    return {k: a[:, i] for i, k in enumerate(COLUMNS)}


def run_liggghts() -> None:
    """The ring's pre-shear, then each point from its restart; each stored as it ends."""
    if not liggghts():
        raise SystemExit("liggghts is not installed")
    r = ring()
    RING_DIR.mkdir(parents=True, exist_ok=True)
    if not (RING_DIR / "preshear.txt").exists() or "done" not in _meta():
        _write_inputs(RING_DIR, r)
        print(f"ring pre-shear: {r.particles} spheres", flush=True)
        wall = _liggghts(RING_DIR, "in.preshear")
        print(f"ring pre-shear: {wall:.0f} s", flush=True)
    gap = preshear_gap()
    for k in range(len(r.normal_stresses)):
        if (RING_DIR / f"shear_{k}.txt").exists() and f"point {k} done" in _meta():
            continue
        (RING_DIR / f"in.point{k}").write_text(r.point_deck(k, gap))
        print(f"ring point {k}: sigma_n {r.normal_stresses[k]:g} Pa", flush=True)
        wall = _liggghts(RING_DIR, f"in.point{k}")
        print(f"ring point {k}: {wall:.0f} s", flush=True)


def _meta() -> str:
    p = RING_DIR / "meta.txt"
    return p.read_text() if p.exists() else ""


def preshear_gap() -> float:
    """The gap h [m] between lid and base grains' mean heights at the pre-shear's start."""
    m = re.search(r"gap (\S+) speed (\S+)", _meta())
    return float(m.group(1))


def preshear_speed() -> float:
    m = re.search(r"gap (\S+) speed (\S+)", _meta())
    return float(m.group(2))


# ---------------------------------------------------------------------------- analysis
def _stresses(c: dict, r: Ring) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sigma [Pa], tau [Pa], gap [m]) of a curve file's samples: F_z / A, T / lever."""
    return c["force_lid"] / r.area, c["torque_lid"] / r.lever, c["z_lid"] - c["z_base"]


def preshear_point(r: Ring) -> dict:
    """The ring's pre-shear: the means over its last ``steady_window`` (0.2) of strain and
    demscale's steady-state checks on its last two windows (10 % shear stress, 1 % height,
    2 % normal stress)."""
    c = curves(RING_DIR / "preshear.txt")
    sig, tau, h = _stresses(c, r)
    gamma = c["step"] * r.dt * preshear_speed() / preshear_gap()
    end = gamma[-1]
    last = gamma > end - 0.2
    prev = (gamma > end - 0.4) & ~last
    drift = abs(tau[last].mean() - tau[prev].mean()) / abs(tau[prev].mean())
    hdrift = abs(h[last].mean() - h[prev].mean()) / h[prev].mean()
    servo = abs(sig[last].mean() - r.preshear_stress) / r.preshear_stress
    return {
        "sigma": float(sig[last].mean()),
        "tau": float(tau[last].mean()),
        "strain": float(end),
        "drift": float(drift),
        "height_drift": float(hdrift),
        "servo_miss": float(servo),
        "steady": bool(drift < 0.1 and hdrift < 0.01 and servo < 0.02),
        "gap": float(h[last].mean()),
    }


def failure_point(r: Ring, k: int) -> dict:
    """Point ``k`` by demscale's rule replayed on the ring's samples: the shear stress
    smoothed over 0.01 strain, the stage over at the first sample 5 % below the running
    peak at least 0.01 strain past it (``peaked``), else at the last sample; the point is
    (smoothed sigma, smoothed tau) at the peak of what was run to there."""
    sn = r.normal_stresses[k]
    c = curves(RING_DIR / f"shear_{k}.txt")
    sig, tau, h = _stresses(c, r)
    vn = r.speed(sn, preshear_gap())
    g = (c["step"] * r.dt) * vn / h[0]
    end, peaked = len(g), False
    for i in range(1, len(g) + 1):
        sm = _smoothed(g[:i], tau[:i], SMOOTHING_STRAIN)
        j = int(np.argmax(sm))
        if sm[-1] < 0.95 * sm[j] and g[i - 1] - g[j] >= SMOOTHING_STRAIN:
            end, peaked = i, True
            break
    st = _smoothed(g[:end], tau[:end], SMOOTHING_STRAIN)
    ss = _smoothed(g[:end], sig[:end], SMOOTHING_STRAIN)
    j = int(np.argmax(st))
    cn = curves(RING_DIR / f"normal_{k}.txt")
    sn_hold = cn["force_lid"][-5:].mean() / r.area
    return {
        "target": sn,
        "sigma": float(ss[j]),
        "tau": float(st[j]),
        "strain": float(g[j]),
        "peaked": peaked,
        "servo_miss": float(abs(ss[j] - sn) / sn),
        "normal_stage_miss": float(abs(sn_hold - sn) / sn),
        "run_strain": float(g[-1]),
    }


def _fit(points: list[dict]) -> tuple[float, float]:
    c, m, _, _ = fit_line([p["sigma"] for p in points], [p["tau"] for p in points])
    return c, m


def demscale_values() -> dict[str, np.ndarray]:
    """Per demscale seed: tau at each normal stress, tau_pre, the locus's c and slope."""
    rows = []
    for res in ds.load_all():
        pts = [p for p in res.yield_points() if p["kind"] == "failure"]
        c, m = _fit(pts)
        rows.append([p["tau"] for p in pts] + [res.scalars["preshear_tau"], m, c])
    keys = [f"tau_{s:g}" for s in ds.NORMAL_STRESSES] + ["tau_pre", "slope", "cohesion"]
    a = np.array(rows)
    return {k: a[:, i] for i, k in enumerate(keys)}


def default_law_values() -> dict[str, float]:
    """Means of the stored default-law runs (kt = 2/7 K1, the adhesion-aware cap): context."""
    root = STORE.parent / "quick" / "shear"
    rows = []
    for s in ds.SEEDS:
        d = json.loads((root / f"cohesionless-h15-s{s}.json").read_text())
        pts = [
            p for p in d["points"] if p["kind"] == "failure" and p["target"] in ds.NORMAL_STRESSES
        ]
        c, m = _fit(pts)
        rows.append([p["tau"] for p in pts] + [d["scalars"]["preshear_tau"], m, c])
    keys = [f"tau_{s:g}" for s in ds.NORMAL_STRESSES] + ["tau_pre", "slope", "cohesion"]
    a = np.array(rows).mean(axis=0)
    return {k: float(a[i]) for i, k in enumerate(keys)}


def tolerance(key: str, dem: dict[str, np.ndarray], n: int) -> float:
    """The stated tolerance of ``key``: A x demscale's mean (c: x its tau at 2 kPa) +
    1.96 s sqrt(1 + 1/n), s the stored spread fixed before the runs."""
    noise = math.sqrt(1 + 1 / n) * Z
    if key == "slope":
        return ALLOWANCE * abs(dem[key].mean()) + noise * SPREAD_SLOPE
    if key == "cohesion":
        return ALLOWANCE * dem["tau_2000"].mean() + noise * SPREAD_COHESION
    return ALLOWANCE * abs(dem[key].mean()) + noise * SPREAD[key]


def ring_values(r: Ring) -> tuple[dict, dict, list[dict]]:
    pre = preshear_point(r)
    pts = [failure_point(r, k) for k in range(len(r.normal_stresses))]
    c, m = _fit(pts)
    vals = {f"tau_{p['target']:g}": p["tau"] for p in pts}
    vals.update(tau_pre=pre["tau"], slope=m, cohesion=c)
    return vals, pre, pts


def ring_cost() -> dict:
    """Steps, loop seconds and atoms of every stored ring run (the LIGGGHTS logs)."""
    out = {}
    for log in sorted(RING_DIR.glob("log.in.*")):
        steps, secs, atoms = loop_times(log.read_text())
        out[log.name[len("log.in.") :]] = {"steps": steps, "seconds": secs, "atoms": atoms}
    return out


MARK = "### Results (`python -m benchmarks.annular_shear --report`)"
KEYS = ("tau_2000", "tau_4000", "tau_8000", "tau_pre", "slope", "cohesion")
LABEL = {
    "tau_2000": "tau at sigma_n = 2 kPa [Pa]",
    "tau_4000": "tau at sigma_n = 4 kPa [Pa]",
    "tau_8000": "tau at sigma_n = 8 kPa [Pa]",
    "tau_pre": "tau_pre at 10 kPa [Pa]",
    "slope": "locus slope tan(phi) [-]",
    "cohesion": "locus cohesion c [Pa]",
}


def _g(x: float) -> str:
    return f"{x:.3g}" if abs(x) < 1 else f"{x:.0f}"


def verdict(r: Ring) -> dict:
    """Every quantity against its stated tolerance and the verdict (docs/SHEAR.md)."""
    dem = demscale_values()
    n = len(dem["tau_pre"])
    ring_v, pre, pts = ring_values(r)
    rows = []
    for k in KEYS:
        d = float(dem[k].mean())
        diff = ring_v[k] - d
        tol = tolerance(k, dem, n)
        rows.append(
            {
                "key": k,
                "ring": ring_v[k],
                "demscale": d,
                "demscale_sd": float(dem[k].std(ddof=1)),
                "difference": diff,
                "relative": diff / d if k != "cohesion" else None,
                "tolerance": tol,
                "within": abs(diff) <= tol,
            }
        )
    valid = (
        pre["steady"]
        and all(p["peaked"] for p in pts)
        and all(p["servo_miss"] <= 0.05 for p in pts)
    )
    if not valid:
        word = "undecided"
    elif all(row["within"] for row in rows):
        word = "agree"
    else:
        word = "differ"
    return {"rows": rows, "preshear": pre, "points": pts, "verdict": word, "seeds": n}


def report() -> str:
    r = ring()
    v = verdict(r)
    (STORE / "comparison.json").write_text(json.dumps(v, indent=1, default=float))
    base = default_law_values()
    cost_rec = (
        json.loads((STORE / "cost.json").read_text()) if (STORE / "cost.json").exists() else None
    )
    runs = ring_cost()
    dem = ds.load_all()
    dem_n = np.mean([x.scalars["particles"] for x in dem])
    dem_steps = np.mean([x.scalars["steps"] for x in dem])
    dem_t = (min(x.scalars["wall_time"] for x in dem), max(x.scalars["wall_time"] for x in dem))
    lines = [
        MARK,
        "",
        "*Written by the command from the stored runs; do not edit by hand.*",
        "",
        f"The ring: Ri = {r.ri * 1e3:.1f} mm, Ro = {r.ro * 1e3:.1f} mm (width {WIDTH_D:g} d, mean "
        f"radius {MEAN_RADIUS_D:g} d: Ro / Ri = {r.ro / r.ri:.2f}, the shear rate "
        f"+-{100 * r.width / 2 / r.mean_radius:.0f} % about its mean across the width), fill "
        f"height {HEIGHT_D:g} d, {r.particles} spheres; dt = {r.dt:.4g} s, the servo's gain "
        f"{r.servo_gain:.4g} m/(Pa s) and relaxation time T = {1e3 * r.servo_time:.2f} ms "
        "demscale's (means of its runs); the servo proportional in the pre-shear (as it was "
        "run), PI with T_i = 5 T in the points (demscale's, without its gain-halving guard). "
        "A first point at 2 kPa with the proportional servo alone held the lid 15 % above "
        "sigma_n while the bed dilated (an invalid point by the rule above); it was stopped, "
        "kept in `liggghts_p_servo_point0/`, and the points rerun with the PI servo.",
        "",
    ]
    if cost_rec:
        lines += [
            f"Cost (`--cost`, measured first: one short run of the fill, consolidation and "
            f"0.02 pre-shear strain in a ring of mean radius {cost_rec['mean_radius_d']:g} d, "
            f"load average {cost_rec['load_average']:.1f}): "
            f"{cost_rec['particles']} spheres, {cost_rec['steps']} steps in "
            f"{cost_rec['wall_seconds']:.0f} s, "
            f"{cost_rec['preshear_seconds_per_particle_step'] * 1e6:.2f} us per particle-step "
            "in the dense pre-shear.",
            "",
        ]
    if runs:
        tot_steps = sum(x["steps"] for x in runs.values())
        tot_secs = sum(x["seconds"] for x in runs.values())
        lines += [
            "The ring's runs (LIGGGHTS loop times, niced on the shared 2-core machine): "
            + ", ".join(f"{k} {x['steps']} steps {x['seconds']:.0f} s" for k, x in runs.items())
            + f"; {tot_steps} steps, {tot_secs / 60:.1f} min in all. demscale: "
            f"{v['seeds']} seeds of {dem_n:.0f} grains, {dem_steps:.0f} steps and "
            f"{dem_t[0]:.0f}-{dem_t[1]:.0f} s each.",
            "",
        ]
    pre = v["preshear"]
    lines += [
        f"The ring's pre-shear: {pre['strain']:.2f} strain; its last two 0.2-strain windows "
        f"{100 * pre['drift']:.1f} % apart in shear stress, {100 * pre['height_drift']:.2f} % in "
        f"gap; normal stress {100 * pre['servo_miss']:.1f} % off sigma_pre; steady by "
        f"demscale's rule: {'yes' if pre['steady'] else 'no'}. Its points:",
        "",
        "| sigma_n [Pa] | sigma [Pa] | tau [Pa] | strain at peak | peaked | servo miss | "
        "sheared to strain | normal stage's end off sigma_n |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for p in v["points"]:
        lines.append(
            f"| {p['target']:g} | {p['sigma']:.0f} | {p['tau']:.0f} | {p['strain']:.3f} | "
            f"{'yes' if p['peaked'] else 'no'} | {100 * p['servo_miss']:.1f} % | "
            f"{p['run_strain']:.3f} | {100 * p['normal_stage_miss']:.1f} % |"
        )
    lines += [
        "",
        f"Against demscale's default cell, the same law ({v['seeds']} seeds, mean +- sd):",
        "",
        "| quantity | ring (LIGGGHTS) | demscale | ring - demscale | tolerance | within | "
        "default law (kt 2/7, context) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in v["rows"]:
        rel = f" ({100 * row['relative']:+.1f} %)" if row["relative"] is not None else ""
        lines.append(
            f"| {LABEL[row['key']]} | {_g(row['ring'])} | {_g(row['demscale'])} +- "
            f"{_g(row['demscale_sd'])} | {row['difference']:+.3g}{rel} | {_g(row['tolerance'])} | "
            f"{'yes' if row['within'] else '**no**'} | {_g(base[row['key']])} |"
        )
    lines += ["", f"**Verdict: {v['verdict']}.**", ""]
    return "\n".join(lines)


def write_doc(text: str) -> None:
    """Replace docs/SHEAR.md's results subsection (from MARK to the next subsection or the
    end) by ``text``; append it where there is none."""
    doc = DOC.read_text()
    i = doc.find(MARK)
    if i < 0:
        DOC.write_text(doc.rstrip("\n") + "\n\n" + text)
        return
    j = doc.find("\n### ", i + len(MARK))
    rest = doc[j:] if j >= 0 else ""
    DOC.write_text(doc[:i] + text.rstrip("\n") + "\n" + rest)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.annular_shear", description=__doc__)
    ap.add_argument("--cost", action="store_true", help="one short ring run: its cost")
    ap.add_argument("--demscale", action="store_true", help="demscale's seeds only")
    ap.add_argument("--liggghts", action="store_true", help="the ring only")
    ap.add_argument("--report", action="store_true", help="the comparison from what is stored")
    a = ap.parse_args(argv)
    if a.cost:
        print(json.dumps(cost(), indent=1))
        return 0
    if a.demscale or not (a.liggghts or a.report):
        ds.run()
    if a.liggghts or not (a.demscale or a.report):
        run_liggghts()
    if a.report or not (a.demscale or a.liggghts):
        text = report()
        write_doc(text)
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
