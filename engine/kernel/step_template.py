"""Time-step kernel template, specialised per scene by :mod:`engine.kernel.specialise`.

The feature block below is rewritten for each scene and the result imported as its own module,
so numba sees every flag as a compile-time constant and compiles out what the scene does not
use (adhesion, plasticity, friction and tangential history, rolling, damping, each periodic
axis, walls, gravity, rotation). The block also names the parameter slots of the pair and the
wall law (generated with the flags: a parameter the scene does not use has no slot and points
at the arrays' trailing NaN), and the per-entry slot layout follows from the flags too.

State travels in the grouped records of :mod:`engine.kernel.state` (``Particles``,
``NeighbourList``, ``Walls``, ``StepParams``, ``Scratch``). Every contact, particle-particle
or particle-wall, goes through the one composition :func:`engine.contact.compose.contact`.

One step (velocity Verlet, LAMMPS ordering; forces see the half-step velocity):

1. pair pass (``_pair_chunk``): every particle i (in parallel, fixed chunks) loops over its
   half list, computes each contact once, adds the force on i to i and stores the force, the
   torque and the rolling moment for j in the entry;
2. particle pass (``_particle_chunk``): every particle gathers what was stored for it (reverse
   list, fixed order), adds walls, rolling resistance and gravity, then kicks and drifts. The
   closing half kick of one step and the opening half kick of the next are fused into one
   full kick.

Threads: a call runs ``run_member`` once per member of a thread team (the calling thread and
threads of the engine's pool). The team takes the fixed chunks of each pass (each thread its
own contiguous block first, then what is left of the others') and meets at a barrier after
each pass (``engine.kernel.team``: atomic counters, a short spin, then a futex sleep),
instead of forking and joining twice per step.

No reduction depends on the thread count: every sum runs in a fixed order over fixed chunks, so
trajectories are bit-identical with any number of threads.
"""

import importlib
import math

import numpy as np
from numba import njit

from engine.contact.compose import composition, rolling_torque
from engine.core.config import CHUNK, NJIT, NJIT_INLINE
from engine.kernel.state import (
    NAN,
    OK,
    OVERLAP,
    PAUSE,
    REBUILD,
    SPEED,
    _advance_walls,
    _finish_forces,
    _flag,
    _largest,
    _status,
    status_code,
)
from engine.kernel.team import (
    SYNC_STATUS,
    SYNC_STEPS,
    block_bounds,
    grab,
    reset_grabs,
    team_barrier,
    team_join,
)

# >>> features (rewritten by engine.kernel.specialise)
PAIR_KERNEL = importlib.import_module("engine.contact.bilinear").KERNEL
WALL_KERNEL = importlib.import_module("engine.contact.hertz").KERNEL

FRICTION = True
ROLLING = True
DAMPING = True
NORMAL_CAP = False
ADHESION = True
ADHESIVE_BRANCH = True
PLASTIC = True
WALL_FRICTION = True
WALL_ROLLING = True
WALL_DAMPING = True
WALL_NORMAL_CAP = False
PERIODIC_X = True
PERIODIC_Y = True
PERIODIC_Z = True
WALLS = True
GRAVITY = True
PAIR_EFFECTIVE_RADIUS = False
PairParams = PAIR_KERNEL.params
PairSwitches = PAIR_KERNEL.switch_tuple
WallParams = WALL_KERNEL.params
WallSwitches = WALL_KERNEL.switch_tuple


@njit(**NJIT_INLINE)
def _pair_law(p):
    """The pair law's parameters from their slots (generated: a parameter this scene does
    not use has no slot and takes its neutral value)."""
    return PairParams(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7])


@njit(**NJIT_INLINE)
def _pair_flags():
    """The pair law's switches (compile-time constants)."""
    return PairSwitches(FRICTION, ROLLING, DAMPING, NORMAL_CAP, ADHESION, ADHESIVE_BRANCH, PLASTIC)


@njit(**NJIT_INLINE)
def _wall_law(p):
    """The wall law's parameters from their slots (generated: a parameter this scene does
    not use has no slot and takes its neutral value)."""
    return WallParams(p[0], p[1], p[2], p[3], p[4])


@njit(**NJIT_INLINE)
def _wall_flags():
    """The wall law's switches (compile-time constants)."""
    return WallSwitches(WALL_FRICTION, WALL_ROLLING, WALL_DAMPING, WALL_NORMAL_CAP)


# <<< features

ROTATION = FRICTION or ROLLING or (WALLS and (WALL_FRICTION or WALL_ROLLING))
ANY_ROLLING = ROLLING or (WALLS and WALL_ROLLING)
#: history slots of a pair entry: largest overlap (contact marker), tangential spring (3)
N_HIST = 4 if FRICTION else 1
#: history slots of a particle-wall row: contact marker, tangential spring (3)
N_WALL_HIST = 4 if WALL_FRICTION else 1
F_SLOT = N_HIST
#: entry slots after the history: force on j (3); friction torque on j (3, with FRICTION);
#: rolling moment mu_r |f_el| of the contact for j (1, with ROLLING)
T_SLOT = F_SLOT + 3
R_SLOT = T_SLOT + 3 if FRICTION else T_SLOT
N_SLOT = R_SLOT + 1 if ROLLING else R_SLOT

# particle_pass modes
FORCES = 0  # forces only
CLOSE = 1  # forces, closing half kick
STEP = 2  # forces, full kick (closing + next opening half kick), drift
OPEN = 3  # opening half kick and drift with the stored forces


#: The contact of each side: the one composition with the side's law family bound in.
pair_contact = composition(PAIR_KERNEL).contact
wall_contact = composition(WALL_KERNEL).contact


@njit(**NJIT)
def _pass(which, mode, rank, size, P, L, W, prm, S):
    """This thread's share of one pass: ``which`` 0 is the pair pass (:func:`_pair_chunk`),
    1 the particle pass (:func:`_particle_chunk`) in ``mode``. The chunks are cut into one
    contiguous block per thread; a thread works through its own block (the same particles
    every step, so their data stay in its core's cache), then helps with the others' (a
    teammate slowed down by other processes or by denser chunks does not hold the step
    up). What a chunk computes does not depend on the thread that takes it."""
    nchunk = (P.pos.shape[0] + CHUNK - 1) // CHUNK
    for q in range(size):
        b = (rank + q) % size
        lo, hi = block_bounds(b, size, nchunk)
        c = grab(S.sync, which, b, lo)
        while c < hi:
            if which == 0:
                _pair_chunk(c, P, L, prm, S)
            else:
                _particle_chunk(c, mode, P, L, W, prm, S)
            c = grab(S.sync, which, b, lo)


@njit(**NJIT)
def _fused_pass(mode, P, L, W, prm, S):
    """Both passes of a step on one thread, chunk by chunk: the pair pass of chunk c, then
    at once its particle pass. Exact (the same operations in the same order per particle
    and per chunk as the two passes one after the other): the half list lists a pair under
    its smaller id, so once the pair pass has done chunks 0 to c every force on a particle
    of chunk c is stored; and the particle pass of c changes only c's particles, which no
    later pair pass reads (it reads partners j > i). What the gather reads was written a
    moment before and is still in cache: a step streams its state through memory once
    instead of twice, which is what a scene larger than a core's cache pays for."""
    for c in range((P.pos.shape[0] + CHUNK - 1) // CHUNK):
        _pair_chunk(c, P, L, prm, S)
        _particle_chunk(c, mode, P, L, W, prm, S)


@njit(**NJIT)
def serial_pass(which, mode, P, L, W, prm, S):
    """One whole pass on the calling thread, chunk by chunk (for profiling the passes one at
    a time, ``benchmarks/engine_speed.py --profile``; a run never calls it)."""
    for c in range((P.pos.shape[0] + CHUNK - 1) // CHUNK):
        if which == 0:
            _pair_chunk(c, P, L, prm, S)
        else:
            _particle_chunk(c, mode, P, L, W, prm, S)


@njit(**NJIT_INLINE)
def _pair_setup(prm):
    """What the pair pass reads once per chunk (CPU) or per thread (CUDA): the pair law, its
    switches, the box lengths [m] and their inverses [1/m]."""
    lx = prm.length[0]
    ly = prm.length[1]
    lz = prm.length[2]
    law = _pair_law(prm.pair)
    flags = _pair_flags()
    return law, flags, lx, ly, lz, 1.0 / lx, 1.0 / ly, 1.0 / lz


@njit(**NJIT_INLINE)
def _wall_setup(prm):
    """The wall law and its switches (read once per chunk, or per CUDA thread)."""
    wlaw = _wall_law(prm.wall)
    wflags = _wall_flags()
    return wlaw, wflags


@njit(**NJIT)
def _pair_chunk(c, P, L, prm, S):
    """Contact forces of the listed pairs of the particles of chunk c (:func:`_pair_one` for
    each, in order). (A plain function: the parallel wrapper stays small, which keeps numba's
    parfor pass, and so the compile time, short.)"""
    law, flags, lx, ly, lz, ilx, ily, ilz = _pair_setup(prm)
    stat = S.chunk_stat
    stat[c, 0] = 0.0
    for i in range(c * CHUNK, min(P.pos.shape[0], (c + 1) * CHUNK)):
        _pair_one(i, c, P, L, prm, stat, law, flags, lx, ly, lz, ilx, ily, ilz)


@njit(**NJIT_INLINE)
def _pair_one(i, c, P, L, prm, stat, law, flags, lx, ly, lz, ilx, ily, ilz):
    """Contact forces of the listed pairs of particle i: the force and torque on i are
    written to ``P.frc``/``P.trq`` [N, N m] and its rolling moments to ``P.roll`` [N]; those
    on j go to the entry's slots for the gather. A problem is flagged in row c of ``stat``
    (the CPU: i's chunk; CUDA: i itself). The one body of the pair pass for both targets
    (compiled as a CUDA device function by engine.cuda)."""
    pos = P.pos
    vel = P.vel
    omg = P.omg
    rad = P.rad
    mass = P.mass
    entry = L.entry
    ovl_frac = prm.max_overlap
    dt = prm.dt
    xi = pos[i, 0]
    yi = pos[i, 1]
    zi = pos[i, 2]
    vxi = vel[i, 0]
    vyi = vel[i, 1]
    vzi = vel[i, 2]
    ri = rad[i]
    mi = mass[i]
    fx = 0.0
    fy = 0.0
    fz = 0.0
    tx = 0.0
    ty = 0.0
    tz = 0.0
    roll = 0.0  # sum of mu_r |f_el| over i's listed contacts
    for k in range(L.start[i], L.start[i + 1]):
        j = L.j[k]
        dx = xi - pos[j, 0]
        dy = yi - pos[j, 1]
        dz = zi - pos[j, 2]
        if PERIODIC_X:
            dx -= lx * math.floor(dx * ilx + 0.5)
        if PERIODIC_Y:
            dy -= ly * math.floor(dy * ily + 0.5)
        if PERIODIC_Z:
            dz -= lz * math.floor(dz * ilz + 0.5)
        r2 = dx * dx + dy * dy + dz * dz
        rj = rad[j]
        rs = ri + rj
        if r2 >= rs * rs:
            if entry[k, 0] != 0.0:  # the contact just opened: delete its history
                for s in range(N_SLOT):
                    entry[k, s] = 0.0
            continue
        r = math.sqrt(r2)
        d = rs - r
        rmin = min(ri, rj)
        if d > ovl_frac * rmin:
            _flag(stat, c, OVERLAP, i, j, d / rmin)
        inv_r = 1.0 / r
        sx = 0.0
        sy = 0.0
        sz = 0.0
        if FRICTION:
            sx = ri * omg[i, 0] + rj * omg[j, 0]
            sy = ri * omg[i, 1] + rj * omg[j, 1]
            sz = ri * omg[i, 2] + rj * omg[j, 2]
        mj = mass[j]
        m_eff = mi * mj / (mi + mj) if DAMPING else 0.0
        r_star = ri * rj / rs if PAIR_EFFECTIVE_RADIUS else 0.0
        fcx, fcy, fcz, tix, tiy, tiz, tjx, tjy, tjz, rm = pair_contact(
            entry,
            k,
            d,
            dx * inv_r,
            dy * inv_r,
            dz * inv_r,
            vxi - vel[j, 0],
            vyi - vel[j, 1],
            vzi - vel[j, 2],
            sx,
            sy,
            sz,
            ri,
            rj,
            r_star,
            m_eff,
            law,
            flags,
            dt,
        )
        fx += fcx
        fy += fcy
        fz += fcz
        entry[k, F_SLOT] = -fcx
        entry[k, F_SLOT + 1] = -fcy
        entry[k, F_SLOT + 2] = -fcz
        if FRICTION:
            tx += tix
            ty += tiy
            tz += tiz
            entry[k, T_SLOT] = tjx
            entry[k, T_SLOT + 1] = tjy
            entry[k, T_SLOT + 2] = tjz
        if ROLLING:
            roll += rm
            entry[k, R_SLOT] = rm
    P.frc[i, 0] = fx
    P.frc[i, 1] = fy
    P.frc[i, 2] = fz
    if FRICTION:
        P.trq[i, 0] = tx
        P.trq[i, 1] = ty
        P.trq[i, 2] = tz
    if ROLLING:
        P.roll[i] = roll


@njit(**NJIT)
def _particle_chunk(c, mode, P, L, W, prm, S):
    """Gather the pair forces on each particle of chunk c, add walls, rolling resistance and
    gravity, integrate (:func:`_particle_one` for each, in order).

    ``mode``: FORCES, CLOSE, STEP or OPEN (see the constants). The chunk's force on each
    wall [N] goes to ``W.acc[c]``, its largest squared displacement since the last list
    build [m^2] to ``S.chunk_disp[c]``.
    """
    wlaw, wflags = _wall_setup(prm)
    disp2 = 0.0
    if mode == OPEN:
        S.chunk_stat[c, 0] = 0.0
    else:
        for w in range(W.point.shape[0]):
            W.acc[c, w, 0] = 0.0
            W.acc[c, w, 1] = 0.0
            W.acc[c, w, 2] = 0.0
    stat = S.chunk_stat
    wacc = W.acc
    pos = P.pos
    vel = P.vel
    omg = P.omg
    frc = P.frc
    trq = P.trq
    roll_in = P.roll
    rad = P.rad
    mass = P.mass
    inv_mass = P.inv_mass
    inv_inertia = P.inv_inertia
    pos_build = P.pos_build
    rev_start = L.rev_start
    rev_k = L.rev_k
    entry = L.entry
    wpoint = W.point
    wnormal = W.normal
    wvel = W.vel
    whist = W.hist
    dt = prm.dt
    ovl_frac = prm.max_overlap
    max_step = prm.max_step
    grav = prm.gravity
    for i in range(c * CHUNK, min(P.pos.shape[0], (c + 1) * CHUNK)):
        # >>> _particle_one (engine.kernel.specialise writes its body here: the same code,
        # inlined in the source, as fast as the pass was before it became a function)
        e2 = _particle_one(
            i,
            c,
            mode,
            pos,
            vel,
            omg,
            frc,
            trq,
            roll_in,
            rad,
            mass,
            inv_mass,
            inv_inertia,
            pos_build,
            rev_start,
            rev_k,
            entry,
            wpoint,
            wnormal,
            wvel,
            whist,
            wacc,
            stat,
            dt,
            ovl_frac,
            max_step,
            grav,
            wlaw,
            wflags,
        )
        # <<< _particle_one
        disp2 = max(disp2, e2)
    S.chunk_disp[c] = disp2


@njit(**NJIT_INLINE)
def _particle_one(
    i,
    c,
    mode,
    pos,
    vel,
    omg,
    frc,
    trq,
    roll_in,
    rad,
    mass,
    inv_mass,
    inv_inertia,
    pos_build,
    rev_start,
    rev_k,
    entry,
    wpoint,
    wnormal,
    wvel,
    whist,
    wacc,
    stat,
    dt,
    ovl_frac,
    max_step,
    grav,
    wlaw,
    wflags,
):
    """Particle i of the particle pass: gather the pair forces stored for it, add walls,
    rolling resistance and gravity, integrate (velocity Verlet kick and drift).

    Problems are flagged in row c of ``stat`` and the force of i on each wall is subtracted
    from ``wacc[c]`` [N] (the CPU: i's chunk; CUDA: i itself). It takes the records' fields
    as arrays and scalars, not the records: passed a record, the
    inlined body took a reference to each of its arrays per particle, which made the CPU
    pass ten times slower. Returns the squared
    displacement of i since the last list build [m^2] (0 in a mode without drift). The one
    body of the particle pass for both targets (a CUDA device function in engine.cuda).
    """
    nw = wpoint.shape[0]
    h = dt if mode == STEP else 0.5 * dt
    ri = rad[i]
    fx = frc[i, 0]
    fy = frc[i, 1]
    fz = frc[i, 2]
    tx = 0.0
    ty = 0.0
    tz = 0.0
    if FRICTION or (ROTATION and mode == OPEN):
        tx = trq[i, 0]
        ty = trq[i, 1]
        tz = trq[i, 2]
    if mode != OPEN:
        roll = 0.0
        if ROLLING:
            roll = roll_in[i]
        for kk in range(rev_start[i], rev_start[i + 1]):
            k = rev_k[kk]
            fx += entry[k, F_SLOT]
            fy += entry[k, F_SLOT + 1]
            fz += entry[k, F_SLOT + 2]
            if FRICTION:
                tx += entry[k, T_SLOT]
                ty += entry[k, T_SLOT + 1]
                tz += entry[k, T_SLOT + 2]
            if ROLLING:
                roll += entry[k, R_SLOT]
        if WALLS:
            for w in range(nw):
                nx = wnormal[w, 0]
                ny = wnormal[w, 1]
                nz = wnormal[w, 2]
                d = ri - (
                    (pos[i, 0] - wpoint[w, 0]) * nx
                    + (pos[i, 1] - wpoint[w, 1]) * ny
                    + (pos[i, 2] - wpoint[w, 2]) * nz
                )
                row = i * nw + w
                if d <= 0.0:
                    if whist[row, 0] != 0.0:  # the contact just opened
                        for s in range(N_WALL_HIST):
                            whist[row, s] = 0.0
                    continue
                if d > ovl_frac * ri:
                    _flag(stat, c, OVERLAP, i, -1 - w, d / ri)
                sx = 0.0
                sy = 0.0
                sz = 0.0
                if WALL_FRICTION:
                    sx = ri * omg[i, 0]
                    sy = ri * omg[i, 1]
                    sz = ri * omg[i, 2]
                fcx, fcy, fcz, tix, tiy, tiz, _tjx, _tjy, _tjz, rm = wall_contact(
                    whist,
                    row,
                    d,
                    nx,
                    ny,
                    nz,
                    vel[i, 0] - wvel[w, 0],
                    vel[i, 1] - wvel[w, 1],
                    vel[i, 2] - wvel[w, 2],
                    sx,
                    sy,
                    sz,
                    ri,
                    0.0,
                    ri,
                    mass[i],
                    wlaw,
                    wflags,
                    dt,
                )
                fx += fcx
                fy += fcy
                fz += fcz
                wacc[c, w, 0] -= fcx
                wacc[c, w, 1] -= fcy
                wacc[c, w, 2] -= fcz
                if WALL_FRICTION:
                    tx += tix
                    ty += tiy
                    tz += tiz
                if WALL_ROLLING:
                    roll += rm
        if ANY_ROLLING:  # every contact pulls against the same unit spin: applied once
            ax, ay, az = rolling_torque(omg[i, 0], omg[i, 1], omg[i, 2], 1.0, roll, ri)
            tx += ax
            ty += ay
            tz += az
        if GRAVITY:
            fx += mass[i] * grav[0]
            fy += mass[i] * grav[1]
            fz += mass[i] * grav[2]
        frc[i, 0] = fx
        frc[i, 1] = fy
        frc[i, 2] = fz
        if ROTATION:
            trq[i, 0] = tx
            trq[i, 1] = ty
            trq[i, 2] = tz
        if mode == FORCES:
            if not math.isfinite(fx + fy + fz + tx + ty + tz):
                _flag(stat, c, NAN, i, -1, 0.0)
    # one exit (no early return): numba then prunes the reference counts of the record
    # fields this function reads, which it does per particle once inlined
    e2 = 0.0
    if mode != FORCES:  # FORCES: no integration
        im = inv_mass[i]
        vx = vel[i, 0] + h * fx * im
        vy = vel[i, 1] + h * fy * im
        vz = vel[i, 2] + h * fz * im
        vel[i, 0] = vx
        vel[i, 1] = vy
        vel[i, 2] = vz
        if ROTATION:
            ii = inv_inertia[i]
            omg[i, 0] += h * tx * ii
            omg[i, 1] += h * ty * ii
            omg[i, 2] += h * tz * ii
        v2 = vx * vx + vy * vy + vz * vz
        if not math.isfinite(v2 + pos[i, 0] + pos[i, 1] + pos[i, 2]):
            _flag(stat, c, NAN, i, -1, 0.0)
        elif v2 * dt * dt > (max_step * ri) ** 2:
            _flag(stat, c, SPEED, i, -1, math.sqrt(v2) * dt / ri)
        if mode == STEP or mode == OPEN:
            x = pos[i, 0] + dt * vx
            y = pos[i, 1] + dt * vy
            z = pos[i, 2] + dt * vz
            pos[i, 0] = x
            pos[i, 1] = y
            pos[i, 2] = z
            ex = x - pos_build[i, 0]
            ey = y - pos_build[i, 1]
            ez = z - pos_build[i, 2]
            e2 = ex * ex + ey * ey + ez * ez
    return e2


@njit(**NJIT)
def run_member(t, team, nsteps, pause, phase, P, L, W, prm, S):
    """The one compiled entry point (so every kernel is compiled once, with one signature):
    member ``t`` of a call's thread team of ``team`` threads. The caller
    (:class:`engine.Simulation`) zeroes ``S.sync`` and runs member 0 in its own thread and
    members 1 to team - 1 on threads of the engine's pool, all at once (the function holds no
    GIL); the result is in ``S.sync[SYNC_STEPS]`` (steps completed) and ``S.sync[SYNC_STATUS]``.

    Args: ``t``, ``team``, ``nsteps``, ``pause``, ``phase`` (int64), then the state records of
    :mod:`engine.kernel.state`: particles ``P``, neighbour list ``L``, walls ``W``, step
    parameters ``prm`` (time step ``prm.dt`` [s]) and scratch ``S``.

    ``nsteps > 0``: advance up to that many steps. ``phase`` 0: the state is at a whole step
    with valid forces; ``phase`` 1: resuming after a neighbour-list rebuild, the opening kick
    and drift of the first step are done. ``nsteps == 0``: evaluate forces and torques at the
    current state, no integration.

    Status: ``REBUILD``: some particle has moved more than half the skin; the caller rebuilds
    the list (engine.kernel.neighbour, compiled once for every scene) and resumes with phase
    1. ``PAUSE``: ``pause`` steps are done and more remain; the call returns exactly where a
    rebuild would (the next step opened), so that the caller, who resumes with phase 1 and no
    rebuild, gets the same bits as one uninterrupted call (a bounded call returns to Python,
    which can then report progress and hear a stop). On an instability ``S.info`` holds the
    particle ids and the value.

    The members meet at barriers between the passes, instead of forking and joining twice
    per step. Every member takes chunks of each pass, then waits at the barrier; after the
    particle pass all read the same chunk flags and displacements and so take the same
    decision (go on, rebuild, stop); rank 0 alone writes the shared scalars (wall forces and
    positions, the result, the chunk counters). Should a member not start in time, the team
    falls back to one thread (:func:`engine.kernel.team.team_join`): slower, never stuck,
    same result. (No ``prange`` region: one cost a scene's kernel about a third more compile
    time, and the threads of the engine's pool do the same work.)
    """
    sync = S.sync
    rank, size = team_join(sync, team)
    if rank < 0:
        return
    # np.int64 arguments throughout: one signature, so every callee is compiled once
    half_skin2 = 0.25 * prm.skin * prm.skin
    if phase == 0 and nsteps > 0:
        _pass(np.int64(1), np.int64(OPEN), rank, size, P, L, W, prm, S)
        team_barrier(sync, size)
        st = status_code(S.chunk_stat)
        if st != OK:
            if rank == 0:
                _result(sync, 0, _status(S.chunk_stat, S.info))
            return
        if rank == 0:
            _advance_walls(W.point, W.vel, prm.dt)
            reset_grabs(sync, 1, size)
        if _largest(S.chunk_disp) > half_skin2:
            if rank == 0:
                _result(sync, 0, REBUILD)
            return
        team_barrier(sync, size)
    s = 0
    while True:
        mode = FORCES if nsteps == 0 else (STEP if s < nsteps - 1 else CLOSE)
        if size == 1:
            _fused_pass(mode, P, L, W, prm, S)
        else:
            _pass(np.int64(0), mode, rank, size, P, L, W, prm, S)
            team_barrier(sync, size)
            _pass(np.int64(1), mode, rank, size, P, L, W, prm, S)
            team_barrier(sync, size)
        st = status_code(S.chunk_stat)
        if rank == 0:
            _finish_forces(W.acc, W.force)
        if st != OK or nsteps == 0:
            if rank == 0:
                _result(sync, s, _status(S.chunk_stat, S.info))
            return
        s += 1
        if s >= nsteps:
            if rank == 0:
                _result(sync, s, OK)
            return
        if rank == 0:
            _advance_walls(W.point, W.vel, prm.dt)
        if _largest(S.chunk_disp) > half_skin2:
            if rank == 0:
                _result(sync, s, REBUILD)
            return
        if s >= pause:  # every thread has the same s: all leave together
            if rank == 0:
                _result(sync, s, PAUSE)
            return
        if rank == 0:
            reset_grabs(sync, 0, size)
            reset_grabs(sync, 1, size)
        team_barrier(sync, size)


@njit(**NJIT)
def _result(sync, steps, status):
    sync[SYNC_STEPS] = steps
    sync[SYNC_STATUS] = status
