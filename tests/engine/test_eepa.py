"""The non-linear EEPA law (engine.EEPA) against its closed forms, the bilinear law it
generalises, its time-step limit and the similarity scaling rule (docs/PHYSICS.md section 8)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import engine
from engine.contact import compose as laws
from engine.contact import eepa
from engine.contact.eepa import eepa_impact_overlap
from engine.contact.limits import oscillator_limit
from engine.core.config import DT_FRACTION
from engine.kernel import specialise as kernels
from tests.engine.helpers import pair_scene, path_forces, run_until_separated, switches_on
from tests.engine.test_kernels import _bed

R = 2.5e-3
RHO = 2000.0
M = 4 / 3 * math.pi * R**3 * RHO
N, CHI = 1.5, 1.25
K1, K2, F0, KADH = 5e5, 2.5e6, -0.4, 1e4  # N/m^1.5, N/m^1.5, N, N/m^1.25


def _law(**kw) -> engine.EEPA:
    base = dict(k1=K1, k2=K2, f0=F0, kadh=KADH, n=N, chi=CHI, mu_s=0.5, mu_r=0.0, restitution=1.0)
    return engine.EEPA(**{**base, **kw})


def _path_forces(law, path):
    return path_forces(law, path, dt=1e-7)


def test_every_branch_in_the_step_kernel_matches_the_closed_form():
    dmax = 2e-4
    dpn = (1 - K1 / K2) * dmax**N  # plastic overlap to the power n
    dp = dpn ** (1 / N)
    assert dp == pytest.approx((1 - K1 / K2) ** (1 / N) * dmax)
    # where the unloading branch meets the adhesive branch: K2 (d^n - dp^n) = -kadh d^chi
    cross = dp * 0.8
    while K2 * (cross**N - dpn) + KADH * cross**CHI < 0:
        cross *= 1.001
    path = [1e-4, dmax, 1.8e-4, 1.02 * dp, 0.3 * dp, 0.5 * dp, 1.9e-4, 2.5e-4]
    expected = [
        F0 + K1 * 1e-4**N,  # virgin loading
        F0 + K1 * dmax**N,  # top of the virgin branch
        F0 + K2 * (1.8e-4**N - dpn),  # unloading
        F0 + K2 * ((1.02 * dp) ** N - dpn),  # unloading, just above the plastic overlap
        F0 - KADH * (0.3 * dp) ** CHI,  # adhesive branch
        F0 - KADH * (0.5 * dp) ** CHI,  # back along the adhesive branch (reversible)
        F0 + K2 * (1.9e-4**N - dpn),  # reloading along K2
        F0 + K1 * 2.5e-4**N,  # virgin line again beyond the old dmax
    ]
    got = _path_forces(_law(), path)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    assert 0.3 * dp < cross < 1.02 * dp  # the path really visits both sides of the crossing


def test_force_reaches_f0_at_the_plastic_overlap_without_adhesive_branch():
    dmax = 2e-4
    dp = (1 - K1 / K2) ** (1 / N) * dmax
    got = _path_forces(_law(kadh=0.0), [dmax, dp, 0.5 * dp])
    np.testing.assert_allclose(got, [F0 + K1 * dmax**N, F0, F0], rtol=1e-9, atol=1e-12)


def test_kernel_function_returns_tangent_stiffness_and_adhesive_pull():
    d, dmax = 1.9e-4, 2e-4  # on the unloading branch
    f, tangent, f_adh, dmax_out = eepa.eepa_normal_force(d, dmax, K1, K2, F0, KADH, N, CHI)
    assert dmax_out == dmax
    assert K1 * tangent == pytest.approx(N * K1 * d ** (N - 1))
    assert f_adh == pytest.approx(KADH * d**CHI)
    assert f == pytest.approx(F0 + K2 * (d**N - (1 - K1 / K2) * dmax**N))


@pytest.mark.parametrize("case", ["plain", "full", "adhesive-elastic"])
def test_n_and_chi_of_one_is_the_bilinear_law_to_the_last_bit(case):
    """A bed with walls, gravity, friction, rolling, damping and adhesion: the EEPA law with
    n = chi = 1 (its own kernel branches, pow included) gives the bilinear trajectory."""
    from tests.engine.test_kernels import BEDS, _trajectory

    bilinear, wall_law, gravity = BEDS[case]
    fields = {
        k: getattr(bilinear, k)
        for k in ("k1", "k2", "f0", "kadh", "kt_ratio", "mu_s", "mu_r", "restitution")
    }
    eepa = engine.EEPA(n=1.0, chi=1.0, **fields)
    a, contacts = _trajectory(_bed(bilinear, wall_law, gravity))
    b, _ = _trajectory(_bed(eepa, wall_law, gravity))
    assert b.features["pair_kernel"] == "eepa" and a.features["pair_kernel"] == "bilinear"
    assert a.n > 150 and contacts > 25
    assert a.dt == b.dt
    for name in ("positions", "velocities", "angular_velocities", "wall_forces"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_array_equal(a.contacts().max_overlaps, b.contacts().max_overlaps)


def restitution_closed_form(k1: float, k2: float, n: float) -> float:
    """Undamped, cohesionless EEPA impact: the work of the loading branch,
    K1 dmax^(n+1)/(n+1), against the work the unloading branch returns from dmax to dp,
    K2 [(dmax^(n+1) - dp^(n+1))/(n+1) - dp^n (dmax - dp)]; with x = dp/dmax =
    (1 - K1/K2)^(1/n): e^2 = (K2/K1) [1 - x^(n+1) - (n+1) x^n (1 - x)], independent of the
    impact speed. n = 1 gives e = sqrt(K1/K2)."""
    x = (1 - k1 / k2) ** (1 / n)
    return math.sqrt(k2 / k1 * (1 - x ** (n + 1) - (n + 1) * x**n * (1 - x)))


@pytest.mark.parametrize("n,v0", [(1.0, 0.05), (1.5, 0.05), (1.5, 0.5), (2.0, 0.2)])
def test_two_particle_restitution_matches_the_integrated_branches(n, v0):
    law = engine.EEPA(k1=K1, k2=K2, n=n, chi=1.0, mu_s=0.0, mu_r=0.0, restitution=1.0)
    scene = pair_scene(law, gap=1e-6, v0=v0)
    lim = engine.critical_time_step(scene, max_speed=v0)
    sim = engine.Simulation(scene, dt=0.02 * lim.dt)
    run_until_separated(sim, 400_000, chunk=20)
    v = sim.velocities
    e = float((v[1, 0] - v[0, 0]) / (2 * v0))
    expected = restitution_closed_form(K1, K2, n)
    assert e == pytest.approx(expected, rel=2e-3)
    if n == 1.0:
        assert expected == pytest.approx(math.sqrt(K1 / K2), rel=1e-12)


def test_time_step_from_the_tangent_stiffness_at_the_largest_expected_overlap():
    law = _law(restitution=0.5)
    scene = pair_scene(law, gap=1e-4)
    v = 0.3
    lim = engine.critical_time_step(scene, max_speed=v)
    m_eff = M / 2
    d = eepa_impact_overlap(m_eff, law, 2 * v)  # head-on: two particles each at v
    # the overlap balances the impact's energy and adhesion's work on the loading branch
    assert K1 * d ** (N + 1) / (N + 1) == pytest.approx(2 * m_eff * v * v - F0 * d, rel=1e-9)
    zeta = engine.contact.limits.damping_ratio(0.5)
    normal = oscillator_limit(N * K2 * d ** (N - 1), m_eff, zeta * math.sqrt(K1 / K2))
    tangential = oscillator_limit(3.5 * law.kt * N * d ** (N - 1), m_eff, zeta * math.sqrt(3.5))
    assert lim.dt == pytest.approx(min(normal, tangential), rel=1e-12)
    assert "n d^(n-1)" in lim.reason and "impact" in lim.reason
    # a faster impact reaches deeper, where the law is stiffer: a smaller step
    assert engine.critical_time_step(scene, max_speed=3 * v).dt < lim.dt
    with pytest.raises(engine.StabilityError):
        engine.Simulation(scene, dt=2 * lim.dt)


def test_linear_eepa_has_the_bilinear_time_step():
    bil = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, restitution=0.4)
    eepa = engine.EEPA(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, restitution=0.4, n=1.0, chi=1.0)
    a = engine.critical_time_step(pair_scene(bil))
    b = engine.critical_time_step(pair_scene(eepa))
    assert a.dt == b.dt and a.recommended == b.recommended


def test_stiff_eepa_impact_with_the_automatic_step_stays_finite():
    """A 5 m/s impact on a law 100 times stiffer, with adhesion and damping: the automatic
    step is the DT_FRACTION policy of the bilinear law at the deepest overlap, nothing is
    non-finite; damping only
    takes energy out, so the overlap stays below the undamped impact's (and well above zero:
    the contact was resolved, not stepped over); adhesion then holds the pair together."""
    law = _law(k1=5e7, k2=5e8, restitution=0.3, mu_s=0.5)
    scene = pair_scene(law, gap=1e-5, v0=2.5)
    sim = engine.Simulation(scene)
    d_impact = eepa_impact_overlap(M / 2, law, 5.0)
    dmax = 0.0
    for _ in range(400):
        sim.run(5)
        c = sim.contacts()
        if c.overlaps.size:
            dmax = max(dmax, float(c.overlaps.max()))
    assert np.all(np.isfinite(sim.velocities)) and np.all(np.isfinite(sim.positions))
    assert 0.3 * d_impact < dmax <= 1.01 * d_impact < 0.1 * R
    omega = math.sqrt(N * law.k2 * d_impact ** (N - 1) / (M / 2))
    assert sim.dt <= DT_FRACTION * 2 / omega


def test_huge_adhesion_is_refused_naming_the_eepa_equilibrium_overlap():
    law = _law(f0=-200.0, k1=1e5)
    with pytest.raises(engine.StabilityError, match=r"\(\|f0\|/k1\)\^\(1/n\)"):
        engine.Simulation(pair_scene(law, gap=1e-4))


def _contact(flags, f_el_case):
    """One sliding contact through the EEPA composition's force: (normal force, |F_t|)."""
    d = 1e-5
    dmax = 2e-4 if f_el_case == "plateau" else d
    law = eepa.EEPAParams(K1, K2, F0, 0.0, 2 / 7 * K1, 0.0, 0.5, 0.0, N, 1.0)
    fn, _, ftx, fty, ftz, *_ = laws.composition(eepa.KERNEL).force(
        d,
        1.0,
        0.0,
        0.0,
        0.0,
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        dmax,
        0.0,
        0.0,
        0.0,
        R / 2,
        M / 2,
        law,
        flags,
        1e-3,
    )
    return fn, math.sqrt(ftx * ftx + fty * fty + ftz * ftz)


def test_friction_cap_conventions():
    """On the adhesive plateau (f_hys = f0, kadh = 0) the EEPA cap allows no friction; the
    LIGGGHTS cap mu |F_n| allows mu |f0|."""
    plain = switches_on(eepa.EEPASwitches, "friction", "adhesion", "plastic")
    total = plain._replace(normal_cap=True)
    fn, ft = _contact(plain, "plateau")
    assert fn == pytest.approx(F0) and ft == 0.0
    fn, ft = _contact(total, "plateau")
    assert ft == pytest.approx(0.5 * abs(F0))
    fn, ft = _contact(plain, "loading")  # virgin loading: mu (K1 d^n) against mu |f0 + K1 d^n|
    assert ft == pytest.approx(0.5 * K1 * 1e-5**N)
    fn, ft = _contact(total, "loading")
    assert ft == pytest.approx(0.5 * abs(F0 + K1 * 1e-5**N))


def test_features_and_slots():
    scene = pair_scene(_law(friction_cap="normal"))
    f = kernels.scene_features(scene)
    assert f["pair_kernel"] == "eepa" and f["normal_cap"]
    assert kernels.pair_slots(f)[-2:] == ("n", "chi")
    linear = kernels.scene_features(pair_scene(engine.BilinearAdhesive(k1=5e3, k2=2.5e4)))
    assert linear["pair_kernel"] == "bilinear" and not linear["normal_cap"]  # pays nothing
    assert "n" not in kernels.pair_slots(linear)
    arr = _law().to_array(kernels.pair_slots(f))
    assert arr[-3] == N and arr[-2] == CHI and np.isnan(arr[-1])


@pytest.mark.parametrize(
    "field,value,limit",
    [
        ("n", 0.5, "in [1, 3]"),
        ("chi", 3.5, "in [1, 3]"),
        ("k2", 1e5, ">= k1"),
        ("f0", 0.1, "<= 0"),
        ("friction_cap", "coulomb", "adhesive"),
    ],
)
def test_bad_parameters_name_the_field_and_the_limit(field, value, limit):
    with pytest.raises(engine.ParameterError) as err:
        _law(**{field: value})
    assert f"EEPA.{field}" in str(err.value) and limit in str(err.value)


def test_similarity_rule_exponents():
    sim = engine.ScalingRule.named("similarity")
    assert sim.exponents(_law()) == (2 - N, 2.0, 2 - CHI)
    assert sim.exponents(engine.BilinearAdhesive(k1=5e3, k2=2.5e4)) == (1.0, 2.0, 1.0)
    assert engine.ScalingRule.named("paper").exponents(_law()) == (1.0, 2.0, 1.0)
    own = engine.ScalingRule("mine", stiffness_exponent=0.5, adhesive_exponent=0.0)
    assert own.exponents(_law()) == (0.5, 2.0, 0.0)


@pytest.mark.parametrize("s", [1.5, 2.0])
def test_similarity_scaling_keeps_every_branch_stress_similar(s):
    """The scaled law at s times the overlaps gives s^2 times the forces, on every branch:
    F_s(s d) = s^2 F(d) (overlaps ~ s, forces ~ s^2)."""
    law = _law()
    scaled = law.scaled(s, *engine.ScalingRule.named("similarity").exponents(law))
    path = np.array([1e-4, 2e-4, 1.8e-4, 1.5e-4, 0.6e-4, 0.3e-4, 1.9e-4, 2.5e-4])
    ref = np.empty(path.size)
    big = np.empty(path.size)
    dmax = dmax_s = 0.0
    for i, d in enumerate(path):
        ref[i], _, _, dmax = eepa.eepa_normal_force(
            d, dmax, law.k1, law.k2, law.f0, law.kadh, N, CHI
        )
        big[i], _, _, dmax_s = eepa.eepa_normal_force(
            s * d, dmax_s, scaled.k1, scaled.k2, scaled.f0, scaled.kadh, N, CHI
        )
    np.testing.assert_allclose(big, s * s * ref, rtol=1e-12)
    # the seed's linear rule does not: K ~ s gives s^(1+n) on the loading branch
    lin = law.scaled(s, 1.0, 2.0)
    f_lin, *_ = eepa.eepa_normal_force(s * 1e-4, 0.0, lin.k1, lin.k2, 0.0, 0.0, N, CHI)
    assert f_lin == pytest.approx(s ** (1 + N) * K1 * 1e-4**N)


def test_study_test_and_result_files_accept_the_law(tmp_path):
    ref = engine.preset("quick", pair_law=_law(kadh=0.0, restitution=0.4))
    again = engine.UniaxialTest.from_dict(json.loads(json.dumps(ref.to_dict())))
    assert again == ref and isinstance(again.pair_law, engine.EEPA)
    spec = engine.StudySpec(
        reference=ref,
        coarse_radii=(3.75e-3,),
        rules=(engine.ScalingRule.named("similarity"), engine.ScalingRule.named("paper")),
    )
    assert engine.StudySpec.from_dict(json.loads(json.dumps(spec.to_dict()))) == spec
    runs = {p.key: p for p in engine.plan(spec).runs}
    s = 1.5
    scaled = runs["r3.75mm-similarity-s1"].test.pair_law
    assert scaled.k1 == pytest.approx(K1 * s ** (2 - N)) and scaled.f0 == pytest.approx(-0.4 * s**2)
    assert runs["r3.75mm-paper-s1"].test.pair_law.k1 == pytest.approx(K1 * s)
