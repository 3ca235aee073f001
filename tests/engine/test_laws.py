"""Contact laws against their closed forms, branch by branch (MercuryDPM style)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine.contact import bilinear
from engine.contact import compose as laws
from engine.contact import hertz as hertz_law
from tests import naive
from tests.engine.helpers import pair_scene, path_forces, switches_on

K1, K2, F0 = 5e3, 2.5e4, -0.4
LAM = 1 - K1 / K2


def _path_forces(kadh: float, path):
    """Drive one contact of the real step kernel through the overlaps ``path`` (two resting
    particles, positions prescribed) and return the normal force on particle 0 at each."""
    law = engine.BilinearAdhesive(
        k1=K1, k2=K2, f0=F0, kadh=kadh, mu_s=0.5, mu_r=0.0, restitution=1.0
    )
    return path_forces(law, path)


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
        fk, dmax_k = bilinear.bilinear_normal_force(d, dmax_k, K1, K2, F0, kadh)
        fn, dmax_n = naive.bilinear_force(d, dmax_n, K1, K2, F0, kadh)
        assert fk == pytest.approx(fn, rel=1e-12, abs=1e-15)
        assert dmax_k == dmax_n


BILINEAR_FLAGS = switches_on(
    bilinear.BilinearSwitches, "friction", "adhesion", "adhesive_branch", "plastic"
)
HERTZ_FLAGS = switches_on(hertz_law.HertzSwitches, "friction")
BILINEAR_FORCE = laws.composition(bilinear.KERNEL).force
HERTZ_FORCE = laws.composition(hertz_law.KERNEL).force


def _bilinear_contact(
    d,
    dmax,
    xi,
    v,
    kadh=0.0,
    k2=K2,
    n=(1.0, 0.0, 0.0),
    spin=(0.0, 0.0, 0.0),
    zeta=0.0,
    m_eff=1e-4,
    dt=1e-5,
):
    law = bilinear.BilinearParams(
        k1=K1, k2=k2, f0=F0, kadh=kadh, kt=2 / 7 * K1, zeta=zeta, mu_s=0.5, mu_r=0.0
    )
    flags = BILINEAR_FLAGS._replace(plastic=k2 > K1, damping=zeta > 0)
    return BILINEAR_FORCE(d, *n, *v, *spin, dmax, *xi, 0.0, m_eff, law, flags, dt)


def test_friction_cap_zero_on_plateau_and_adhesion_aware():
    vt = (0.0, 0.3, 0.0)  # tangential sliding velocity [m/s]
    dt = 1e-5
    # on the plateau (f_hys = f0): no friction at all, however large the spring
    out = _bilinear_contact(1e-4, 2e-4, (0.0, 1e-3, 0.0), vt)
    assert out[1] == pytest.approx(F0)
    assert out[2:5] == (0.0, 0.0, 0.0)
    # loaded: the force grows with the spring until it slides at mu_s |f_hys - f0|
    d = 2e-4
    xi = (0.0, 0.0, 0.0)
    ft = []
    for _ in range(200):
        out = _bilinear_contact(d, d, xi, vt)
        xi = out[6:9]
        ft.append(math.hypot(*out[2:5]))
    cap = 0.5 * abs((F0 + K1 * d) - F0)
    assert ft[0] == pytest.approx(2 / 7 * K1 * 0.3 * dt)  # first increment: kt vt dt
    assert max(ft) == pytest.approx(cap, rel=1e-12)
    assert ft[-1] == pytest.approx(cap, rel=1e-12)
    # the spring was truncated to the cap: kt |xi| = cap
    assert 2 / 7 * K1 * math.hypot(*xi) == pytest.approx(cap, rel=1e-12)


@pytest.mark.parametrize("k2", [K1, K2])
def test_friction_cap_keeps_the_adhesive_slope_also_without_plasticity(k2):
    """mu_s |f_hys - f0 + kadh d| whether or not k2 > k1 (the compiled cap once dropped kadh
    when k2 == k1)."""
    kadh, d = 3e3, 1e-4
    out = _bilinear_contact(d, d, (0.0, 1.0, 0.0), (0.0, 0.0, 0.0), kadh=kadh, k2=k2)
    assert out[1] == pytest.approx(F0 + K1 * d, rel=1e-12)  # virgin line either way
    assert math.hypot(*out[2:5]) == pytest.approx(0.5 * (K1 + kadh) * d, rel=1e-12)


@pytest.mark.parametrize("hertz", [False, True])
def test_tangential_force_stays_in_the_tangent_plane(hertz):
    """An oblique, spinning contact: the tangential force is perpendicular to n, and the
    normal force is the closed form whatever the tangential motion."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        v = rng.normal(0, 0.5, 3)
        spin = rng.normal(0, 1e-3, 3)
        xi = np.cross(n, rng.normal(0, 1e-5, 3))  # a spring already in the tangent plane
        d = 1e-4
        if hertz:
            law = hertz_law.HertzParams(e_star=5e7, g_star=2e7, zeta=0.0, mu_s=0.3, mu_r=0.0)
            out = HERTZ_FORCE(d, *n, *v, *spin, 0.0, *xi, 1.25e-3, 1e-4, law, HERTZ_FLAGS, 1e-6)
            f_el = naive.hertz_force(d, 5e7, 1.25e-3)
        else:
            d = 1.4e-4  # unloading branch above the plastic overlap: f_el > f0
            out = _bilinear_contact(d, 1.5e-4, xi, v, n=n, spin=spin, dt=1e-6)
            f_el = naive.bilinear_force(d, 1.5e-4, K1, K2, F0, 0.0)[0]
        ft = np.array(out[2:5])
        assert np.linalg.norm(ft) > 0
        assert abs(ft @ n) <= 1e-12 * np.linalg.norm(ft)
        assert out[0] == pytest.approx(f_el, rel=1e-12)  # no damping: F_n = f_el
        # the spring's increment is the tangential contact-point velocity (no normal part);
        # the force is the spring's, or the cap when that is larger
        vt = v - (v @ n) * n - np.cross(spin, n)
        trial = xi + vt * 1e-6
        kt = 8 * 2e7 * math.sqrt(1.25e-3 * d) if hertz else 2 / 7 * K1
        cap = 0.3 * f_el if hertz else 0.5 * abs(f_el - F0)
        if kt * np.linalg.norm(trial) < 0.999 * cap:
            np.testing.assert_allclose(out[6:9], trial, rtol=1e-9, atol=1e-18)
            np.testing.assert_allclose(ft, -kt * trial, rtol=1e-9, atol=1e-15)
        else:
            assert np.linalg.norm(ft) == pytest.approx(cap, rel=1e-12)
            np.testing.assert_allclose(
                ft / cap, -trial / np.linalg.norm(trial), rtol=1e-9, atol=1e-12
            )


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
        f, s = hertz_law.hertz_normal_force(d, 5e7, 1.25e-3)
        assert f == pytest.approx(naive.hertz_force(d, 5e7, 1.25e-3), rel=1e-12)
        # S_n is dF/dd
        h = d * 1e-6
        df = (
            hertz_law.hertz_normal_force(d + h, 5e7, 1.25e-3)[0]
            - hertz_law.hertz_normal_force(d - h, 5e7, 1.25e-3)[0]
        ) / (2 * h)
        assert s == pytest.approx(df, rel=1e-6)


def test_hertz_contact_friction_cap():
    law = hertz_law.HertzParams(e_star=5e7, g_star=2e7, zeta=0.0, mu_s=0.3, mu_r=0.0)
    out = HERTZ_FORCE(
        1e-5, 0, 0, 1, 0.5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2.5e-3, 1e-4, law, HERTZ_FLAGS, 1e-5
    )
    f_el = out[1]
    assert f_el == pytest.approx(naive.hertz_force(1e-5, 5e7, 2.5e-3), rel=1e-12)
    assert math.hypot(*out[2:5]) == pytest.approx(0.3 * f_el, rel=1e-12)


def test_damping_coefficients():
    assert engine.contact.limits.damping_ratio(1.0) == 0.0
    e = 0.4
    z = engine.contact.limits.damping_ratio(e)
    # inverse relation of the linear spring-dashpot: e = exp(-pi z / sqrt(1 - z^2))
    assert math.exp(-math.pi * z / math.sqrt(1 - z * z)) == pytest.approx(e, rel=1e-12)
    assert laws.viscous_damping_coefficient(z, 2.0, 8.0) == pytest.approx(2 * z * 4.0)


@pytest.mark.parametrize("hertz", [False, True])
def test_step_kernel_damps_with_the_tested_coefficient(hertz):
    """The normal force of the step kernel on an approaching pair is f_el - c_n v_n with
    c_n from laws.viscous_damping_coefficient (the helper the kernel calls)."""
    r, v0, d = 2.5e-3, 0.2, 5e-5
    if hertz:
        law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.4, mu=0.0)
    else:
        law = engine.BilinearAdhesive(k1=K1, k2=K2, f0=F0, mu_s=0.0, mu_r=0.0, restitution=0.4)
    sim = engine.Simulation(pair_scene(law, gap=-d, v0=v0), dt=1e-7)
    c = sim.contacts()
    m_eff = sim.masses[0] / 2
    d = float(c.overlaps[0])
    if hertz:
        e_star, _ = law.pair_moduli()
        f_el, s_n = hertz_law.hertz_normal_force(d, e_star, r / 2)
        zeta = math.sqrt(5 / 6) * engine.contact.limits.damping_ratio(0.4)  # Tsuji, on S_n
        c_n = laws.viscous_damping_coefficient(zeta, m_eff, s_n)
    else:
        f_el = F0 + K1 * d
        c_n = laws.viscous_damping_coefficient(law.zeta, m_eff, K1)
    fn = float(c.forces[0] @ c.normals[0])
    assert fn == pytest.approx(f_el + c_n * 2 * v0, rel=1e-12)  # v_n = -2 v0
    assert c_n * 2 * v0 > 0.1 * abs(f_el)  # the damping part is not negligible
