"""Oblique impacts against closed forms (Chung & Ooi 2011, tests 5 and 6 style).

Gross sliding (large impact angle, the contact point slides for the whole contact): the
tangential impulse is mu times the normal impulse, so for a sphere of mass m, radius R and
moment of inertia 2/5 m R^2, with normal approach speed vn0 and normal restitution e,

- on a wall: v_t' = v_t - mu (1 + e) vn0 and w' = 5 mu (1 + e) vn0 / (2 R);
- two equal spheres: the relative tangential velocity drops by mu (1 + e) vn0 and each
  sphere spins up by 5 mu (1 + e) vn0 / (4 R), both the same way,

valid while v_t > 7/2 mu (1 + e) vn0 (the limit of the analytic solution of Maw, Barber &
Fawcett 1976 that Chung & Ooi compare with). Sticking (no sliding) with the linear law and
Kt = 2/7 K1, undamped: the tangential oscillation of the contact point has the period of the
normal one, so the contact point leaves with its tangential velocity reversed.

Throughout each impact the normal component of the contact force must be the closed-form
elastic force of the overlap: a tangential force that leaks out of the tangent plane shows
up there.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine.contact.hertz import hertz_contact_time
from tests import naive

R = 2.5e-3
RHO = 2000.0
M = 4 / 3 * math.pi * R**3 * RHO
K1, K2 = 5e3, 2.5e4


def _pair(law, vn0: float, vt0: float) -> engine.Scene:
    """Two equal spheres on the x axis 1 um apart; relative velocity (vn0, vt0, 0) of
    particle 0 against particle 1 (approaching along x, sliding along y), in a box periodic
    along x and y 100 radii wide (no image within reach), as tests/engine/helpers.py's
    pair_scene: the kernel of the suite's other pair tests, none of its own to compile."""
    x = R + 0.5e-6
    vel = np.array([[0.5 * vn0, 0.5 * vt0, 0.0], [-0.5 * vn0, -0.5 * vt0, 0.0]])
    h = 50.0 * x
    return engine.Scene(
        np.array([[-x, 0.0, 0.0], [x, 0.0, 0.0]]),
        R,
        RHO,
        velocities=vel,
        box=((-h, h), (-h, h), (-h, h)),
        periodic=(True, True, False),
        gravity=(0, 0, 0),
        pair_law=law,
    )


def _wall(wall_law, vn0: float, vt0: float) -> engine.Scene:
    return engine.Scene(
        [[0.0, 0.0, R + 1e-6]],
        R,
        RHO,
        velocities=[[vt0, 0.0, -vn0]],
        gravity=(0, 0, 0),
        pair_law=engine.BilinearAdhesive(k1=K1, k2=K1, mu_s=0, mu_r=0, restitution=1),
        walls=[engine.Plane((0, 0, 0), (0, 0, 1))],
        wall_law=wall_law,
        wall_material=engine.WallMaterial(),
    )


def _impact(sim: engine.Simulation, normal_force, wall: bool, max_steps: int = 100_000):
    """Step through the impact; at every step compare the normal component of the contact
    force with ``normal_force(d, dmax)``. Returns the number of contact steps."""
    steps = 0
    touched = False
    for _ in range(max_steps):
        sim.run(1)
        c = sim.contacts()
        if wall:
            if not c.wall_overlaps.size:
                if touched:
                    return steps
                continue
            d = dmax = float(c.wall_overlaps[0])
            fn = -float(sim.wall_forces[0, 2])  # force of the wall on the particle, along +z
            f_total = -sim.wall_forces[0]
        else:
            if not len(c.pairs):
                if touched:
                    return steps
                continue
            d, dmax = float(c.overlaps[0]), float(c.max_overlaps[0])
            fn = float(c.forces[0] @ c.normals[0])
            f_total = c.forces[0]
        touched = True
        steps += 1
        expected = normal_force(d, dmax)
        # the tangential force has no normal component: F.n is the elastic closed form
        assert fn == pytest.approx(expected, rel=1e-9, abs=1e-12 * np.linalg.norm(f_total))
    raise AssertionError("the contact never opened")


def _bilinear_f(d, dmax):
    return naive.bilinear_force(d, dmax, K1, K2, 0.0, 0.0)[0]


@pytest.mark.parametrize("kind", ["bilinear", "hertz"])
def test_pair_oblique_impact_in_gross_sliding(kind):
    # slow and low friction, so that the spheres slide past each other by only ~1 um during
    # the contact: the closed form assumes a fixed normal and an overlap set by the approach
    mu, vn0 = 0.1, 0.01
    if kind == "bilinear":
        law = engine.BilinearAdhesive(k1=K1, k2=K2, f0=0.0, mu_s=mu, mu_r=0.0, restitution=1.0)
        dt = 0.1 * engine.critical_time_step(_pair(law, vn0, 0)).recommended
        force = _bilinear_f
    else:
        law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=mu)
        e_star, _ = law.pair_moduli()
        dt = hertz_contact_time(M / 2, R / 2, e_star, vn0) / 400

        def force(d, _dmax):
            return naive.hertz_force(d, e_star, R / 2)

    vt0 = 1.0 * vn0
    sim = engine.Simulation(_pair(law, vn0, vt0), dt=dt)
    assert _impact(sim, force, wall=False) > 100
    v, w = sim.velocities, sim.angular_velocities
    rel = v[0] - v[1]
    e = -rel[0] / vn0  # measured normal restitution
    assert e == pytest.approx(math.sqrt(K1 / K2) if kind == "bilinear" else 1.0, rel=0.01)
    assert vt0 > 3.5 * mu * (1 + e) * vn0  # gross sliding throughout
    assert rel[1] == pytest.approx(vt0 - mu * (1 + e) * vn0, rel=0.01)
    w_expected = -5 * mu * (1 + e) * vn0 / (4 * R)  # both spheres turn the same way
    np.testing.assert_allclose(w[:, 2], [w_expected, w_expected], rtol=0.01)
    assert np.all(np.abs(w[:, :2]) < 1e-9 * abs(w_expected))


def test_wall_oblique_impact_in_gross_sliding():
    mu, vn0 = 0.3, 0.5
    wall_law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=mu)
    e_star, _ = wall_law.wall_moduli(engine.WallMaterial())
    vt0 = 3.0 * vn0
    sim = engine.Simulation(
        _wall(wall_law, vn0, vt0), dt=hertz_contact_time(M, R, e_star, vn0) / 400
    )
    n = _impact(sim, lambda d, _: naive.hertz_force(d, e_star, R), wall=True)
    assert n > 100
    v, w = sim.velocities[0], sim.angular_velocities[0]
    e = v[2] / vn0
    assert e == pytest.approx(1.0, rel=0.01)
    assert vt0 > 3.5 * mu * (1 + e) * vn0
    assert v[0] == pytest.approx(vt0 - mu * (1 + e) * vn0, rel=1e-3)
    assert w[1] == pytest.approx(5 * mu * (1 + e) * vn0 / (2 * R), rel=1e-3)
    assert abs(w[0]) + abs(w[2]) < 1e-9 * abs(w[1])


def test_pair_oblique_impact_sticking_reverses_the_contact_point_velocity():
    """Linear law, Kt = 2/7 K1, no damping, no sliding: tangential restitution -1."""
    law = engine.BilinearAdhesive(
        k1=K1, k2=K1, f0=0.0, kt_ratio=2 / 7, mu_s=50.0, mu_r=0.0, restitution=1.0
    )
    vn0 = 0.05
    vt0 = 0.2 * vn0
    sim = engine.Simulation(
        _pair(law, vn0, vt0), dt=0.05 * engine.critical_time_step(_pair(law, vn0, 0)).recommended
    )
    assert _impact(sim, lambda d, _: K1 * d, wall=False) > 100
    v, w = sim.velocities, sim.angular_velocities
    rel = v[0] - v[1]
    assert -rel[0] / vn0 == pytest.approx(1.0, rel=1e-3)
    # contact-point tangential velocity v_t - (R w_0 + R w_1) x n with n = -x
    vc = rel[1] + R * (w[0, 2] + w[1, 2])
    assert vc == pytest.approx(-vt0, rel=0.01)
