"""The state a step kernel call takes (grouped records of arrays), its status codes and the
flag-independent helpers of the step (problem flags, wall forces and motion), compiled once
for every scene. The thread team is :mod:`engine.kernel.team`.
"""

from collections import namedtuple

from numba import njit

from ..core.config import NJIT

#: Per-particle state [SI]: positions [m], velocities [m/s], angular velocities [rad/s], forces
#: [N] and torques [N m] of the last evaluation (N, 3); ``roll``: the summed rolling moments
#: ``mu_r |f_el|`` [N] of each particle's own half-list contacts, left by the pair pass for the
#: particle pass ((N,), or (0,) without rolling); radii [m], masses [kg], inverse masses
#: [1/kg], inverse moments of inertia [1/(kg m^2)] (N,); positions at the last list build [m].
Particles = namedtuple(
    "Particles", "pos vel omg frc trq roll rad mass inv_mass inv_inertia pos_build"
)

#: Half Verlet list in CSR form with its per-entry slots and the reverse list (see
#: engine.kernel.neighbour): ``start`` (N+1,), ``j`` (capacity,), ``entry`` (capacity, N_SLOT),
#: ``rev_start`` (N+1,), ``rev_k`` (capacity,).
NeighbourList = namedtuple("NeighbourList", "start j entry rev_start rev_k")

#: Walls: the planes, then the meshes. Planes: the unit normal into the domain (n_planes, 3);
#: ``hist``: per particle and plane contact history (N * n_planes, N_WALL_HIST), row
#: ``i * n_planes + w``. Rows ``0 .. n_planes - 1`` of ``point``, ``vel``, ``force`` and
#: ``acc`` are the planes' (a point of the plane [m], its velocity [m/s]), rows ``n_planes +
#: m`` those of mesh m (its translation since time 0 [m], its velocity [m/s]): every wall
#: moves and sums its force alike. ``force``: force of the particles on each wall [N]
#: (n_planes + n_meshes, 3); ``acc``: its per-chunk partial sums (n_chunks, n_planes +
#: n_meshes, 3). ``mesh``: the meshes' arrays (:data:`Meshes`) where the kernel has meshes
#: compiled in, else an empty tuple (a scene of planes passes the kernel what it passed
#: before meshes existed: an empty tuple adds no argument to the compiled functions).
Walls = namedtuple("Walls", "point normal vel hist force acc mesh")

#: Meshes (engine.kernel.mesh, empty arrays without meshes): ``mvert``, ``mtri``, ``mtri_n``,
#: ``medge``, ``mvert_start``, ``mvert_edge`` (geometry and topology), ``cand_start``,
#: ``cand_t`` (each particle's candidate triangles), ``mhist`` (contact rows), ``mscr``
#: (scratch of the particle in hand), ``mshift0`` (the meshes' translations at the last list
#: build, (n_meshes, 3) [m]), ``box`` (the box's lower corner and lengths, (2, 3) [m]: a
#: contact carried across a periodic face is matched to its row at the nearest image).
Meshes = namedtuple(
    "Meshes",
    "mvert mtri mtri_n medge mvert_start mvert_edge cand_start cand_t mhist mscr mshift0 box",
)

#: Step parameters: pair and wall law parameter arrays (named slots, see engine.kernel.specialise),
#: gravity [m/s^2] (3,), box lengths [m] (3,), time step dt [s], Verlet skin [m], the overlap
#: and step-length guards as fractions of the radius [-].
StepParams = namedtuple("StepParams", "pair wall gravity length dt skin max_overlap max_step")

#: Per-chunk scratch of the parallel passes: the first problem found (code, i, j, value)
#: (n_chunks, 4), the largest squared displacement since the list build [m^2] (n_chunks,), the
#: reported problem (i, j, value) (3,), and the thread team's counters ``sync`` (int64,
#: ``engine.kernel.team.sync_length(threads)``; see its ``SYNC_*`` slots).
Scratch = namedtuple("Scratch", "chunk_stat chunk_disp info sync")


# status codes of a step kernel call (engine.kernel.step_template.run_member)
OK = 0
REBUILD = 1
NAN = 2
OVERLAP = 3
SPEED = 4
PAUSE = 5  # the call's bound on steps reached (its pause), more steps remain


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
def status_code(chunk_stat):
    """The first problem's code over the chunks, in chunk order (``OK`` if none)."""
    for c in range(chunk_stat.shape[0]):
        if chunk_stat[c, 0] != 0.0:
            return int(chunk_stat[c, 0])
    return OK
