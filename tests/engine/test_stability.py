"""Stiff and extreme cases: stable with the automatic step, or refused/stopped with the
documented error; never NaN."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from tests import naive
from tests.engine.helpers import pair_scene, wall_scene, walled_bed

R = 2.5e-3


def _compressed_bed(law, n=400, platen_speed=0.05):
    """A bed that starts in contact (overlaps up to 10 % of the radius) under a platen."""
    lengths = np.array([0.02, 0.02, 0.03])
    pos, rad = naive.rsa_packing(
        n, lengths, 0.9 * R, R, 11, max_overlap=0.1, periodic=(True, True, False)
    )
    top = float(pos[:, 2].max() + R)
    return engine.Simulation(walled_bed(pos, rad, lengths, law, top, platen_speed))


def _assert_finite(sim):
    for a in (sim.positions, sim.velocities, sim.angular_velocities, sim.forces, sim.wall_forces):
        assert np.all(np.isfinite(a))


@pytest.mark.parametrize("k1,k2", [(5e3, 5e6), (5e5, 1e9)])
def test_stiff_laws_are_stable_with_the_automatic_step(k1, k2):
    law = engine.BilinearAdhesive(k1=k1, k2=k2, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)
    sim = _compressed_bed(law)
    assert sim.dt <= 0.15 * 2 * math.sqrt(sim.masses.min() / 2 / k2) * 1.0001
    assert len(sim.contacts().pairs) > 40
    sim.run(3000)
    _assert_finite(sim)
    assert len(sim.contacts().pairs) > 20


def test_huge_adhesion_is_refused_with_the_equilibrium_overlap():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-100.0)
    with pytest.raises(engine.StabilityError, match=r"f0 = -100 N.*overlap \|f0\|/k1 = 0\.02 m"):
        engine.Simulation(pair_scene(law, gap=1e-4))


@pytest.mark.parametrize("f0", [-1.6, -5.0])
def test_strong_adhesion_runs_finite_or_stops_on_the_overlap_guard(f0):
    # f0 = -5 N: equilibrium overlap |f0|/k1 = 0.4 R is admitted at construction, but the
    # adhesive snap-in overshoots it; beyond 0.5 R the run stops with the documented error
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=f0, mu_s=0.5, restitution=0.4)
    sim = _compressed_bed(law, platen_speed=0.0)
    try:
        sim.run(3000)
    except engine.InstabilityError as err:
        assert f0 == -5.0 and err.reason == "overlap"
        assert "max_overlap_fraction" in str(err)
    else:
        assert f0 == -1.6
    _assert_finite(sim)


def test_deep_initial_overlap_stops_with_the_documented_error():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4)
    with pytest.raises(engine.InstabilityError) as err:
        engine.Simulation(pair_scene(law, gap=-0.6 * R))  # 60 % of the radius
    assert err.value.reason == "overlap" and err.value.particles == (0, 1)
    assert "max_overlap_fraction = 0.5" in str(err.value)


def test_deep_but_admissible_initial_overlap_pushes_apart_finite():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, restitution=0.4)
    sim = engine.Simulation(pair_scene(law, gap=-0.45 * R))
    sim.run(5000)
    _assert_finite(sim)
    v = sim.velocities
    assert v[0, 0] < 0 < v[1, 0]  # pushed apart


def test_ten_metres_per_second_impact_on_a_platen_with_the_automatic_step():
    wall_law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.3)
    sim = engine.Simulation(wall_scene(wall_law, gap=1e-4, v0=10.0))
    assert sim.limit.max_speed == pytest.approx(10.0)
    sim.run(20_000)
    _assert_finite(sim)
    assert sim.velocities[0, 2] > 0  # bounced


def test_ten_metres_per_second_soft_pair_impact_is_stopped_not_nan():
    # K1 = 5e3 N/m at 10 m/s would need an overlap of about 45 % of the radius per particle
    # pair; beyond max_overlap_fraction the run stops with the documented error
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, restitution=0.4)
    sim = engine.Simulation(pair_scene(law, gap=1e-4, v0=10.0))
    with pytest.raises(engine.InstabilityError) as err:
        sim.run(20_000)
    assert err.value.reason in ("overlap", "speed")
    assert err.value.step > 0 and err.value.time == pytest.approx(err.value.step * sim.dt)
    with pytest.raises(RuntimeError, match="cannot go on"):
        sim.run(1)


def test_given_step_above_the_limit_is_refused_naming_both_numbers():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4)
    scene = pair_scene(law, gap=1e-4)
    lim = engine.critical_time_step(scene)
    with pytest.raises(engine.StabilityError) as err:
        engine.Simulation(scene, dt=2 * lim.dt)
    msg = str(err.value)
    assert f"{2 * lim.dt:.4g} s" in msg and f"{lim.dt:.4g} s" in msg and "k2" in msg
    assert err.value.dt == 2 * lim.dt and err.value.limit == lim.dt
    engine.Simulation(scene, dt=0.9 * lim.dt)  # below the limit: accepted


def test_critical_time_step_names_the_limiting_contact_kind():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, restitution=1.0)
    dt, reason = engine.critical_time_step(pair_scene(law))
    m = 4 / 3 * math.pi * R**3 * 2000
    assert dt == pytest.approx(2 * math.sqrt(m / 2 / 2.5e4))  # undamped: 2 sqrt(m_eff / K2)
    assert reason.startswith("pair unloading stiffness k2")
    wall = engine.HertzMindlin(E=1e10, nu=0.25, restitution=1.0, mu=0.0)
    lim = engine.critical_time_step(wall_scene(wall, pair_law=law))
    assert lim.reason.startswith("wall Hertz")


def test_runaway_speed_is_stopped():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4)
    scene = pair_scene(law, gap=5e-3, v0=100.0)
    sim = engine.Simulation(scene, dt=1e-5)  # 100 m/s x 1e-5 s = 0.4 R per step
    with pytest.raises(engine.InstabilityError) as err:
        sim.run(10)
    assert err.value.reason == "speed" and "runaway kinetic energy" in str(err.value)


def test_non_finite_state_is_stopped_not_written():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4)
    sim = engine.Simulation(pair_scene(law, gap=1e-3))
    sim._particles.vel[sim._rank[1], 2] = np.nan  # corrupt the state from outside (internal id)
    with pytest.raises(engine.InstabilityError) as err:
        sim.run(5)
    assert err.value.reason == "nan" and err.value.particles == (1,)
