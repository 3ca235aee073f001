"""The simulated Jenike-type shear test (engine.shear, docs/SHEAR.md): its record's refusals,
the Mohr-circle construction against hand-computed numbers, driven (glued) grains against
closed forms, the normal-stress servo on an elastic bed, and whole tests of a cohesionless
and a cohesive bed in a cell a few grains across (seconds each)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine.shear.driver import SERVO_STEPS, SMOOTHING_STRAIN, _peak, _Shear, _smoothed
from engine.shear.locus import (
    consolidation_circle,
    fit_line,
    unconfined_yield_strength,
    yield_locus,
)

from .helpers import whole_run_fixtures

#: The cohesive law of tests/engine/test_uniaxial.py's cohesive bed (pull-off 0.4 N, about
#: the contact force sigma d^2 = 0.25 N at the pre-shear stress of 10 kPa).
COHESIVE = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001)
#: Student's t, two-sided 95 %, two degrees of freedom (a line through four points).
T_975_2DOF = 4.303


def tiny(**kw) -> engine.ShearTest:
    """About 120 grains in a 30 x 15 x 30 mm cell (6 x 3 x 6 diameters): seconds per test.
    Sheared at the inertial number 2e-3 (twice the default) to keep it short."""
    base = {
        "cell": (0.03, 0.015, 0.03),
        "normal_stresses": (2e3, 4e3, 6e3, 8e3),
        "inertial_number": 2e-3,
        "max_stage_time": 2.0,
    }
    return engine.ShearTest(**{**base, **kw})


# ---------------------------------------------------------------------- the record
def test_the_record_refuses_what_gives_no_yield_locus_naming_the_field():
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.normal_stresses\[1\]"):
        engine.ShearTest(preshear_stress=5e3, normal_stresses=(2e3, 5e3))
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.normal_stresses\[0\]"):
        engine.ShearTest(normal_stresses=(-1.0, 5e3))
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.normal_stresses = "):
        engine.ShearTest(normal_stresses=(5e3,))
    with pytest.raises(engine.ParameterError, match="two different"):
        engine.ShearTest(normal_stresses=(5e3, 5e3))
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.preshear_stress"):
        engine.ShearTest(preshear_stress=-1.0)
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.steady_window"):
        engine.ShearTest(preshear_min_strain=0.1, preshear_strain=0.3, steady_window=0.2)
    # the consolidation test's checks come back under this record's names
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.cell"):
        engine.ShearTest(cell=(0.01, 0.05, 0.05))
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.pair_law\.f0"):
        engine.ShearTest(pair_law=engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-50.0))
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.cell"):
        engine.ShearTest(cell=(0.05, 0.05, 0.015), platen_layer=1.0)


def test_the_record_round_trips_through_json():
    t = tiny(pair_law=COHESIVE)
    assert engine.ShearTest.from_dict(t.to_dict()) == t
    c = t.consolidation_test()
    assert c.pre_stress == t.preshear_stress and c.gravity_off_after_fill
    assert c.cell == t.cell and c.pair_law == t.pair_law and c.seed == t.seed


# ---------------------------------------------------------------------- the construction
def test_the_mohr_circles_match_hand_computed_numbers():
    # a locus through the origin at tan(phi) = 0.5 and the pre-shear point (10, 4.5) kPa
    # below it: (10 - p)^2 + 4.5^2 = (p sin phi)^2, sin^2 phi = 0.2, so
    # 0.8 p^2 - 20 p + 120.25 = 0 and the smaller root p = (20 - sqrt(15.2)) / 1.6
    p, r, above = consolidation_circle(0.0, 0.5, 10e3, 4.5e3)
    p_hand = (20 - math.sqrt(15.2)) / 1.6 * 1e3
    assert p == pytest.approx(p_hand, rel=1e-12)
    assert r == pytest.approx(p_hand / math.sqrt(5), rel=1e-12)
    assert above == 0.0
    # the tangent point p - r sin(phi) lies left of the pre-shear point (the locus ends there)
    assert p - r / math.sqrt(5) <= 10e3
    # a cohesionless locus: sigma_c = 0, ffc infinite, and the effective angle is phi itself
    loc = yield_locus([2e3, 6e3], [1e3, 3e3], 10e3, 4.5e3)
    assert loc.cohesion == pytest.approx(0.0, abs=1e-9) and loc.sigma_c == 0.0
    assert loc.ffc == math.inf
    assert loc.effective_friction_angle == pytest.approx(math.degrees(math.atan(0.5)))
    assert loc.sigma_1 == pytest.approx(p_hand + p_hand / math.sqrt(5), rel=1e-9)
    # sigma_c = 2 c (1 + sin phi) / cos phi = 2 c tan(45 + phi / 2): c = 1 kPa, phi = 30 deg
    assert unconfined_yield_strength(1e3, math.tan(math.radians(30))) == pytest.approx(
        2e3 * math.sqrt(3), rel=1e-12
    )
    assert unconfined_yield_strength(-10.0, 0.5) == 0.0


def test_the_consolidation_circle_is_continuous_across_the_locus():
    # the pre-shear point on the locus: the circle is tangent there, p = s + t tan(phi),
    # r = t / cos(phi); just below and just above it both branches give about that circle
    # (below, the two circles split as the square root of the distance: 1e-9 Pa below
    # moves p by about 1e-3 Pa)
    c, m, s = 500.0, 0.6, 10e3
    t = c + m * s
    p0, r0 = s + t * m, t / math.cos(math.atan(m))
    for dt in (-1e-9, 0.0, 1e-9):
        p, r, above = consolidation_circle(c, m, s, t + dt)
        assert p == pytest.approx(p0, rel=1e-5) and r == pytest.approx(r0, rel=1e-5)
        assert above == pytest.approx(max(dt, 0.0), abs=1e-9)
    # a point well above: reported how far, circle tangent to the parallel line through it
    p, r, above = consolidation_circle(c, m, s, t + 300.0)
    assert above == pytest.approx(300.0)
    assert (s - p) ** 2 + (t + 300.0) ** 2 == pytest.approx(r * r, rel=1e-12)


def test_the_line_fit_and_its_refusals():
    c, m, se_c, se_m = fit_line([1e3, 2e3, 3e3], [700.0, 1200.0, 1700.0])
    assert (c, m) == (pytest.approx(200.0), pytest.approx(0.5))
    assert se_c == pytest.approx(0.0, abs=1e-9) and se_m == pytest.approx(0.0, abs=1e-12)
    c, m, se_c, se_m = fit_line([1e3, 2e3, 3e3], [700.0, 1300.0, 1700.0])
    # residuals (-1/3, 2/3, -1/3) x 100 Pa: s^2 = (2/3) 1e4 / 1, Sxx = 2e6
    assert se_m == pytest.approx(math.sqrt(2e4 / 3 / 2e6), rel=1e-9)
    with pytest.raises(ValueError, match="two different"):
        fit_line([1e3, 1e3], [1.0, 2.0])
    with pytest.raises(ValueError, match="not > 0"):
        yield_locus([1e3, 2e3], [900.0, 800.0], 10e3, 5e3)
    # the helper's wet-bead run: cohesion 3922 Pa, tan(phi) 0.281, pre-shear point (1959,
    # 2482) Pa far below the locus: the circle would be centred at p < 0 (was a bare "math
    # domain error" from asin)
    sig = [500.0, 1000.0, 1500.0]
    with pytest.raises(ValueError, match="no consolidation circle.*centred at p = -"):
        yield_locus(sig, [3922.0 + 0.281 * x for x in sig], 1959.0, 2482.0)


# ---------------------------------------------------------------------- driven grains
def test_a_glued_grain_slides_over_another_at_the_coulomb_limit():
    """Two driven grains, the upper moved along x over the lower at a fixed height: it keeps
    its velocity exactly, and once the tangential spring has reached the cap the tangential
    force is mu_s times the elastic normal force k1 delta (k2 = k1: elastic), the force on
    each equal and opposite."""
    r, k1 = 1e-3, 1e3
    law = engine.BilinearAdhesive(k1=k1, k2=k1, mu_s=0.4, mu_r=0.0)
    pos = [(0.0, 0.0, 0.0), (0.0, 0.0, 2 * r - 2e-5)]
    scene = engine.Scene(pos, r, 2500.0, gravity=(0, 0, 0), pair_law=law)
    sim = engine.Simulation(scene, dt=1e-6)
    v = 0.01
    sim.set_driven([0], (0.0, 0.0, 0.0))
    sim.set_driven([1], (v, 0.0, 0.0))
    x1 = sim.positions[1, 0]
    ratios = []
    for _ in range(100):
        sim.run(50)
        c = sim.contacts()
        f, n, d = c.forces[0], c.normals[0], c.overlaps[0]
        ft = f - np.dot(f, n) * n
        ratios.append(np.linalg.norm(ft) / (k1 * d))
        assert np.allclose(sim.forces[0], -sim.forces[1], rtol=1e-12, atol=1e-15)
    assert sim.velocities[1].tolist() == [v, 0.0, 0.0]
    assert sim.angular_velocities.tolist() == [[0.0] * 3] * 2
    assert sim.positions[1, 0] == pytest.approx(x1 + v * sim.time, rel=1e-9)
    # the spring loads, kt v t with kt = 2/7 k1, until it reaches mu_s k1 delta = 8e-3 N
    # at t = 2.8e-3 s, then slides (the run lasts 5e-3 s; the gap's change, (v t)^2 / 4R,
    # is 3 % of the overlap at its end)
    assert ratios[0] < 0.4
    assert ratios[-1] == pytest.approx(0.4, rel=1e-9)


def test_driven_grains_refuse_bad_ids_and_leave_the_kinetic_energy_finite():
    # the previous test's kind of scene (no walls, no gravity, no rolling): one kernel
    law = engine.BilinearAdhesive(k1=1e3, k2=1e3, mu_s=0.4, mu_r=0.0)
    pos = [(0.0, 0.0, 0.0), (0.01, 0.0, 0.0)]
    scene = engine.Scene(pos, 1e-3, 2500.0, gravity=(0, 0, 0), pair_law=law)
    sim = engine.Simulation(scene, dt=1e-6)
    with pytest.raises(engine.ParameterError, match="set_driven.ids"):
        sim.set_driven([2], (0, 0, 0))
    with pytest.raises(engine.ParameterError, match="set_driven.velocity"):
        sim.set_driven([0], (0, 0, math.nan))
    sim.set_driven([0], (1.0, 0.0, 0.0))
    m = sim.masses[0]
    assert sim.kinetic_energy() == pytest.approx(0.5 * m)
    sim.run(10)  # out of contact: the driven grain moves, the free one stays
    assert sim.velocities.tolist() == [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    assert sim.positions[0, 0] == pytest.approx(10 * 1e-6 * 1.0, rel=1e-12)


# ---------------------------------------------------------------------- the servo
def test_the_servo_holds_the_normal_stress_on_an_elastic_bed():
    """Hertz-Mindlin grains (elastic) consolidated to 10 kPa, the lid glued, its servo
    asked for 4 kPa without shear: after ten relaxation times the mean normal stress over
    the next ten is within 1 % of the target (a PI servo on a static elastic bed has no
    steady error; 1 % is the mean of readings scattered by the bed's stress waves), the
    base carries the same stress within 1 % (no gravity, no wall: the bed's force balance)
    and the lid has come to rest (its speed below 1 % of the servo's limit)."""
    law = engine.HertzMindlin(E=5e7, nu=0.25, restitution=0.4, mu=0.5)
    t = tiny(pair_law=law)
    sh = _Shear(t, None)
    cell = sh.glue(sh.consolidate())
    relax = cell.servo["relaxation_time"]
    steps = round(10 * relax / cell.sim.dt)
    target = 4e3
    cell.advance(steps, target)
    means, _ = cell.advance(steps, target)
    assert abs(means[1] - target) < 0.01 * target
    assert abs(means[3] - means[1]) < 0.01 * target
    assert abs(cell.vz) < 0.01 * cell.servo["max_speed"]
    assert SERVO_STEPS * cell.sim.dt < relax / 4


def test_the_servo_guard_tames_a_gain_far_too_high():
    """The same bed with the servo's gain made 64 times its design value: the lid swings
    between its speed limits, the guard halves the gain until it stops (at least once), and
    the normal stress then settles within 1 % of the target as in the test above."""
    law = engine.HertzMindlin(E=5e7, nu=0.25, restitution=0.4, mu=0.5)
    sh = _Shear(tiny(pair_law=law), None)
    cell = sh.glue(sh.consolidate())
    g0 = cell.servo["gain"]
    steps = round(10 * cell.servo["relaxation_time"] / cell.sim.dt)
    cell.servo["gain"] = 64 * g0
    cell.advance(steps, 4e3)
    means, _ = cell.advance(steps, 4e3)
    assert cell.servo["halvings"] >= 1 and cell.servo["gain"] < 64 * g0
    assert abs(means[1] - 4e3) < 0.01 * 4e3


# ---------------------------------------------------------------------- whole tests
cohesionless, cohesive = whole_run_fixtures(engine.run_shear, tiny, COHESIVE)


def test_a_shear_test_gives_its_locus_curves_and_progress(cohesionless):
    res, seen = cohesionless
    t = res.test
    names = ["preshear"] + [
        f"point{k}_{s}" for k in range(4) for s in ("reverse", "normal", "shear")
    ]
    assert list(res.stages) == names
    assert list(res.consolidation) == ["fill", "pre_compression"]
    for st in res.stages.values():
        for k, v in st.curves.items():
            assert np.all(np.isfinite(v)), k
    # the lid was reversed to zero shear stress before each point's normal stress was set
    for k in range(4):
        assert res.stages[f"point{k}_reverse"].curves["shear_stress"][-1] <= 0.1 * t.preshear_stress
    pts = res.yield_points()
    assert pts[0]["kind"] == "preshear" and len(pts) == 5
    # every point failed at a peak, at its normal stress within 5 % (the servo's lag while
    # the bed dilates at the peak), below the pre-shear point's shear stress within the
    # scatter of its readings: in a cell 3
    # diameters deep these scatter by about 20 % (two standard deviations of the steady
    # window's readings), and the highest point (0.8 of the pre-shear's normal stress, a
    # dilatant peak at tau / sigma near 0.6 against the steady 0.4) can lie above their mean
    # (4.66 kPa against 3.98 on one CPU, below on another: the last bits differ)
    pre = res.stages["preshear"].curves
    window = pre["shear_strain"] >= pre["shear_strain"][-1] - t.steady_window
    scatter = 2.0 * float(np.std(pre["shear_stress"][window]))
    for p in res.points:
        assert p.peaked
        assert abs(p.sigma - p.target) < 0.05 * p.target
        assert 0 < p.tau < res.scalars["preshear_tau"] + scatter
    # progress never goes back and reaches the last shear stage
    fractions = [f for _, f in seen]
    assert fractions == sorted(fractions) and 0 <= fractions[0] and fractions[-1] <= 1
    assert seen[-1][0] == "point3_shear"
    assert res.scalars["sigma_1"] > res.scalars["preshear_sigma"]
    assert res.scalars["bulk_density"] < t.density


def test_the_pre_shear_is_steady_and_the_bed_in_force_balance(cohesionless):
    """Over the last steady window the bed's mean x-velocity does not change, so the mean
    shear forces of the lid and of the base balance: within 5 % of the shear stress (the
    window's means of readings that scatter by tens of per cent); the lid held the
    pre-shear stress within servo_tolerance (the stage's criterion)."""
    res, _ = cohesionless
    t = res.test
    c = res.stages["preshear"].curves
    last = c["shear_strain"] >= c["shear_strain"][-1] - t.steady_window
    tau, tau_b = c["shear_stress"][last].mean(), c["shear_stress_base"][last].mean()
    assert abs(tau - tau_b) < 0.05 * tau
    assert res.scalars["preshear_drift"] < t.steady_tolerance
    assert abs(res.scalars["preshear_sigma"] - t.preshear_stress) < (
        t.servo_tolerance * t.preshear_stress
    )


def test_a_cohesionless_bed_has_no_cohesion_and_a_friction_angle_of_grains(cohesionless):
    """A cohesionless bed's locus passes through the origin: c = 0 is not rejected at 95 %
    by the fit of its four points (|c| < t(0.975, 2 dof) = 4.303 standard errors); its
    angle of internal friction lies between 15 deg (frictionless spheres reach about 6 deg,
    Peyneau and Roux 2008; with mu_s = 0.5 the grains' sliding adds to it) and 45 deg."""
    res, _ = cohesionless
    s = res.scalars
    assert s["cohesion_se"] > 0
    assert abs(s["cohesion"]) < T_975_2DOF * s["cohesion_se"]
    assert 15 < s["friction_angle"] < 45
    assert 15 < s["effective_friction_angle"] < 45


def test_adhesion_gives_cohesion_and_a_lower_flowability(cohesive):
    """Pull-off forces of 0.4 N (about the contact force at the pre-shear stress) give the
    bed a cohesion, and so an unconfined yield strength: c above 10 % of the pre-shear
    stress and significantly above zero (over t(0.975, 2 dof) standard errors), ffc finite
    and below 10 (not free flowing: Jenike's classes, among which ffc < 1, "not flowing",
    is one), phi_e above phi (a locus with an intercept)."""
    s = cohesive.scalars
    assert s["cohesion"] > 0.1 * cohesive.test.preshear_stress
    assert s["cohesion"] > T_975_2DOF * s["cohesion_se"]
    assert s["sigma_c"] > 0 and s["sigma_1"] > cohesive.test.preshear_stress
    assert 0 < s["ffc"] < 10
    assert s["effective_friction_angle"] > s["friction_angle"]


def test_a_non_finite_curve_is_refused_naming_it(monkeypatch):
    """A curve with a NaN is never returned: the stage raises FloatingPointError naming the
    stage and the curve (here the free grains' kinetic energy made NaN on purpose)."""
    from engine.shear import driver

    monkeypatch.setattr(driver._Cell, "kinetic_energy", lambda self: math.nan)
    with pytest.raises(FloatingPointError, match="preshear: non-finite values in the kinetic"):
        engine.run_shear(tiny())


def test_a_result_has_a_json_form(cohesionless):
    import json

    res, _ = cohesionless
    d = json.loads(json.dumps(res.to_dict()))
    assert engine.ShearTest.from_dict(d["test"]) == res.test
    assert [p["kind"] for p in d["points"]] == ["preshear"] + ["failure"] * 4
    assert d["locus"]["sigma_1"] == res.locus.sigma_1


def test_an_eepa_bed_gives_a_yield_locus():
    """The non-linear EEPA law (n = 1.5, pull-off 0.1 N): every point peaked at its normal
    stress within 5 % (its servo gain from n K2 / K1; an EEPA bed's servo once failed to
    settle here) and the bed has a cohesion significantly above zero."""
    law = engine.EEPA(k1=5e5, k2=2.5e6, f0=-0.1, n=1.5, chi=1.5)
    res = engine.run_shear(tiny(pair_law=law))
    for p in res.points:
        assert p.peaked and abs(p.sigma - p.target) < 0.05 * p.target
    s = res.scalars
    assert s["cohesion"] > T_975_2DOF * s["cohesion_se"] > 0


#: The shear stress [Pa] of size series shear/bond1/d20-s2's point at 4 kPa, its 48 curve
#: samples (0.905 ms apart, shear strain rate 0.283 / s) before the drop criterion stopped it
D20_S2_POINT1 = [
    -1060,
    256,
    282,
    365,
    440,
    472,
    521,
    577,
    624,
    688,
    766,
    863,
    974,
    1079,
    1186,
    1287,
    1374,
    1446,
    1466,
    1463,
    1430,
    1372,
    1300,
    1216,
    1123,
    1027,
    933,
    841,
    754,
    675,
    605,
    545,
    494,
    450,
    411,
    378,
    354,
    339,
    333,
    335,
    349,
    383,
    440,
    518,
    624,
    771,
    980,
    1263,
]


def test_a_shear_to_failure_s_start_up_ringing_is_no_peak():
    """The lid's start rang a 20-diameter cell (servo relaxation time 21.8 ms): up to 1.47
    kPa at 0.5 % strain and down to 0.33 kPa at 1 %, which the drop criterion took for
    failure (a yield point of 1.47 kPa at 4 kPa, where its neighbours' were near 7 kPa).
    Sought after three relaxation times, the ringing ends nothing, and the peak of a curve
    that goes on to yield is the later one."""
    relax, dt, rate = 0.0218, 0.905e-3, 0.283
    tau = np.array(D20_S2_POINT1, dtype=float)
    time = dt * np.arange(tau.size)
    strain = rate * time
    sm = _smoothed(strain, tau, SMOOTHING_STRAIN)
    i, dropped = _peak(time, strain, sm, 0.0, 0.05)
    assert dropped and strain[i] < 0.01  # the criterion without the wait: what the run did
    i, dropped = _peak(time, strain, sm, 3 * relax, 0.05)
    assert not dropped
    # the curve goes on: the bed yields at 7 kPa at 6 % strain, then softens
    t2 = time[-1] + dt * np.arange(1, 400)
    g2 = rate * t2
    more = 1263 + (7000 - 1263) * np.sin(0.5 * np.pi * np.clip((g2 - g2[0]) / (0.06 - g2[0]), 0, 1))
    more -= 2e4 * np.clip(g2 - 0.06, 0, None)
    time, strain, tau = np.r_[time, t2], np.r_[strain, g2], np.r_[tau, more]
    sm = _smoothed(strain, tau, SMOOTHING_STRAIN)
    i, dropped = _peak(time, strain, sm, 3 * relax, 0.05)
    assert dropped and 0.05 < strain[i] < 0.07 and tau[i] > 6.5e3
    assert strain[-1] - strain[i] >= SMOOTHING_STRAIN


# ---------------------------------------------------------------------- checkpoints
class Killed(Exception):
    """Stands for the process dying: raised from the progress callback."""


def test_a_shear_run_killed_and_resumed_gives_the_same_result(tmp_path, cohesive):
    """Killed after a checkpoint written within the fill, right after the fill's own
    checkpoint, and within the pre-compression, the pre-shear, a point's reversal, a
    point's normal stage and the last shear to failure, resumed each time from the file: the
    curves of every stage byte for byte, the points and the scalars (but the wall time)
    those of the run never interrupted. (Each attempt writes at every sample of the stage
    it is killed in, and nowhere else but the fill's end: a write at every sample of the
    whole run, each flushed to disk, cost the test twice the run.)"""
    from engine.uniaxial.checkpoint import Checkpoint

    class InStage(Checkpoint):
        """Writes at every sample of the stage ``target``, nowhere else."""

        target, stage_now = "", ""

        def due(self, driver) -> bool:
            if self.stage_now != self.target:
                return False
            self.save(driver)
            return True

    path = tmp_path / "shear.ckpt"
    test = tiny(pair_law=COHESIVE)
    kills = [
        ("fill", True),
        ("pre_compression", False),  # at its first sample: the fill's checkpoint the last
        ("pre_compression", True),
        ("preshear", True),
        ("point0_reverse", True),
        ("point1_normal", True),
        ("point3_shear", True),
    ]
    killed_in, resumed = [], []
    for where, within in kills:
        ck = InStage(path, interval=1e-12)
        ck.target = where
        first = {}

        def stop(p, ck=ck, where=where, within=within, first=first):
            ck.stage_now = p.stage
            if p.message.startswith("resumed"):
                resumed.append((p.stage, p.fraction))
            if p.stage == where:
                first.setdefault("writes", ck.writes)
                if ck.writes > first["writes"] or not within:
                    killed_in.append(p.stage)
                    raise Killed()

        with pytest.raises(Killed):
            engine.run_shear(test, progress=stop, checkpoint=ck)
    assert killed_in == [w for w, _ in kills]
    # each resumed run says so first, in the stage it goes on with, and its progress
    # never goes back past the one reported before the kill
    assert [s for s, _ in resumed] == [
        "fill",
        "fill",
        "pre_compression",
        "preshear",
        "point0_reverse",
        "point1_normal",
    ]
    fractions = [f for _, f in resumed]
    assert fractions == sorted(fractions) and fractions[-1] > 0.3
    last = Checkpoint(path, interval=1e9)
    res = engine.run_shear(test, checkpoint=last)
    assert last.resumed_steps is not None and last.resumed_steps > 0
    want = cohesive
    for got_stages, want_stages in (
        (res.consolidation, want.consolidation),
        (res.stages, want.stages),
    ):
        assert list(got_stages) == list(want_stages)
        for name, st in want_stages.items():
            assert got_stages[name].steps == st.steps, name
            for k, v in st.curves.items():
                assert got_stages[name].curves[k].tobytes() == v.tobytes(), f"{name}.{k}"
    assert res.points == want.points
    for k, v in want.scalars.items():
        if k != "wall_time":
            assert res.scalars[k] == v, k
    assert path.exists()  # left for the caller, who stores the result first
