"""Flag-independent pieces of the step kernel, compiled once for every scene.

Kept out of the specialised template so that a new feature set does not compile them again.
"""

from numba import njit

from .config import NJIT

# status codes returned by the step kernel's run_steps
OK = 0
REBUILD = 1
NAN = 2
OVERLAP = 3
SPEED = 4


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
