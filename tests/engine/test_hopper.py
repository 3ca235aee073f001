"""The hopper test kind (docs/HOPPER.md): validation, scene, measures on synthetic curves, and
the registry. No simulation here (tests/engine/test_hopper_run.py runs small discharges)."""

import math
from dataclasses import replace

import numpy as np
import pytest

import engine
from engine.core.errors import ParameterError
from engine.hopper.measures import (
    binned_stress,
    flow_index,
    hertz_wall_force,
    steady_rate,
    stop_time,
)
from engine.hopper.scene import (
    build_hopper,
    heap_height,
    lattice_fill,
    radii_of,
    wall_bin_areas,
    wall_radius,
)
from engine.hopper.spec import CONE_SIDES, HopperTest, control_test, halved_protocol
from engine.hopper.study import hopper_metric_values, hopper_steps
from engine.study.kinds import kind_for_json, kind_of

R = 2.5e-3
D = 2 * R


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"half_angle": 0.0}, "HopperTest.half_angle"),
        ({"half_angle": 90.0}, "HopperTest.half_angle"),
        ({"half_angle": -5.0}, "HopperTest.half_angle"),
        ({"outlet_width": 2.5 * D}, "HopperTest.outlet_width"),
        ({"outlet_width": 0.0}, "HopperTest.outlet_width"),
        ({"depth": 3 * D}, "HopperTest.depth"),
        ({"shape": "wedge"}, "HopperTest.shape"),
        ({"particles": 10}, "HopperTest.particles"),
        ({"particles": None}, "HopperTest.particles"),  # neither count nor height
        ({"fill_height": 0.05}, "HopperTest.particles"),  # both
        ({"particles": None, "fill_height": 1e-4}, "HopperTest.fill_height"),
        ({"window_start": 0.7, "window_end": 0.6}, "HopperTest.window_start"),
        ({"arch_wait": 1.0}, "HopperTest.arch_wait"),
        ({"wall_bins": 0}, "HopperTest.wall_bins"),
        ({"radius": -1.0}, "HopperTest.radius"),
    ],
)
def test_bad_input_is_refused_naming_the_field(kwargs, field):
    with pytest.raises(ParameterError) as e:
        HopperTest(**kwargs)
    assert e.value.field == field
    assert e.value.limit


def test_outlet_limit_is_in_largest_diameters():
    # 3.2 mean diameters is enough for equal spheres, not with radii up to 1.2 R
    HopperTest(outlet_width=3.2 * D)
    with pytest.raises(ParameterError, match="outlet_width"):
        HopperTest(outlet_width=3.2 * D, polydispersity=0.2)


def test_a_depth_is_not_asked_of_a_cone():
    t = HopperTest(shape="cone", depth=1e-3, outlet_width=6 * D)
    assert t.shape == "cone"


def test_json_round_trip_and_the_registry():
    t = HopperTest(shape="cone", half_angle=20.0, outlet_width=8 * D, particles=300, seed=3)
    assert HopperTest.from_dict(t.to_dict()) == t
    kind = kind_for_json({"type": "HopperTest"})
    assert kind.name == "hopper" and kind_of(t) is kind
    assert kind.from_json(t.to_dict(), "reference") == t
    assert kind.wall_time_limit and kind.checkpoints
    with pytest.raises(ParameterError) as e:
        kind.from_json({**t.to_dict(), "half_angle": 95.0}, "reference")
    assert "half_angle" in e.value.field
    assert set(kind.metrics) == {"discharge_number", "bulk_density"}
    assert all(0 < m.tolerance < 1 and m.reason for m in kind.metrics.values())
    assert hopper_steps(t) > 0


def test_control_and_halved_protocol():
    t = HopperTest(outlet_width=8 * D, depth=10 * D, particles=None, fill_height=0.04)
    c = control_test(t, 2 * R, 1e-5)  # a coarse run of twice the radius
    assert c.outlet_width == pytest.approx(4 * D) and c.depth == pytest.approx(5 * D)
    assert c.fill_height == pytest.approx(0.02) and c.gravity == pytest.approx(2 * t.gravity)
    # the coarse run's hopper in its diameters: as many particles as the coarse run
    coarse = replace(t, radius=2 * R)
    assert c.n_particles == coarse.n_particles < t.n_particles
    assert c.radius == t.radius and c.pair_law == t.pair_law
    # the control's mass rates are s^2 its coarse run's (lengths x s, gravity / s, the mass
    # rate ~ rho g^(1/2) B^(3/2) depth): the discharge number divides it out
    assert c.rate_scale == pytest.approx(t.rate_scale / 4, rel=1e-12)
    cone = HopperTest(shape="cone", outlet_width=8 * D)
    assert control_test(cone, 2 * R, 1e-5).rate_scale == pytest.approx(cone.rate_scale / 4)
    h = halved_protocol(t)
    assert h.dt_fraction == t.dt_fraction / 2 and h.outlet_width == t.outlet_width


def test_particle_count_from_fill_height():
    t = HopperTest(
        half_angle=30.0, outlet_width=8 * D, depth=5 * D, particles=None, fill_height=0.05
    )
    v = t.depth * (t.outlet_width * 0.05 + math.tan(math.radians(30)) * 0.05**2)
    assert t.volume_below(0.05) == pytest.approx(v, rel=1e-12)
    assert t.n_particles == round(0.6 * v / (4 / 3 * math.pi * R**3))
    c = HopperTest(shape="cone", half_angle=30.0, outlet_width=8 * D)
    # a polygon of many sides: near the circular frustum pi h (a^2 + ab + b^2) / 3
    a, b = 4 * D, 4 * D + 0.05 * math.tan(math.radians(30))
    circle = math.pi * 0.05 * (a * a + a * b + b * b) / 3
    assert c.volume_below(0.05) == pytest.approx(circle, rel=0.01)
    assert c.volume_below(0.05) < circle


# ------------------------------------------------------------------ the scene
@pytest.mark.parametrize("shape", ["slot", "cone"])
def test_the_poured_fill_lies_inside_the_walls_without_overlaps(shape):
    t = HopperTest(
        shape=shape, half_angle=25.0, outlet_width=5 * D, particles=400, polydispersity=0.1
    )
    p = lattice_fill(t)
    r = radii_of(t)
    assert p.shape == (400, 3) and r.shape == (400,)
    assert r.min() >= R * 0.9 and r.max() <= R * 1.1
    # no two particles overlap (the largest radii)
    diff = p[:, None, :] - p[None, :, :]
    if shape == "slot":
        diff[..., 1] -= t.depth * np.round(diff[..., 1] / t.depth)  # periodic depth
    dist = np.sqrt((diff**2).sum(-1)) + np.eye(len(p)) * 1e9
    assert dist.min() > 2 * R * 1.1
    # above the gate, and at least a largest radius from the wall normal to it
    assert p[:, 2].min() > R * 1.1
    across = np.abs(p[:, 0]) if shape == "slot" else np.hypot(p[:, 0], p[:, 1])
    inner = wall_radius(t, p[:, 2]) * (math.cos(math.pi / CONE_SIDES) if shape == "cone" else 1)
    gap = (inner - across) * math.cos(math.radians(25.0))
    assert gap.min() > 1.1 * R
    g = build_hopper(t)
    assert g.wall_top > p[:, 2].max() + D and g.gate_stop < -g.catch_depth - D
    # the catch floor lies below the outlet by 20 d + 2 B and a heap of the whole fill
    heap = heap_height(t)
    assert g.catch_depth == pytest.approx(20 * 1.1 * D + 2 * t.outlet_width + heap)
    # the heap holds the fill's solid volume at solid fraction 0.5 with 35-degree slopes
    v = 400 * t.mean_particle_volume / 0.5
    ta = math.tan(math.radians(35.0))
    held = heap**2 / ta * t.depth if shape == "slot" else math.pi * heap**3 / (3 * ta * ta)
    assert held == pytest.approx(v, rel=1e-12)
    assert len(g.scene.meshes) == (3 if shape == "slot" else 2) and g.scene.n == 400
    assert g.gate_mesh == len(g.scene.meshes) - 1 and g.gate_mesh not in g.wall_meshes
    if shape == "slot":
        assert g.scene.periodic == (False, True, False)


def test_wall_bin_areas_add_up_to_the_wall():
    t = HopperTest(half_angle=20.0)
    edges = np.linspace(0.0, 0.04, 5)
    total = 2 * t.depth * 0.04 / math.cos(math.radians(20.0))
    assert wall_bin_areas(t, edges).sum() == pytest.approx(total, rel=1e-12)
    c = HopperTest(shape="cone", half_angle=20.0)
    a = wall_bin_areas(c, edges)
    # the lateral area of the circular frustum, the polygon's a little less
    r0, r1 = 0.5 * c.outlet_width, 0.5 * c.outlet_width + 0.04 * math.tan(math.radians(20))
    circle = math.pi * (r0 + r1) * 0.04 / math.cos(math.radians(20.0))
    assert a.sum() == pytest.approx(circle, rel=0.01) and a.sum() < circle
    assert np.all(np.diff(a) > 0)  # the cone widens upwards


# ------------------------------------------------------------------ measures
def test_steady_rate_recovers_a_known_rate_with_its_error():
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 1.0, 1e-3)
    rate = 0.7
    grain = 1.3e-4
    # whole grains passing at random (Poisson) at 0.7 kg/s from t = 0.05 s, 0.5 kg in all
    counts = rng.poisson(rate * 1e-3 / grain, len(t)) * (t >= 0.05)
    m = np.minimum(np.cumsum(counts) * grain, 0.5)
    s = steady_rate(t, m, 0.5, 0.2, 0.6)
    assert s.rate == pytest.approx(rate, rel=0.02)
    assert 0 < s.se < 0.02 and s.batches == 4
    assert abs(s.rate - rate) < 4 * s.se
    assert s.start == pytest.approx(0.05 + 0.1 / rate, abs=0.02)
    assert s.end == pytest.approx(0.05 + 0.3 / rate, abs=0.02)
    # a flow that stopped before the window's end: no rate
    cut = steady_rate(t, np.minimum(m, 0.25), 0.5, 0.2, 0.6)
    assert math.isnan(cut.rate) and math.isnan(cut.se)
    with pytest.raises(ValueError):
        steady_rate(t, m, 0.5, 0.6, 0.2)


def test_stop_time_finds_an_arch_on_a_synthetic_discharge():
    grain = 1e-4
    t = np.arange(0.0, 2.0, 1e-3)
    # flows at 0.2 kg/s (2,000 grains a second) for 0.3 s, then nothing passes
    m = np.floor(np.minimum(0.2 * t, 0.06) / grain) * grain
    wait = 0.5
    stop = stop_time(t, m, wait, 0.01, grain)
    # found within arch_fraction x wait (5 ms here) before the last grain
    assert 0.3 - 0.01 * wait - 1e-3 <= stop <= 0.3
    # a discharge that goes on to the end of the samples has not stopped
    assert stop_time(t, 0.2 * t, wait, 0.01, grain) is None
    # a trickle of one grain every 0.2 s is still flow at fraction 0 ...
    trickle = np.floor(t / 0.2) * grain
    assert stop_time(t, trickle, wait, 0.0, grain) is None
    # ... but far below 1 % of a 0.2 kg/s flow's: the flow has stopped
    late = stop_time(t, m + np.where(t > 0.3, trickle, 0), wait, 0.01, grain)
    assert 0.3 - 0.01 * wait - 1e-3 <= late <= 0.3
    # nothing ever passed after the opening: stopped at once
    assert stop_time(t, np.zeros_like(t), wait, 0.01, grain, opened=0.1) == pytest.approx(0.1)


def test_flow_index_and_wall_forces():
    assert flow_index([0.0, 0.0], [3, 4], [0.1, 0.2], [2, 2]) == 0.0
    assert flow_index([0.1], [1], [0.2], [1]) == pytest.approx(0.5)
    assert math.isnan(flow_index([0.1], [1], [np.nan], [0]))
    f = hertz_wall_force(np.array([1e-6, -1e-6]), np.array([R, R]), 1e8)
    assert f[0] == pytest.approx(4 / 3 * 1e8 * math.sqrt(R) * 1e-9) and f[1] == 0
    s = binned_stress(
        np.array([0.5, 1.5, 1.6, 5.0]), np.array([1.0, 2.0, 3.0, 9.0]), [0, 1, 2], [2.0, 5.0]
    )
    assert s.tolist() == [0.5, 1.0]


def test_metric_values_of_a_result():
    t = HopperTest()
    res = engine.HopperResult(
        t,
        {},
        np.array([0.0, 1.0]),
        np.zeros(1),
        np.zeros(1),
        {
            "discharge_number": 0.5,
            "bulk_density": 1200.0,
            "mass_flow_index": 0.1,
            "mass_flow": 0.0,
            "arched": 0.0,
        },
    )
    v = hopper_metric_values(res)
    assert v["discharge_number"].tolist() == [0.5] and v["bulk_density"].tolist() == [1200.0]
    assert kind_of(res).name == "hopper" and res.flow_mode == "funnel" and not res.arched


def test_a_hopper_study_is_planned_by_the_study_machinery():
    from engine.study.plan import plan

    ref = HopperTest(outlet_width=8 * D, depth=7 * D, particles=None, fill_height=0.03)
    spec = engine.StudySpec(
        reference=ref,
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        reference_seeds=(1, 2),
        seeds=(1, 2),
    )
    assert spec.tolerances == {"discharge_number": 0.10, "bulk_density": 0.03}
    assert engine.StudySpec.from_dict(spec.to_dict()) == spec
    runs = {r.key: r for r in plan(spec).runs}
    assert {"ref-s1", "half-s1", "r3.1mm-paper-s1", "ctl-r3.1mm-s1"} <= set(runs)
    coarse, ctl = runs["r3.1mm-paper-s1"].test, runs["ctl-r3.1mm-s1"].test
    assert isinstance(coarse, HopperTest) and coarse.radius == 3.1e-3
    assert coarse.outlet_width == ref.outlet_width and coarse.n_particles < ref.n_particles
    assert ctl.radius == ref.radius and ctl.outlet_width == pytest.approx(
        ref.outlet_width * 2.5 / 3.1
    )
    assert ctl.n_particles == coarse.n_particles
    assert runs["half-s1"].test.dt_fraction == ref.dt_fraction / 2
    assert all(r.particle_steps > 0 for r in runs.values())


def test_a_result_is_stored_and_read_back(tmp_path):
    from engine.hopper.results import HOPPER_CURVE_UNITS, load_hopper, save_hopper

    t = HopperTest(shape="cone", outlet_width=7 * D, particles=300, seed=4)
    curves = {k: np.linspace(0.0, 1.0, 5) * (i + 1) for i, k in enumerate(HOPPER_CURVE_UNITS)}
    res = engine.HopperResult(
        t,
        curves,
        np.array([0.0, 0.01, 0.02]),
        np.array([300.0, 100.0]),
        np.array([np.nan, np.nan]),
        {"discharge_rate": 0.25, "arch_time": math.nan, "mass_flow_index": 0.2, "mass_flow": 0.0},
    )
    save_hopper(tmp_path / "run.json", res, seed=4)
    back = load_hopper(tmp_path / "run.json", curves=True)
    assert back.test == t and back.flow_mode == "funnel"
    assert back.scalars["discharge_rate"] == 0.25 and math.isnan(back.scalars["arch_time"])
    assert back.wall_stress_fill.tolist() == [300.0, 100.0]
    assert np.isnan(back.wall_stress_flow).all()
    for k, v in curves.items():
        assert np.array_equal(back.curves[k], v)
    assert load_hopper(tmp_path / "run.json").curves == {}
