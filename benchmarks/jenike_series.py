"""Cohesive arching in the slot hopper against Jenike's critical outlet width (issue 52
item 3, the cohesive part): the runs, stored as compact digests in git.

    python -m benchmarks.jenike_series                 # every run not yet stored, in order
    python -m benchmarks.jenike_series --list          # the runs and what is stored
    python -m benchmarks.jenike_series --only shear    # the runs whose key contains shear
    python -m benchmarks.jenike_series --predict       # the predicted B_crit from the store
    python -m benchmarks.jenike_series --law bond0.5   # the second law's runs (--predict, ...)

Choices, fixed here before the hopper runs (2026-12-06):

- **Law**: the size series' ``bond1`` law (``benchmarks.size_series.law("bond1")``: the
  bilinear adhesive law, f0 = -0.4 N, mu_s = 0.5, mu_r = 0.001), grains of R = 2.5 mm,
  density 2000 kg/m^3, monodisperse as in the shear cell, walls Hertz E = 1e8 Pa, mu = 0.3
  (the shear cell's wall law, the hopper's default).
- **Flow function**: the stored shear cell at 10 kPa is one point of it (sigma_1, sigma_c);
  Jenike's critical point is the flow function's intersection with sigma_1 / ff, which one
  point does not fix. So the same cell (``size_series.shear_test("bond1", 5.0, seed)``,
  5 diameters thin, R = 2.5 mm: the hopper's own grain) is run here at the further
  pre-shear stresses :data:`PRESHEARS` (the shear points at the same fractions
  0.2, 0.4, 0.6, 0.8 of it as the stored runs), :data:`SHEAR_SEEDS` seeds each; with the
  size series' six stored seeds at 10 kPa of that size, that is the flow function
  (:mod:`engine.hopper.jenike_inputs`).
- **Hopper**: ``engine.HopperTest(shape="slot")``, half-angle :data:`HALF_ANGLE` = 30 deg,
  periodic depth 5 d, fill height max(B, 8 d) (:data:`FILL_OUTLETS`,
  :data:`FILL_DIAMETERS`: the law's soft loading spring, k1 = 5e3 N/m, carries the fill's
  weight at 400 m/s^2 only so deep: a 20 d fill, rho_b g h about 50 kPa on the gate, pressed
  two grains half a radius into each other at 9 d; Jenike's B_crit does not depend on the
  head), the fill poured under Earth's gravity and gravity then raised
  (:func:`ramped_hopper`), the default gate, stop criterion (20 free-fall times
  sqrt(B/g) with under 1 % of the fastest rate) and time step. **Gravity**
  :data:`GRAVITY` m/s^2: at 9.81 m/s^2 Jenike's width for this law is metres (sigma_c of
  tens of kPa over rho_b g), hundreds of diameters, out of reach; B_crit ~ 1/g, so the
  hopper runs in a centrifuge, as geotechnical models do, with g chosen so that the
  predicted B_crit lies near 10 diameters. Gravity changes nothing else in Jenike's method
  (ff and H are angles' functions; the stress level at the critical point is sigma_1* = ff
  sigma_c*, whatever g).
- **Outlet widths** :data:`WIDTHS` diameters bracketing the prediction, seeds
  :data:`HOPPER_SEEDS`; a second gravity :data:`GRAVITY_2` (B_crit doubled, the hopper's
  Bond number |f0| / (m g) doubled) at :data:`G2_WIDTHS`, :data:`G2_SEEDS` seeds (added
  after the first gravity's runs had been seen; the widths 10 d and the third seed added
  after its first seeds had been).

- **A second law** (added 2026-12-06; :data:`SERIES`, ``--law bond0.5``): ``bond1``'s law
  with half its adhesion, because ``bond3`` has no flow factor (its reasons and choices at
  :data:`BOND05_F0` and :data:`BOND05_GRAVITY`); its runs under ``bond0.5/``, its
  prediction written at :data:`GRAVITY` as ``bond1``'s and scaled as 1 / g.

Each run is stored at once as a digest (:mod:`engine.io.digest`) under
``benchmarks/results/jenike_series/`` (``shear/p<kPa>-s<seed>.json``,
``hopper/w<B/d>-s<seed>.json``, ``hopper_g2/...`` at the second gravity; ``extra``: wall
and CPU seconds, the hopper protocol, a hopper run's flow mode and discharged fraction; the
scalars hold whether it stopped or arched and when). Full files are not kept (the digests
hold every number the comparison reads).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import engine
from benchmarks import size_series
from engine.io.digest import make_digest, read_digest, write_digest

ROOT = Path(__file__).resolve().parent.parent
STORE = Path(
    os.environ.get("JENIKE_SERIES_STORE", ROOT / "benchmarks" / "results" / "jenike_series")
)

LAW = "bond1"
#: The shear cell's size [diameters across its thin width]: the law's own grain (R = 2.5 mm).
SHEAR_SIZE = 5.0
#: Pre-shear stresses run here [Pa] (10 kPa is the size series' own, stored there).
PRESHEARS = (20e3, 5e3, 40e3)
#: The shear points as fractions of the pre-shear stress (the stored runs' 2-8 kPa at 10).
SHEAR_FRACTIONS = (0.2, 0.4, 0.6, 0.8)
SHEAR_SEEDS = 3

RADIUS = 2.5e-3
D = 2.0 * RADIUS
HALF_ANGLE = 30.0
DEPTH = 5.0 * D
#: The settled fill's height: max(FILL_OUTLETS B, FILL_DIAMETERS d) (module docstring).
FILL_OUTLETS = 1.0
FILL_DIAMETERS = 8.0
#: The hopper's gravity [m/s^2] (module docstring: the prediction near 10 d).
GRAVITY = 400.0
#: The pour's gravity [m/s^2] and time [s] (the fill's fall from the walls' top, 0.21 m at
#: most (18 d), takes 0.20 s), and gravity's ramp to :data:`GRAVITY` [s] in stages
#: (:func:`ramped_hopper`).
G_POUR = 9.81
POUR_TIME = 0.4
RAMP_TIME = 0.1
RAMP_STAGES = 50
#: The hopper runs' protocol, written in each digest (a digest of another is not this run).
PROTOCOL = f"pour {G_POUR:g} m/s^2 {POUR_TIME:g} s, ramp {RAMP_TIME:g} s in {RAMP_STAGES}"
#: Outlet widths [diameters] and seeds.
WIDTHS = (4.0, 5.0, 6.0, 7.0, 9.0, 11.0, 13.0, 18.0)
HOPPER_SEEDS = 3
#: A second gravity [m/s^2], its widths [diameters] and seeds: half the gravity doubles
#: Jenike's B_crit (sigma_c* does not depend on g) and the hopper's Bond number
#: |f0| / (m g) (7.6 at 400 m/s^2, 15.3 at 200): a second cohesion-to-weight ratio of the
#: same law.
GRAVITY_2 = 200.0
G2_WIDTHS = (9.0, 10.0, 11.0, 13.0, 15.0, 18.0)
G2_SEEDS = 3


@dataclass(frozen=True)
class Series:
    """One law's Jenike series: its shear points and its hoppers.

    ``f0`` [N]: the law's pull-off force (everything else is ``bond1``'s law);
    ``preshears`` [Pa]: the pre-shear stresses run here; ``size_series_point``: whether the
    size series' stored 10 kPa cells are a point of the flow function (``bond1`` only);
    ``hoppers``: stored kind -> (gravity [m/s^2], outlet widths [d], seeds); its runs
    are stored under the law's name (:attr:`prefix`)."""

    law: str
    f0: float
    preshears: tuple[float, ...]
    size_series_point: bool
    hoppers: dict

    @property
    def prefix(self) -> str:
        """The store's sub-folder: "" for ``bond1``, whose runs were stored first."""
        return "" if self.law == LAW else self.law


#: The second law (added 2026-12-06, after ``bond3`` had been seen to give no flow factor:
#: its consolidation circles reach into tension, delta = 90 deg, at every stored seed):
#: ``bond0.5``, half ``bond1``'s adhesion (f0 = -0.2 N; the granular Bond number at a
#: consolidation stress halved), whose flow function lies where Jenike's radial field
#: exists at lower stresses. Its pre-shears bracket the critical point that halving f0
#: would move to about half ``bond1``'s (sigma_1* 19.6 kPa there) if the Bond number set
#: it alone: 2.5 to 20 kPa, three seeds each, all run here (the size series has no cell of
#: this law). Its hoppers' gravity and widths are fixed from its prediction, before any of
#: its hopper runs (:data:`BOND05_GRAVITY`).
BOND05_F0 = -0.2
BOND05_PRESHEARS = (2.5e3, 5e3, 10e3, 20e3)
#: ``bond0.5``'s hopper gravity [m/s^2], widths [d] and seeds, fixed from its prediction
#: (``bond0.5/prediction.json``: B_crit = 4.11 d at 400 m/s^2, so 8.22 d at 200) before any
#: of its hopper runs: 200 m/s^2 puts the prediction near bond1's (9.15 d) and gives the
#: hopper's Bond number |f0| / (m g) of bond1 at 400 m/s^2 (7.6), so the two laws differ
#: there only in the granular Bond number of their consolidated solid; the widths bracket
#: the prediction and, at bond1's ratio of simulated to predicted width (0.66-0.77), the
#: outcome, with bond1's three seeds.
BOND05_GRAVITY = 200.0
BOND05_WIDTHS = (4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 11.0, 13.0)
SERIES = {
    "bond1": Series(
        "bond1",
        size_series.LAWS["bond1"][0],
        PRESHEARS,
        True,
        {
            "hopper": (GRAVITY, WIDTHS, HOPPER_SEEDS),
            "hopper_g2": (GRAVITY_2, G2_WIDTHS, G2_SEEDS),
        },
    ),
    "bond0.5": Series(
        "bond0.5",
        BOND05_F0,
        BOND05_PRESHEARS,
        False,
        {"hopper": (BOND05_GRAVITY, BOND05_WIDTHS, HOPPER_SEEDS)},
    ),
}


def series_law(name: str) -> engine.BilinearAdhesive:
    """The pair law of series ``name``: ``bond1``'s law with the series' f0."""
    return replace(size_series.law(LAW), f0=SERIES[name].f0)


def shear_test(preshear: float, seed: int, law: str = LAW) -> engine.ShearTest:
    """The size series' shear cell at :data:`SHEAR_SIZE` with series ``law``'s pair law,
    pre-sheared at ``preshear`` [Pa]."""
    # the size series' cell at its reference size is its reference test (no scaling of the
    # law), so its pair law can be swapped for the series' own
    assert SHEAR_SIZE == size_series.SHEAR_REFERENCE_SIZE
    base = size_series.shear_test(LAW, SHEAR_SIZE, seed)
    return replace(
        base,
        pair_law=series_law(law),
        preshear_stress=float(preshear),
        normal_stresses=tuple(f * float(preshear) for f in SHEAR_FRACTIONS),
    )


def hopper_test(
    width: float, seed: int, gravity: float | None = None, law: str = LAW
) -> engine.HopperTest:
    """The slot hopper at outlet ``width`` [diameters], fill ``seed``, ``gravity`` [m/s^2]
    (None: the series' first hopper gravity), series ``law``'s pair law (module
    docstring)."""
    if gravity is None:
        gravity = next(iter(SERIES[law].hoppers.values()))[0]
    b = width * D
    return engine.HopperTest(
        shape="slot",
        half_angle=HALF_ANGLE,
        outlet_width=b,
        depth=DEPTH,
        particles=None,
        fill_height=max(FILL_OUTLETS * b, FILL_DIAMETERS * D),
        radius=RADIUS,
        polydispersity=0.0,
        gravity=gravity,
        pair_law=series_law(law),
        wall_law=engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.3),
        seed=seed,
    )


def keys(only=None, laws=None) -> list[tuple[str, float, int, str]]:
    """(kind, preshear [Pa] or width [d], seed, law) of the series ``laws`` (default all),
    in the order they are taken: per law the shear points first (the prediction needs
    them), then its hoppers, seed 1 of every width first."""
    out = []
    for name in laws or SERIES:
        se = SERIES[name]
        out += [("shear", p, s, name) for p in se.preshears for s in range(1, SHEAR_SEEDS + 1)]
        for kind, (_, widths, seeds) in se.hoppers.items():
            out += [(kind, w, s, name) for s in range(1, seeds + 1) for w in widths]
    if only:
        out = [k for k in out if any(o in key_name(*k) for o in only)]
    return out


def key_name(kind: str, x: float, seed: int, law: str = LAW) -> str:
    """The run's name, its path under the store without ``.json``."""
    prefix = f"{SERIES[law].prefix}/" if SERIES[law].prefix else ""  # bond1: the top
    if kind == "shear":
        return f"{prefix}shear/p{x / 1e3:g}-s{seed}"
    return f"{prefix}{kind}/w{x:g}-s{seed}"


def test_of(kind: str, x: float, seed: int, law: str = LAW):
    if kind == "shear":
        return shear_test(x, seed, law)
    return hopper_test(x, seed, SERIES[law].hoppers[kind][0], law)


def path_of(kind: str, x: float, seed: int, store: Path | None = None, law: str = LAW) -> Path:
    return Path(store or STORE) / f"{key_name(kind, x, seed, law)}.json"


def stored(kind: str, x: float, seed: int, store: Path | None = None, law: str = LAW):
    """The stored run's digest if it was made with today's test, else None."""
    path = path_of(kind, x, seed, store, law)
    if not path.exists():
        return None
    d = read_digest(path)
    want = json.loads(json.dumps(test_of(kind, x, seed, law).to_dict()))
    if kind != "shear" and d.extra.get("protocol") != PROTOCOL:
        return None
    return d if d.test == want else None


def extra_of(outcome, wall: float, cpu: float) -> dict:
    out = {"wall_seconds": wall, "cpu_seconds": cpu, "threads": 1, "protocol": PROTOCOL}
    if isinstance(outcome, str) or not isinstance(outcome, engine.HopperResult):
        return out
    s = outcome.scalars
    out.update(
        {
            "flow_mode": outcome.flow_mode,
            "discharged_fraction": s["discharged_mass"] / s["total_mass"],
        }
    )
    return out


def ramped_hopper(test: engine.HopperTest, run=None) -> engine.HopperResult:
    """The hopper run with its fill poured under Earth's gravity first (:data:`G_POUR` for
    :data:`POUR_TIME`), gravity then raised to the test's linearly over :data:`RAMP_TIME`,
    then the run's own settling (at least two free-fall times at the test's gravity, to its
    kinetic energy criterion) and discharge. Why: poured straight under 400 m/s^2 the lattice
    fill's grains meet at up to about 20 m/s and the law's soft loading spring (k1 = 5e3
    N/m) lets two of them overlap by half a radius (``InstabilityError`` in 5 of the 6 runs
    at 9 d and wider at the first attempt, a fill max(1.5 B, 20 d) deep); raised once the
    grains touch, gravity compresses the packing quasi-statically. The result's
    ``settle_time`` includes the pour and the ramp. ``run``: the test's ``HopperRun``
    (one thread), made by a caller that reads its state after an error; None: made here."""
    from engine.hopper.driver import HopperRun

    if run is None:
        run = HopperRun(test, threads=1)
    sim = run.sim
    sim.set_gravity((0.0, 0.0, -G_POUR))
    sim.run(max(1, round(POUR_TIME / run.dt)))
    for k in range(1, RAMP_STAGES + 1):
        g = G_POUR + (test.gravity - G_POUR) * k / RAMP_STAGES
        sim.set_gravity((0.0, 0.0, -g))
        sim.run(max(1, round(RAMP_TIME / RAMP_STAGES / run.dt)))
    run.settle()
    return run.discharge()


def run_one(kind: str, x: float, seed: int, law: str = LAW) -> str:
    """Run and store one run; a line for the log."""
    import numba

    numba.set_num_threads(1)
    test = test_of(kind, x, seed, law)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if kind == "shear":
            outcome = engine.run_shear(test)
        else:
            outcome = ramped_hopper(test)
    except Exception as e:
        outcome = f"{type(e).__name__}: {e}"
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    write_digest(
        path_of(kind, x, seed, law=law),
        make_digest(outcome, test, None, extra_of(outcome, wall, cpu)),
    )
    if isinstance(outcome, str):
        what = outcome
    elif kind == "shear":
        s = outcome.scalars
        what = f"sigma_1 = {s['sigma_1']:.4g} Pa, sigma_c = {s['sigma_c']:.4g} Pa"
    else:
        what = describe(make_digest(outcome, test, None, {}))
    return f"{key_name(kind, x, seed, law)}: {what} ({wall:.0f} s wall, {cpu:.0f} s CPU)"


#: The wall friction angle [deg]: atan of the wall law's sliding friction mu = 0.3, a stated
#: approximation (the bulk's friction on the wall is not measured: no wall shear test); the
#: spheres may roll on the wall (its law has no rolling resistance), so the bulk's angle may
#: be lower: :func:`predict` gives phi_w = 0 beside it.
WALL_FRICTION_ANGLE = math.degrees(math.atan(0.3))
#: The stored pre-shear of the size series [Pa] and its seeds at :data:`SHEAR_SIZE`.
STORED_PRESHEAR = 10e3
STORED_SEEDS = 6
#: Effective angles of internal friction [deg] at which ff is tabulated (interpolated
#: linearly between: ff is smooth in delta; the table's error is checked in :func:`predict`).
#: Outside it np.interp holds the end values: a point of delta = 90 (a circle into tension)
#: reads ff(88), one below 40 reads ff(40) (``ff_table_error`` in the prediction says how
#: far that is from the exact ff where the critical point falls there).
FF_DELTAS = tuple(float(d) for d in range(40, 89, 2))
BOOTSTRAP = 400


def shear_levels(size_series_size: float = SHEAR_SIZE, law: str = LAW) -> dict[float, list[dict]]:
    """The flow function's points of series ``law``, seed by seed: pre-shear [Pa] ->
    [{sigma_1, sigma_2, sigma_c, bulk_density} per seed], from the size series' stored cell
    at ``size_series_size`` diameters (10 kPa; ``bond1`` only) and this series' (the other
    pre-shears)."""
    levels: dict[float, list[dict]] = {}
    names = ("sigma_1", "sigma_2", "sigma_c", "bulk_density")
    if SERIES[law].size_series_point:
        n = size_series.SHEAR_SIZES[LAW][size_series_size]
        for seed in range(1, n + 1):
            d = size_series.stored("shear", LAW, size_series_size, seed)
            if d is not None and d.ok:
                levels.setdefault(STORED_PRESHEAR, []).append({k: d.scalars[k] for k in names})
    for p in SERIES[law].preshears:
        for seed in range(1, SHEAR_SEEDS + 1):
            d = stored("shear", p, seed, law=law)
            if d is not None and d.ok:
                levels.setdefault(p, []).append({k: d.scalars[k] for k in names})
    return dict(sorted(levels.items()))


def level_means(levels: dict[float, list[dict]]) -> dict[float, dict]:
    """Each pre-shear's seed means, and delta = asin((s1 - s2) / (s1 + s2)) of the means
    [deg] (90 where the mean circle reaches into tension)."""
    out = {}
    for p, runs in levels.items():
        m = {k: float(np.mean([r[k] for r in runs])) for k in runs[0]}
        q = (m["sigma_1"] - m["sigma_2"]) / (m["sigma_1"] + m["sigma_2"])
        m["delta"] = math.degrees(math.asin(min(1.0, q)))
        m["seeds"] = len(runs)
        out[p] = m
    return out


def ff_table(phi_w: float) -> tuple[np.ndarray, np.ndarray]:
    """ff of the slot hopper against delta (:data:`FF_DELTAS`; NaN where no field)."""
    from engine.hopper import jenike

    ffs = []
    for d in FF_DELTAS:
        try:
            ffs.append(jenike.flow_factor(d, phi_w, HALF_ANGLE, "slot"))
        except engine.ParameterError:
            ffs.append(math.nan)
    return np.asarray(FF_DELTAS), np.asarray(ffs)


def critical(means: dict[float, dict], table) -> dict:
    """Jenike's critical point of the flow function ``means`` (:func:`level_means`) with
    ff from ``table`` at delta interpolated in sigma_1 at the critical point (a fixed
    point: ff sets sigma_1*, delta there sets ff), and B_crit at :data:`GRAVITY` (every
    series' prediction is written at this gravity; B_crit ~ 1 / g)."""
    from engine.hopper import jenike

    pts = sorted(means.values(), key=lambda m: m["sigma_1"])
    s1 = np.array([m["sigma_1"] for m in pts])
    sc = np.array([m["sigma_c"] for m in pts])
    dl = np.array([m["delta"] for m in pts])
    rb = np.array([m["bulk_density"] for m in pts])
    x = s1[0]
    for _ in range(50):
        delta = float(np.interp(x, s1, dl))
        ff = float(np.interp(delta, *table))
        if not math.isfinite(ff):
            raise engine.ParameterError("jenike.delta", delta, "where a radial field exists")
        x_new, c = jenike.critical_point(s1, sc, ff)
        if abs(x_new - x) < 1e-9 * x_new:
            break
        x = x_new
    rho = float(np.interp(x_new, s1, rb))
    b = jenike.critical_outlet_width(c, rho, GRAVITY, HALF_ANGLE, "slot")
    return {
        "sigma_1": x_new,
        "sigma_c": c,
        "delta": delta,
        "ff": ff,
        "bulk_density": rho,
        "H": jenike.h_function(HALF_ANGLE, "slot"),
        "B_crit": b,
        "B_crit_d": b / D,
    }


def predict(
    phi_w: float = WALL_FRICTION_ANGLE,
    seed: int = 1,
    stored_size: float = SHEAR_SIZE,
    law: str = LAW,
) -> dict:
    """The predicted B_crit of the slot hopper with its inputs, and its uncertainty from the
    flow function's seeds: a bootstrap over seeds within each pre-shear (``BOOTSTRAP``
    resamples, seeded by ``seed``), its standard deviation and 2.5-97.5 % percentiles.
    ``stored_size``: the size series' cell [diameters] whose 10 kPa runs are the flow
    function's point there (``bond1`` only; the other pre-shears, and every pre-shear of a
    series without that point, are this series' own, at 5 d)."""
    from engine.hopper import jenike

    levels = shear_levels(stored_size, law)
    means = level_means(levels)
    table = ff_table(phi_w)
    base = {"phi_w": phi_w, "half_angle": HALF_ANGLE, "gravity": GRAVITY, "d": D, "law": law}
    base["stored_size"] = stored_size if SERIES[law].size_series_point else None
    base["levels"] = {f"{p:g}": m for p, m in means.items()}
    try:
        best = critical(means, table)
    except engine.ParameterError as e:
        return {**base, "error": str(e)}
    exact = jenike.flow_factor(best["delta"], phi_w, HALF_ANGLE, "slot")
    rng = np.random.default_rng(seed)
    boot = []
    for _ in range(BOOTSTRAP):
        res = {
            p: [runs[i] for i in rng.integers(0, len(runs), len(runs))]
            for p, runs in levels.items()
        }
        try:
            boot.append(critical(level_means(res), table)["B_crit_d"])
        except engine.ParameterError:
            boot.append(math.nan)
    boot = np.asarray(boot)
    ok = boot[np.isfinite(boot)]
    return {
        **base,
        "critical": best,
        "ff_table_error": best["ff"] / exact - 1.0,
        "B_crit_d_sd": float(np.std(ok, ddof=1)),
        "B_crit_d_95": [float(np.percentile(ok, 2.5)), float(np.percentile(ok, 97.5))],
        "bootstrap": {"resamples": BOOTSTRAP, "failed": int(np.sum(~np.isfinite(boot)))},
    }


def store_of(law: str = LAW) -> Path:
    """Series ``law``'s folder (its prediction.json and comparison.json)."""
    return STORE / SERIES[law].prefix if SERIES[law].prefix else STORE


def compare(law: str = LAW) -> dict:
    """Every gravity's comparison of series ``law`` (:func:`compare_at`)."""
    return {
        f"{g:g}": compare_at(kind, widths, seeds, g, law)
        for kind, (g, widths, seeds) in SERIES[law].hoppers.items()
    }


def compare_at(kind: str, widths, seeds: int, gravity: float, law: str = LAW) -> dict:
    """The stored hopper runs of ``kind`` at ``gravity`` [m/s^2] against the stored
    prediction (scaled from :data:`GRAVITY` by 1/g): per width, how many seeds arched,
    stopped without an arch, emptied or failed, the mean discharged fraction and settled bulk
    density of those that did not fail; the simulated critical width's bracket (the widest
    outlet at which every seed that did not fail arched, the narrowest above it at which
    every one emptied), and the prediction with the shear cell's bulk density and rescaled
    to the hoppers' own."""
    pred = json.loads((store_of(law) / "prediction.json").read_text())
    rows = []
    for w in widths:
        ds = [stored(kind, w, s, law=law) for s in range(1, seeds + 1)]
        ds = [d for d in ds if d is not None]
        ok = [d for d in ds if d.ok]
        arched = sum(1 for d in ok if d.scalars["arched"])
        stopped = sum(1 for d in ok if d.scalars["stopped"] and not d.scalars["arched"])
        rows.append(
            {
                "width_d": w,
                "runs": len(ds),
                "arched": arched,
                "stopped_no_arch": stopped,
                "emptied": len(ok) - arched - stopped,
                "failed": len(ds) - len(ok),
                "discharged_fraction": float(
                    np.mean([d.scalars["discharged_mass"] / d.scalars["total_mass"] for d in ok])
                )
                if ok
                else math.nan,
                "bulk_density": float(np.mean([d.scalars["bulk_density"] for d in ok]))
                if ok
                else math.nan,
                "particles": int(ok[0].scalars["particles"]) if ok else 0,
                "cpu_seconds": [d.extra.get("cpu_seconds", math.nan) for d in ds],
            }
        )
    # a failed run (InstabilityError) neither arched nor flowed: the bracket reads the others
    done = [r for r in rows if r["runs"] > r["failed"]]
    all_arch = [r["width_d"] for r in done if r["arched"] == r["runs"] - r["failed"]]
    all_flow = [r["width_d"] for r in done if r["emptied"] == r["runs"] - r["failed"]]
    low = max(all_arch) if all_arch else math.nan
    high = min((w for w in all_flow if w > low), default=math.nan) if all_arch else math.nan
    c = pred["wall_law_mu"]["critical"]
    g_pred = pred["wall_law_mu"]["gravity"]  # the gravity the prediction is written at
    rho_h = [r["bulk_density"] for r in done if math.isfinite(r["bulk_density"])]
    rho_hopper = float(np.mean(rho_h)) if rho_h else math.nan
    return {
        "law": law,
        "rows": rows,
        "all_arched_up_to_d": low,
        "all_flowed_from_d": high,
        "gravity": gravity,
        "predicted_d": c["B_crit_d"] * g_pred / gravity,
        "predicted_d_95": [b * g_pred / gravity for b in pred["wall_law_mu"]["B_crit_d_95"]],
        "hopper_bulk_density": rho_hopper,
        "predicted_d_hopper_density": c["B_crit_d"]
        * g_pred
        / gravity
        * c["bulk_density"]
        / rho_hopper,
    }


def describe(d) -> str:
    """A stored run in a line: its outcome and what the comparison reads, or "not stored"."""
    if d is None:
        return "not stored"
    cpu, wall = d.extra.get("cpu_seconds"), d.extra.get("wall_seconds")
    cost = "cost not recorded" if cpu is None else f"{cpu:.0f} s CPU, {wall:.0f} s wall"
    if not d.ok:
        return f"failed: {d.outcome[:80]} ({cost})"
    s = d.scalars
    if d.kind == "ShearTest":
        return (
            f"sigma_1 = {s['sigma_1']:.0f} Pa, sigma_2 = {s['sigma_2']:.0f} Pa, sigma_c = "
            f"{s['sigma_c']:.0f} Pa, rho_b = {s['bulk_density']:.0f} kg/m^3 ({cost})"
        )
    state = "arched" if s["arched"] else ("stopped, no arch" if s["stopped"] else "emptied")
    return (
        f"{state}, {100 * s['discharged_mass'] / s['total_mass']:.1f} % discharged"
        + (f" at {s['arch_time']:.3f} s" if s["arched"] else "")
        + f", {int(s['particles'])} particles, rho_b = {s['bulk_density']:.0f} kg/m^3, "
        f"{s['particle_steps']:.3g} particle-steps ({cost})"
    )


def report_comparison(out: dict) -> None:
    """Print one gravity's comparison (:func:`compare_at`)."""
    for r in out["rows"]:
        print(
            f"B = {r['width_d']:g} d: {r['runs']} runs, {r['arched']} arched, "
            f"{r['stopped_no_arch']} stopped without an arch, {r['emptied']} emptied, "
            f"{r['failed']} failed; discharged {100 * r['discharged_fraction']:.1f} %, "
            f"rho_b {r['bulk_density']:.0f} kg/m^3, {r['particles']} particles, CPU s "
            + ", ".join(f"{c:.0f}" for c in r["cpu_seconds"])
        )
    print(
        f"every seed arched up to {out['all_arched_up_to_d']:g} d, every seed flowed from "
        f"{out['all_flowed_from_d']:g} d; predicted B_crit {out['predicted_d']:.2f} d "
        f"(95 % {out['predicted_d_95'][0]:.2f}-{out['predicted_d_95'][1]:.2f}), "
        f"{out['predicted_d_hopper_density']:.2f} d at the hoppers' mean settled bulk "
        f"density {out['hopper_bulk_density']:.0f} kg/m^3"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="runs whose key contains any of these")
    ap.add_argument("--list", action="store_true", help="list the runs, stored or not")
    ap.add_argument("--predict", action="store_true", help="store the predicted B_crit")
    ap.add_argument("--compare", action="store_true", help="store the comparison")
    ap.add_argument(
        "--law",
        choices=sorted(SERIES),
        help="one law's series (default: every law; --predict and --compare: bond1)",
    )
    args = ap.parse_args(argv)
    law = args.law or LAW
    if args.compare:
        both = compare(law)
        (store_of(law) / "comparison.json").write_text(json.dumps(both, indent=1) + "\n")
        for g, out in both.items():
            print(f"g = {g} m/s^2:")
            report_comparison(out)
        return 0
    if args.predict:
        out = {"wall_law_mu": predict(law=law), "smooth_wall": predict(phi_w=0.0, law=law)}
        if SERIES[law].size_series_point:
            out["largest_cell_at_10kPa"] = predict(stored_size=10.0, law=law)
        path = store_of(law) / "prediction.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=1) + "\n")
        for k, v in out.items():
            if "error" in v:
                print(f"{k}: phi_w = {v['phi_w']:.2f} deg: {v['error']}")
                continue
            c = v["critical"]
            print(
                f"{k}: phi_w = {v['phi_w']:.2f} deg, delta* = {c['delta']:.1f} deg, "
                f"ff = {c['ff']:.3f}, sigma_1* = {c['sigma_1']:.0f} Pa, sigma_c* = "
                f"{c['sigma_c']:.0f} Pa, B_crit = {c['B_crit_d']:.2f} d "
                f"(sd {v['B_crit_d_sd']:.2f}, 95 % {v['B_crit_d_95'][0]:.2f}-"
                f"{v['B_crit_d_95'][1]:.2f})"
            )
        print(f"written {path}")
        return 0
    todo = keys(args.only, [args.law] if args.law else None)
    if args.list:
        for k in todo:
            print(f"{key_name(*k):26s} {describe(stored(*k[:3], law=k[3]))}")
        return 0
    for k in todo:
        if stored(*k[:3], law=k[3]) is None:
            print(f"running {key_name(*k)}", flush=True)
            print(run_one(*k), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
