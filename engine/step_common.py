"""Flag-independent pieces of the step kernel, compiled once for every scene.

Kept out of the specialised template so that a new feature set does not compile them again.
"""

from collections import namedtuple

from numba import njit

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
from .config import NJIT, TEAM_JOIN_WAIT_US, TEAM_POLL_US, TEAM_SPIN_CYCLES

#: Per-particle state [SI]: positions [m], velocities [m/s], angular velocities [rad/s], forces
#: [N] and torques [N m] of the last evaluation (N, 3); ``roll``: the summed rolling moments
#: ``mu_r |f_el|`` [N] of each particle's own half-list contacts, left by the pair pass for the
#: particle pass ((N,), or (0,) without rolling); radii [m], masses [kg], inverse masses
#: [1/kg], inverse moments of inertia [1/(kg m^2)] (N,); positions at the last list build [m].
Particles = namedtuple(
    "Particles", "pos vel omg frc trq roll rad mass inv_mass inv_inertia pos_build"
)

#: Half Verlet list in CSR form with its per-entry slots and the reverse list (see
#: engine.neighbour): ``start`` (N+1,), ``j`` (capacity,), ``entry`` (capacity, N_SLOT),
#: ``rev_start`` (N+1,), ``rev_k`` (capacity,).
NeighbourList = namedtuple("NeighbourList", "start j entry rev_start rev_k")

#: Planar walls: a point [m], the unit normal into the domain, the velocity [m/s] (n_walls, 3);
#: ``hist``: per particle and wall contact history (N * n_walls, N_WALL_HIST), row
#: ``i * n_walls + w``; ``force``: force of the particles on each wall [N] (n_walls, 3);
#: ``acc``: its per-chunk partial sums (n_chunks, n_walls, 3).
Walls = namedtuple("Walls", "point normal vel hist force acc")

#: Step parameters: pair and wall law parameter arrays (named slots, see engine.kernels),
#: gravity [m/s^2] (3,), box lengths [m] (3,), time step dt [s], Verlet skin [m], the overlap
#: and step-length guards as fractions of the radius [-].
StepParams = namedtuple("StepParams", "pair wall gravity length dt skin max_overlap max_step")

#: Per-chunk scratch of the parallel passes: the first problem found (code, i, j, value)
#: (n_chunks, 4), the largest squared displacement since the list build [m^2] (n_chunks,), the
#: reported problem (i, j, value) (3,), and the thread team's counters ``sync`` (int64,
#: ``sync_length(threads)``; see the ``SYNC_*`` slots).
Scratch = namedtuple("Scratch", "chunk_stat chunk_disp info sync")

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


UNDECIDED = 0
TEAM = 1
SOLO = 2

# status codes returned by the step kernel's run_steps
OK = 0
REBUILD = 1
NAN = 2
OVERLAP = 3
SPEED = 4
PAUSE = 5  # the call's bound on steps reached (run_steps' pause), more steps remain


@njit(**NJIT)
def _flag(chunk_stat, c, code, i, j, value):
    """Record the first problem found in chunk c."""
    if chunk_stat[c, 0] == 0.0:
        chunk_stat[c, 0] = code
        chunk_stat[c, 1] = i
        chunk_stat[c, 2] = j
        chunk_stat[c, 3] = value


@njit(**NJIT)
def _status(chunk_stat, info):
    """First problem over the chunks, in chunk order; its particles and value go to info."""
    for c in range(chunk_stat.shape[0]):
        if chunk_stat[c, 0] != 0.0:
            info[0] = chunk_stat[c, 1]
            info[1] = chunk_stat[c, 2]
            info[2] = chunk_stat[c, 3]
            return int(chunk_stat[c, 0])
    return OK


@njit(**NJIT)
def _largest(a):
    m = a[0]
    for k in range(1, a.shape[0]):
        m = max(m, a[k])
    return m


@njit(**NJIT)
def _finish_forces(wall_acc, wall_force):
    """Force on each wall [N]: chunk partial sums added in chunk order."""
    for w in range(wall_force.shape[0]):
        wall_force[w, 0] = 0.0
        wall_force[w, 1] = 0.0
        wall_force[w, 2] = 0.0
        for c in range(wall_acc.shape[0]):
            wall_force[w, 0] += wall_acc[c, w, 0]
            wall_force[w, 1] += wall_acc[c, w, 1]
            wall_force[w, 2] += wall_acc[c, w, 2]


@njit(**NJIT)
def _advance_walls(wall_point, wall_vel, dt):
    for w in range(wall_point.shape[0]):
        for a in range(3):
            wall_point[w, a] += wall_vel[w, a] * dt


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
    ``TEAM_JOIN_WAIT_US`` for the others and otherwise works alone (``SOLO``). A thread pool
    that runs the team's iterations one after the other (nested parallelism, a thread limit)
    therefore cannot deadlock at a barrier, and a teammate the OS keeps off the cores only
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


@njit(**NJIT)
def status_code(chunk_stat):
    """The first problem's code over the chunks, in chunk order (``OK`` if none)."""
    for c in range(chunk_stat.shape[0]):
        if chunk_stat[c, 0] != 0.0:
            return int(chunk_stat[c, 0])
    return OK
