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
from engine.kernel.mesh import (
    MESH_SLOTS,
    SAME_POINT,
    T_MESH,
    T_OWN,
    edge_function,
    end_dot,
    mesh_drift2,
)
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
MESHES = True
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

ANY_WALLS = WALLS or MESHES
ROTATION = FRICTION or ROLLING or (ANY_WALLS and (WALL_FRICTION or WALL_ROLLING))
ANY_ROLLING = ROLLING or (ANY_WALLS and WALL_ROLLING)
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
#: a mesh contact row (engine.kernel.mesh): the wall history, then the contact point in the
#: mesh's frame (3) [m], the mesh + 1 (0: a free row), the overlap [m]
MH_POINT = N_WALL_HIST
MH_TAG = N_WALL_HIST + 3
MH_OVERLAP = N_WALL_HIST + 4
N_MESH_HIST = N_WALL_HIST + 5
#: mesh contact rows per particle: its kept contacts and one spare (no history kept)
MESH_ROWS = MESH_SLOTS + 1

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
    if MESHES:  # (without meshes W.mesh is an empty tuple, and this is compiled out)
        ms = W.mesh
        mvert = ms.mvert
        mtri = ms.mtri
        mtri_n = ms.mtri_n
        medge = ms.medge
        mvert_start = ms.mvert_start
        mvert_edge = ms.mvert_edge
        cand_start = ms.cand_start
        cand_t = ms.cand_t
        mhist = ms.mhist
        mscr = ms.mscr
        mbox = ms.box
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
            mvert,
            mtri,
            mtri_n,
            medge,
            mvert_start,
            mvert_edge,
            cand_start,
            cand_t,
            mhist,
            mscr,
            mbox,
            dt,
            ovl_frac,
            max_step,
            grav,
            wlaw,
            wflags,
        )
        # <<< _particle_one
        disp2 = max(disp2, e2)
    if MESHES:
        if c == 0 and (mode == STEP or mode == OPEN):  # the meshes move too: list valid?
            disp2 = max(disp2, mesh_drift2(wpoint, wvel, ms.mshift0, wnormal.shape[0], dt))
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
    mvert,
    mtri,
    mtri_n,
    medge,
    mvert_start,
    mvert_edge,
    cand_start,
    cand_t,
    mhist,
    mscr,
    mbox,
    dt,
    ovl_frac,
    max_step,
    grav,
    wlaw,
    wflags,
):
    """Particle i of the particle pass: gather the pair forces stored for it, add walls (the
    planes, then the meshes: :func:`_mesh_one`), rolling resistance and gravity, integrate
    (velocity Verlet kick and drift).

    Problems are flagged in row c of ``stat`` and the force of i on each wall is subtracted
    from ``wacc[c]`` [N] (the CPU: i's chunk; CUDA: i itself); ``mscr[c]`` is the scratch of
    its mesh contacts. It takes the records' fields
    as arrays and scalars, not the records: passed a record, the
    inlined body took a reference to each of its arrays per particle, which made the CPU
    pass ten times slower. Returns the squared
    displacement of i since the last list build [m^2] (0 in a mode without drift). The one
    body of the particle pass for both targets (a CUDA device function in engine.cuda).
    """
    # the planes (the meshes' rows of wpoint follow them)
    nw = wnormal.shape[0] if MESHES else wpoint.shape[0]
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
        if MESHES:
            if cand_start[i + 1] > cand_start[i]:  # near a mesh at the last list build
                msx = 0.0
                msy = 0.0
                msz = 0.0
                if WALL_FRICTION:
                    msx = ri * omg[i, 0]
                    msy = ri * omg[i, 1]
                    msz = ri * omg[i, 2]
                # >>> _mesh_one (engine.kernel.specialise writes its body here: called, the
                # fourteen arrays it takes cost as many reference counts each time)
                mfx, mfy, mfz, mtx, mty, mtz, mroll = _mesh_one(
                    i,
                    c,
                    pos[i, 0],
                    pos[i, 1],
                    pos[i, 2],
                    vel[i, 0],
                    vel[i, 1],
                    vel[i, 2],
                    msx,
                    msy,
                    msz,
                    ri,
                    mass[i],
                    nw,
                    wpoint,
                    wvel,
                    wacc,
                    stat,
                    mvert,
                    mtri,
                    mtri_n,
                    medge,
                    mvert_start,
                    mvert_edge,
                    cand_start,
                    cand_t,
                    mhist,
                    mscr,
                    mbox,
                    ovl_frac,
                    dt,
                    wlaw,
                    wflags,
                )
                # <<< _mesh_one
                fx += mfx
                fy += mfy
                fz += mfz
                if WALL_FRICTION:
                    tx += mtx
                    ty += mty
                    tz += mtz
                if WALL_ROLLING:
                    roll += mroll
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


@njit(**NJIT_INLINE)
def _mesh_keep(mscr, c, n_c, first, qx, qy, qz, nx, ny, nz, d, m, tol2):
    """Add a contact (closest point q in the mesh's frame [m], unit normal n from the mesh to
    the particle, overlap d [m], mesh m) to the particle's list ``mscr[c]`` unless a contact
    of the same mesh (listed from ``first``) has its closest point within ``sqrt(tol2)``
    [m]: then it is that contact, seen again through the rounding (engine.kernel.mesh).
    Returns the new count (unchanged when full: more contacts than ``MESH_CONTACTS``)."""
    for q in range(first, n_c):
        ex = mscr[c, q, 0] - qx
        ey = mscr[c, q, 1] - qy
        ez = mscr[c, q, 2] - qz
        if ex * ex + ey * ey + ez * ez <= tol2:
            return n_c
    if n_c >= mscr.shape[1]:
        return n_c
    mscr[c, n_c, 0] = qx
    mscr[c, n_c, 1] = qy
    mscr[c, n_c, 2] = qz
    mscr[c, n_c, 3] = nx
    mscr[c, n_c, 4] = ny
    mscr[c, n_c, 5] = nz
    mscr[c, n_c, 6] = d
    mscr[c, n_c, 7] = m
    mscr[c, n_c, 8] = -1.0
    return n_c + 1


@njit(**NJIT)
def _mesh_one(
    i,
    c,
    xi,
    yi,
    zi,
    vxi,
    vyi,
    vzi,
    sx,
    sy,
    sz,
    ri,
    mi,
    nw,
    wpoint,
    wvel,
    wacc,
    stat,
    mvert,
    mtri,
    mtri_n,
    medge,
    mvert_start,
    mvert_edge,
    cand_start,
    cand_t,
    mhist,
    mscr,
    mbox,
    ovl_frac,
    dt,
    wlaw,
    wflags,
):
    """The mesh contacts of particle i (centre x [m], velocity v [m/s], spin term
    ``s = R_i w_i`` [m/s], radius ri [m], mass mi [kg]) through the one wall composition.

    1. Contacts: over its candidate triangles (by mesh, then triangle), each face whose
       interior holds the centre's projection, each edge and vertex this triangle owns whose
       closest point is a local minimum of the distance over the mesh (engine.kernel.mesh),
       within ri; one contact per closest point (``_mesh_keep``); a mesh touched but left
       without a contact by the rounding gets its nearest point.
    2. History: each contact takes the kept row of the same mesh whose last contact point
       lies nearest its own (within ri; nearest pairs first), so that a contact rolling or
       sliding from one triangle to the next, across an edge or a vertex, keeps its
       tangential spring; rows left unclaimed are contacts that ended (cleared); a new
       contact takes a free row (the spare row, its history not kept, when none is free).
    3. Forces: ``wall_contact`` as for a plane (normal from the closest point to the
       centre, the mesh's velocity), the force on mesh m into ``wacc[c, nw + m]``.

    Returns the force [N], torque [N m] and rolling moment [N] on i. Its one ``return`` is
    its last line: engine.kernel.specialise writes the body in place of its call in
    :func:`_particle_one` (its locals renamed, its array arguments the caller's own), as
    numba would count a reference to each of the fourteen arrays at every call."""
    r2 = ri * ri
    tol2 = (SAME_POINT * ri) * (SAME_POINT * ri)
    n_c = 0
    first = 0
    cur = -1
    best = math.inf
    bx = 0.0
    by = 0.0
    bz = 0.0
    px = 0.0
    py = 0.0
    pz = 0.0
    k1 = cand_start[i + 1]
    k = cand_start[i]
    while True:
        m = mtri[cand_t[k], T_MESH] if k < k1 else -1
        if m != cur:
            if cur >= 0 and n_c == first and best < r2:
                # touched but nothing counted (rounding): the nearest point is a contact
                dist = math.sqrt(best)
                n_c = _mesh_keep(
                    mscr,
                    c,
                    n_c,
                    first,
                    bx,
                    by,
                    bz,
                    (px - bx) / dist,
                    (py - by) / dist,
                    (pz - bz) / dist,
                    ri - dist,
                    cur,
                    tol2,
                )
            if k >= k1:
                break
            cur = m
            first = n_c
            best = math.inf
            px = xi - wpoint[nw + m, 0]  # the centre in the mesh's frame
            py = yi - wpoint[nw + m, 1]
            pz = zi - wpoint[nw + m, 2]
        t = cand_t[k]
        k += 1
        a = mtri[t, 0]
        b = mtri[t, 1]
        cc = mtri[t, 2]
        nx = mtri_n[t, 0]
        ny = mtri_n[t, 1]
        nz = mtri_n[t, 2]
        hh = (px - mvert[a, 0]) * nx + (py - mvert[a, 1]) * ny + (pz - mvert[a, 2]) * nz
        if hh * hh >= r2:  # its plane out of reach: so are its face, edges and corners
            continue
        # the face: the projection strictly inside (the edge functions its edges also read)
        s0 = edge_function(mvert, mtri_n, t, a, b, px, py, pz)
        s1 = edge_function(mvert, mtri_n, t, b, cc, px, py, pz)
        s2 = edge_function(mvert, mtri_n, t, cc, a, px, py, pz)
        if s0 > 0.0 and s1 > 0.0 and s2 > 0.0:
            qx = px - hh * nx
            qy = py - hh * ny
            qz = pz - hh * nz
            if hh * hh < best:
                best = hh * hh
                bx = qx
                by = qy
                bz = qz
            if hh < 0.0:  # two-sided: the particle below the triangle
                hh = -hh
                nx = -nx
                ny = -ny
                nz = -nz
            n_c = _mesh_keep(mscr, c, n_c, first, qx, qy, qz, nx, ny, nz, ri - hh, m, tol2)
        own = mtri[t, T_OWN]
        if own != 0:
            for q in range(3):
                if own & (1 << q):  # its edge q: the closest point inside the segment
                    e = mtri[t, 3 + q]
                    v = medge[e, 0]
                    w = medge[e, 1]
                    dv = end_dot(mvert, v, w, px, py, pz)
                    dw = end_dot(mvert, w, v, px, py, pz)
                    if dv > 0.0 and dw > 0.0:
                        ex = mvert[w, 0] - mvert[v, 0]
                        ey = mvert[w, 1] - mvert[v, 1]
                        ez = mvert[w, 2] - mvert[v, 2]
                        f = dv / (ex * ex + ey * ey + ez * ez)
                        qx = mvert[v, 0] + f * ex
                        qy = mvert[v, 1] + f * ey
                        qz = mvert[v, 2] + f * ez
                        dx = px - qx
                        dy = py - qy
                        dz = pz - qz
                        dd = dx * dx + dy * dy + dz * dz
                        if dd < best:
                            best = dd
                            bx = qx
                            by = qy
                            bz = qz
                        if dd < r2:
                            # a local minimum: no triangle beside the edge has the
                            # projection on its side of it
                            ok = True
                            for side in range(2):
                                u = medge[e, 2 + 2 * side]
                                if u >= 0:
                                    uq = medge[e, 3 + 2 * side]
                                    s = edge_function(
                                        mvert,
                                        mtri_n,
                                        u,
                                        mtri[u, uq],
                                        mtri[u, (uq + 1) % 3],
                                        px,
                                        py,
                                        pz,
                                    )
                                    if s > 0.0:
                                        ok = False
                            if ok:
                                dist = math.sqrt(dd)
                                n_c = _mesh_keep(
                                    mscr,
                                    c,
                                    n_c,
                                    first,
                                    qx,
                                    qy,
                                    qz,
                                    dx / dist,
                                    dy / dist,
                                    dz / dist,
                                    ri - dist,
                                    m,
                                    tol2,
                                )
            for q in range(3):
                if own & (8 << q):  # its corner q
                    v = mtri[t, q]
                    dx = px - mvert[v, 0]
                    dy = py - mvert[v, 1]
                    dz = pz - mvert[v, 2]
                    dd = dx * dx + dy * dy + dz * dz
                    if dd < best:
                        best = dd
                        bx = mvert[v, 0]
                        by = mvert[v, 1]
                        bz = mvert[v, 2]
                    if dd < r2:
                        # a local minimum: the projection past v on none of its edges
                        ok = True
                        for kk in range(mvert_start[v], mvert_start[v + 1]):
                            e = mvert_edge[kk]
                            w = medge[e, 0] + medge[e, 1] - v
                            if end_dot(mvert, v, w, px, py, pz) > 0.0:
                                ok = False
                        if ok:
                            dist = math.sqrt(dd)
                            n_c = _mesh_keep(
                                mscr,
                                c,
                                n_c,
                                first,
                                mvert[v, 0],
                                mvert[v, 1],
                                mvert[v, 2],
                                dx / dist,
                                dy / dist,
                                dz / dist,
                                ri - dist,
                                m,
                                tol2,
                            )

    # 2. the kept rows: nearest (contact, row) pairs of the same mesh first
    base = i * MESH_ROWS
    claimed = 0
    for _ in range(n_c):
        nearest = r2
        bj = -1
        bs = -1
        for j in range(n_c):
            if mscr[c, j, 8] >= 0.0:
                continue
            tag = mscr[c, j, 7] + 1.0
            for s in range(MESH_SLOTS):
                row = base + s
                if (claimed >> s) & 1 or mhist[row, MH_TAG] != tag:
                    continue
                ex = mhist[row, MH_POINT] - mscr[c, j, 0]
                ey = mhist[row, MH_POINT + 1] - mscr[c, j, 1]
                ez = mhist[row, MH_POINT + 2] - mscr[c, j, 2]
                if PERIODIC_X:  # a contact carried across a periodic face: the nearest image
                    ex -= mbox[1, 0] * math.floor(ex / mbox[1, 0] + 0.5)
                if PERIODIC_Y:
                    ey -= mbox[1, 1] * math.floor(ey / mbox[1, 1] + 0.5)
                if PERIODIC_Z:
                    ez -= mbox[1, 2] * math.floor(ez / mbox[1, 2] + 0.5)
                dd = ex * ex + ey * ey + ez * ez
                if dd < nearest:
                    nearest = dd
                    bj = j
                    bs = s
        if bj < 0:
            break
        mscr[c, bj, 8] = base + bs
        claimed |= 1 << bs
    for s in range(MESH_SLOTS):  # unclaimed rows: their contacts ended
        row = base + s
        if not (claimed >> s) & 1 and mhist[row, MH_TAG] != 0.0:
            for col in range(N_MESH_HIST):
                mhist[row, col] = 0.0
    for j in range(n_c):  # new contacts: a free row, else the spare one
        if mscr[c, j, 8] < 0.0:
            row = base + MESH_SLOTS
            for s in range(MESH_SLOTS):
                if not (claimed >> s) & 1:
                    claimed |= 1 << s
                    row = base + s
                    break
            if row == base + MESH_SLOTS:
                for col in range(N_MESH_HIST):
                    mhist[row, col] = 0.0
            mscr[c, j, 8] = row

    # 3. the forces, each contact through the wall composition
    fx = 0.0
    fy = 0.0
    fz = 0.0
    tx = 0.0
    ty = 0.0
    tz = 0.0
    roll = 0.0
    for j in range(n_c):
        row = int(mscr[c, j, 8])
        m = int(mscr[c, j, 7])
        d = mscr[c, j, 6]
        if d > ovl_frac * ri:
            _flag(stat, c, OVERLAP, i, -1 - (nw + m), d / ri)
        fcx, fcy, fcz, tix, tiy, tiz, _tjx, _tjy, _tjz, rm = wall_contact(
            mhist,
            row,
            d,
            mscr[c, j, 3],
            mscr[c, j, 4],
            mscr[c, j, 5],
            vxi - wvel[nw + m, 0],
            vyi - wvel[nw + m, 1],
            vzi - wvel[nw + m, 2],
            sx,
            sy,
            sz,
            ri,
            0.0,
            ri,
            mi,
            wlaw,
            wflags,
            dt,
        )
        fx += fcx
        fy += fcy
        fz += fcz
        wacc[c, nw + m, 0] -= fcx
        wacc[c, nw + m, 1] -= fcy
        wacc[c, nw + m, 2] -= fcz
        if WALL_FRICTION:
            tx += tix
            ty += tiy
            tz += tiz
        if WALL_ROLLING:
            roll += rm
        if row < base + MESH_SLOTS:  # a kept row: where the contact is, for the next step
            mhist[row, MH_POINT] = mscr[c, j, 0]
            mhist[row, MH_POINT + 1] = mscr[c, j, 1]
            mhist[row, MH_POINT + 2] = mscr[c, j, 2]
            mhist[row, MH_TAG] = m + 1.0
            mhist[row, MH_OVERLAP] = d
    return fx, fy, fz, tx, ty, tz, roll


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
