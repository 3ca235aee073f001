"""The uniaxial stage driver on a tiny cell: stages, targets, independent measurements."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import engine
from engine.uniaxial.driver import stages_of

from .helpers import whole_run_fixtures

R = 2.5e-3
COHESIVE = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)


def tiny(**kw) -> engine.UniaxialTest:
    """About 30 particles filling a 15 x 15 x 15 mm cuboid: seconds per full test. The
    stage driver's tests run the seed's protocol (a constant platen speed, here 20 mm/s, and
    dt = 1e-5 s, engine.SEED_PROTOCOL), whose stage ends they count in steps;
    tests/engine/test_protocol.py runs the default protocol."""
    base = {
        **engine.SEED_PROTOCOL,
        "cell": (0.015, 0.015, 0.015),
        "output_interval": 1e-3,
        "platen_speed": 0.02,
    }
    return engine.UniaxialTest(**{**base, **kw})


cohesionless, cohesive = whole_run_fixtures(engine.run_uniaxial, tiny, COHESIVE)


def test_stages_run_in_order_and_reach_their_targets(cohesionless):
    res, seen = cohesionless
    assert list(res.stages) == list(stages_of(res.test))
    order = [s for i, (s, _) in enumerate(seen) if i == 0 or seen[i - 1][0] != s]
    assert order == list(stages_of(res.test))
    fractions = [f for _, f in seen]
    assert all(0 <= f <= 1 for f in fractions) and fractions[-1] == pytest.approx(1.0)
    assert all(b >= a - 1e-12 for a, b in itertools.pairwise(fractions))
    t = res.test
    pre = res.stages["pre_compression"].curves["stress_top"][-1]
    cons = res.stages["consolidation"].curves["stress_top"][-1]
    # stages stop at the first sample past the target: within one sample's stress increment
    assert t.pre_stress <= pre <= 1.2 * t.pre_stress
    assert t.consolidation_stress <= cons <= 1.1 * t.consolidation_stress
    assert res.stages["unloading"].curves["stress_top"][-1] <= t.unloaded_stress * cons
    times = np.concatenate([s.curves["time"] for s in res.stages.values()])
    assert np.all(np.diff(times) >= 0)
    for s in res.stages.values():
        for k, v in s.curves.items():
            assert np.all(np.isfinite(v)), k
    assert res.scalars["particles"] == t.n_particles
    assert res.scalars["max_inertial_number"] < 0.1


def _brute_contacts(pos, rad, lengths, periodic):
    """Contacts per particle, by all pairs."""
    n = len(pos)
    counts = np.zeros(n, dtype=int)
    for i in range(n):
        d = pos[i] - pos[i + 1 :]
        for a in range(3):
            if periodic[a]:
                d[:, a] -= lengths[a] * np.round(d[:, a] / lengths[a])
        dist = np.linalg.norm(d, axis=1)
        js = i + 1 + np.flatnonzero(dist < rad[i] + rad[i + 1 :])
        counts[i] += len(js)
        counts[js] += 1
    return counts


def _slab_solid(z, rad, lo, hi, n=4001):
    """Solid volume in lo <= z <= hi by integrating the spheres' disc areas on a fine grid."""
    zs = np.linspace(lo, hi, n)
    area = np.pi * np.clip(rad[:, None] ** 2 - (zs[None, :] - z[:, None]) ** 2, 0, None)
    return float(np.trapezoid(area.sum(axis=0), zs))


@pytest.mark.parametrize("stage", ["consolidation", "unloading"])
def test_porosity_and_coordination_match_positions(cohesionless, stage):
    res, _ = cohesionless
    st = res.stages[stage]
    lx, ly, _ = res.test.cell
    gap = st.curves["platen_gap"][-1]
    solid = float(np.sum(4.0 / 3.0 * math.pi * st.radii**3))
    assert st.curves["porosity"][-1] == pytest.approx(1 - solid / (lx * ly * gap), rel=1e-9)
    counts = _brute_contacts(st.positions, st.radii, (lx, ly, 1.0), (True, True, False))
    assert st.curves["coordination"][-1] == pytest.approx(counts.sum() / len(st.radii))
    assert counts.sum() > 0
    # interior: the slab between the platen layers, from the positions independently
    z = st.positions[:, 2] - 0.0  # the bottom platen stays at z = 0
    m = max(0.0, min(res.test.margin, gap / 2 - st.radii.max()))
    solid_in = _slab_solid(z, st.radii, m, gap - m)
    assert st.curves["porosity_interior"][-1] == pytest.approx(
        1 - solid_in / (lx * ly * (gap - 2 * m)), rel=1e-5
    )
    inside = (z >= m) & (z <= gap - m)
    assert st.curves["coordination_interior"][-1] == pytest.approx(counts[inside].mean())


def test_cohesionless_has_no_strength_cohesive_has_a_peak(cohesionless, cohesive):
    res, _ = cohesionless
    assert res.scalars["unconfined_strength"] < 0.02 * res.test.consolidation_stress
    assert cohesive.scalars["unconfined_strength"] > 0.02 * cohesive.test.consolidation_stress
    u = cohesive.stages["unconfined"].curves["stress_top"]
    k = int(np.argmax(u))
    assert k < len(u) - 1  # a peak, then a drop (failure), not just the end of the stage
    assert cohesive.scalars["strain_at_peak"] > 0


def test_callback_can_stop_a_run():
    calls = []

    def stop(p):
        calls.append(p.stage)
        return p.stage != "pre_compression"

    with pytest.raises(engine.StopRequested):
        engine.run_uniaxial(tiny(), progress=stop)
    assert calls[-1] == "pre_compression" and "consolidation" not in calls


def test_unreachable_stress_ends_with_stage_error():
    # a slow platen travels 5 um in max_stage_time: it does not even reach the bed
    test = tiny(
        pre_stress=2e4,
        consolidation_stress=4e4,
        platen_speed=1e-5,
        max_stage_time=0.5,
        unconfined=False,
    )
    with pytest.raises(engine.StageError, match="pre-compression stress 20000 Pa") as e:
        engine.run_uniaxial(test)
    assert e.value.stage == "pre_compression"
    assert e.value.steps >= 0.5 / 1e-5 - 1


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("radius", -1.0, "radius"),
        ("consolidation_stress", 1e3, "consolidation_stress"),
        ("cell", (0.005, 0.05, 0.1), "cell"),
        ("pour_fraction", 0.5, "pour_fraction"),
        ("solid_fraction", 0.8, "solid_fraction"),
        ("interior_margin", -1e-3, "interior_margin"),
        ("platen_speed", 0.0, "platen_speed"),
        ("seed", -3, "seed"),
    ],
)
def test_bad_parameters_name_the_field(field, value, match):
    with pytest.raises(engine.ParameterError, match=match):
        tiny(**{field: value})


def test_presets_and_round_trip():
    paper = engine.preset("paper")
    assert paper.cell == (0.05, 0.15, 0.30) and paper.radius == 2.5e-3
    # the default protocol (engine.uniaxial.spec.DEFAULT_PROTOCOL), and the seed's one option
    # away
    assert paper.dt is None and paper.dt_fraction == 0.4 and paper.inertial_number == 5e-4
    assert paper.strength_from == "interior" and paper.pour_speed == 2.0
    seed = engine.preset("paper", protocol="seed")
    assert seed.dt == 1e-5 and seed.platen_speed == 0.01 and seed.inertial_number is None
    assert seed.pour_speed is None and seed.strength_from == "platen"
    assert seed == engine.preset("paper", **engine.SEED_PROTOCOL)
    # the quick sample: the seed's height and slenderness on a third of its cross-section
    assert engine.preset("quick").cell == (0.05, 0.05, 0.30)
    # the seed's cuboid filled: 0.6 x 50 x 150 x 300 mm of 2.5 mm spheres, poured from 600 mm
    assert paper.n_particles == round(0.6 * 0.05 * 0.15 * 0.30 / (4 / 3 * math.pi * 2.5e-3**3))
    assert paper.pour_height == pytest.approx(0.6)
    assert paper.thickness_diameters == pytest.approx(10.0)
    q = engine.preset("quick", seed=7)
    assert engine.UniaxialTest.from_dict(q.to_dict()) == q
    with pytest.raises(engine.ParameterError, match="preset"):
        engine.preset("huge")


def test_gravity_switched_off_after_the_fill_takes_the_overburden_away(cohesionless):
    # the diagnostic option: the sample settles under gravity, then is compressed without
    # its own weight, so the base carries what the top platen does
    from engine.uniaxial.measures import overburden_ratio

    res_on, _ = cohesionless
    res_off = engine.run_uniaxial(tiny(gravity_off_after_fill=True, unconfined=False))
    t = res_on.test
    assert overburden_ratio(res_off) == 0.0 and overburden_ratio(res_on) > 0
    # the fill is the same (gravity goes off only after it)
    fill_on, fill_off = res_on.stages["fill"].curves, res_off.stages["fill"].curves
    assert np.array_equal(fill_on["stress_bottom"], fill_off["stress_bottom"])

    def base_minus_top(res):
        c = res.stages["unloading"].curves
        return float(np.mean(c["stress_bottom"][-5:] - c["stress_top"][-5:]))

    weight = overburden_ratio(res_on) * t.consolidation_stress
    assert base_minus_top(res_on) == pytest.approx(weight, rel=0.3)
    assert abs(base_minus_top(res_off)) < 0.1 * weight


def test_set_gravity_is_refused_where_the_step_has_no_gravity():
    # a scene without gravity compiles its step without it: switching it on there would do
    # nothing, so it is refused (switching it off is what gravity_off_after_fill does, and
    # the test above shows its effect); refused in either kernel mode (a general kernel has
    # gravity, but a simulation behaves as its scene's own kernel would)
    from tests.engine.helpers import pair_scene

    plain = engine.BilinearAdhesive(k1=5e3, k2=5e3, f0=0.0, mu_s=0.0, mu_r=0.0, restitution=1.0)
    sim = engine.Simulation(pair_scene(plain, gap=1e-3))
    sim.set_gravity((0.0, 0.0, 0.0))
    with pytest.raises(engine.ParameterError, match="built without gravity"):
        sim.set_gravity((0.0, 0.0, -9.81))
    with pytest.raises(engine.ParameterError, match="set_gravity"):
        sim.set_gravity((0.0, float("nan"), 0.0))


def test_a_capped_pour_never_falls_faster_than_its_speed():
    # UniaxialTest.pour_speed: every particle faster than the cap is slowed to it between
    # curve samples during the fill, so the kinetic energy at each fill sample is at most
    # that of every particle moving at the cap; the free fall reaches more
    from engine.simulation.packing import sphere_volume

    cap = 0.15
    res = engine.run_uniaxial(tiny(pour_speed=cap, unconfined=False))
    t = res.test
    m = t.density * sphere_volume(t.radius)
    ke = res.stages["fill"].curves["kinetic_energy"]
    assert ke.max() <= 0.5 * m * cap**2 * t.n_particles * (1 + 1e-9)
    assert t.fall_time == pytest.approx(t.pour_height / cap)
    free = engine.run_uniaxial(tiny(unconfined=False)).stages["fill"].curves["kinetic_energy"]
    assert free.max() > 2 * ke.max()
    with pytest.raises(engine.ParameterError, match="pour_speed"):
        tiny(pour_speed=0.0)


def test_pair_stress_is_the_contact_virial():
    # two spheres overlapping by d along x: sigma_xx = K1 d (2R - d) / V, compressive positive
    from tests.engine.helpers import pair_scene

    d = 1e-5
    sc = pair_scene(engine.BilinearAdhesive(k1=5e3, k2=2.5e4), gap=-d)
    sig = engine.Simulation(sc, dt=1e-6).pair_stress(2.0)
    expected = np.zeros((3, 3))
    expected[0, 0] = 5e3 * d * (2 * R - d) / 2.0
    np.testing.assert_allclose(sig, expected, rtol=1e-12, atol=1e-18)


def test_the_virial_stress_agrees_with_the_platens_and_gives_k0(cohesionless):
    # the curves stress_lateral and stress_vertical (contact virial over the sample, the
    # platens' lever included) and the scalar k0: quasi-static, the vertical virial is the
    # mean of the two platens' stresses (measured apart: forces on the walls), and the
    # lateral stress ratio is that of a granular bed
    res, _ = cohesionless
    c = res.stages["consolidation"].curves
    platens = 0.5 * (c["stress_top"][-1] + c["stress_bottom"][-1])
    assert c["stress_vertical"][-1] == pytest.approx(platens, rel=0.02)
    assert 0.1 < res.scalars["k0"] < 1.2
    assert np.all(c["stress_lateral"] >= 0)


def test_a_flow_function_branches_one_fill_bit_for_bit():
    # engine.flow_function: the fill once, then each consolidation stress; each branch is
    # the run run_uniaxial makes of the test at that stress, bit for bit
    from dataclasses import replace

    t = tiny(pair_law=COHESIVE)
    ff = engine.flow_function(t, [2e4, 1e4])
    assert ff.consolidation_stresses == (1e4, 2e4)
    fresh = engine.run_uniaxial(replace(t, consolidation_stress=2e4))
    branch = ff.results[1]
    for stage, st in fresh.stages.items():
        for k, v in st.curves.items():
            assert np.array_equal(v, branch.stages[stage].curves[k]), (stage, k)
    assert branch.scalars["unconfined_strength"] == fresh.scalars["unconfined_strength"]
    # one fill for all
    fills = [r.stages["fill"].curves["time"] for r in ff.results]
    assert np.array_equal(fills[0], fills[1])
    pts = ff.points()
    assert [p["consolidation_stress"] for p in pts] == [1e4, 2e4]
    assert all(p["ffc"] == pytest.approx(p["consolidation_stress"] / p["strength"]) for p in pts)
    with pytest.raises(engine.ParameterError, match=r"consolidation_stresses\[0\]"):
        engine.flow_function(t, [1e3])  # below the pre-compression stress
    with pytest.raises(engine.ParameterError, match="unconfined"):
        engine.flow_function(tiny(unconfined=False), [2e4])
