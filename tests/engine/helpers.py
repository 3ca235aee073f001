"""Small scene builders shared by the engine tests."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import engine
from benchmarks.engine_speed import scene_for
from engine.study.rates import CONFIDENCE
from tests import naive


def pair_scene(
    law, gap: float = 0.0, v0: float = 0.0, radius: float = 2.5e-3, density: float = 2000.0, **kw
) -> engine.Scene:
    """Two equal spheres on the x axis, surfaces ``gap`` apart, approaching at ``v0`` each,
    in a box periodic along x and y (``50 (2 radius + gap)`` wide: an image is reached only by
    a pair that travels about 48 (radius + gap / 2) apart, far beyond these tests' runs), so
    that the suite's pair tests run the kernel of its periodic cells (one kernel per law
    family compiled, not two: tests/conftest.py)."""
    x = radius + 0.5 * gap
    pos = np.array([[-x, 0.0, 0.0], [x, 0.0, 0.0]])
    vel = np.array([[v0, 0.0, 0.0], [-v0, 0.0, 0.0]])
    h = 50.0 * x
    kw.setdefault("box", ((-h, h), (-h, h), (-h, h)))
    kw.setdefault("periodic", (True, True, False))
    return engine.Scene(pos, radius, density, velocities=vel, gravity=(0, 0, 0), pair_law=law, **kw)


def wall_scene(
    wall_law,
    gap: float = 0.0,
    v0: float = 0.0,
    radius: float = 2.5e-3,
    density: float = 2000.0,
    pair_law=None,
) -> engine.Scene:
    """One sphere above a plane z = 0, its surface ``gap`` above it, falling at ``v0``."""
    pair_law = pair_law or engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0, mu_r=0, restitution=1)
    return engine.Scene(
        [[0.0, 0.0, radius + gap]],
        radius,
        density,
        velocities=[[0.0, 0.0, -v0]],
        gravity=(0, 0, 0),
        pair_law=pair_law,
        walls=[engine.Plane((0, 0, 0), (0, 0, 1))],
        wall_law=wall_law,
        wall_material=engine.WallMaterial(),
    )


def box_gas(pos, rad, lengths, law, velocities=None, periodic: bool = True) -> engine.Scene:
    """The particles ``pos``, ``rad`` [m] (density 2000 kg/m^3, ``velocities`` [m/s], None:
    at rest) in the box ``lengths`` [m] from the origin, periodic along every axis (or along
    none), without gravity or walls: ``law`` alone acts."""
    return engine.Scene(
        pos,
        rad,
        2000.0,
        velocities=velocities,
        box=[(0, L) for L in lengths],
        periodic=(periodic,) * 3,
        gravity=(0, 0, 0),
        pair_law=law,
    )


def walled_bed(
    pos,
    rad,
    lengths,
    law,
    top: float | None = None,
    platen_speed: float = 0.0,
    velocities=None,
    periodic: bool = True,
) -> engine.Scene:
    """The particles ``pos``, ``rad`` [m] (density 2000 kg/m^3, gravity 9.81 m/s^2 along -z)
    in the cell ``lengths`` [m], periodic in x and y (unless ``periodic`` is False), on a
    floor at z = 0 and, where ``top`` is given, under a platen at height ``top`` [m] moving
    down at ``platen_speed`` [m/s]; ``law`` between particles, Hertz-Mindlin walls
    (E = 1e8 Pa, nu = 0.25, mu = 0.3) of the default material: the benchmarks' bed
    (:func:`benchmarks.engine_speed.scene_for`) with the tests' walls."""
    return scene_for(
        pos,
        rad,
        lengths,
        law,
        top,
        platen_speed,
        wall_law=engine.HertzMindlin(E=1e8, nu=0.25, mu=0.3),
        wall_material=engine.WallMaterial(),
        velocities=velocities,
        periodic=periodic,
    )


def stirred_cohesive_bed(n: int, lengths, seed: int, platen_speed: float) -> engine.Scene:
    """``n`` particles (radii in [0.8 R, R], R = 2.5 mm, overlaps up to 5 %) packed from
    ``seed`` in the cell ``lengths`` [m] and stirred (velocities 0.05 m/s rms each way),
    cohesive (f0 = -0.4 N), under a platen at the cell's top moving down at ``platen_speed``
    [m/s] (:func:`walled_bed`)."""
    r = 2.5e-3
    pos, rad = naive.rsa_packing(
        n, lengths, 0.8 * r, r, seed, max_overlap=0.05, periodic=(True, True, False)
    )
    vel = np.random.default_rng(seed).normal(0, 0.05, pos.shape)
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)
    return walled_bed(pos, rad, lengths, law, lengths[2], platen_speed, velocities=vel)


def rel_diff(a, b) -> float:
    """Largest |a - b| over the largest |a| (the absolute difference where a is all zero);
    infinite where the shapes differ, zero for empty arrays."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        return float("inf")
    if a.size == 0:
        return 0.0
    scale = float(np.max(np.abs(a)))
    diff = float(np.max(np.abs(a - b)))
    return diff / scale if scale > 0 else diff


def run_until_separated(sim: engine.Simulation, max_steps: int, chunk: int = 1, wall: bool = False):
    """Step until the contact has formed and opened again. Returns (largest overlap [m],
    largest normal force magnitude [N], contact duration [s])."""
    dmax = fmax = 0.0
    t_on = t_off = None
    for _ in range(max_steps // chunk):
        sim.run(chunk)
        c = sim.contacts()
        ovl = c.wall_overlaps if wall else c.overlaps
        if ovl.size:
            if t_on is None:
                t_on = sim.time
            dmax = max(dmax, float(ovl.max()))
            f = np.abs(sim.wall_forces[:, 2]).max() if wall else np.abs(c.forces[:, 0]).max()
            fmax = max(fmax, float(f))
        elif t_on is not None:
            t_off = sim.time
            break
    assert t_on is not None and t_off is not None, "contact never formed or never opened"
    return dmax, fmax, t_off - t_on


def path_forces(law, path, dt: float = 1e-6, radius: float = 2.5e-3) -> np.ndarray:
    """Drive one contact of the real step kernel through the overlaps ``path`` [m] (two
    resting particles, positions prescribed) and return the normal force on particle 0 at
    each [N] (repulsive positive)."""
    sim = engine.Simulation(pair_scene(law, gap=1e-4, radius=radius), dt=dt)
    out = []
    for d in path:
        x = radius - 0.5 * d
        sim.set_positions([[-x, 0, 0], [x, 0, 0]])
        c = sim.contacts()
        assert len(c.pairs) == 1
        # force on particle 0 (at -x), repulsive = -x direction; normal n points j -> i
        out.append(float(-c.forces[0, 0]))
    return np.array(out)


def deciding_spec(
    tolerances: dict,
    rules,
    max_seeds: int,
    max_reference_seeds: int = 6,
    rounds: int = 1,
    budget: float | None = None,
    consolidation_stress: float = 2e4,
) -> SimpleNamespace:
    """The fields of a deciding study that engine.study.allocate.next_runs and the judge
    read: relative ``tolerances`` per metric, ``rules`` (objects with a ``name``), the seed
    caps, a look after the pilot and after each of ``rounds``, the study's confidence, the budget
    [particle-steps] and the consolidation stress [Pa]."""
    return SimpleNamespace(
        reference=SimpleNamespace(consolidation_stress=consolidation_stress),
        tolerances=tolerances,
        confidence=CONFIDENCE,
        decide=True,
        max_seeds=max_seeds,
        max_reference_seeds=max_reference_seeds,
        rounds=rounds,
        looks=rounds + 1,
        budget=budget,
        rules=rules,
    )


def whole_run_fixtures(run, tiny, cohesive_law):
    """The module-scoped fixtures of a test kind's whole runs, each run once per module by
    ``run`` (engine.run_uniaxial, engine.run_shear): ``cohesionless``, the result of
    ``tiny()`` and every progress report's (stage, fraction); ``cohesive``, the result of
    ``tiny(pair_law=cohesive_law)``. Assign both to module names of the same names."""

    @pytest.fixture(scope="module", name="cohesionless")
    def cohesionless():
        seen = []
        res = run(tiny(), progress=lambda p: seen.append((p.stage, p.fraction)))
        return res, seen

    @pytest.fixture(scope="module", name="cohesive")
    def cohesive():
        return run(tiny(pair_law=cohesive_law))

    return cohesionless, cohesive


def switches_on(switch_tuple, *on: str):
    """A law's step-kernel switches (``switch_tuple``, its named tuple of booleans) with the
    ones named in ``on`` on and every other one off."""
    unknown = set(on) - set(switch_tuple._fields)
    if unknown:
        raise ValueError(f"{switch_tuple.__name__} has no switch {sorted(unknown)}")
    return switch_tuple(**{name: name in on for name in switch_tuple._fields})


def assert_same_to_round_off(got, want, rel: float = 1e-9, path: str = "") -> None:
    """Two JSON documents the same to round-off: keys, lengths, strings, booleans and nulls
    equal, numbers within ``rel`` (relative, no absolute floor: a zero is a zero). A stored report
    recomputed on another CPU differs in its last bits (OpenBLAS and numpy pick kernels by
    the CPU's instruction sets: a fit's sums then round in another order, 1e-13 relative
    seen between two machines); a changed verdict, run or rule moves a number by far more."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and set(got) == set(want), (path, set(got) ^ set(want))
        for k in want:
            assert_same_to_round_off(got[k], want[k], rel, f"{path}/{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), path
        for i, (a, b) in enumerate(zip(got, want)):
            assert_same_to_round_off(a, b, rel, f"{path}[{i}]")
    elif isinstance(want, bool) or isinstance(got, bool):
        assert got is want, (path, got, want)
    elif isinstance(want, float) or (isinstance(got, float) and isinstance(want, int)):
        assert isinstance(got, (int, float)), path
        assert math.isclose(got, want, rel_tol=rel, abs_tol=0.0), (path, got, want)
    else:
        assert got == want and type(got) is type(want), (path, got, want)


def computed_once(tmp_path_factory, name: str, make) -> dict:
    """``make()`` (a JSON-able dict) computed once for the whole test session, however many
    pytest-xdist workers ask: the first to ask computes it holding an exclusive lock on a
    file in the session's shared temporary folder and stores it there; the others wait on
    the lock and read it. (The CUDA simulator's cases run in one process a module this way
    instead of one process each, which started python, imported engine and numba.cuda and
    loaded its CPU kernels: 110 s of CPU for the three modules before, 83 s after, on a cold
    run, CHANGELOG.)"""
    import fcntl
    import json
    import os

    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the folder every worker's basetemp lies in
    path = base / f"{name}.json"
    with open(base / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if path.exists():
            return json.loads(path.read_text())
        out = make()
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out))
        tmp.replace(path)
        return out
