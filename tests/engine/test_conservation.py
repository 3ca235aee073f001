"""Energy and momentum conservation (jax-md style checks)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from tests import naive
from tests.engine.helpers import box_gas

R = 2.5e-3


def _elastic_energy(sim: engine.Simulation, k: float, wall_e_star: float) -> float:
    c = sim.contacts()
    e = 0.5 * k * float(np.sum(c.overlaps**2))
    r = sim.radii[c.wall_particles]
    e += float(np.sum(8 / 15 * wall_e_star * np.sqrt(r) * c.wall_overlaps**2.5))
    return e


def _bed(gravity, seed=4, n=300):
    lengths = np.array([0.03, 0.03, 0.04])
    pos, rad = naive.rsa_packing(n, lengths, 0.8 * R, R, seed, periodic=(True, True, False))
    rng = np.random.default_rng(seed)
    vel = rng.normal(0.0, 0.1, (len(pos), 3))
    k = 5e3
    law = engine.BilinearAdhesive(k1=k, k2=k, f0=0.0, mu_s=0.0, mu_r=0.0, restitution=1.0)
    wall_law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=0.0)
    walls = [engine.Plane((0, 0, 0), (0, 0, 1)), engine.Plane((0, 0, 0.04), (0, 0, -1))]
    scene = engine.Scene(
        pos,
        rad,
        2000.0,
        velocities=vel,
        box=((0, 0.03), (0, 0.03), (0, 0.04)),
        periodic=(True, True, False),
        walls=walls,
        gravity=gravity,
        pair_law=law,
        wall_law=wall_law,
        wall_material=engine.WallMaterial(),
    )
    e_star, _ = wall_law.wall_moduli(engine.WallMaterial())
    return scene, k, e_star


@pytest.mark.parametrize("gravity", [(0.0, 0.0, 0.0), (0.0, 0.0, -9.81)])
def test_undamped_frictionless_bed_conserves_energy(gravity):
    scene, k, e_star = _bed(gravity)
    # a third of the default step (omega dt ~ 0.1): the sampled energy then fluctuates well
    # below the tolerance, and a force/energy inconsistency would still show as a drift
    sim = engine.Simulation(scene, dt=engine.critical_time_step(scene).recommended / 3)
    g = np.array(gravity)

    def energy():
        # potential energy of gravity measured from the floor contact height
        pe = -float(np.sum(sim.masses * ((sim.positions - sim.radii[:, None]) @ g)))
        return sim.kinetic_energy() + _elastic_energy(sim, k, e_star) + pe

    e0 = energy()
    drift = 0.0
    collisions = 0
    for _ in range(20):
        sim.run(500)
        drift = max(drift, abs(energy() - e0) / e0)
        collisions += len(sim.contacts().pairs)
    assert sim.steps == 10_000
    assert collisions > 200  # the particles really interact (contacts summed over snapshots)
    print(f"relative energy drift {drift:.2e}, {len(sim.contacts().pairs)} contacts now")
    assert drift < 1e-4


def test_momentum_conserved_in_fully_periodic_box():
    lengths = np.array([0.03, 0.03, 0.03])
    pos, rad = naive.rsa_packing(200, lengths, 0.7 * R, R, 9)
    rng = np.random.default_rng(9)
    vel = rng.normal(0.0, 0.2, (len(pos), 3))
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.05, mu_s=0.5, mu_r=0.001, restitution=0.4)
    sim = engine.Simulation(box_gas(pos, rad, lengths, law, velocities=vel))
    p0 = sim.masses @ sim.velocities
    scale = float(np.sum(sim.masses * np.linalg.norm(sim.velocities, axis=1)))
    sim.run(5000)
    assert len(sim.contacts().pairs) > 20
    p1 = sim.masses @ sim.velocities
    np.testing.assert_allclose(p1, p0, atol=1e-12 * scale)
    # the damped, adhesive gas did lose energy: momentum is not conserved trivially
    assert sim.kinetic_energy() < 0.9 * 0.5 * float(sim.masses @ np.sum(vel**2, axis=1))
    assert math.isfinite(sim.kinetic_energy())
