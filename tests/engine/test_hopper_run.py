"""Small hopper discharges (docs/HOPPER.md): a slot hopper at two outlet widths, the closed gate,
mass conservation, a cone, and a narrow frictional outlet that arches. 400-500 particles of
R = 2.5 mm each; one thread."""

import math

import numpy as np
import pytest

import engine
from engine.hopper.driver import HopperRun
from engine.hopper.spec import HopperTest

D = 5e-3  # particle diameter [m]


def _discharge(test: HopperTest, hold: float = 0.0, at_rest=None):
    run = HopperRun(test, threads=1)
    run.settle()
    held = run.hold(hold) if hold > 0 else 0.0
    if at_rest is not None:
        at_rest(run)
    return run, held, run.discharge()


def _wall_forces(run: HopperRun, seen: dict) -> None:
    """The normal force on the slot's +x wall [N] two ways: the engine's force on that mesh
    along the wall's outward normal, and the sum of the contacts' elastic Hertz forces the
    wall stress is made of."""
    from engine.hopper.measures import hertz_wall_force

    sim, t = run.sim, run.test
    th = math.radians(t.half_angle)
    outward = np.array([math.cos(th), 0.0, -math.sin(th)])
    right = run.geo.wall_meshes[1]
    c = sim.mesh_contacts()
    on = c.meshes == right
    e_star, _ = t.wall_law.wall_moduli(t.wall_material)
    seen["engine"] = float(sim.mesh_forces[right] @ outward)
    seen["elastic"] = float(
        hertz_wall_force(c.overlaps[on], sim.radii[c.particles[on]], e_star).sum()
    )
    seen["contacts"] = int(on.sum())


def _conserved(run: HopperRun, res) -> None:
    c = res.curves
    total = res.scalars["total_mass"]
    assert run.sim.n == res.test.n_particles
    assert total == pytest.approx(
        res.test.n_particles * res.test.density * (4 / 3) * math.pi * (D / 2) ** 3
    )
    # every sample: discharged + in the hopper = all of it, nothing anywhere else
    assert np.all(c["escaped_mass"] == 0.0)
    assert np.allclose(c["discharged_mass"] + c["remaining_mass"], total, rtol=1e-12)
    assert np.all(np.diff(c["discharged_mass"]) >= 0.0)  # nothing comes back up
    assert c["time"][0] == 0.0 and c["discharged_mass"][0] == 0.0


@pytest.fixture(scope="module")
def slots():
    """Slot hoppers of outlet 6 and 10 diameters, 500 particles, half-angle 30 degrees; the
    narrower one's gate held closed for 0.05 s after the settling first."""
    seen: dict = {}
    narrow = _discharge(
        HopperTest(outlet_width=6 * D, particles=500),
        hold=0.05,
        at_rest=lambda run: _wall_forces(run, seen),
    )
    wide = _discharge(HopperTest(outlet_width=10 * D, particles=500))
    return narrow, wide, seen


def test_closed_gate_holds_the_fill(slots):
    (_, held, res), _, seen = slots
    assert held == 0.0
    assert res.scalars["settle_time"] > 0
    # the settled fill presses on the walls: positive normal stress in the lower bins
    assert np.all(res.wall_stress_fill[:3] > 0)
    # at most the hydrostatic pressure at the bin's lower edge (walls carry part of the
    # weight by friction: Janssen), far from zero
    h = res.scalars["fill_height"]
    rho_g = res.scalars["bulk_density"] * res.test.gravity
    lower = res.wall_edges[:-1]
    assert np.all(res.wall_stress_fill[:3] < 1.5 * rho_g * (h - lower[:3]))
    # the wall stress's contact forces add up to the engine's own force on the wall
    assert seen["contacts"] > 20
    assert seen["elastic"] == pytest.approx(seen["engine"], rel=1e-3)


def test_slot_discharges_at_a_rate_that_grows_with_the_outlet(slots):
    (run6, _, r6), (run10, _, r10), _ = slots
    for run, res in ((run6, r6), (run10, r10)):
        _conserved(run, res)
        s = res.scalars
        assert s["discharged_mass"] == pytest.approx(s["total_mass"])  # emptied
        assert not res.arched and not s["stopped"]
        assert s["discharge_rate"] > 0 and 0 < s["discharge_rate_se"] < 0.2 * s["discharge_rate"]
        assert s["window_samples"] >= 12
        assert s["discharge_rate_per_depth"] == pytest.approx(s["discharge_rate"] / 0.025)
        assert 0.4 * 2000 < s["bulk_density"] < 0.7 * 2000
        assert res.flow_mode in ("mass", "funnel")
        assert np.isfinite(res.wall_stress_flow).all()
    w6, w10 = r6.scalars, r10.scalars
    gap = w10["discharge_rate"] - w6["discharge_rate"]
    assert gap > 3 * math.hypot(w6["discharge_rate_se"], w10["discharge_rate_se"])


def test_the_sink_parks_the_discharged_grains_before_the_floor(slots):
    """Issue 52: grains that fell 2 B and more hit a heap on the catch floor fast enough to
    stop a run; every grain whose centre crosses the sink is parked at its own site of the
    lattice below it (at rest, radius 0, out of contact) and stays there."""
    from engine.hopper.driver import impact_speed

    _, (run, _, res), _ = slots
    t, geo, d = run.test, run.geo, run.test.max_diameter
    sim = run.sim
    # the sink lies 2 B + 10 d below the outlet, its lattice below it and above the floor
    assert geo.sink == pytest.approx(-(2 * t.outlet_width + 10 * d))
    assert -geo.catch_depth < geo.sink < -2 * t.outlet_width
    assert geo.parking.origin[2] == pytest.approx(geo.sink - 2 * d)
    assert geo.parking.lowest(sim.n) > -geo.catch_depth + d
    # applied at least every quarter diameter of the fastest grain's travel
    assert run.sink_steps * run.dt * impact_speed(t, geo) <= 0.25 * d
    assert res.scalars["discharged_mass"] == res.scalars["total_mass"]
    # the hopper is empty; the grains fall on (twice the free-fall time of the catch depth):
    # every one is parked at its scene id's site, at rest, radius 0, and none is in contact
    run._advance(round(2 * math.sqrt(2 * geo.catch_depth / t.gravity) / run.dt))
    assert np.all(sim.radii == 0.0)
    assert np.array_equal(sim.positions, geo.parking.sites(np.arange(sim.n)))
    assert not sim.velocities.any() and not sim.angular_velocities.any()
    assert sim.n_contacts() == 0 and len(sim.mesh_contacts().particles) == 0
    assert sim.masses.sum() == pytest.approx(res.scalars["total_mass"], rel=1e-12)
    assert sim.kinetic_energy() == 0.0
    # and they stay there: a thousand steps more move none
    before = sim.positions
    sim.run(1000)
    assert np.array_equal(sim.positions, before)


def test_park_below_leaves_the_others_alone_and_refuses_bad_input():
    """Two grains falling side by side, out of each other's reach, and a third resting on a
    floor: parking the lowest leaves the others' trajectories bit-identical to those of a run
    without it; a grain touching the parked one loses that contact at the next step."""
    from engine.simulation.parking import ParkingLattice

    r = 1e-3
    pos = [[0.0, 0.0, 0.05], [0.01, 0.0, 0.02], [0.02, 0.0, 2.999 * r], [0.02, 0.0, r]]
    scene = engine.Scene(
        pos,
        r,
        2500.0,
        box=((-0.05, 0.05), (-0.05, 0.05), (-0.2, 0.1)),
        walls=[engine.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))],
        gravity=(0.0, 0.0, -9.81),
        pair_law=engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=0.5, restitution=0.4),
        wall_law=engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.5, mu=0.3),
        wall_material=engine.WallMaterial(),
    )
    # sites above the floor, beside the grains
    lattice = ParkingLattice((-0.04, -0.04, 0.03), (4 * r, 4 * r, 4 * r), 3, 2)
    a = engine.Simulation(scene, 2e-6, threads=1)
    b = engine.Simulation(scene, 2e-6, threads=1)
    a.run(500)
    b.run(500)
    assert 3 in a.contacts().wall_particles.tolist()
    a.park_below(0.0025, lattice)  # the grain resting on the floor (centre at ~1 mm)
    c = a.contacts()  # its contacts deleted with it: the floor's and the grain's above
    assert 3 not in c.wall_particles.tolist() and 3 not in c.pairs.ravel().tolist()
    assert a.radii[3] == 0.0 and np.all(a.radii[:3] == r)
    assert np.array_equal(a.positions[3], lattice.sites([3])[0])
    assert a.velocities[3].tolist() == [0.0, 0.0, 0.0]
    a.run(20000)
    b.run(20000)
    assert np.array_equal(a.positions[:2], b.positions[:2])  # the free fallers: untouched
    assert np.array_equal(a.positions[3], lattice.sites([3])[0])  # the parked: still
    # the grain that lay on the parked one has fallen into its place
    assert a.positions[2, 2] < b.positions[2, 2] - r
    assert not any(3 in p for p in a.contacts().pairs.tolist())
    with pytest.raises(engine.ParameterError, match="park_below.height"):
        a.park_below(math.nan, lattice)
    with pytest.raises(engine.ParameterError, match="park_below.lattice"):
        a.park_below(0.0, (0.0, 0.0, 0.0))
    with pytest.raises(engine.ParameterError, match="ParkingLattice.spacing"):
        a.park_below(0.0, ParkingLattice((0.0, 0.0, 0.01), (1e-5, 1e-3, 1e-3), 3, 3))
    with pytest.raises(engine.ParameterError, match="behind wall 0"):
        a.park_below(0.0, ParkingLattice((0.0, 0.0, 0.002), (1e-3, 1e-3, 1e-3), 1, 1))
    with pytest.raises(engine.ParameterError, match="inside the box"):
        a.park_below(0.0, ParkingLattice((0.0, 0.0, 0.01), (0.1, 1e-3, 1e-3), 4, 1))
    with pytest.raises(engine.ParameterError, match="ParkingLattice.nx"):
        ParkingLattice((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0, 3)


def test_cone_discharges_and_conserves_mass():
    run, _, res = _discharge(HopperTest(shape="cone", outlet_width=6 * D, particles=500))
    _conserved(run, res)
    s = res.scalars
    assert s["discharge_rate"] > 0 and math.isnan(s["discharge_rate_per_depth"])
    assert s["discharged_mass"] == pytest.approx(s["total_mass"])


def test_narrow_frictional_outlet_arches():
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=0.0, mu_s=1.0, mu_r=0.3, restitution=0.4)
    t = HopperTest(
        outlet_width=3.2 * D, particles=400, pair_law=law, arch_wait=5.0, max_discharge_time=1.0
    )
    run, _, res = _discharge(t)
    _conserved(run, res)
    s = res.scalars
    assert s["stopped"] and res.arched
    assert s["remaining_mass"] > 0.5 * s["total_mass"]
    # the arch formed after the opening, and the run waited arch_wait free-fall times after it
    assert 0.0 <= s["arch_time"] <= s["discharge_time"] - t.arch_wait * t.free_fall_time + 2e-3
    assert math.isnan(s["discharge_rate"])  # no steady window
    # the arch rests on the walls within a diameter of the outlet, and spans it
    tan = math.tan(math.radians(t.half_angle))
    assert t.outlet_width <= s["arch_span"] <= t.outlet_width + 2 * tan * D
    assert 0.0 <= s["arch_height"] < t.outlet_width


def test_the_arch_profile_reads_crown_and_feet_from_the_lowest_grains():
    from engine.hopper.measures import arch_profile

    # an arch over a slot 10 d wide: the lowest grain of each column at 2 d - (x / 2.5 d)^2 d
    # above the outlet, grains stacked above it; its crown 2 d, its feet in the outer bins
    d, half = 1e-3, 5e-3
    x = np.linspace(-half + 0.5 * d, half - 0.5 * d, 10)
    under = (2.0 - (x / (2.5 * d)) ** 2) * d
    across = np.abs(np.concatenate([x, x, x]))
    bottoms = np.concatenate([under, under + d, under + 2 * d])
    crown, feet = arch_profile(across, bottoms, half, d)
    assert crown == pytest.approx(under.max()) and feet == pytest.approx(under.min())
    # grains beyond the outlet's half-width do not count; an empty column: no arch
    assert arch_profile(np.append(across, 2 * half), np.append(bottoms, -1.0), half, d) == (
        pytest.approx(crown),
        pytest.approx(feet),
    )
    keep = across < 4e-3  # the outermost columns left out
    assert all(math.isnan(v) for v in arch_profile(across[keep], bottoms[keep], half, d))


def test_wall_time_limit_and_stop_request_are_honoured():
    t = HopperTest(outlet_width=6 * D, particles=100)
    with pytest.raises(engine.WallTimeExceeded) as e:
        engine.run_hopper(t, max_wall_time=1e-9, wall_time_setting="max_run_wall_time")
    assert e.value.setting == "max_run_wall_time" and e.value.limit == 1e-9
    seen = []

    def stop(p):
        seen.append(p)
        return False

    with pytest.raises(engine.StopRequested):
        engine.run_hopper(t, progress=stop)
    assert len(seen) == 1 and seen[0].stage == "settle" and 0 <= seen[0].fraction <= 1


def test_backend_is_checked_and_named():
    t = HopperTest(outlet_width=6 * D, particles=100)
    with pytest.raises(engine.ParameterError, match="run_hopper.backend"):
        engine.run_hopper(t, backend="tpu")
