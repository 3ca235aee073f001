"""The run protocol (docs/PROTOCOL.md, docs/PHYSICS.md sections 4 and 6): the time step as a
stated fraction of the critical time of the stiffest contact, the platen speed that holds a
stated inertial number, the halved protocol, the interior virial strength and the seed's
protocol kept one option away."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

import engine
from engine.contact.hertz import hertz_damping_factor, hertz_impact_overlap
from engine.contact.limits import damping_ratio
from engine.simulation.packing import sphere_volume
from engine.uniaxial.driver import stages_of
from engine.uniaxial.measures import (
    SAMPLES_PER_WINDOW,
    SHEAR_BAND_DIAMETERS,
    held_inertial_numbers,
    interior_axial_stress,
    loading_speed,
    stress_floor,
)
from engine.uniaxial.spec import SEED_PROTOCOL, halved_protocol

from .test_uniaxial import COHESIVE, tiny

ROOT = Path(__file__).resolve().parents[2]
R = 2.5e-3


def _oscillator(k: float, m: float, zeta: float) -> float:
    w = math.sqrt(k / m)
    return 2.0 / w * (math.sqrt(1 + zeta * zeta) - zeta)


def test_the_step_is_a_fraction_of_the_pair_unloading_limit_when_the_pour_is_slow():
    # a pour capped at 0.1 m/s: the platen Hertz contact at that impact is softer than the
    # pair unloading branch K2, whose damped-oscillator limit (lightest pair, the damping of
    # K1 seen by K2) is then the critical time
    t = tiny(pair_law=COHESIVE, dt=None, dt_fraction=0.3, pour_speed=0.1)
    ts = t.time_step()
    m = 2000.0 * sphere_volume(R)
    zeta = damping_ratio(0.4) * math.sqrt(COHESIVE.k1 / COHESIVE.k2)
    assert ts.kind == "pair"
    assert ts.critical == pytest.approx(_oscillator(COHESIVE.k2, m / 2, zeta), rel=1e-12)
    assert ts.dt == pytest.approx(0.3 * ts.critical, rel=1e-12) and t.resolved_dt() == ts.dt
    assert ts.impact_speed == pytest.approx(0.1 + t.gravity * t.output_interval)


def test_the_step_is_a_fraction_of_the_platen_hertz_limit_at_the_free_fall_speed():
    # a free fall from the pour column hits the platen at sqrt(2 g H_pour): the Hertz
    # stiffness at the overlap of that impact, 2 E* sqrt(R d_max), is the stiffest contact
    t = engine.preset("paper", dt=None, dt_fraction=0.25, pour_speed=None)
    ts = t.time_step()
    v = math.sqrt(2 * t.gravity * t.pour_height)
    e_star = 1 / ((1 - 0.25**2) / 1e8 + (1 - 0.3**2) / 2e11)
    m = 2000.0 * sphere_volume(R)
    d = hertz_impact_overlap(m, R, e_star, v)
    limit = _oscillator(2 * e_star * math.sqrt(R * d), m, 0.5 * hertz_damping_factor(0.4))
    assert ts.kind == "wall" and ts.impact_speed == pytest.approx(v)
    assert ts.critical == pytest.approx(limit, rel=1e-12)
    assert ts.dt == pytest.approx(0.25 * limit, rel=1e-12)
    # an explicit dt is kept; its fraction of the critical time is reported
    seed = engine.preset("paper", protocol="seed")
    assert seed.time_step().dt == 1e-5
    assert seed.time_step().fraction == pytest.approx(1e-5 / ts.critical)


@pytest.fixture(scope="module")
def held():
    """A tiny cohesive run at a stated inertial number and dt fraction, its strength from the
    interior virial stress."""
    t = tiny(
        pair_law=COHESIVE,
        dt=None,
        dt_fraction=0.4,
        inertial_number=1e-3,
        strength_from="interior",
        interior_margin=R,
    )
    return engine.run_uniaxial(t)


def test_a_run_records_its_step_and_the_inertial_number_it_held(held):
    s, t = held.scalars, held.test
    ts = t.time_step()
    assert s["dt"] == ts.dt and s["dt_fraction"] == pytest.approx(0.4, rel=1e-12)
    assert s["dt_critical"] == ts.critical
    assert s["dt_limited_by_wall"] == (1.0 if ts.kind == "wall" else 0.0)
    assert s["impact_speed"] == ts.impact_speed
    # the speed is set from each sample for the next, and it is bounded (the floor, the
    # resolution cap, the post-peak band): the median holds I* within the change of the
    # stress over one sample, and none exceeds it by much
    assert s["inertial_number_held"] == pytest.approx(1e-3, rel=0.15)
    assert s["inertial_number_held_max"] < 3e-3
    assert all(np.all(np.isfinite(st.curves["stress_interior"])) for st in held.stages.values())


def test_a_slower_unloading_holds_its_own_inertial_number_and_changes_nothing_before(held):
    """``unloading_inertial_number`` a quarter of the loading's: every stage before the
    unloading is the same run bit for bit (the field acts on the unloading's platen speed
    alone), and the unloading holds its own inertial number (the median of its samples
    within 15 %, as the loading's above), taking longer over the same stress drop."""
    slow = engine.run_uniaxial(replace(held.test, unloading_inertial_number=2.5e-4))
    for name in ("fill", "pre_compression", "consolidation"):
        for k, v in held.stages[name].curves.items():
            assert slow.stages[name].curves[k].tobytes() == v.tobytes(), (name, k)
    got = np.median(held_inertial_numbers(slow.stages["unloading"].curves, slow.test))
    was = np.median(held_inertial_numbers(held.stages["unloading"].curves, held.test))
    assert got == pytest.approx(2.5e-4, rel=0.15) and was == pytest.approx(1e-3, rel=0.15)
    assert slow.stages["unloading"].steps > 2 * held.stages["unloading"].steps
    # the run's held scalar counts the slow unloading as its share of the target
    assert slow.scalars["inertial_number_held"] == pytest.approx(1e-3, rel=0.15)


def test_an_unloading_cut_short_is_the_full_ones_prefix_and_reads_the_same_stiffness(held):
    """The size series' cut checks (benchmarks/size_series.cut_short) stop below a fifth of
    the consolidation stress with no release or unconfined stage: their unloading
    curve is the full run's up to that point bit for bit (the stage's end acts on nothing
    before it), so the secant over the samples above half the peak is the same number."""
    from benchmarks.size_series import cut_short

    short = engine.run_uniaxial(cut_short(held.test))
    assert set(short.stages) == {"fill", "pre_compression", "consolidation", "unloading"}
    full, cut = held.stages["unloading"].curves, short.stages["unloading"].curves
    n = len(cut["time"])
    assert 2 < n < len(full["time"])
    assert cut["stress_top"][-1] <= 0.2 * held.test.consolidation_stress
    for k, v in full.items():
        assert cut[k].tobytes() == v[:n].tobytes(), k
    for k in ("loading_stiffness", "unloading_stiffness", "consolidated_porosity"):
        assert short.scalars[k] == held.scalars[k], k


def test_a_hold_stops_the_platen_until_rest_and_the_unloading_starts_from_there(held):
    """``hold_time``: a stage between consolidation and unloading with the top platen still
    for at least hold_time, then until the kinetic energy is below settle_ke N m g R; what
    came before is the run without it bit for bit, and the unloading starts where the hold
    ended."""
    from benchmarks.size_series import cut_short

    t = replace(cut_short(held.test), hold_time=5e-3)
    res = engine.run_uniaxial(t)
    assert list(res.stages) == ["fill", "pre_compression", "consolidation", "hold", "unloading"]
    plain = held.stages["consolidation"].curves
    for k, v in res.stages["consolidation"].curves.items():
        assert v.tobytes() == plain[k].tobytes(), k
    h, u = res.stages["hold"].curves, res.stages["unloading"].curves
    assert np.all(h["platen_gap"] == h["platen_gap"][0])  # the platen did not move
    assert h["time"][-1] - h["time"][0] >= t.hold_time
    m = t.density * sphere_volume(t.radius)
    assert h["kinetic_energy"][-1] <= t.settle_ke * t.n_particles * m * t.gravity * t.radius
    assert h["kinetic_energy"][0] > h["kinetic_energy"][-1]  # it came to rest in the hold
    assert u["stress_top"][0] == h["stress_top"][-1] and u["time"][0] == h["time"][-1]
    assert u["platen_gap"][-1] > u["platen_gap"][0]  # then the unloading lifts the platen
    assert res.scalars["loading_stiffness"] == held.scalars["loading_stiffness"]
    assert math.isfinite(res.scalars["unloading_stiffness"])
    # the JSON form: left out while None, so a test made before the field keeps its form
    assert "hold_time" not in held.test.to_dict()
    assert engine.UniaxialTest.from_dict(t.to_dict()) == t
    for value in (0.0, -1e-3, 1e3, t.max_stage_time):
        with pytest.raises(engine.ParameterError, match="hold_time"):
            replace(t, hold_time=value)
    # the run order with every stage: the hold after the consolidation, before the unloading
    assert stages_of(replace(t, unconfined=True)) == (
        "fill",
        "pre_compression",
        "consolidation",
        "hold",
        "unloading",
        "release",
        "unconfined",
    )
    assert "hold" not in stages_of(held.test)
    # hold_quiet: the hold ends only after a window of samples all below the energy, the
    # start counting as above it; the stages before it as without it
    # (a window longer than hold_time, the start counting as loud: it must bind)
    q = engine.run_uniaxial(replace(t, hold_quiet=8e-3))
    hq = q.stages["hold"].curves
    energy = t.settle_ke * t.n_particles * m * t.gravity * t.radius
    loud = np.nonzero(hq["kinetic_energy"] > energy)[0]
    last = hq["time"][loud[-1]] if len(loud) else hq["time"][0]
    # quiet for the window at its end (and hold_time past), not both one sample sooner
    assert hq["time"][-1] - last >= 8e-3
    t1, t0 = hq["time"][-2], hq["time"][0]
    assert t1 - last < 8e-3 or t1 - t0 < t.hold_time
    assert hq["time"][-1] > h["time"][-1]  # later than the single-sample hold ended
    assert "hold_quiet" not in t.to_dict() and q.test.to_dict()["hold_quiet"] == 8e-3
    assert q.scalars["loading_stiffness"] == held.scalars["loading_stiffness"]
    for bad in ({"hold_time": None, "hold_quiet": 4e-3}, {"hold_quiet": t.max_stage_time}):
        with pytest.raises(engine.ParameterError, match="hold_quiet"):
            replace(t, **bad)


def test_the_unloading_inertial_number_is_a_field_like_the_others():
    t = tiny(inertial_number=5e-4, unloading_inertial_number=1e-4)
    assert t.stage_inertial_number("unloading") == 1e-4
    assert t.stage_inertial_number("consolidation") == 5e-4
    # the JSON form: left out while None (a test made before the field keeps its form)
    assert "unloading_inertial_number" not in tiny(inertial_number=5e-4).to_dict()
    assert t.to_dict()["unloading_inertial_number"] == 1e-4
    assert engine.UniaxialTest.from_dict(t.to_dict()) == t
    assert halved_protocol(t).unloading_inertial_number == 5e-5
    for value in (0.0, 0.5):
        with pytest.raises(engine.ParameterError, match="unloading_inertial_number"):
            tiny(inertial_number=5e-4, unloading_inertial_number=value)
    # a constant platen speed has no inertial number to slow
    with pytest.raises(engine.ParameterError, match="unloading_inertial_number.*platen_speed"):
        tiny(inertial_number=None, unloading_inertial_number=1e-4)


def test_the_interior_strength_is_the_smoothed_peak_and_the_stage_ends_at_failure(held):
    # the strength is the peak of the interior curve smoothed over failure_strain, sought one
    # window past the stage's start; the platen's strength and the self-weight stand beside
    # it; a failed sample's stage ends once the documented failure holds on that curve
    from engine.uniaxial.measures import curve_failed, smoothed

    s, t = held.scalars, held.test
    u = held.stages["unconfined"].curves
    e, si = u["strain"], u["stress_interior"]
    sm = smoothed(e, si, t.failure_strain)
    past = e >= e[0] + t.failure_strain
    assert s["strength_from_interior"] == 1.0
    assert s["unconfined_strength"] == s["unconfined_strength_interior"] == sm[past].max()
    assert s["unconfined_strength_platen"] == u["stress_top"].max()
    weight = t.density * t.n_particles * sphere_volume(R) * t.gravity / (2 * t.cell[0] ** 2)
    assert s["self_weight_stress"] == pytest.approx(weight, rel=1e-9)
    # the stage ended at the first sample where the documented failure holds, or at the
    # strain limit (or the detector's drop) without it
    shorter = {k: v[:-1] for k, v in u.items()}
    assert not curve_failed(t, shorter)
    assert curve_failed(t, u) or e[-1] >= t.max_unconfined_strain or s["unconfined_failure"]
    assert s["unconfined_failure"] == (1.0 if curve_failed(t, u) else s["unconfined_failure"])


def test_the_platen_speed_holds_the_inertial_number_in_closed_form():
    t = tiny(inertial_number=2e-4, max_platen_speed=0.5, failure_strain=0.005)
    d, rho, gap, h0 = 2 * R, 2000.0, 0.1, 0.12
    # above the floor: v = I* (h / d) sqrt(p / rho)
    p = 1.5e4
    v = 2e-4 * gap / d * math.sqrt(p / rho)
    assert loading_speed(t, gap, p, h0) == pytest.approx(v, rel=1e-12)
    # below the weight of one layer (rho g d) the floor holds
    floor = rho * t.gravity * d
    assert stress_floor(t) == pytest.approx(floor)
    v0 = 2e-4 * gap / d * math.sqrt(floor / rho)
    assert loading_speed(t, gap, 0.0, h0) == pytest.approx(v0, rel=1e-12)
    assert loading_speed(t, gap, -50.0, h0) == pytest.approx(v0, rel=1e-12)
    # past the unconfined peak the band of SHEAR_BAND_DIAMETERS holds I*
    post = loading_speed(t, gap, p, h0, unconfined=True, post_peak=True)
    assert post == pytest.approx(v * SHEAR_BAND_DIAMETERS * d / gap, rel=1e-12)
    # the bound, and the unconfined resolution cap: failure_strain h0 per SAMPLES_PER_WINDOW
    fast = replace(t, inertial_number=1e-2)
    assert loading_speed(replace(fast, max_platen_speed=0.05), gap, p, h0) == 0.05
    cap = 0.005 * h0 / (SAMPLES_PER_WINDOW * t.output_interval)
    assert loading_speed(fast, gap, p, h0, unconfined=True) == pytest.approx(cap, rel=1e-12)
    # and on a synthetic row: a platen closing at that speed holds I* (held_inertial_numbers)
    tt = np.array([0.0, 1e-3])
    curves = {
        "time": tt,
        "platen_gap": np.array([gap + v * 1e-3, gap]),
        "stress_top": np.array([p - 500.0, p - 500.0]),
        "stress_bottom": np.array([p + 500.0, p + 500.0]),
    }
    np.testing.assert_allclose(held_inertial_numbers(curves, t), [2e-4], rtol=1e-9)


def test_halved_protocol_halves_the_rate_and_the_step_and_nothing_else():
    t = tiny(inertial_number=5e-4, dt=None, dt_fraction=0.3, max_platen_speed=0.08)
    h = halved_protocol(t)
    assert h.inertial_number == 2.5e-4 and h.dt_fraction == 0.15 and h.dt is None
    assert h.max_platen_speed == 0.04
    assert replace(h, inertial_number=5e-4, dt_fraction=0.3, max_platen_speed=0.08) == t
    seed = tiny(**SEED_PROTOCOL)
    hs = halved_protocol(seed)
    assert hs.platen_speed == 0.005 and hs.dt == 5e-6 and hs.inertial_number is None
    assert replace(hs, platen_speed=0.01, dt=1e-5) == seed


def test_a_simple_cubic_stack_carries_the_platen_stress_in_its_interior():
    # m x m columns of n spheres in contact, each vertical contact pressed by F: the interior
    # virial stress is F / d^2 whatever whole layers the window holds (the platen's stress
    # over the cross-section m d x m d)
    m, n, f, delta = 3, 8, 0.7, 1e-6
    d = 2 * R - delta
    z = np.tile(R + d * np.arange(n), m * m)
    ids = np.arange(m * m * n).reshape(m * m, n)
    pairs = np.array([(c[k + 1], c[k]) for c in ids for k in range(n - 1)])
    forces = np.tile([0.0, 0.0, f], (len(pairs), 1))  # on the upper sphere, upwards
    normals = np.tile([0.0, 0.0, 1.0], (len(pairs), 1))
    gap = 2 * R + (n - 1) * d
    area = (m * 2 * R) ** 2
    for margin in (1.5 * 2 * R, 2.5 * 2 * R):
        s = interior_axial_stress(
            z, np.full(z.size, R), pairs, forces, normals, np.full(len(pairs), delta), gap,
            margin, area,
        )  # fmt: skip
        # the window [margin, gap - margin] holds whole layers k with z_k inside: each
        # particle's lever R - delta/2 on its two contacts, over the window's volume
        inside = (z[:n] >= margin) & (z[:n] <= gap - margin)
        lever = 2 * (R - delta / 2) * f * inside.sum() * m * m
        assert s == pytest.approx(lever / (area * (gap - 2 * margin)), rel=1e-12)
    # with the window holding every contact whole, the stress is F d / (2R)^2 per column
    whole = interior_axial_stress(
        z, np.full(z.size, R), pairs, forces, normals, np.full(len(pairs), delta), gap, 0.0,
        area,
    )  # fmt: skip
    assert whole == pytest.approx(f * d * (n - 1) * m * m / (area * gap), rel=1e-12)


def test_the_interior_virial_stress_is_the_mean_platen_stress_quasi_statically():
    # a bed 6 x 6 x 12 diameters (about 500 particles) consolidated at I* = 1e-3: the
    # interior window's axial virial stress is the mean axial force over the window, the top
    # platen's plus the weight above the window's middle, the mean of the two platens'
    # stresses for a centred window. Tolerance 5 %: the count of particle centres near the
    # window's two edges fluctuates by about its square root (about 12 of its ~400 particles,
    # 3 %), the kinetic part is below 1e-3.
    t = engine.UniaxialTest(
        cell=(0.03, 0.03, 0.06),
        pair_law=COHESIVE,
        dt=None,
        dt_fraction=0.4,
        inertial_number=1e-3,
        interior_margin=2 * R,
        unconfined=False,
    )
    res = engine.run_uniaxial(t)
    c = res.stages["consolidation"].curves
    platens = 0.5 * (c["stress_top"][-1] + c["stress_bottom"][-1])
    assert c["stress_interior"][-1] == pytest.approx(platens, rel=0.05)


def test_bad_protocol_values_name_the_field():
    for field, value in (
        ("inertial_number", 0.5),
        ("inertial_number", 0.0),
        ("dt_fraction", 0.9),
        ("max_platen_speed", 0.0),
        ("strength_from", "bottom"),
    ):
        with pytest.raises(engine.ParameterError, match=field):
            tiny(**{field: value})
    with pytest.raises(engine.ParameterError, match="protocol"):
        engine.preset("quick", protocol="fast")


def test_stored_seed_runs_read_as_the_seed_protocol_and_keep_their_platen_strength():
    # a run stored before the protocol fields existed (experiment (b) at the quick scale):
    # its test reads them at the seed's values and is the seed preset's, so the stored study
    # still finds it; its strength is the top platen's, and it has no interior curve
    from benchmarks.experiments import experiments
    from engine.io.store import load_run

    path = ROOT / "benchmarks" / "results" / "quick" / "b_cohesive" / "ref-s1.h5"
    with h5py.File(path, "r") as f:
        stored = json.loads(f.attrs["test"])
    assert "inertial_number" not in stored and "strength_from" not in stored
    res = load_run(path)
    ref = experiments("quick")["b_cohesive"].reference
    assert res.test == replace(ref, interior_margin=res.test.interior_margin, seed=1)
    assert res.test.inertial_number is None and res.test.dt == 1e-5
    assert res.test.strength_from == "platen"
    u = res.stages["unconfined"].curves
    assert "stress_interior" not in u
    assert res.scalars["unconfined_strength"] == pytest.approx(float(np.max(u["stress_top"])))
    assert engine.preset("quick", protocol="seed").cell == (0.05, 0.05, 0.1)


def test_a_dip_before_the_peak_does_not_hold_the_platen_at_the_band_s_speed():
    """The unconfined stage's turn (the platen slows to hold I* over a shear band) clears
    when the smoothed curve climbs to a new peak: a 10 % dip on the way up (stick-slip) once
    latched the slow speed to the end (size series column/bond1/d6.67-s4 held 1.2e-4 of its
    5e-4 up to its peak)."""
    from types import SimpleNamespace

    from engine.uniaxial.driver import CURVE_UNITS, STRENGTH_COLUMN, _Recorder

    t = tiny(strength_from="platen", failure_strain=0.005)
    col = STRENGTH_COLUMN["platen"]
    driver = SimpleNamespace(test=t, sim=SimpleNamespace(time=0.0, steps=0))
    rec = _Recorder(driver, "unconfined", 0.1)
    strain = np.arange(0.0, 0.08, 0.0005)  # ten samples per smoothing window

    def stress(e: float) -> float:
        up = 3e3 + 2e4 * e  # loading
        if 0.02 <= e < 0.03:
            return 0.9 * up  # the dip: 10 % for two windows
        return up if e < 0.05 else 4e3 - 1e5 * (e - 0.05)  # the true peak, then softening

    state = []
    for e in strain:
        row = [0.0] * len(CURVE_UNITS)
        row[1], row[col] = e, stress(e)
        rec.rows.append(tuple(row))
        state.append(rec.turned())
    state = np.array(state)
    assert state[(strain > 0.02) & (strain < 0.03)].any()  # the dip turns it ...
    assert not state[(strain > 0.035) & (strain < 0.05)].any()  # ... a new peak clears it
    assert state[strain > 0.056].all()  # past the true peak it stays turned
