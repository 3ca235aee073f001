"""Contact laws against their closed forms, branch by branch (MercuryDPM style)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine import laws
from tests import naive
from tests.engine.helpers import pair_scene

K1, K2, F0 = 5e3, 2.5e4, -0.4
LAM = 1 - K1 / K2


def _path_forces(kadh: float, path):
    """Drive one contact of the real step kernel through the overlaps ``path`` (two resting
    particles, positions prescribed) and return the normal force on particle 0 at each."""
    law = engine.BilinearAdhesive(
        k1=K1, k2=K2, f0=F0, kadh=kadh, mu_s=0.5, mu_r=0.0, restitution=1.0
    )
    r = 2.5e-3
    sim = engine.Simulation(pair_scene(law, gap=1e-4), dt=1e-6)
    out = []
    for d in path:
        x = r - 0.5 * d
        sim.set_positions([[-x, 0, 0], [x, 0, 0]])
        c = sim.contacts()
        assert len(c.pairs) == 1
        # force on particle 0 (at -x), repulsive = -x direction; normal n points j -> i
        out.append(float(-c.forces[0, 0]))
    return np.array(out)


def test_bilinear_branches_in_the_step_kernel():
    dmax = 2e-4
    dp = LAM * dmax
    path = [1e-4, dmax, 1.8e-4, dp, 1e-4, 0.5e-4, 1.9e-4, 2.5e-4]
    expected = [
        F0 + K1 * 1e-4,  # virgin loading
        F0 + K1 * dmax,  # virgin loading, top
        F0 + K2 * (1.8e-4 - dp),  # unloading
        F0,  # reaches f0 exactly at the plastic overlap
        F0,  # plateau at f0 (kadh = 0)
        F0,
        F0 + K2 * (1.9e-4 - dp),  # reloading along K2
        F0 + K1 * 2.5e-4,  # back on the virgin line beyond the old dmax
    ]
    got = _path_forces(0.0, path)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


def test_adhesive_branch_with_kadh():
    kadh = 2e3
    dmax = 2e-4
    dp = LAM * dmax
    cross = K2 * dp / (K2 + kadh)  # where K2 (d - dp) = -kadh d
    path = [dmax, 1.5e-4, 1e-4, 0.2e-4]
    got = _path_forces(kadh, path)
    assert 1.5e-4 > cross > 1e-4
    expected = [F0 + K1 * dmax, F0 + K2 * (1.5e-4 - dp), F0 - kadh * 1e-4, F0 - kadh * 0.2e-4]
    np.testing.assert_allclose(got, expected, rtol=1e-9)


def test_contact_opening_deletes_history():
    # load deep, separate, touch again lightly: the new contact starts on the virgin line
    law_path = [2e-4, -1e-5, 0.5e-4]
    law = engine.BilinearAdhesive(k1=K1, k2=K2, f0=F0, mu_s=0.5, mu_r=0, restitution=1)
    r = 2.5e-3
    sim = engine.Simulation(pair_scene(law, gap=1e-4), dt=1e-6)
    forces = []
    for d in law_path:
        x = r - 0.5 * d
        sim.set_positions([[-x, 0, 0], [x, 0, 0]])
        c = sim.contacts()
        forces.append(float(-c.forces[0, 0]) if len(c.pairs) else 0.0)
    assert forces[1] == 0.0
    assert forces[2] == pytest.approx(F0 + K1 * 0.5e-4, rel=1e-12)  # not K2 (d - dp)


@pytest.mark.parametrize("kadh", [0.0, 3e3])
def test_scalar_kernel_matches_naive_on_random_paths(kadh):
    rng = np.random.default_rng(3)
    d_path = np.abs(np.cumsum(rng.normal(0, 2e-5, 400))) + 1e-7
    dmax_k = dmax_n = 0.0
    for d in d_path:
        fk, dmax_k = laws.bilinear_normal_force(d, dmax_k, K1, K2, F0, kadh)
        fn, dmax_n = naive.bilinear_force(d, dmax_n, K1, K2, F0, kadh)
        assert fk == pytest.approx(fn, rel=1e-12, abs=1e-15)
        assert dmax_k == dmax_n


def test_friction_cap_zero_on_plateau_and_adhesion_aware():
    n = (1.0, 0.0, 0.0)
    vt = (0.0, 0.3, 0.0)  # tangential sliding velocity [m/s]
    dt = 1e-5
    common = dict(
        k1=K1,
        k2=K2,
        f0=F0,
        kadh=0.0,
        kt=2 / 7 * K1,
        zeta=0.0,
        mu_s=0.5,
        dt=dt,
        plastic=True,
        adhesion=True,
        friction=True,
        damping=False,
    )

    def contact(d, dmax, xi):
        a = common
        return laws.bilinear_contact(
            d,
            *n,
            vt[0],
            vt[1],
            vt[2],
            dmax,
            *xi,
            1e-4,
            a["k1"],
            a["k2"],
            a["f0"],
            a["kadh"],
            a["kt"],
            a["zeta"],
            a["mu_s"],
            a["dt"],
            a["plastic"],
            a["adhesion"],
            a["friction"],
            a["damping"],
        )

    # on the plateau (f_hys = f0): no friction at all, however large the spring
    out = contact(1e-4, 2e-4, (0.0, 1e-3, 0.0))
    assert out[1] == pytest.approx(F0)
    assert out[2:5] == (0.0, 0.0, 0.0)
    # loaded: the force grows with the spring until it slides at mu_s |f_hys - f0|
    d = 2e-4
    xi = (0.0, 0.0, 0.0)
    ft = []
    for _ in range(200):
        out = contact(d, d, xi)
        xi = out[6:9]
        ft.append(math.hypot(*out[2:5]))
    cap = 0.5 * abs((F0 + K1 * d) - F0)
    assert ft[0] == pytest.approx(2 / 7 * K1 * 0.3 * dt)  # first increment: kt vt dt
    assert max(ft) == pytest.approx(cap, rel=1e-12)
    assert ft[-1] == pytest.approx(cap, rel=1e-12)
    # the spring was truncated to the cap: kt |xi| = cap
    assert 2 / 7 * K1 * math.hypot(*xi) == pytest.approx(cap, rel=1e-12)


def test_tangential_spring_turns_with_the_contact():
    xi = (0.0, 2e-6, 0.0)  # in the tangent plane of n = x
    th = 0.1
    n2 = (math.cos(th), math.sin(th), 0.0)
    out = laws.tangential_spring_force(*xi, *n2, 0.0, 0.0, 0.0, 1e3, 0.0, 1e9, 1e-5)
    xi2 = np.array(out[3:6])
    assert abs(xi2 @ np.array(n2)) < 1e-18  # back in the new tangent plane
    assert np.linalg.norm(xi2) == pytest.approx(2e-6, rel=1e-12)  # length kept
    np.testing.assert_allclose(out[0:3], -1e3 * xi2, rtol=1e-12)


def test_rolling_torque_opposes_spin_with_the_closed_form_magnitude():
    w = np.array([3.0, -4.0, 0.0])
    t = np.array(laws.rolling_torque(*w, 0.01, 2.0, 2.5e-3))
    np.testing.assert_allclose(t, -0.01 * 2.0 * 2.5e-3 * w / 5.0, rtol=1e-12)
    assert laws.rolling_torque(0.0, 0.0, 1e-12, 0.01, 2.0, 2.5e-3) == (0.0, 0.0, 0.0)


def test_hertz_normal_force_and_stiffness():
    for d in (1e-7, 1e-5, 3e-4):
        f, s = laws.hertz_normal_force(d, 5e7, 1.25e-3)
        assert f == pytest.approx(naive.hertz_force(d, 5e7, 1.25e-3), rel=1e-12)
        # S_n is dF/dd
        h = d * 1e-6
        df = (
            laws.hertz_normal_force(d + h, 5e7, 1.25e-3)[0]
            - laws.hertz_normal_force(d - h, 5e7, 1.25e-3)[0]
        ) / (2 * h)
        assert s == pytest.approx(df, rel=1e-6)


def test_hertz_contact_friction_cap():
    out = laws.hertz_contact(
        1e-5, 0, 0, 1, 0.5, 0, 0, 0, 0, 0, 2.5e-3, 1e-4, 5e7, 2e7, 0.0, 0.3, 1e-5, True, False
    )
    f_el = out[1]
    assert math.hypot(*out[2:5]) == pytest.approx(0.3 * f_el, rel=1e-12)


def test_damping_coefficients():
    assert engine.materials.damping_ratio(1.0) == 0.0
    e = 0.4
    z = engine.materials.damping_ratio(e)
    # inverse relation of the linear spring-dashpot: e = exp(-pi z / sqrt(1 - z^2))
    assert math.exp(-math.pi * z / math.sqrt(1 - z * z)) == pytest.approx(e, rel=1e-12)
    assert laws.viscous_damping_coefficient(z, 2.0, 8.0) == pytest.approx(2 * z * 4.0)
