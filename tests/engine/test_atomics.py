"""The atomic operations the step kernel's thread team is built on."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from numba import njit, prange

from engine.kernel.atomics import (
    atomic_add,
    atomic_cas,
    atomic_load,
    atomic_store,
    cycles,
    futex_wait,
    futex_wake,
    sleep_us,
)
from engine.kernel.team import sync_length, team_barrier


@njit
def _serial(a):
    old = atomic_add(a, 1, 5)
    atomic_store(a, 2, 7)
    won = atomic_cas(a, 3, 0, 9)
    lost = atomic_cas(a, 3, 0, 11)
    t0 = cycles()
    sleep_us(1)
    futex_wait(a, 1, 5)  # the value is 8, not 5: returns at once
    futex_wake(a, 1)  # nobody sleeps: nothing happens
    return old, atomic_load(a, 1), won, lost, cycles() > t0


def test_each_operation_does_what_it_says():
    a = np.array([0, 3, 0, 0], dtype=np.int64)
    old, now, won, lost, ticked = _serial(a)
    assert (old, now, won, lost, ticked) == (3, 8, True, False, True)
    assert a.tolist() == [0, 8, 7, 9]


@njit(parallel=True)
def _count(a, per_thread, team):
    for _t in prange(team):
        for _ in range(per_thread):
            atomic_add(a, 0, 1)


@njit(parallel=True)
def _rounds(sync, log, team, rounds):
    """Each round every thread writes its slot, meets the others at the barrier, then checks
    that it sees every slot of that round (the barrier publishes what was written before).
    Every 100th round one thread is 2 ms late: the others outwait their spin and sleep."""
    for t in prange(team):
        for r in range(rounds):
            if t == team - 1 and r % 100 == 0:
                sleep_us(2000)
            log[t] = r
            team_barrier(sync, team)
            for u in range(team):
                if log[u] < r:
                    log[team + t] += 1  # a write the barrier did not publish
            team_barrier(sync, team)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")
@pytest.mark.timeout(120)
def test_counts_and_barriers_hold_across_threads():
    old = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        a = np.zeros(1, dtype=np.int64)
        _count(a, 200_000, 2)
        assert a[0] == 400_000  # a plain += would lose increments
        log = np.zeros(4, dtype=np.int64)
        _rounds(np.zeros(sync_length(2), dtype=np.int64), log, 2, 2000)
        assert log.tolist() == [1999, 1999, 0, 0]
    finally:
        numba.set_num_threads(old)
