"""The similarity of the equations of motion tested as what it is, a change of units
(docs/PHYSICS.md section 5.1; issue 50 item 1): a small cohesive test and the same test at
factors 4 and 16 (cell, radii, gravity, stiffnesses, adhesion, time constants and output
intervals scaled by the similarity's units, engine.core.similarity) run the same trajectory
and give the same metrics. Powers of two scale floating-point numbers exactly, so any
difference is a constant of the code fixed in seconds, metres or metres per second (or a
field the transform missed): the curves are compared bit for bit after the change of units.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import engine
from engine.core.errors import ParameterError
from engine.core.similarity import similar, unit_exponent
from engine.study.metrics import metric_values

LAW = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4)

#: Unit of each curve and the power of s it scales with.
CURVE_POWERS = {"m": 1, "s": 1, "Pa": 0, "1": 0, "J": 3, "": 0}


@pytest.mark.parametrize(
    "unit, exponent",
    [
        ("m", 1),
        ("s", 1),
        ("m/s", 0),
        ("m/s^2", -1),
        ("N", 2),
        ("N/m", 1),
        ("Pa", 0),
        ("kg/m^3", 0),
        ("1", 0),
        ("J", 3),
        ("N*m", 3),
    ],
)
def test_unit_exponents(unit, exponent):
    assert unit_exponent(unit) == exponent


def test_a_unit_it_cannot_read_is_refused_naming_the_field():
    with pytest.raises(ParameterError, match=r"Thing\.width"):
        unit_exponent("furlong", owner="Thing.width")
    with pytest.raises(ParameterError, match="exponent"):
        unit_exponent("N/m^q", owner="Law.k")


@pytest.mark.parametrize(
    "law",
    [
        LAW,
        engine.EEPA(k1=2e4, k2=1e5, f0=-0.3, kadh=3e3, n=1.5, chi=1.5),
        engine.EEPA(k1=2e4, k2=1e5, f0=-0.3, kadh=3e3, n=1.2, chi=2.0),
    ],
)
def test_the_units_give_each_laws_own_similarity_rule(law):
    # K ~ s^(2-n), kadh ~ s^(2-chi), f0 ~ s^2: the law's declared rule and the units agree
    for s in (0.25, 3.0, 16.0):
        a, b, c = law.similarity_exponents()
        want = law.scaled(s, a, b, c)
        got = similar(law, s)
        for k in ("k1", "k2", "kadh", "f0"):
            assert math.isclose(getattr(got, k), getattr(want, k), rel_tol=1e-14), k


def test_similar_scales_every_dimensional_field_of_a_test():
    t = engine.UniaxialTest(pair_law=LAW, dt=2e-5)
    u = similar(t, 4.0)
    assert u.cell == tuple(4 * c for c in t.cell)
    assert u.radius == 4 * t.radius and u.gravity == t.gravity / 4
    assert u.dt == 4 * t.dt and u.output_interval == 4 * t.output_interval
    assert u.release_time == 4 * t.release_time and u.max_stage_time == 4 * t.max_stage_time
    assert similar(replace(t, hold_time=0.01), 4.0).hold_time == 0.04
    # velocities, stresses, densities and dimensionless fields are unchanged
    for k in ("platen_speed", "max_platen_speed", "pour_speed", "pre_stress", "density"):
        assert getattr(u, k) == getattr(t, k), k
    assert u.pair_law.k1 == 4 * LAW.k1 and u.pair_law.f0 == 16 * LAW.f0
    assert u.wall_law == t.wall_law and u.wall_material == t.wall_material
    with pytest.raises(ParameterError, match="similar.s"):
        similar(t, -1.0)


def _tiny() -> engine.UniaxialTest:
    # 3.5 x 3.5 x 10.5 diameters (about 140 particles): the whole test, cohesive, with a
    # hold stage before the unloading (its time in seconds, its rest in joules). Its time
    # step is given (the automatic one, 0.4 of the critical time), so that it scales exactly:
    # the automatic step's Hertz limit takes fractional powers, exact to round-off only
    # (test_the_automatic_time_step_follows_the_similarity)
    d = 2 * 2.5e-3
    t = engine.UniaxialTest(
        cell=(3.5 * d, 3.5 * d, 10.5 * d),
        pair_law=LAW,
        seed=3,
        max_unconfined_strain=0.04,
        hold_time=4e-3,
        hold_quiet=6e-3,  # longer than hold_time: the window binds (the start is loud)
    )
    return replace(t, dt=t.resolved_dt())


@pytest.mark.parametrize("s", [0.1, 4.0, 16.0, 10.0])
def test_the_automatic_time_step_follows_the_similarity(s):
    d = 2 * 2.5e-3
    t = engine.UniaxialTest(cell=(3.5 * d, 3.5 * d, 10.5 * d), pair_law=LAW)
    a, b = t.time_step(), similar(t, s).time_step()
    assert math.isclose(b.dt, s * a.dt, rel_tol=1e-13)
    assert (b.reason, b.kind) == (a.reason, a.kind)


@pytest.fixture(scope="module")
def runs():
    base = _tiny()
    return {s: engine.run_uniaxial(similar(base, float(s))) for s in (1, 4, 16)}


@pytest.mark.parametrize("s", [4, 16])
def test_a_whole_test_in_other_units_is_the_same_run_bit_for_bit(runs, s):
    a, b = runs[1], runs[s]
    assert list(a.stages) == list(b.stages) and "hold" in a.stages
    for stage, ra in a.stages.items():
        rb = b.stages[stage]
        assert ra.steps == rb.steps, stage
        for name, unit in engine.uniaxial.results.CURVE_UNITS.items():
            p = CURVE_POWERS[unit]
            np.testing.assert_array_equal(rb.curves[name], ra.curves[name] * s**p, err_msg=name)
        np.testing.assert_array_equal(rb.positions, ra.positions * s, err_msg=stage)
    # and so the same metrics, every one the study judges
    va, vb = metric_values(a), metric_values(b)
    assert va.keys() == vb.keys()
    for k in va:
        assert np.all(np.asarray(va[k]) == np.asarray(vb[k])), k


def test_a_constant_in_seconds_breaks_it(runs):
    # the same comparison fails when one time constant is left in seconds: the release's
    # bound (release_time) not scaled. What the bit-for-bit test above would catch in code.
    base = _tiny()
    broken = replace(similar(base, 16.0), release_time=base.release_time)
    b = engine.run_uniaxial(broken)
    a = runs[1]
    differs = any(
        not np.array_equal(b.stages[k].curves["time"], a.stages[k].curves["time"] * 16)
        for k in a.stages
    )
    assert differs
