"""Differential test of the scene-specialised kernels: the all-features kernel run with the
neutral parameters of the features a scene does not use gives bit-identical trajectories to
the kernel specialised for that scene. (A wrong parameter slot, a flag compiled into the wrong
branch or a composition step that is not neutral shows up as a difference.)"""

from __future__ import annotations

import numpy as np
import pytest

import engine
import engine.simulation.simulation
from engine.kernel import specialise as kernels
from tests import naive

R = 2.5e-3


def _bed(pair_law, wall_law=None, gravity=(0.0, 0.0, -9.81), seed=7):
    lengths = np.array([0.03, 0.03, 0.03])
    pos, rad = naive.rsa_packing(
        400, lengths, 0.8 * R, R, seed, max_overlap=0.1, periodic=(True, True, False)
    )
    rng = np.random.default_rng(seed)
    walls = []
    if wall_law is not None:
        walls = [
            engine.Plane((0, 0, 0), (0, 0, 1)),
            engine.Plane((0, 0, 0.03), (0, 0, -1), velocity=(0, 0, -0.05)),
        ]
    return engine.Scene(
        pos,
        rad,
        2000.0,
        velocities=rng.normal(0, 0.05, pos.shape),
        angular_velocities=rng.normal(0, 20.0, pos.shape),
        box=[(0, L) for L in lengths],
        periodic=(True, True, False),
        walls=walls,
        gravity=gravity,
        pair_law=pair_law,
        wall_law=wall_law or engine.HertzMindlin(E=1e8, nu=0.25, mu=0.3),
        wall_material=engine.WallMaterial(),
    )


NOT_NEUTRAL = kernels.NOT_NEUTRAL


@pytest.fixture(autouse=True)
def _scene_kernels(monkeypatch):
    """Each scene's own kernel (DEMSCALE_KERNELS=scene, the default outside the tests): the
    specialised kernel is what these tests hold the all-features one to."""
    monkeypatch.setenv("DEMSCALE_KERNELS", "scene")


def _all_features(scene, periodic=None):
    """Every switch of the scene's two kernel families on (with the neutral parameters of
    those the scene does not use they must not change a bit): the general kernel, whose
    periodic axes, friction caps and meshes are the scene's (a minimum image along an axis
    without a period is no neutral switch), and which the suite's other tests compile too."""
    return kernels.kernel_features(kernels.scene_features(scene, periodic), "general")


def _trajectory(scene, monkeypatch=None):
    """The simulation after 1,500 steps, and the contacts counted over five snapshots."""
    if monkeypatch is not None:
        with monkeypatch.context() as m:
            m.setattr(engine.simulation.simulation, "scene_features", _all_features)
            sim = engine.Simulation(scene, dt=5e-6)
    else:
        sim = engine.Simulation(scene, dt=5e-6)
    contacts = 0
    for _ in range(5):
        sim.run(300)
        contacts += len(sim.contacts().pairs)
    return sim, contacts


#: The beds' laws: each case's pair law, wall law and gravity (tests/engine/test_eepa.py runs
#: the EEPA with n = chi = 1 on three of them).
BEDS = {
    "full": (
        engine.BilinearAdhesive(
            k1=5e3, k2=2.5e4, f0=-0.2, kadh=1e3, mu_s=0.5, mu_r=0.002, restitution=0.4
        ),
        engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.002),
        (0.0, 0.0, -9.81),
    ),
    "plain": (
        engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0, mu_r=0, restitution=1),
        None,
        (0.0, 0.0, 0.0),
    ),
    "friction-only": (
        engine.BilinearAdhesive(k1=5e3, k2=2.5e4, mu_s=0.5, mu_r=0, restitution=1),
        engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=0.0),
        (0.0, 0.0, -9.81),
    ),
    "adhesive-elastic": (
        engine.BilinearAdhesive(
            k1=5e3, k2=5e3, f0=-0.2, kadh=2e3, mu_s=0.4, mu_r=0, restitution=0.6
        ),
        None,
        (0.0, 0.0, 0.0),
    ),
    "hertz": (
        engine.HertzMindlin(E=5e7, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.0),
        engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=0.3),
        (0.0, 0.0, -9.81),
    ),
}
#: The beds whose own kernel differs from the general one in the switches it leaves out.
#: ("full", every switch on, was one until the general kernels kept the scene's meshes: its
#: kernel is now the general one. No kernel now runs a scene without meshes with the
#: meshes' switch on, except test_mesh.py's periodic plane run, held there to the mesh's
#: trajectory bit for bit.)
CASES = {k: v for k, v in BEDS.items() if k != "full"}


@pytest.mark.parametrize("case", list(CASES))
def test_all_features_kernel_with_neutral_parameters_is_bit_identical(case, monkeypatch):
    pair_law, wall_law, gravity = CASES[case]
    scene = _bed(pair_law, wall_law, gravity)
    special, contacts = _trajectory(scene)
    general, _ = _trajectory(scene, monkeypatch)
    assert all(v for k, v in general.features.items() if k not in kernels.KEPT_IN_GENERAL)
    assert special.features != general.features  # two different kernels
    assert special.n > 150 and contacts > 25
    for name in ("positions", "velocities", "angular_velocities", "wall_forces"):
        a, b = getattr(special, name), getattr(general, name)
        # bit-identical: the same doubles (an addition of a signed zero may flip the sign
        # of a zero, which compares equal)
        np.testing.assert_array_equal(a, b, err_msg=name)
    np.testing.assert_array_equal(special.contacts().max_overlaps, general.contacts().max_overlaps)


def test_a_general_kernel_gives_the_scene_kernel_s_bits(monkeypatch):
    """DEMSCALE_KERNELS=general (the test suite's mode, tests/conftest.py): the kernel with
    every neutral switch on, the families, friction caps, periodic axes and meshes the
    scene's; the
    default study's laws (engine.UniaxialTest's) give the bits of their own kernel."""
    t = engine.UniaxialTest()
    scene = _bed(t.pair_law, t.wall_law, (0.0, 0.0, -t.gravity))
    special, contacts = _trajectory(scene)  # the fixture's scene mode
    monkeypatch.setenv("DEMSCALE_KERNELS", "general")
    general, _ = _trajectory(scene)
    f = kernels.scene_features(scene)
    assert general.features == kernels.kernel_features(f) != special.features == f
    for k, v in general.features.items():
        assert v == (f[k] if k in kernels.KEPT_IN_GENERAL else True), k
    assert special.n > 150 and contacts > 25
    for name in ("positions", "velocities", "angular_velocities", "wall_forces"):
        np.testing.assert_array_equal(getattr(special, name), getattr(general, name), err_msg=name)
    monkeypatch.setenv("DEMSCALE_KERNELS", "fast")
    with pytest.raises(ValueError, match="DEMSCALE_KERNELS = 'fast'"):
        engine.Simulation(scene, dt=5e-6)


def _switches_off(pair: str, wall: str = "hertz") -> dict:
    names = kernels.feature_names(kernels.kernel_named(pair), kernels.kernel_named(wall))
    f = dict.fromkeys(names, False)
    f.update(pair_kernel=pair, wall_kernel=wall)
    return f


def test_parameter_slots_follow_the_features():
    f = _switches_off("bilinear")
    assert kernels.pair_slots(f) == ("k1",)
    assert kernels.wall_slots(f) == ()
    # a switched-off parameter has no slot: the generated reader gives its neutral value,
    # K2 = K1 without plasticity, 0 for the others
    src = kernels._source(f)
    assert "return PairParams(p[0], p[0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)\n" in src
    f.update(friction=True, walls=True, wall_rolling=True)
    assert kernels.pair_slots(f) == ("k1", "kt", "mu_s")
    assert kernels.wall_slots(f) == ("e_star", "mu_r")
    h = _switches_off("hertz")
    h.update(friction=True)
    assert kernels.pair_slots(h) == ("e_star", "g_star", "mu_s")
    src = kernels._source(h)
    assert "return PairParams(p[0], p[1], 0.0, p[2], 0.0)\n" in src
    assert "PAIR_EFFECTIVE_RADIUS = True\n" in src
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4)
    arr = law.to_array(("k1", "f0"))
    assert arr[0] == 5e3 and arr[1] == -0.4 and np.isnan(arr[2]) and arr.size == 3


def test_features_must_be_those_of_the_two_families():
    f = _switches_off("bilinear")
    f["eepa_only"] = True
    with pytest.raises(ValueError, match="features must be exactly"):
        kernels._source(f)
    with pytest.raises(KeyError, match="no registered law has the kernel family 'nope'"):
        kernels.pair_slots({**_switches_off("bilinear"), "pair_kernel": "nope"})


def test_the_template_default_block_is_the_generated_one():
    """The feature block written in the template (what ruff and a reader see) is the one
    generated for the all-features bilinear scene with Hertz walls."""
    f = _switches_off("bilinear")
    f.update({k: True for k in f if k not in NOT_NEUTRAL})
    text = kernels._TEMPLATE.read_text()
    a = text.index("# >>> features")
    written = text[a : text.index("# <<< features", a)]
    generated = kernels.features_block(f).replace("generated by", "rewritten by")
    generated = generated[: generated.index("# <<< features")]
    assert "".join(written.replace("'", '"').split()) == "".join(
        generated.replace("'", '"').split()
    )
