"""Public API: validation messages that name the field and the limit, features, units."""

from __future__ import annotations

import numpy as np
import pytest

import engine
from engine.kernel.specialise import scene_features
from tests.engine.helpers import pair_scene

R = 2.5e-3
LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4)
ADHESIVE = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4)
#: No periodic axis: the pair of tests/engine/helpers.py::pair_scene in open space (the scene
#: kernels of the specialisation tests below have every switch off).
OPEN = (False, False, False)


@pytest.mark.parametrize(
    "kwargs,field,limit",
    [
        (dict(k1=0, k2=1), "BilinearAdhesive.k1", "> 0 N/m"),
        (dict(k1=5e3, k2=1e3), "BilinearAdhesive.k2", ">= k1 = 5000 N/m"),
        (dict(k1=5e3, k2=2.5e4, f0=0.4), "BilinearAdhesive.f0", "<= 0 N"),
        (dict(k1=5e3, k2=2.5e4, restitution=0.0), "BilinearAdhesive.restitution", "in (0, 1]"),
        (dict(k1=5e3, k2=2.5e4, mu_s=-1), "BilinearAdhesive.mu_s", ">= 0"),
        (dict(k1=float("nan"), k2=2.5e4), "BilinearAdhesive.k1", "finite"),
        (dict(k1="soft", k2=2.5e4), "BilinearAdhesive.k1", "a real number"),
    ],
)
def test_bilinear_validation_names_field_and_limit(kwargs, field, limit):
    with pytest.raises(engine.ParameterError) as err:
        engine.BilinearAdhesive(**kwargs)
    assert err.value.field == field
    assert limit in str(err.value) and field in str(err.value)


@pytest.mark.parametrize(
    "cls,kwargs,field",
    [
        (engine.HertzMindlin, dict(E=-1), "HertzMindlin.E"),
        (engine.HertzMindlin, dict(E=1e8, nu=0.5), "HertzMindlin.nu"),
        (engine.WallMaterial, dict(E=0), "WallMaterial.E"),
        (engine.Plane, dict(point=(0, 0, 0), normal=(0, 0, 0)), "Plane.normal"),
        (engine.Plane, dict(point=(0, 0), normal=(0, 0, 1)), "Plane.point"),
    ],
)
def test_other_records_validate(cls, kwargs, field):
    with pytest.raises(engine.ParameterError) as err:
        cls(**kwargs)
    assert err.value.field == field


def test_scene_validation():
    pos = np.array([[0, 0, 0.01], [0.006, 0, 0.01]])
    with pytest.raises(engine.ParameterError, match=r"Scene.radii.*size ratio <= 3"):
        engine.Scene(pos, [R, R / 4], 2000.0, pair_law=LAW)
    with pytest.raises(engine.ParameterError, match=r"Scene.positions.*shape \(N, 3\)"):
        engine.Scene(pos[:, :2], R, 2000.0, pair_law=LAW)
    with pytest.raises(engine.ParameterError, match=r"Scene.box.*given when an axis is periodic"):
        engine.Scene(pos, R, 2000.0, periodic=(True, False, False), pair_law=LAW)
    with pytest.raises(engine.ParameterError, match=r"Scene.wall_law"):
        engine.Scene(pos, R, 2000.0, walls=[engine.Plane((0, 0, 0), (0, 0, 1))], pair_law=LAW)
    with pytest.raises(engine.ParameterError, match=r"Scene.density.*> 0"):
        engine.Scene(pos, R, [2000.0, -1.0], pair_law=LAW)
    with pytest.raises(engine.ParameterError, match=r"Scene.pair_law"):
        engine.Scene(pos, R, 2000.0)


def test_periodic_box_must_hold_twice_the_cutoff():
    pos = np.array([[0.002, 0.002, 0.01]])
    scene = engine.Scene(
        pos,
        R,
        2000.0,
        box=((0, 0.008), (0, 1), (0, 1)),
        periodic=(True, False, False),
        pair_law=LAW,
        gravity=(0, 0, 0),
    )
    with pytest.raises(engine.ParameterError, match=r"Scene.box.*along x.*minimum image"):
        engine.Simulation(scene, dt=1e-6)


def test_simulation_argument_validation():
    scene = pair_scene(LAW, gap=1e-3)
    with pytest.raises(engine.ParameterError, match="Simulation.dt"):
        engine.Simulation(scene, dt=-1.0)
    with pytest.raises(engine.ParameterError, match="Simulation.skin"):
        engine.Simulation(scene, skin=0.0)
    sim = engine.Simulation(scene)
    with pytest.raises(engine.ParameterError, match="Simulation.run.steps"):
        sim.run(-3)
    with pytest.raises(engine.ParameterError, match="Simulation.run.steps"):
        sim.run(2.5)
    with pytest.raises(AttributeError):
        sim.dt = 1.0  # read-only: a step is checked once, at construction
    with pytest.raises(engine.ParameterError, match="wall index"):
        sim.set_wall_velocity(0, (0, 0, 1))


def test_features_leave_out_what_the_scene_does_not_use(monkeypatch):
    monkeypatch.setenv("DEMSCALE_KERNELS", "scene")  # the scene's own kernel (the default)
    plain = engine.BilinearAdhesive(k1=5e3, k2=5e3, f0=0.0, mu_s=0.0, mu_r=0.0, restitution=1.0)
    # pair_scene's box, periodic along x and y: the kernel of test_kernels' plain case (the
    # same features: one compilation for both tests, about 10 s of CPU)
    sim = engine.Simulation(pair_scene(plain, gap=1e-3))
    # no switch on but the periodic axes (no gravity in pair_scene); the families name the laws
    on = {k for k, v in sim.features.items() if v and not k.endswith("_kernel")}
    assert on == {"periodic_x", "periodic_y"}
    assert sim.features["pair_kernel"] == "bilinear"
    assert sim._k.N_SLOT == 4  # marker + force on j: no tangential history, no torque
    full = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, kadh=1e3, mu_s=0.5, mu_r=0.001)
    # the features a Simulation compiles for (its module is the one test_features_... above
    # loads; compiling a second one here would only cost CI time)
    f = scene_features(pair_scene(full, gap=1e-3, periodic=OPEN))
    assert f["adhesion"] and f["adhesive_branch"] and f["plastic"] and f["friction"]
    assert f["rolling"] and f["damping"] and not f["walls"] and not f["periodic_x"]
    assert set(f) <= set(engine.FEATURES)
    # the scene's features are those of its two families: the EEPA's or Hertz's are not there
    assert "plastic" in f and "wall_friction" in f and "wall_plastic" not in f


def test_unused_features_are_absent_from_the_compiled_module(monkeypatch):
    monkeypatch.setenv("DEMSCALE_KERNELS", "scene")  # the scene's own kernel (the default)
    plain = engine.BilinearAdhesive(k1=5e3, k2=5e3, f0=0.0, mu_s=0.0, mu_r=0.0, restitution=1.0)
    sim = engine.Simulation(pair_scene(plain, gap=1e-3))  # the kernel of the test above
    src = open(sim._k.__file__).read()
    assert "FRICTION = False" in src and "ROLLING = False" in src and "WALLS = False" in src
    # numba froze the flags into the machine code: functions compiled once, for this module
    assert sim._k.FRICTION is False and sim._k.PERIODIC_Z is False


def test_state_accessors_are_copies_in_si_units():
    sim = engine.Simulation(pair_scene(LAW, gap=1e-3, v0=0.1))
    p = sim.positions
    p[:] = 0
    assert not np.all(sim.positions == 0)
    assert sim.velocities[0, 0] == pytest.approx(0.1)
    assert sim.kinetic_energy() == pytest.approx(2 * 0.5 * sim.masses[0] * 0.01)
    assert sim.time == 0.0 and sim.steps == 0
    sim.run(10)
    assert sim.time == pytest.approx(10 * sim.dt)


def test_set_periodic_removes_contacts_across_the_face():
    # two particles touching across the z face of a periodic box; the axis removed is z, so
    # that the kernel after the change (periodic along x and y) is the one the periodic
    # cells of the other tests compile (a kernel costs about 25 s of CPU to compile)
    L = 0.03
    pos = np.array([[0.015, 0.015, 0.001], [0.015, 0.015, L - 0.0035]])
    law = ADHESIVE
    scene = engine.Scene(
        pos,
        R,
        2000.0,
        box=((0, L), (0, L), (0, L)),
        periodic=(True, True, True),
        gravity=(0, 0, 0),
        pair_law=law,
    )
    sim = engine.Simulation(scene)
    assert len(sim.contacts().pairs) == 1
    sim.set_periodic((True, True, False))
    assert len(sim.contacts().pairs) == 0 and sim.periodic == (True, True, False)
    assert not sim.features["periodic_z"] and sim.features["periodic_x"]
    with pytest.raises(engine.ParameterError, match="removed, not added"):
        sim.set_periodic((True, True, True))


def test_unwrapped_positions_undo_the_periodic_wraps():
    """A lone particle drifting along a periodic x axis: wrapped into the box, and unwrapped
    at x0 + v t, two box lengths on."""
    length = 0.05
    scene = engine.Scene(
        [[0.04, 0.01, 0.01]],
        R,
        2000.0,
        velocities=[[1.0, 0.0, 0.0]],
        box=((0, length), (0, 0.03), (0, 0.03)),
        # periodic along all three axes with the adhesive law of the test above: the kernel
        # it compiled (the particle moves along x only)
        periodic=(True, True, True),
        pair_law=ADHESIVE,
        gravity=(0, 0, 0),
    )
    sim = engine.Simulation(scene, dt=1e-4)
    sim.run(1000)  # 0.1 m: two lengths
    x = 0.04 + 1.0 * sim.time
    assert sim.unwrapped_positions[0, 0] == pytest.approx(x, abs=1e-12)
    assert 0 <= sim.positions[0, 0] < length
    assert sim.positions[0, 0] == pytest.approx(x - 2 * length, abs=1e-12)
