"""Results independent of the thread count."""

from __future__ import annotations

import numba
import numpy as np
import pytest

import engine
from tests.engine.helpers import stirred_cohesive_bed

R = 2.5e-3

pytestmark = pytest.mark.skipif(
    numba.config.NUMBA_NUM_THREADS < 2, reason="needs at least 2 numba threads"
)


def _run(threads: int, calls: int = 1, sim_class=engine.Simulation) -> engine.Simulation:
    """3,000 steps of a 700-particle cohesive bed between platens, in ``calls`` calls."""
    scene = stirred_cohesive_bed(700, np.array([0.03, 0.03, 0.04]), 21, 0.1)
    old = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        sim = sim_class(scene, dt=1e-5, threads=threads)
        assert sim.threads == threads
        for _ in range(calls):
            sim.run(3000 // calls)
    finally:
        numba.set_num_threads(old)
    return sim


def test_one_and_two_threads_give_the_same_trajectory():
    a = _run(1)
    b = _run(2)
    assert a.n > 250 and len(a.contacts().pairs) > 60  # several chunks per thread
    # one thread runs both passes chunk by chunk, two run them one after the other; both
    # renumbered the particles at the same steps into the same order
    assert a.n_renumbers == b.n_renumbers >= 1
    # fixed chunks, fixed summation order: identical to the last bit (1e-12 is the spec)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    np.testing.assert_array_equal(a.angular_velocities, b.angular_velocities)
    np.testing.assert_array_equal(a.wall_forces, b.wall_forces)


def _assert_same(a, b):
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    np.testing.assert_array_equal(a.angular_velocities, b.angular_velocities)
    np.testing.assert_array_equal(a.wall_forces, b.wall_forces)


@pytest.mark.timeout(300)
def test_many_short_calls_form_the_team_again_each_time():
    """500 calls of 6 steps: the team forms, meets at its barriers and breaks up 500 times
    (a lost wake-up or a miscounted barrier would hang or diverge)."""
    _assert_same(_run(1, calls=500), _run(2, calls=500))


class _TeamOfTwoOnOneThread(engine.Simulation):
    """Asks the kernel for a team of two, whose members run one after the other on one
    thread (as when the pool's thread is held up)."""

    def _call_kernel(self, nsteps, phase, team):
        return super()._call_kernel(nsteps, phase, 2)

    def _run_team(self, team, args):
        for t in range(team):
            self._k.run_member(t, *args)


@pytest.mark.timeout(300)
def test_a_team_whose_threads_do_not_all_start_runs_alone():
    """The team's second member only starts after the first has finished: the first must
    give up waiting and do all the work alone (the same result, no deadlock)."""
    _assert_same(_run(1, calls=10), _run(2, calls=10, sim_class=_TeamOfTwoOnOneThread))


def test_small_scenes_run_on_one_thread_unless_told():
    scene = engine.Scene(
        [[0.01, 0.01, 0.01], [0.02, 0.01, 0.01]],
        R,
        2000.0,
        gravity=(0.0, 0.0, 0.0),  # the kernel of tests/engine/test_laws.py's impacts: no compile
        pair_law=engine.BilinearAdhesive(k1=5e3, k2=2.5e4),
    )
    assert engine.Simulation(scene, dt=1e-5).threads == 1
    assert engine.Simulation(scene, dt=1e-5, threads=2).threads == min(2, numba.get_num_threads())
    with pytest.raises(engine.ParameterError, match="Simulation.threads"):
        engine.Simulation(scene, dt=1e-5, threads=0)
