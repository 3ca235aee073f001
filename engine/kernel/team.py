"""The thread team of a step kernel call: its threads (the caller's and the engine's pool's,
engine.simulation.simulation.run_team) take the fixed chunks of each pass and meet at
barriers (atomic counters, a short spin, then a futex sleep), instead of forking and joining
twice per step. Compiled once for every scene.

The counters live in ``Scratch.sync`` (:mod:`engine.kernel.state`), int64, at the ``SYNC_*``
slots below, each on its own 64-byte cache line.
"""

from numba import njit

from ..core.config import NJIT, TEAM_JOIN_WAIT_US, TEAM_POLL_US, TEAM_SPIN_CYCLES
from .atomics import (
    atomic_add,
    atomic_cas,
    atomic_load,
    atomic_store,
    cycles,
    futex_wait,
    futex_wake,
    pause,
    sleep_us,
)

# Slots of ``Scratch.sync``, each on its own 64-byte cache line, so that a thread waiting on
# one does not slow the counter another thread is taking chunks from.
SYNC_COUNT = 0  # threads arrived at the current barrier
SYNC_GEN = 8  # barrier generation (a waiting thread leaves when it changes)
SYNC_SLEEPERS = 16  # threads asleep (or about to be) at the current barrier
SYNC_ARRIVE = 24  # threads that have joined the team in this call
SYNC_MODE = 32  # UNDECIDED, TEAM (all threads work) or SOLO (the first one works alone)
SYNC_STEPS = 40  # result: steps completed
SYNC_STATUS = 48  # result: status code
#: first chunk counter: the counter of block b in pass p (0 pair, 1 particle) is at
#: ``SYNC_GRAB + 8 * (2 * b + p)``
SYNC_GRAB = 56


def sync_length(threads: int) -> int:
    """Length of ``Scratch.sync`` for teams of up to ``threads`` threads."""
    return SYNC_GRAB + 16 * max(1, threads)


# SYNC_MODE: how this call's threads work
UNDECIDED = 0
TEAM = 1
SOLO = 2


@njit(**NJIT)
def _spin(sync, slot, value):
    """Spin until ``sync[slot]`` differs from ``value``, for at most ``TEAM_SPIN_CYCLES``;
    returns whether it changed. (Spinning catches the usual short waits of a balanced team;
    a longer one sleeps, so that a waiting thread never holds a core others need.)"""
    t0 = cycles()
    n = 0
    while atomic_load(sync, slot) == value:
        pause()
        n += 1
        if n > TEAM_SPIN_CYCLES // 16 or cycles() - t0 > TEAM_SPIN_CYCLES:
            return False
    return True


@njit(**NJIT)
def team_join(sync, team):
    """Join this call's thread team of ``team`` threads; returns (rank, size), or (-1, 0) for
    a thread that is not needed.

    The team forms only if all ``team`` threads arrive; the first waits at most
    ``TEAM_JOIN_WAIT_US`` for the others and otherwise works alone (``SOLO``). A pool that
    runs the team's members one after the other (its threads busy elsewhere) therefore
    cannot deadlock at a barrier, and a teammate the OS keeps off the cores only
    costs this call its parallelism. Results do not depend on the outcome.
    """
    k = atomic_add(sync, SYNC_ARRIVE, 1)
    if team == 1:
        return 0, 1
    if k == team - 1:
        if atomic_cas(sync, SYNC_MODE, UNDECIDED, TEAM):
            futex_wake(sync, SYNC_MODE)
    elif k == 0:
        if not _spin(sync, SYNC_MODE, UNDECIDED):
            waited = 0
            while atomic_load(sync, SYNC_MODE) == UNDECIDED and waited < TEAM_JOIN_WAIT_US:
                sleep_us(TEAM_POLL_US)
                waited += TEAM_POLL_US
            if atomic_cas(sync, SYNC_MODE, UNDECIDED, SOLO):
                futex_wake(sync, SYNC_MODE)
    elif not _spin(sync, SYNC_MODE, UNDECIDED):
        while atomic_load(sync, SYNC_MODE) == UNDECIDED:
            futex_wait(sync, SYNC_MODE, UNDECIDED)
    if atomic_load(sync, SYNC_MODE) == SOLO:
        return (0, 1) if k == 0 else (-1, 0)
    return k, team


@njit(**NJIT)
def team_barrier(sync, size):
    """Wait until all ``size`` threads of the team have arrived (sense-reversing: the last
    to arrive resets the count and advances the generation the others wait on, and wakes
    those that went to sleep)."""
    if size == 1:
        return
    gen = atomic_load(sync, SYNC_GEN)
    if atomic_add(sync, SYNC_COUNT, 1) == size - 1:
        atomic_store(sync, SYNC_COUNT, 0)
        atomic_add(sync, SYNC_GEN, 1)
        if atomic_load(sync, SYNC_SLEEPERS) > 0:
            futex_wake(sync, SYNC_GEN)
    elif not _spin(sync, SYNC_GEN, gen):
        # counted before the last check of the generation: either the releaser sees this
        # sleeper and wakes it, or the futex sees the new generation and returns at once
        atomic_add(sync, SYNC_SLEEPERS, 1)
        while atomic_load(sync, SYNC_GEN) == gen:
            futex_wait(sync, SYNC_GEN, gen)
        atomic_add(sync, SYNC_SLEEPERS, -1)


@njit(**NJIT)
def block_bounds(b, size, nchunk):
    """Chunks [lo, hi) of block b when ``nchunk`` chunks are cut into ``size`` blocks."""
    return b * nchunk // size, (b + 1) * nchunk // size


@njit(**NJIT)
def grab(sync, which, b, lo):
    """The next chunk of block b in pass ``which`` (0 pair, 1 particle): the block's owner
    takes them in order, and a thread done with its own block takes the rest of another's."""
    return lo + atomic_add(sync, SYNC_GRAB + 8 * (2 * b + which), 1)


@njit(**NJIT)
def reset_grabs(sync, which, size):
    """Rewind the chunk counters of pass ``which`` (only between barriers)."""
    for b in range(size):
        sync[SYNC_GRAB + 8 * (2 * b + which)] = 0
