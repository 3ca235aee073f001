"""Jenike's critical outlet width (engine/hopper/jenike.py) against a published chart point
and its own limits, and the Jenike series' reader of the stored shear-cell digests.
Pure Python: no kernel is compiled."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine.hopper import jenike


def test_flow_factor_against_jenikes_chart_as_rhodes_reads_it():
    # Rhodes, Introduction to Particle Technology (2nd ed., 2008), ch. 10 worked example:
    # delta = 30 deg, phi_w = 19 deg, conical hopper at 27.5 deg: ff = 1.8 read off
    # Jenike's chart, H(27.5) = 2.46, the mass-flow limit at 30.5 deg.
    ff = jenike.flow_factor(30.0, 19.0, 27.5, "cone")
    assert ff == pytest.approx(1.8, abs=0.06)  # 1.850 here; a chart read to +-0.05
    assert jenike.h_function(27.5, "cone") == pytest.approx(2.46, abs=0.005)
    # the radial field exists up to the chart's mass-flow limit and ends within 2 deg of it
    jenike.radial_stress_field(30.0, 19.0, 30.5, "cone")
    with pytest.raises(engine.ParameterError, match="jenike.theta.*mass-flow region"):
        jenike.radial_stress_field(30.0, 19.0, 32.5, "cone")


def test_radial_field_meets_its_boundary_conditions():
    beta = jenike.wall_stress_angle(50.0, 20.0)
    want = 0.5 * (
        20.0 + math.degrees(math.asin(math.sin(math.radians(20)) / math.sin(math.radians(50))))
    )
    assert beta == pytest.approx(want, rel=1e-12)
    assert jenike.wall_stress_angle(50.0, 0.0) == 0.0  # a smooth wall: sigma_1 along its normal
    f = jenike.radial_stress_field(50.0, 20.0, 30.0, "slot")
    assert f.psi_wall == pytest.approx(90.0 + beta, abs=1e-5)
    assert 0 < f.s_axis < f.s_wall  # the stress grows from the axis to the wall
    # a smooth wall: psi = 90 deg at the wall as on the axis
    assert jenike.radial_stress_field(50.0, 0.0, 30.0, "slot").psi_wall == pytest.approx(
        90.0, abs=1e-5
    )
    # ff from its definition
    k = math.sin(math.radians(50.0))
    ff = (1 + k) * f.s_wall * jenike.h_function(30.0, "slot") / (2 * math.sin(math.radians(30.0)))
    assert jenike.flow_factor(50.0, 20.0, 30.0, "slot") == pytest.approx(ff, rel=1e-12)


def test_h_function_limits():
    assert jenike.h_function(1e-9, "cone") == pytest.approx(2.0)
    assert jenike.h_function(1e-9, "slot") == pytest.approx(1.0)
    assert jenike.h_function(30.0, "slot") == pytest.approx(1.25)


def test_critical_point_of_a_linear_flow_function_is_exact():
    # sigma_c = a + b sigma_1 crosses sigma_1 / ff at sigma_1* = a / (1 / ff - b)
    a, b, ff = 3000.0, 0.3, 1.4
    s1 = np.array([2e3, 8e3, 2e4, 5e4])
    x, c = jenike.critical_point(s1, a + b * s1, ff)
    assert x == pytest.approx(a / (1 / ff - b), rel=1e-12)
    assert c == pytest.approx(x / ff, rel=1e-12)
    assert jenike.critical_outlet_width(c, 1200.0, 9.81, 30.0, "slot") == pytest.approx(
        1.25 * c / (1200.0 * 9.81), rel=1e-12
    )
    with pytest.raises(engine.ParameterError, match="above the stresses measured"):
        low = np.array([1e3, 2e3])  # the flow function still above the line at the last
        jenike.critical_point(low, a + b * low, ff)
    with pytest.raises(engine.ParameterError, match="below the stresses measured"):
        jenike.critical_point(s1[2:] * 100, a + b * s1[2:], ff)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: jenike.flow_factor(90.0, 10.0, 20.0, "slot"), "jenike.delta"),
        (lambda: jenike.flow_factor(40.0, 45.0, 20.0, "slot"), "jenike.phi_w"),
        (lambda: jenike.flow_factor(40.0, 10.0, 0.0, "slot"), "jenike.theta"),
        (lambda: jenike.flow_factor(40.0, 10.0, 20.0, "wedge"), "jenike.shape"),
        (
            lambda: jenike.critical_outlet_width(1e3, -1.0, 9.81, 30.0, "slot"),
            "jenike.bulk_density",
        ),
        (lambda: jenike.critical_outlet_width(1e3, 1e3, 0.0, 30.0, "slot"), "jenike.gravity"),
        (lambda: jenike.critical_point([1e3], [1e3], 1.3), "jenike.flow_function"),
        (lambda: jenike.critical_point([1e3, 2e3], [1e3, 1.5e3], math.nan), "jenike.ff"),
    ],
)
def test_bad_input_names_the_field(call, field):
    with pytest.raises(engine.ParameterError) as e:
        call()
    assert e.value.field == field


def test_the_series_reads_the_stored_shear_digests():
    from benchmarks import jenike_series, size_series
    from engine.io.digest import read_digest

    d = read_digest(size_series.path_of("shear", "bond1", 5.0, 1))
    assert d.kind == "ShearTest" and d.ok and d.test["preshear_stress"] == 10e3
    levels = jenike_series.shear_levels()
    runs = levels[jenike_series.STORED_PRESHEAR]
    assert len(runs) == jenike_series.STORED_SEEDS
    assert runs[0]["sigma_c"] == d.scalars["sigma_c"]  # bit-exact from the digest
    m = jenike_series.level_means({10e3: runs})[10e3]
    assert m["sigma_1"] == pytest.approx(np.mean([r["sigma_1"] for r in runs]), rel=1e-15)
    q = (m["sigma_1"] - m["sigma_2"]) / (m["sigma_1"] + m["sigma_2"])
    assert m["delta"] == pytest.approx(math.degrees(math.asin(q)), rel=1e-12)


def test_the_stored_comparison_brackets_what_the_docs_say():
    # docs/HOPPER.md, "Cohesive arching against Jenike's critical outlet width": read from
    # the stored digests (no run): arched up to 6 d and flowed from 7 d at 400 m/s^2, the
    # prediction above both
    from benchmarks import jenike_series

    out = jenike_series.compare_at(
        "hopper", jenike_series.WIDTHS, jenike_series.HOPPER_SEEDS, jenike_series.GRAVITY
    )
    assert (out["all_arched_up_to_d"], out["all_flowed_from_d"]) == (6.0, 7.0)
    assert out["predicted_d_95"][0] > out["all_flowed_from_d"]
    assert sum(r["runs"] for r in out["rows"]) == len(jenike_series.WIDTHS) * 3


def test_the_second_laws_stored_comparison_brackets_what_the_docs_say():
    # docs/HOPPER.md, "The second law": bond0.5 (f0 = -0.2 N) at 200 m/s^2, read from its
    # stored digests (no run): every seed arched at 4 and 5 d and emptied from 6 d, Jenike's
    # prediction (from its own 12 shear points) above both, its runs the law's own
    from benchmarks import jenike_series as J

    se = J.SERIES["bond0.5"]
    g, widths, seeds = se.hoppers["hopper"]
    out = J.compare_at("hopper", widths, seeds, g, "bond0.5")
    assert (out["all_arched_up_to_d"], out["all_flowed_from_d"]) == (5.0, 6.0)
    assert out["predicted_d_95"][0] > out["all_flowed_from_d"]
    assert sum(r["runs"] - r["failed"] for r in out["rows"]) == len(widths) * seeds
    d = J.stored("hopper", 6.0, 1, law="bond0.5")
    assert d.test["pair_law"]["f0"] == se.f0 == -0.2 and d.test["gravity"] == g
    levels = J.shear_levels(law="bond0.5")
    assert sorted(levels) == sorted(se.preshears) and all(len(v) == 3 for v in levels.values())
