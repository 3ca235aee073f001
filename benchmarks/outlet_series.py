"""How many particles a hopper outlet needs across it (issue 52 item 4, issue 50's feature
kind "outlet"): size series of the fine law in the slot hopper with the stress level held,
stored as compact digests in git; the fits and docs/RESOLUTION.md's outlet rows are
:mod:`benchmarks.outlet_report`'s.

    python -m benchmarks.outlet_series                 # every run not yet stored, in order
    python -m benchmarks.outlet_series --list          # the runs, particles, stored or cost
    python -m benchmarks.outlet_series --only flow     # the runs whose key contains flow

Why this series measures the outlet. For the bilinear law scaled by the rule (K ~ R,
f0 ~ R^2) a coarse model at factor s of an outlet B wide under gravity g is, exactly, the
fine law in an outlet B / s wide under gravity g s (docs/PHYSICS.md section 5.1): the same
g B, so the same stress level rho_b g B, and B / d divided by s. So the fine law run at
varying B / d with **g B held** (and every other length in units of B) is what a user's
coarse-graining of an outlet does, and its size effect is the whole error of it. Two
properties, fixed here before any run of this series (2026-12-06):

- **Discharge rate** (series ``flow``): the discharge number W / (rho sqrt(g) B^1.5 D)
  (``HopperTest.rate_scale``; the same for every size of a held-stress series where the
  continuum holds) at **g B = :data:`G_FLOW` = 30 m^2/s^2**, 2.3 to 3 times the g B at
  which the same law's outlet arched in the Jenike series (``benchmarks.jenike_series``:
  12-14 m^2/s^2 at 6-7 d, 9-11 at 9-11 d), so that every size discharges and the cohesion
  still acts (the hopper's Bond number |f0| / (m g) is 2.3 at 8 d, 18 at 64 d). Outlet
  widths :data:`FLOW_WIDTHS` = 8 to 64 diameters (about x 1.4 apart), then 80 (the issue's
  widest, added after the others had run: 57,000 particles, 22-24 minutes on one core;
  its first two seeds, run with the hopper's catch zone (a drag far below the outlet),
  failed at 96 % discharged, the dense falling fill jammed where the drag slowed it, and
  were run again with the hopper's sink: docs/HOPPER.md, "The sink"),
  :data:`FLOW_SEEDS` seeds.
- **Discharge rate through a conical outlet** (series ``cone``, fixed 2026-12-06 before its
  runs, after the slot's discharge series and the sink check had been seen): the
  discharge series' hopper made a cone (``flow_test``'s every field, ``shape="cone"``:
  half-angle 30 deg, the fill B deep, radii +- 10 %, g B = G_FLOW, the same sampling), at
  :data:`CONE_WIDTHS` = 8 to 32 diameters, :data:`FLOW_SEEDS` seeds (the fill grows as
  (B / d)^3: 1,178 particles at 8 d, 75,406 at 32 d). Its discharge number is
  W / (rho sqrt(g) B^2.5) (``HopperTest.rate_scale``), with the slot's window, fit and 10 %
  tolerance; the outlet's N_req is the largest over its properties, this one among them
  (a user's outlet is as often a cone as a slot). Arching through a cone is not run.
- **The sink against the runs made before it** (series ``sink``, fixed 2026-12-06 before its
  runs): the runs of the discharge series up to 64 d were made before the sink (and before
  the catch zone's drag: their grains fell freely onto the floor's heap; said "the drag"
  here when this rule was fixed, corrected from their digests after the runs, the rule
  unchanged), the 80 d ones with the sink (``engine.hopper.driver``). Both act only 2 B +
  10 d below the outlet; whether the change moves the discharge number is measured, not argued:
  the :data:`SINK_CHECK_WIDTH` = 32 d runs of the three seeds made again with the sink, the
  same fills, paired by seed. The two are **equivalent** if the 90 % t-interval of the mean
  paired relative difference of the discharge number lies within +-
  :data:`SINK_CHECK_MARGIN` = 5 % (half the series' 10 % tolerance: a change of method
  smaller than that cannot move N_req across it by itself), **different** if it lies
  wholly outside, else undecided. Only if equivalent do the 80 d runs join the fit.
  The fill: radii uniform in R (1 +- 0.1) (``hopper_series``' reason: a monodisperse fill
  in a thin periodic slot crystallises and discharges in bursts), height B (held in units
  of B, as the stress), half-angle 30 deg, periodic depth 5 d, walls and gate Hertz
  E = 1e8 Pa, mu = 0.3 (the Jenike series' hopper); the discharge number in the steady
  window 20-60 % of the mass (the HopperTest default), sampled every 1/40 of the free-fall
  time sqrt(B / g) (:data:`SAMPLES_PER_FREE_FALL`; held like every time of the series. Set
  after the first runs: at the HopperTest's default of 1 ms the 8 and 11 d outlets, whose
  discharge lasts about 20 ms, had too few samples in the window for a rate: a constant
  in seconds that the similarity does not scale, the error issue 50 warns of. The four
  runs made with it were not kept).
- **Not held**: the fill's preparation (``jenike_series.ramped_hopper``: poured 0.4 s
  under 9.81 m/s^2, gravity then ramped to the test's in 0.1 s) is in seconds and m/s^2;
  after it the run settles at the test's gravity to its kinetic-energy criterion, so the
  packing is made at the held stress, but its history is not similar across sizes.
- **Arching width** (series ``arch``): the g B below which the outlet arches, G* = g B_crit.
  Where the continuum holds, Jenike's method gives B_crit = H(theta) sigma_c* / (rho_b g)
  with sigma_c* set by the flow function alone: G* does not depend on B / d. The Jenike
  series bracketed B_crit at g = 400 and 200 m/s^2 (B_crit near 6.5 and 10 d); this series
  adds g = :data:`ARCH_GRAVITIES` (100 and 50 m/s^2) with widths :data:`ARCH_WIDTHS`
  chosen to bracket B_crit if G* goes on falling as it did from 6.5 to 10 d (about
  13 -> 10 m^2/s^2) and if it does not, :data:`ARCH_SEEDS` seeds, with the Jenike series'
  own hopper and protocol (``jenike_series.hopper_test``, ``ramped_hopper``: monodisperse,
  fill max(B, 8 d) deep, so B deep at every width here). The four gravities' brackets give
  G* at four numbers of particles across B_crit. (45 d at g = 50 added on 2026-12-06 after
  two of its seeds had stopped at every width up to 40 d: the next width of the bracket
  rule, run for those seeds, about 15 min of CPU each.)

Fits, stated before the runs (those of :mod:`benchmarks.size_report`): the log of each
property linear in d / B, its value at d / B = 0 the bulk; N_req the B / d beyond which the
fitted line stays within the tolerance of the bulk: **10 % for the discharge rate** (the
spread of Beverloo's C between published slot and orifice experiments, 0.55-0.65 for
spheres, is about +- 8 %: a model closer than that is not told apart from a different
lab), **15 % for the arching width** (B_crit is proportional to sigma_c*, whose tolerance
in the shear cell is 15 %). The point estimate on the fitted slope, the 95 % bound from
its interval.

Each run is stored at once, on one engine thread, as a digest
``benchmarks/results/outlet_series/<series>/w<B/d>-s<seed>.json`` (:mod:`engine.io.digest`;
``extra``: the wall and CPU seconds, the protocol, the flow mode, the discharged fraction,
the discharge curve decimated). Full files are not kept: the digests hold every number the
fits read. A run cut off starts again (the ramped protocol drives the engine directly).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import engine
from benchmarks import jenike_series
from benchmarks.hopper_series import decimate
from benchmarks.series import list_or_run
from engine.hopper.scene import SINK_DIAMETERS
from engine.io.digest import make_digest, read_digest, write_digest

ROOT = Path(__file__).resolve().parent.parent
STORE = Path(
    os.environ.get("OUTLET_SERIES_STORE", ROOT / "benchmarks" / "results" / "outlet_series")
)

D = jenike_series.D
#: The held g B of the discharge series [m^2/s^2] (module docstring).
G_FLOW = 30.0
FLOW_WIDTHS = (8.0, 11.0, 16.0, 23.0, 32.0, 45.0, 64.0, 80.0)
FLOW_SEEDS = 3
#: Outlet widths of the conical discharge series [d] (module docstring).
CONE_WIDTHS = (8.0, 11.0, 16.0, 23.0, 32.0)
POLYDISPERSITY = 0.1
#: Samples of the discharge curve per free-fall time sqrt(B / g) (held: module docstring).
SAMPLES_PER_FREE_FALL = 40
#: The fill's height over the outlet width (held).
FILL_OVER_B = 1.0
#: Gravities [m/s^2] and outlet widths [d] of the arching series (module docstring).
ARCH_GRAVITIES = (100.0, 50.0)
ARCH_WIDTHS = {
    100.0: (11.0, 13.0, 15.0, 17.0, 20.0, 23.0),
    50.0: (20.0, 23.0, 26.0, 30.0, 35.0, 40.0, 45.0),
}
ARCH_SEEDS = 3
#: The sink check's width [d] and equivalence margin (module docstring).
SINK_CHECK_WIDTH = 32.0
SINK_CHECK_MARGIN = 0.05
#: The tolerances of the properties (module docstring).
TOLERANCES = {"discharge_number": 0.10, "cone_discharge_number": 0.10, "arching_g_b": 0.15}
PROTOCOL = jenike_series.PROTOCOL


def flow_test(width: float, seed: int) -> engine.HopperTest:
    """The discharge series' hopper at outlet ``width`` [d], fill ``seed``: the Jenike
    series' hopper with g = G_FLOW / B, the fill B deep, radii +- 10 %."""
    b = width * D
    g = G_FLOW / b
    base = jenike_series.hopper_test(width, seed, g)
    return replace(
        base,
        fill_height=FILL_OVER_B * b,
        polydispersity=POLYDISPERSITY,
        output_interval=(b / g) ** 0.5 / SAMPLES_PER_FREE_FALL,
    )


def series_name(kind: str, x: float) -> str:
    """``flow``, ``cone``, ``sink`` or ``arch-g<gravity>``."""
    return kind if kind in ("flow", "cone", "sink") else f"arch-g{x:g}"


def keys(only=None) -> list[tuple[str, float, float, int]]:
    """(kind, gravity or None, width [d], seed) in the order they are taken: the sink check
    first, then seed 1 of every width of both series (the widest last), then seed 2, then
    seed 3."""
    out = [("sink", G_FLOW, SINK_CHECK_WIDTH, s) for s in range(1, FLOW_SEEDS + 1)]
    for s in range(1, max(FLOW_SEEDS, ARCH_SEEDS) + 1):
        if s <= ARCH_SEEDS:
            out += [("arch", g, w, s) for g in ARCH_GRAVITIES for w in ARCH_WIDTHS[g]]
        if s <= FLOW_SEEDS:
            out += [("flow", G_FLOW, w, s) for w in FLOW_WIDTHS]
            out += [("cone", G_FLOW, w, s) for w in CONE_WIDTHS]
    if only:
        out = [k for k in out if any(o in key_name(*k) for o in only)]
    return out


def key_name(kind: str, x: float, width: float, seed: int) -> str:
    return f"{series_name(kind, x)}/w{width:g}-s{seed}"


def test_of(kind: str, x: float, width: float, seed: int) -> engine.HopperTest:
    if kind in ("flow", "sink"):
        return flow_test(width, seed)
    if kind == "cone":
        return replace(flow_test(width, seed), shape="cone")
    return jenike_series.hopper_test(width, seed, x)


def path_of(kind: str, x: float, width: float, seed: int, store: Path | None = None) -> Path:
    return Path(store or STORE) / f"{key_name(kind, x, width, seed)}.json"


def stored(kind: str, x: float, width: float, seed: int, store: Path | None = None):
    """The stored run's digest if it was made with today's test and protocol, else None."""
    path = path_of(kind, x, width, seed, store)
    if not path.exists():
        return None
    d = read_digest(path)
    want = json.loads(json.dumps(test_of(kind, x, width, seed).to_dict()))
    if d.extra.get("protocol") != PROTOCOL:
        return None
    return d if d.test == want else None


#: Throughput on these fills, one thread of this 2-core machine [particle-steps per CPU
#: second]: 2.9e6 in the Jenike series' 18 d run (1.15e8 particle-steps in 39.6 s).
THROUGHPUT = 2.9e6


def estimate(kind: str, x: float, width: float, seed: int) -> float:
    """A run's CPU time on one thread [s], estimated: the pour and ramp (0.5 s), twice the
    free-fall time sqrt(B / g) of settling, then 20 free-fall times (an arch's wait, or
    about a discharge), in steps of 0.4 of the contact time, times the particles."""
    t = test_of(kind, x, width, seed)
    tff = (t.outlet_width / t.gravity) ** 0.5
    steps = (0.5 + 22.0 * tff) / 1.48e-5
    return t.n_particles * steps / THROUGHPUT


def extra_of(outcome, wall: float, cpu: float) -> dict:
    # what took the discharged grains below the outlet: of the runs made before the sink, the
    # 14 arching runs made again with the catch zone have "catch_zone" (the drag); the first
    # runs (the discharge series to 64 d, most arching runs) neither: their grains fell freely
    out = {
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "threads": 1,
        "protocol": PROTOCOL,
        "sink": f"parked from {SINK_DIAMETERS:g} d above the heap's highest point down "
        "(engine.Simulation.park_below)",
    }
    if isinstance(outcome, str):
        return out
    s = outcome.scalars
    out.update(
        {
            "flow_mode": outcome.flow_mode,
            "discharged_fraction": s["discharged_mass"] / s["total_mass"],
            "curve": decimate(outcome.curves),
        }
    )
    return out


def before_failure(run) -> dict | None:
    """Where a run that failed had got to: None before the gate opened, else the time since
    the opening [s], the fraction of the fill discharged and whether the stop criterion had
    read a stop. Why (the first runs): a discharged grain fell onto the catch floor far below
    the outlet (``engine.hopper.scene``: 2 B and the heap's height below it), at up to
    sqrt(2 g (top + catch depth)), 8-11 m/s at the widest outlets of the arching series; on
    the heap there the soft loading spring (k1 = 5e3 N/m) lets two grains overlap by half a
    radius, which stops the run (``InstabilityError``) long after the outlet's behaviour is
    read: a run that had discharged half its fill without a stop had not arched
    (:mod:`benchmarks.outlet_report`).
    The hopper's catch zone (a drag) ended these failures and the failed runs were made
    again with it; its failures at 80 d ended with the sink that replaced it
    (``engine.hopper.driver``)."""
    if run is None or run.flow is None or not run.flow["rows"]:
        return None
    rows = run.flow["rows"]
    return {
        "time": float(rows[-1][0]),
        "discharged_fraction": float(rows[-1][1]) / float(run.total),
        "stopped": bool(run.flow["stopped"]),
    }


def run_one(kind: str, x: float, width: float, seed: int) -> str:
    """Run and store one run; a line for the log."""
    import numba

    numba.set_num_threads(1)
    test = test_of(kind, x, width, seed)
    t0, c0 = time.perf_counter(), time.process_time()
    from engine.hopper.driver import HopperRun

    run = None
    try:
        run = HopperRun(test, threads=1)
        outcome = jenike_series.ramped_hopper(test, run)
    except Exception as e:
        outcome = f"{type(e).__name__}: {e}"
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    extra = extra_of(outcome, wall, cpu)
    if isinstance(outcome, str):
        extra["before_failure"] = before_failure(run)
    digest = make_digest(outcome, test, None, extra)
    write_digest(path_of(kind, x, width, seed), digest)
    what = outcome if isinstance(outcome, str) else jenike_series.describe(digest)
    return f"{key_name(kind, x, width, seed)}: {what} ({wall:.0f} s wall, {cpu:.0f} s CPU)"


def line(key, digest, seconds: float) -> str:
    n = test_of(*key).n_particles
    if digest is None:
        return f"{key_name(*key):24s} {n:7d} particles  not run  (about {seconds:.0f} s CPU)"
    what = "ok" if digest.ok else "failed"
    return f"{key_name(*key):24s} {n:7d} particles  {what} ({digest.extra['cpu_seconds']:.0f} s)"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.outlet_series", description=__doc__)
    p.add_argument("--list", action="store_true", help="list the runs and what is stored")
    p.add_argument("--only", nargs="+", help="only the runs whose key contains one of these")
    a = p.parse_args(argv)
    return list_or_run(
        a.list,
        keys(a.only),
        stored,
        estimate,
        line,
        key_name,
        test_of,
        run_one,
        "benchmarks.outlet_report",
    )


if __name__ == "__main__":
    raise SystemExit(main())
