"""The porosity range: what the engine's sphere packings reach in confined compression, with
adhesion, friction and polydispersity from none to strong (issue 41 item 4).

    python -m benchmarks.porosity_range              # the runs not yet stored, then the report
    python -m benchmarks.porosity_range --report     # the report from the stored runs only
    python -m benchmarks.porosity_range --only KEY   # one run (its cost), e.g. none-low-mono-s1

``LabTargets`` refuses a compression-curve porosity outside
:data:`engine.calibration.targets.POROSITY_RANGE`: a target the engine's packings cannot reach
would make a calibration distort every other parameter trying. This benchmark measures that
range instead of assuming it.

The grid, chosen before any run (a full factorial, 2 packing seeds per point):

- adhesion (bilinear law, K1 = 5e3 N/m, K2 = 2.5e4 N/m at R = 2.5 mm, the paper's): the
  Bond number Bo = |f0| / (m g) of the mean particle (m g = 1.28e-3 N) 0 (no adhesion), 100
  (f0 = -0.128 N) and 1000 (f0 = -1.28 N, about 2.6 times the mean contact force at 20 kPa,
  sigma (2 R)^2 = 0.5 N), each with kadh = 0; Bo = 1000 with kadh = K2, the pull-off growing
  with the plastic overlap to half its saturation (docs/CALIBRATION.md
  "Consolidation-dependent adhesion"); and Bo = 1e4 (f0 = -12.8 N) with K1 and K2 ten
  times the paper's (the strongest adhesion the law takes at K1 = 5e3 N/m is about
  Bo = 2600 at p = 0.49, |f0| < K1 r_min / 2; scaled so, its equilibrium overlap |f0| / K1
  stays 0.26 mm, a tenth of the radius, as at Bo = 1000, so that the spheres' overlap
  volume, counted as solid, moves the porosity by less than about 0.005);
- friction: low (mu_s = 0.1, mu_r = 0) and high (mu_s = 1.0, mu_r = 0.3, the tops of the
  boxes the stored calibrations used): rolling resistance is what holds a loose cohesive
  packing's arches;
- polydispersity: monodisperse (p = 0) and the widest the engine takes (p = 0.49: radii
  uniform in [0.51 R, 1.49 R], UniaxialTest.polydispersity < 0.5);
- stresses: the default fill, at the cloud's solid fraction 0.25 (the default 0.3 jams in
  this cell at p = 0.49: random sequential addition of 710 spheres), rained down at most
  2 m/s,
  loaded to the pre-compression 1 kPa, on to the consolidation 20 kPa (a shear or uniaxial
  tester's range), unloaded to 200 Pa; the porosity read on loading at 0.5, 1, 2, 5, 10 and
  20 kPa and on unloading at 10, 5, 2 and 1 kPa, as the calibration reads a compression
  target (the top platen's stress, interpolated on the pre-compression and consolidation
  curves, or on the unloading curve);
- the cell: 40 x 40 x 60 mm at R = 2.5 mm (8 x 8 x 12 mean diameters, 880 particles
  monodisperse, 5.4 largest diameters across at p = 0.49), periodic in x and y, density
  2000 kg/m^3, g = 9.81 m/s^2, the default protocol, no unconfined stage. Each porosity is
  read twice: the whole sample's (what a calibration compares with a lab value, in its own
  cell) and the interior's (two largest diameters at each platen left out: the bulk's).

What decides the range (fixed before the runs): the lowest and the highest porosity any run
reaches at any of those stresses on either branch, by either reading, widened by twice the
pooled seed standard deviation (the root mean square of the two seeds' sd over every grid
point, stress and reading: the scatter of one run of one packing about its point's mean),
and rounded outward to 0.01. Why it bounds what a calibration can match: a calibration's
runs are this engine's spheres under this law family, so a lab porosity below the densest
run or above the loosest is one no parameter set within the grid's span reaches; the
whole-sample reading in a cell 12 diameters tall with its platen layers and the interior
reading bracket a calibration cell's reading between a short cell and the bulk. What it
does not bound (not measured): adhesion beyond Bo = 1e4 (or at Bo = 1e4 with softer
contacts: deeper overlaps), softer laws than the paper's (which compact by overlap), other
fills (a more dilute cloud, a sieve), non-spherical particles, cells shorter than 12
diameters (whose platen layers loosen the whole-sample porosity further), and stresses
outside 0.5-20 kPa.

Added after 2 of the first 19 runs (Bo >= 100, low friction, p = 0.49) were stopped because
their fill's kinetic energy stayed above the settling threshold (settle_ke = 1e-4 of N m g R,
2.3e-7 J here) for the 5 s a stage may last, at 2-4 times the threshold (the grains'
rms speed about 4-5 mm/s: a slow creep of a bed without rolling resistance): such a run is
made once more with the threshold ten times higher (1e-3 N m g R; the same bed, its
platen lowered while it creeps at about 3 times that speed), stored as ``<key>-retry.h5``
and read in its place; the table marks it. A run that fails again is reported, not read.

Every run is stored as it finishes (``benchmarks/results/porosity_range/<key>.h5``, curves
only); a rerun makes only the missing ones. ``--report`` writes ``summary.json`` (every run's
readings and the range by the rule above: the file tests/engine/test_porosity_range.py
checks ``POROSITY_RANGE`` against) and ``report.md`` in the same folder.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.checks import publish
from engine.calibration.calibrate import compression_branch

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "benchmarks" / "results" / "porosity_range"
SUMMARY = STORE / "summary.json"
REPORT = STORE / "report.md"

RADIUS = 2.5e-3  # [m]
DENSITY = 2000.0  # [kg/m^3]
GRAVITY = 9.81  # [m/s^2]
CELL = (0.04, 0.04, 0.06)  # [m]
POUR_FRACTION = 0.25  # [-]
K1, K2 = 5e3, 2.5e4  # [N/m]
PRE_STRESS, CONSOLIDATION_STRESS = 1e3, 20e3  # [Pa]
#: Stresses the porosity is read at [Pa], on loading and on unloading.
LOADING_STRESSES = (500.0, 1e3, 2e3, 5e3, 10e3, 20e3)
UNLOADING_STRESSES = (10e3, 5e3, 2e3, 1e3)
#: The grid's axes: adhesion name -> (Bond number |f0| / (m g), kadh / K2, the factor on the
#: paper's K1 and K2).
ADHESION = {
    "none": (0.0, 0.0, 1.0),
    "bo100": (100.0, 0.0, 1.0),
    "bo1000": (1000.0, 0.0, 1.0),
    "bo1000-kadh": (1000.0, 1.0, 1.0),
    "bo10000": (1e4, 0.0, 10.0),
}
#: friction name -> (mu_s, mu_r).
FRICTION = {"low": (0.1, 0.0), "high": (1.0, 0.3)}
#: polydispersity name -> p (radii uniform in [R (1 - p), R (1 + p)]).
POLYDISPERSITY = {"mono": 0.0, "poly": 0.49}
SEEDS = (1, 2)
#: A run whose fill does not settle within max_stage_time (5 s simulated) is made once more
#: with the fill's settling threshold ten times the default (1e-4 N m g R), stored under its
#: key with this suffix, and read in its place (added after the first such failures: see the
#: module docstring).
RETRY = "-retry"
RETRY_SETTLE_KE = 1e-3
#: The readings of the porosity: the whole sample's (the calibration's) and the interior's.
READINGS = {"whole": "porosity", "interior": "porosity_interior"}
#: The range is widened by this many pooled seed standard deviations.
SEED_WIDENING = 2.0


def particle_weight() -> float:
    """m g of the mean particle [N]."""
    return DENSITY * 4.0 / 3.0 * math.pi * RADIUS**3 * GRAVITY


def points() -> list[tuple[str, str, str]]:
    """The grid points (adhesion, friction, polydispersity), in run order."""
    return list(itertools.product(ADHESION, FRICTION, POLYDISPERSITY))


def key(point: tuple[str, str, str], seed: int) -> str:
    return f"{'-'.join(point)}-s{seed}"


def grid_test(point: tuple[str, str, str], seed: int, retry: bool = False):
    """The uniaxial test of one grid point and packing seed; ``retry``: with the fill's
    settling threshold :data:`RETRY_SETTLE_KE` (a fill that did not settle)."""
    from engine import BilinearAdhesive, UniaxialTest

    adhesion, friction, poly = point
    bond, kadh, stiffer = ADHESION[adhesion]
    mu_s, mu_r = FRICTION[friction]
    law = BilinearAdhesive(
        k1=stiffer * K1,
        k2=stiffer * K2,
        f0=-bond * particle_weight(),
        kadh=kadh * stiffer * K2,
        mu_s=mu_s,
        mu_r=mu_r,
        restitution=0.4,
    )
    return UniaxialTest(
        cell=CELL,
        radius=RADIUS,
        polydispersity=POLYDISPERSITY[poly],
        density=DENSITY,
        gravity=GRAVITY,
        pair_law=law,
        pour_fraction=POUR_FRACTION,
        pre_stress=PRE_STRESS,
        consolidation_stress=CONSOLIDATION_STRESS,
        unconfined=False,
        seed=seed,
        settle_ke=RETRY_SETTLE_KE if retry else 1e-4,
    )


def jobs() -> list[tuple[tuple[str, str, str], int]]:
    return [(p, s) for p in points() for s in SEEDS]


def _stored(point, seed, retry: bool = False):
    """The stored outcome of a run made with the grid's test (or its retry), or None."""
    from engine.io.store import load_run

    path = STORE / f"{key(point, seed)}{RETRY * retry}.h5"
    if not path.exists():
        return None
    old = load_run(path)
    if isinstance(old, str) or old.test == grid_test(point, seed, retry):
        return old
    return None


def _unsettled(outcome) -> bool:
    return isinstance(outcome, str) and "stage fill did not settle" in outcome


def run_one(point, seed, retry: bool = False) -> str:
    """Run one grid point and seed (or its retry) and store it at once (an error is stored
    as its text)."""
    from engine.io.store import save_run
    from engine.uniaxial.driver import run_uniaxial

    name = f"{key(point, seed)}{RETRY * retry}"
    t0 = time.perf_counter()
    try:
        outcome = run_uniaxial(grid_test(point, seed, retry))
    except Exception as e:  # stored as the run's error, as the studies do
        outcome = f"{type(e).__name__}: {e}"
    save_run(STORE / f"{name}.h5", outcome, keep_particles=False)
    extra = "" if not isinstance(outcome, str) else f" FAILED {outcome}"
    n = "" if isinstance(outcome, str) else f", {int(outcome.scalars['particles'])} particles"
    return f"{name}: {time.perf_counter() - t0:.0f} s{n}{extra}"


def run(only: str | None = None) -> None:
    import numba

    numba.set_num_threads(1)
    todo = [(p, s) for p, s in jobs() if _stored(p, s) is None]
    if only is not None:
        todo = [(p, s) for p, s in jobs() if key(p, s) == only]
        if not todo:
            raise SystemExit(f"no grid run {only!r}; one of {', '.join(key(*j) for j in jobs())}")
    print(f"{len(todo)} runs to make", flush=True)
    for p, s in todo:
        print("  stored", run_one(p, s), flush=True)
    if only is None:
        retries = [
            (p, s)
            for p, s in jobs()
            if _unsettled(_stored(p, s)) and _stored(p, s, retry=True) is None
        ]
        print(f"{len(retries)} fills that did not settle to retry", flush=True)
        for p, s in retries:
            print("  stored", run_one(p, s, retry=True), flush=True)


# ------------------------------------------------------------------ what a run reaches
def readings(result) -> dict:
    """A run's porosities: per reading, per branch, per stress [-]; and the poured bed's
    (the first sample of the pre-compression, the platen just above the bed)."""
    out = {}
    for name, curve in READINGS.items():
        out[name] = {}
        for branch, stresses in (("loading", LOADING_STRESSES), ("unloading", UNLOADING_STRESSES)):
            sig, por = compression_branch(result, branch, curve)
            out[name][branch] = {f"{s:g}": float(np.interp(s, sig, por)) for s in stresses}
        out[name]["poured"] = float(result.stages["pre_compression"].curves[curve][0])
    return out


def decide_range(runs: dict) -> dict:
    """The range by the module's rule from ``runs`` (key -> :func:`readings`): the extreme
    values at the stated stresses (both branches, both readings), the pooled seed sd, and
    the range widened by :data:`SEED_WIDENING` sd and rounded outward to 0.01."""
    values, lo_at, hi_at = [], None, None
    var, dof = 0.0, 0
    for point in points():
        seeds = [runs[key(point, s)] for s in SEEDS if key(point, s) in runs]
        for reading in READINGS:
            for branch in ("loading", "unloading"):
                for stress in seeds[0][reading][branch] if seeds else ():
                    v = [r[reading][branch][stress] for r in seeds]
                    for x in v:
                        where = f"{'-'.join(point)} {reading} {branch} {stress} Pa"
                        if lo_at is None or x < lo_at[0]:
                            lo_at = (x, where)
                        if hi_at is None or x > hi_at[0]:
                            hi_at = (x, where)
                        values.append(x)
                    if len(v) > 1:
                        var += float(np.var(v, ddof=1)) * (len(v) - 1)
                        dof += len(v) - 1
    sd = math.sqrt(var / dof) if dof else float("nan")
    lo = math.floor(100 * (lo_at[0] - SEED_WIDENING * sd)) / 100
    hi = math.ceil(100 * (hi_at[0] + SEED_WIDENING * sd)) / 100
    return {
        "lowest": lo_at[0],
        "lowest_at": lo_at[1],
        "highest": hi_at[0],
        "highest_at": hi_at[1],
        "pooled_seed_sd": sd,
        "seed_dof": dof,
        "widening_sd": SEED_WIDENING,
        "range": [lo, hi],
    }


def summary() -> dict:
    """Every stored run's readings and the range they decide."""
    runs, failed, missing = {}, {}, []
    for p, s in jobs():
        r = _stored(p, s)
        retried = None
        if _unsettled(r):
            retried, r = r, _stored(p, s, retry=True)
        if r is None:
            missing.append(key(p, s) + (RETRY if retried else ""))
        elif isinstance(r, str):
            failed[key(p, s)] = r
        else:
            runs[key(p, s)] = readings(r) | {
                "particles": int(r.scalars["particles"]),
                "wall_time": float(r.scalars["wall_time"]),
                "retried_after": retried,
            }
    return {
        "command": "python -m benchmarks.porosity_range --report",
        "grid": {
            "adhesion (Bond number, kadh / K2, factor on K1 and K2)": ADHESION,
            "friction (mu_s, mu_r)": FRICTION,
            "polydispersity": POLYDISPERSITY,
            "seeds": SEEDS,
            "cell_m": CELL,
            "radius_m": RADIUS,
            "density_kg_m3": DENSITY,
            "k1_k2_N_m": [K1, K2],
            "particle_weight_N": particle_weight(),
            "pre_stress_Pa": PRE_STRESS,
            "consolidation_stress_Pa": CONSOLIDATION_STRESS,
        },
        "runs": runs,
        "failed": failed,
        "missing": missing,
        "range": decide_range(runs) if runs and not missing else None,
    }


def report_text(s: dict) -> str:
    runs = s["runs"]
    lines = [
        "# The porosity range (benchmarks/porosity_range.py)",
        "",
        f"Generated by `{s['command']}` from benchmarks/results/porosity_range/*.h5. Mean of "
        f"seeds {', '.join(map(str, SEEDS))} (their half difference in brackets); whole "
        "sample / interior.",
        "",
        "Retried: a fill that did not settle, made again at settle_ke 1e-3 (module docstring).",
        "",
        "| adhesion | friction | size spread | poured | 1 kPa | 20 kPa | unloaded to 1 kPa |",
        "|---|---|---|---|---|---|---|",
    ]

    def cell(point, get):
        v = {
            r: [get(runs[k][r]) for k in (key(point, sd) for sd in SEEDS) if k in runs]
            for r in READINGS
        }
        if not v["whole"]:
            return "-"
        spread = [f"{abs(x[0] - x[-1]) / 2:.3f}" if len(x) > 1 else "1 seed" for x in v.values()]
        return " / ".join(f"{np.mean(x):.3f} ({d})" for x, d in zip(v.values(), spread))

    for point in points():
        a, f, p = point
        bond, kadh, stiffer = ADHESION[a]
        law = ", kadh = K2" if kadh else ""
        law += f", K1 and K2 x {stiffer:g}" if stiffer != 1 else ""
        retried = [f"s{sd}" for sd in SEEDS if runs.get(key(point, sd), {}).get("retried_after")]
        if retried:
            law += f" ({', '.join(retried)} retried)"
        lines.append(
            f"| Bo {bond:g}{law} "
            f"| mu_s {FRICTION[f][0]:g}, mu_r {FRICTION[f][1]:g} | p = {POLYDISPERSITY[p]:g} "
            f"| {cell(point, lambda r: r['poured'])} "
            f"| {cell(point, lambda r: r['loading']['1000'])} "
            f"| {cell(point, lambda r: r['loading']['20000'])} "
            f"| {cell(point, lambda r: r['unloading']['1000'])} |"
        )
    lines.append("")
    rng = s["range"]
    if rng is not None:
        lines += [
            f"Lowest porosity: {rng['lowest']:.4f} ({rng['lowest_at']}); highest: "
            f"{rng['highest']:.4f} ({rng['highest_at']}); pooled seed sd "
            f"{rng['pooled_seed_sd']:.4f} ({rng['seed_dof']} degrees of freedom). "
            f"Range: [{rng['range'][0]:.2f}, {rng['range'][1]:.2f}] (extremes widened by "
            f"{rng['widening_sd']:g} sd, rounded outward to 0.01).",
            "",
        ]
    for k, e in s["failed"].items():
        lines.append(f"- {k} failed: {e}")
    if s["missing"]:
        lines.append(f"- not run yet: {', '.join(s['missing'])}")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", action="store_true", help="only the report, from stored runs")
    ap.add_argument("--only", help="make (or remake) one run, e.g. none-low-mono-s1")
    args = ap.parse_args(argv)
    if not args.report:
        run(args.only)
    s = summary()
    STORE.mkdir(parents=True, exist_ok=True)
    SUMMARY.write_text(json.dumps(s, indent=1) + "\n")
    publish(REPORT, report_text(s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
