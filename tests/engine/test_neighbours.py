"""Neighbour list and contact detection against all-pairs searches; history across rebuilds."""

from __future__ import annotations

import itertools
import pickle

import numpy as np
import pytest

import engine
import engine.simulation.simulation as simulation
from engine.kernel.neighbour import build_neighbour_list
from tests import naive
from tests.engine.helpers import box_gas, walled_bed

R = 2.5e-3


def _build(pos, rad, lengths, periodic, skin):
    n = len(pos)
    pos = pos.copy()
    nbr_start = np.zeros(n + 1, dtype=np.int64)
    rev_start = np.zeros(n + 1, dtype=np.int64)
    cap = 0
    while True:
        nbr_j = np.zeros(cap, dtype=np.int32)
        entry = np.zeros((cap, 4))
        rev_k = np.zeros(cap, dtype=np.int32)
        total = build_neighbour_list(
            pos,
            rad,
            np.zeros(3),
            np.asarray(lengths, float),
            np.array(periodic),
            skin,
            np.zeros((n, 3), np.int64),
            nbr_start,
            nbr_j,
            entry,
            1,
            rev_start,
            rev_k,
            pos.copy(),
        )
        if total >= 0:
            break
        assert cap == 0, "a second overflow after growing to the reported size"
        cap = -total
    pairs = {(i, int(j)) for i in range(n) for j in nbr_j[nbr_start[i] : nbr_start[i + 1]]}
    assert len(pairs) == total  # no duplicates
    rev = {
        (int(i), j)
        for j in range(n)
        for i in [
            np.searchsorted(nbr_start, k, side="right") - 1
            for k in rev_k[rev_start[j] : rev_start[j + 1]]
        ]
    }
    assert rev == pairs  # the reverse list is the transpose
    return pairs, pos


def _with_boundary_particles(pos, rad, lengths, rng):
    """Add particles hugging faces, edges and corners so pairs cross them."""
    extra_p, extra_r = [], []
    for corner in itertools.product([0, 1], repeat=3):
        c = np.array(corner, float) * lengths
        extra_p.append(np.abs(c - rng.uniform(0.1, 0.6, 3) * R))  # just inside the corner
        extra_r.append(R)
    extra_p += [
        [0.2 * R, lengths[1] / 2, lengths[2] / 2],
        [lengths[0] - 0.3 * R, lengths[1] / 2 + 0.5 * R, lengths[2] / 2],
    ]
    extra_r += [R, R]
    return np.vstack([pos, extra_p]), np.concatenate([rad, extra_r])


@pytest.mark.parametrize(
    "periodic",
    [(True, True, True), (True, True, False), (False, False, False), (False, True, False)],
)
@pytest.mark.parametrize("lengths_r", [(20.0, 24.0, 28.0), (9.0, 10.0, 14.0)])
def test_neighbour_list_equals_all_pairs(periodic, lengths_r):
    """Polydisperse (radius ratio 3), boxes with many cells and with only 2 per axis."""
    rng = np.random.default_rng(abs(hash((periodic, lengths_r))) % 2**32)
    lengths = np.array(lengths_r) * R
    pos, rad = naive.rsa_packing(120, lengths, R / 3, R, 1, max_overlap=0.3, periodic=periodic)
    pos, rad = _with_boundary_particles(pos, rad, lengths, rng)
    skin = 0.3 * R
    pairs, wrapped = _build(pos, rad, lengths, periodic, skin)
    expect = naive.all_pairs_within(wrapped, rad, lengths, periodic, skin)
    assert pairs == expect
    assert expect == naive.all_pairs_within_by_images(wrapped, rad, lengths, periodic, skin)
    if all(periodic):
        n = len(rad)
        corner_ids = range(n - 10, n - 2)
        crossing = [(i, j) for i, j in itertools.combinations(corner_ids, 2)]
        assert set(crossing) <= pairs  # every corner particle neighbours every other one


def test_contacts_equal_all_pairs_overlaps():
    lengths = np.array([0.02, 0.02, 0.02])
    pos, rad = naive.rsa_packing(400, lengths, R / 3, R, 5, max_overlap=0.2)
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.1, restitution=0.4)
    sim = engine.Simulation(box_gas(pos, rad, lengths, law))
    c = sim.contacts()
    got = {tuple(p) for p in c.pairs.tolist()}
    expect = naive.all_pairs_within(sim.positions, rad, lengths, (1, 1, 1), 0.0)
    assert len(expect) > 100 and got == expect
    assert sim.n_contacts() == len(expect)
    for (i, j), d in zip(c.pairs, c.overlaps):
        dx = naive.minimum_image(sim.positions[i] - sim.positions[j], lengths, (1, 1, 1))
        assert d == pytest.approx(rad[i] + rad[j] - np.linalg.norm(dx), rel=1e-9)


def _sheared_bed(skin, periodic):
    lengths = np.array([0.025, 0.025, 0.03])
    pos, rad = naive.rsa_packing(
        350, lengths, 0.8 * R, R, 2, max_overlap=0.05, periodic=(periodic, periodic, False)
    )
    rng = np.random.default_rng(2)
    vel = rng.normal(0, 0.05, pos.shape)
    vel[:, 0] += 2.0 * (pos[:, 2] - 0.015)  # a shear flow: contacts slide and roll
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.2, mu_s=0.5, mu_r=0.01, restitution=0.5)
    scene = walled_bed(pos, rad, lengths, law, velocities=vel, periodic=periodic)
    return engine.Simulation(scene, dt=5e-6, skin=skin)


def test_history_unchanged_across_a_forced_rebuild():
    sim = _sheared_bed(0.2 * R, periodic=True)
    sim.run(400)
    before = sim.contacts()
    assert np.count_nonzero(np.linalg.norm(before.tangential_springs, axis=1)) > 50
    assert np.count_nonzero(before.max_overlaps > before.overlaps) > 50  # unloaded contacts
    sim.rebuild_neighbour_list()
    after = sim.contacts()
    np.testing.assert_array_equal(before.pairs, after.pairs)
    np.testing.assert_array_equal(before.max_overlaps, after.max_overlaps)
    np.testing.assert_array_equal(before.tangential_springs, after.tangential_springs)


def test_trajectory_independent_of_skin_and_rebuild_schedule():
    """Open boundaries (no wrapping): the same forces summed in the same order whatever the
    list holds, so frequent rebuilds or almost none give bit-identical trajectories; the
    particles are renumbered at the same steps (a multiple of RENUMBER_STEPS, whatever the
    list builds) into the same order."""
    a = _sheared_bed(0.05 * R, periodic=False)
    b = _sheared_bed(2.0 * R, periodic=False)
    steps = simulation.RENUMBER_STEPS + 100
    a.run(steps)
    b.run(steps)
    assert a.n_rebuilds >= b.n_rebuilds + 8
    assert a.n_renumbers == b.n_renumbers == 1
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.angular_velocities, b.angular_velocities)


def _contacts_equal(a, b):
    for field in ("pairs", "overlaps", "normals", "max_overlaps", "tangential_springs"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    for field in ("wall_particles", "wall_ids", "wall_overlaps"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


def test_renumbering_carries_state_ids_and_contact_history():
    """A random renumbering: every accessor, every contact and its history (largest overlap,
    tangential spring, negated where the pair's two particles swap roles) and the wall
    contacts are those of before, in the scene's order; run on, the trajectory is that of the
    simulation that kept its order, up to rounding (the contacts' sums run in another
    order). Tolerance: 1e-9 m, a millionth of a radius, far above float64 rounding grown over
    a few contact durations (about 1e-13 relative) and far below any physical change."""
    sim = _sheared_bed(0.2 * R, periodic=True)
    ref = _sheared_bed(0.2 * R, periodic=True)
    sim.run(400)
    ref.run(400)
    before = sim.contacts()
    assert np.count_nonzero(np.linalg.norm(before.tangential_springs, axis=1)) > 50
    fields = ("positions", "unwrapped_positions", "velocities", "angular_velocities", "forces")
    state = {f: getattr(sim, f) for f in fields}
    sim.permute(np.random.default_rng(4).permutation(sim.n))
    for f in fields:
        np.testing.assert_array_equal(getattr(sim, f), state[f], err_msg=f)
    _contacts_equal(before, sim.contacts())
    with pytest.raises(engine.ParameterError, match="permutation"):
        sim.permute(np.zeros(sim.n, dtype=int))
    sim.run(200)
    ref.run(200)
    assert np.count_nonzero(sim._order != ref._order) > sim.n // 2
    assert np.abs(sim.positions - ref.positions).max() < 1e-9


def test_renumbering_restores_the_cell_order_after_a_fall():
    """A cloud renumbered in cell order at the start falls onto its platen; at the next
    multiple of RENUMBER_STEPS the particles are renumbered in the cell order of where they
    are, the map to the scene's ids kept."""
    lengths = np.array([0.02, 0.02, 0.05])
    pos, rad = naive.rsa_packing(
        100, lengths, R, R, 6, max_overlap=0.0, periodic=(True, True, False)
    )
    vel = np.random.default_rng(6).normal(0.0, 0.3, pos.shape)  # a stirred cloud
    vel[:, 2] -= 2.0
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, mu_s=0.3, restitution=0.3)
    sim = engine.Simulation(walled_bed(pos, rad, lengths, law, velocities=vel))
    sim.run(simulation.RENUMBER_STEPS)  # ends on the renumbering step, at a whole step
    p = sim._particles
    order = simulation.cell_order(p.pos, p.rad, sim._lo, sim._params.length, sim._periodic)
    assert not np.array_equal(order, np.arange(sim.n))  # the fall left it out of order
    state = (sim.positions, sim.velocities, sim.contacts())
    assert len(state[2].wall_particles) > 5 and len(state[2].pairs) > 20
    kept = pickle.loads(pickle.dumps(sim))
    kept._next_renumber = 10**9  # the same simulation, never renumbered
    assert sim._renumber()  # what the next run does first
    order = simulation.cell_order(p.pos, p.rad, sim._lo, sim._params.length, sim._periodic)
    np.testing.assert_array_equal(order, np.arange(sim.n))
    np.testing.assert_array_equal(sim.positions, state[0])
    np.testing.assert_array_equal(sim.velocities, state[1])
    _contacts_equal(state[2], sim.contacts())
    assert not sim._renumber()  # in order: nothing to do
    assert sim._next_renumber == 2 * simulation.RENUMBER_STEPS
    # wall and pair histories went with their particles (the tolerance of the test above)
    sim.run(300)
    kept.run(300)
    assert sim.n_renumbers == 1 and kept.n_renumbers == 0
    assert np.abs(sim.positions - kept.positions).max() < 1e-9


def test_list_grows_instead_of_dropping_pairs():
    """Start dilute (small list), compress into a dense state: the buffers must grow."""
    lengths = np.array([0.03, 0.03, 0.03])
    pos, rad = naive.rsa_packing(300, lengths, 0.9 * R, R, 8)
    law = engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0.0, mu_r=0.0, restitution=0.3)
    centre = lengths / 2
    vel = -(pos - centre) * 20.0  # everything rushes to the centre
    scene = box_gas(pos, rad, lengths, law, velocities=vel, periodic=False)
    sim = engine.Simulation(scene, dt=2e-6, max_overlap_fraction=0.9)
    n0 = sim.n_neighbour_entries
    cap0 = sim._list.j.shape[0]
    sim.run(3000)
    assert sim.n_neighbour_entries > 2 * n0 and sim._list.j.shape[0] > cap0
    expect = naive.all_pairs_within(sim.positions, sim.radii, lengths, (0, 0, 0), 0.0)
    assert {tuple(p) for p in sim.contacts().pairs.tolist()} == expect
