"""Time-step kernel template, specialised per scene by :mod:`engine.kernels`.

The feature block below is rewritten for each scene and the result imported as its own module,
so numba sees every flag as a compile-time constant and compiles out what the scene does not
use (adhesion, plasticity, friction and tangential history, rolling, damping, each periodic
axis, walls, gravity, rotation). The per-entry slot layout follows from the flags too.

One step (velocity Verlet, LAMMPS ordering; forces see the half-step velocity):

1. pair pass (``_pair_chunk``): every particle i (in parallel, fixed chunks) loops over its
   half list, computes each contact once, adds the force on i to i and stores the force on j
   in the entry;
2. particle pass (``_particle_chunk``): every particle gathers the forces stored for it
   (reverse list, fixed order), adds walls and gravity, then kicks and drifts. The closing half
   kick of one step and the opening half kick of the next are fused into one full kick.

No reduction depends on the thread count: every sum runs in a fixed order over fixed chunks, so
trajectories are bit-identical with any number of threads.
"""

import math

import numpy as np
from numba import njit, prange

from engine.config import CHUNK, NJIT, NJIT_PARALLEL
from engine.laws import bilinear_contact, hertz_contact, rolling_torque
from engine.step_common import (
    NAN,
    OK,
    OVERLAP,
    REBUILD,
    SPEED,
    _advance_walls,
    _finish_forces,
    _flag,
    _largest,
    _status,
)

# >>> features (rewritten by engine.kernels)
PAIR_HERTZ = False
ADHESION = True
ADHESIVE_BRANCH = True
PLASTIC = True
FRICTION = True
ROLLING = True
DAMPING = True
PERIODIC_X = True
PERIODIC_Y = True
PERIODIC_Z = False
WALLS = True
WALL_FRICTION = True
WALL_ROLLING = True
WALL_DAMPING = True
GRAVITY = True
# <<< features

PAIR_TORQUE = FRICTION or ROLLING
ROTATION = PAIR_TORQUE or (WALLS and (WALL_FRICTION or WALL_ROLLING))
#: history slots: overlap marker / largest overlap, then the tangential spring
N_HIST = 4 if FRICTION else 1
F_SLOT = N_HIST
#: entry slots after the history: force on j (3); friction torque on j (3, with FRICTION);
#: |f| of the contact for j's rolling resistance (1, with ROLLING)
T_SLOT = F_SLOT + 3
R_SLOT = T_SLOT + 3 if FRICTION else T_SLOT
N_SLOT = R_SLOT + 1 if ROLLING else R_SLOT

# particle_pass modes
FORCES = 0  # forces only
CLOSE = 1  # forces, closing half kick
STEP = 2  # forces, full kick (closing + next opening half kick), drift
OPEN = 3  # opening half kick and drift with the stored forces


@njit(**NJIT_PARALLEL)
def parallel_pass(
    which,
    pos,
    vel,
    omg,
    rad,
    mass,
    inv_mass,
    inv_inertia,
    frc,
    trq,
    pos_build,
    nbr_start,
    nbr_j,
    rev_start,
    rev_k,
    entry,
    pp,
    length,
    wall_point,
    wall_normal,
    wall_vel,
    wall_hist,
    wp,
    gravity,
    dt,
    mode,
    step_frac,
    ovl_frac,
    wall_acc,
    chunk_stat,
    chunk_disp,
):
    """Run one pass over all particle chunks in parallel: ``which`` 0 is the pair pass
    (:func:`_pair_chunk`), 1 the particle pass (:func:`_particle_chunk`) in ``mode``.

    One parallel function for both passes: numba's parfor machinery, the slow part of
    compiling, then runs once per scene instead of twice.
    """
    nchunk = (pos.shape[0] + CHUNK - 1) // CHUNK
    for c in prange(nchunk):
        # np.int64: the gufunc's loop index is unsigned, typing's is signed; one signature
        if which == 0:
            _pair_chunk(
                np.int64(c),
                pos,
                vel,
                omg,
                rad,
                mass,
                frc,
                trq,
                nbr_start,
                nbr_j,
                entry,
                pp,
                length,
                dt,
                ovl_frac,
                chunk_stat,
            )
        else:
            _particle_chunk(
                np.int64(c),
                pos,
                vel,
                omg,
                frc,
                trq,
                rad,
                mass,
                inv_mass,
                inv_inertia,
                pos_build,
                rev_start,
                rev_k,
                entry,
                wall_point,
                wall_normal,
                wall_vel,
                wall_hist,
                pp,
                wp,
                gravity,
                dt,
                mode,
                step_frac,
                ovl_frac,
                wall_acc,
                chunk_stat,
                chunk_disp,
            )


@njit(**NJIT)
def _pair_chunk(
    c,
    pos,
    vel,
    omg,
    rad,
    mass,
    frc,
    trq,
    nbr_start,
    nbr_j,
    entry,
    pp,
    length,
    dt,
    ovl_frac,
    chunk_stat,
):
    """Contact forces of the listed pairs of the particles of chunk c. The force and torque
    on i are written to frc/trq [N, N m]; those on j go to the entry's force slots for the
    gather. (A plain function: the parallel wrapper stays small, which keeps numba's parfor
    pass, and so the compile time, short.)"""
    n = pos.shape[0]
    lx = length[0]
    ly = length[1]
    lz = length[2]
    ilx = 1.0 / lx
    ily = 1.0 / ly
    ilz = 1.0 / lz
    p0 = pp[0]
    p1 = pp[1]
    p2 = pp[2]
    p3 = pp[3] if (ADHESIVE_BRANCH or PAIR_HERTZ) else 0.0
    p4 = pp[4]
    p5 = pp[5]
    p6 = pp[6]
    mu_r = pp[4] if PAIR_HERTZ else pp[7]
    chunk_stat[c, 0] = 0.0
    for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        vxi = vel[i, 0]
        vyi = vel[i, 1]
        vzi = vel[i, 2]
        wxi = 0.0
        wyi = 0.0
        wzi = 0.0
        if FRICTION:
            wxi = omg[i, 0]
            wyi = omg[i, 1]
            wzi = omg[i, 2]
        ri = rad[i]
        mi = mass[i]
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        f_abs_sum = 0.0  # sum of |f| over i's contacts, for its rolling resistance
        for k in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr_j[k]
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
                _flag(chunk_stat, c, OVERLAP, i, j, d / rmin)
            inv_r = 1.0 / r
            nx = dx * inv_r
            ny = dy * inv_r
            nz = dz * inv_r
            vx = vxi - vel[j, 0]
            vy = vyi - vel[j, 1]
            vz = vzi - vel[j, 2]
            if FRICTION:
                # contact-point velocity: v_rel -= (Ri wi + Rj wj) x n
                sx = ri * wxi + rj * omg[j, 0]
                sy = ri * wyi + rj * omg[j, 1]
                sz = ri * wzi + rj * omg[j, 2]
                vx -= sy * nz - sz * ny
                vy -= sz * nx - sx * nz
                vz -= sx * ny - sy * nx
            mj = mass[j]
            meff = mi * mj / (mi + mj)
            xix = 0.0
            xiy = 0.0
            xiz = 0.0
            if FRICTION:
                xix = entry[k, 1]
                xiy = entry[k, 2]
                xiz = entry[k, 3]
            if PAIR_HERTZ:
                fn, f_roll, ftx, fty, ftz, xix, xiy, xiz = hertz_contact(
                    d,
                    nx,
                    ny,
                    nz,
                    vx,
                    vy,
                    vz,
                    xix,
                    xiy,
                    xiz,
                    ri * rj / rs,
                    meff,
                    p0,
                    p1,
                    p2,
                    p3,
                    dt,
                    FRICTION,
                    DAMPING,
                )
                entry[k, 0] = d
            else:
                fn, f_roll, ftx, fty, ftz, dmax, xix, xiy, xiz = bilinear_contact(
                    d,
                    nx,
                    ny,
                    nz,
                    vx,
                    vy,
                    vz,
                    entry[k, 0],
                    xix,
                    xiy,
                    xiz,
                    meff,
                    p0,
                    p1,
                    p2,
                    p3,
                    p4,
                    p5,
                    p6,
                    dt,
                    PLASTIC,
                    ADHESION,
                    FRICTION,
                    DAMPING,
                )
                entry[k, 0] = dmax
            if FRICTION:
                entry[k, 1] = xix
                entry[k, 2] = xiy
                entry[k, 3] = xiz
            fcx = fn * nx + ftx
            fcy = fn * ny + fty
            fcz = fn * nz + ftz
            fx += fcx
            fy += fcy
            fz += fcz
            entry[k, F_SLOT] = -fcx
            entry[k, F_SLOT + 1] = -fcy
            entry[k, F_SLOT + 2] = -fcz
            if FRICTION:
                # both spheres turn the same way: t_i = -Ri n x Ft, t_j = -Rj n x Ft
                cx = ny * ftz - nz * fty
                cy = nz * ftx - nx * ftz
                cz = nx * fty - ny * ftx
                tx -= ri * cx
                ty -= ri * cy
                tz -= ri * cz
                entry[k, T_SLOT] = -rj * cx
                entry[k, T_SLOT + 1] = -rj * cy
                entry[k, T_SLOT + 2] = -rj * cz
            if ROLLING:
                # every contact of a particle pulls against the same unit spin vector, so the
                # torques are applied once per particle with the summed |f| (particle pass)
                f_abs = abs(f_roll)
                f_abs_sum += f_abs
                entry[k, R_SLOT] = f_abs
        if ROLLING:
            ax, ay, az = rolling_torque(omg[i, 0], omg[i, 1], omg[i, 2], mu_r, f_abs_sum, ri)
            tx += ax
            ty += ay
            tz += az
        frc[i, 0] = fx
        frc[i, 1] = fy
        frc[i, 2] = fz
        if ROTATION:
            trq[i, 0] = tx
            trq[i, 1] = ty
            trq[i, 2] = tz


@njit(**NJIT)
def _particle_chunk(
    c,
    pos,
    vel,
    omg,
    frc,
    trq,
    rad,
    mass,
    inv_mass,
    inv_inertia,
    pos_build,
    rev_start,
    rev_k,
    entry,
    wall_point,
    wall_normal,
    wall_vel,
    wall_hist,
    pp,
    wp,
    gravity,
    dt,
    mode,
    step_frac,
    ovl_frac,
    wall_acc,
    chunk_stat,
    chunk_disp,
):
    """Gather the pair forces on each particle of chunk c, add walls and gravity, integrate.

    ``mode``: FORCES, CLOSE, STEP or OPEN (see the constants). The chunk's force on each
    wall [N] goes to ``wall_acc[c]``, its largest squared displacement since the last list
    build [m^2] to ``chunk_disp[c]``.
    """
    n = pos.shape[0]
    nw = wall_point.shape[0]
    h = dt if mode == STEP else 0.5 * dt
    disp2 = 0.0
    if mode == OPEN:
        chunk_stat[c, 0] = 0.0
    else:
        for w in range(nw):
            wall_acc[c, w, 0] = 0.0
            wall_acc[c, w, 1] = 0.0
            wall_acc[c, w, 2] = 0.0
    for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
        ri = rad[i]
        fx = frc[i, 0]
        fy = frc[i, 1]
        fz = frc[i, 2]
        tx = 0.0
        ty = 0.0
        tz = 0.0
        if PAIR_TORQUE or (ROTATION and mode == OPEN):
            tx = trq[i, 0]
            ty = trq[i, 1]
            tz = trq[i, 2]
        if mode != OPEN:
            f_abs_sum = 0.0
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
                    f_abs_sum += entry[k, R_SLOT]
            if ROLLING:  # j-side rolling resistance of the pairs, applied once
                ax, ay, az = rolling_torque(
                    omg[i, 0], omg[i, 1], omg[i, 2], pp[4] if PAIR_HERTZ else pp[7], f_abs_sum, ri
                )
                tx += ax
                ty += ay
                tz += az
            if WALLS:
                for w in range(nw):
                    nx = wall_normal[w, 0]
                    ny = wall_normal[w, 1]
                    nz = wall_normal[w, 2]
                    d = ri - (
                        (pos[i, 0] - wall_point[w, 0]) * nx
                        + (pos[i, 1] - wall_point[w, 1]) * ny
                        + (pos[i, 2] - wall_point[w, 2]) * nz
                    )
                    if d <= 0.0:
                        if WALL_FRICTION:
                            wall_hist[i, w, 0] = 0.0
                            wall_hist[i, w, 1] = 0.0
                            wall_hist[i, w, 2] = 0.0
                        continue
                    if d > ovl_frac * ri:
                        _flag(chunk_stat, c, OVERLAP, i, -1 - w, d / ri)
                    vx = vel[i, 0] - wall_vel[w, 0]
                    vy = vel[i, 1] - wall_vel[w, 1]
                    vz = vel[i, 2] - wall_vel[w, 2]
                    xix = 0.0
                    xiy = 0.0
                    xiz = 0.0
                    if WALL_FRICTION:
                        # contact point at -R n: v_c = v - R w x n
                        wx = omg[i, 0]
                        wy = omg[i, 1]
                        wz = omg[i, 2]
                        vx -= ri * (wy * nz - wz * ny)
                        vy -= ri * (wz * nx - wx * nz)
                        vz -= ri * (wx * ny - wy * nx)
                        xix = wall_hist[i, w, 0]
                        xiy = wall_hist[i, w, 1]
                        xiz = wall_hist[i, w, 2]
                    fn, f_el, ftx, fty, ftz, xix, xiy, xiz = hertz_contact(
                        d,
                        nx,
                        ny,
                        nz,
                        vx,
                        vy,
                        vz,
                        xix,
                        xiy,
                        xiz,
                        ri,
                        mass[i],
                        wp[0],
                        wp[1],
                        wp[2],
                        wp[3],
                        dt,
                        WALL_FRICTION,
                        WALL_DAMPING,
                    )
                    fcx = fn * nx + ftx
                    fcy = fn * ny + fty
                    fcz = fn * nz + ftz
                    fx += fcx
                    fy += fcy
                    fz += fcz
                    wall_acc[c, w, 0] -= fcx
                    wall_acc[c, w, 1] -= fcy
                    wall_acc[c, w, 2] -= fcz
                    if WALL_FRICTION:
                        wall_hist[i, w, 0] = xix
                        wall_hist[i, w, 1] = xiy
                        wall_hist[i, w, 2] = xiz
                        tx -= ri * (ny * ftz - nz * fty)
                        ty -= ri * (nz * ftx - nx * ftz)
                        tz -= ri * (nx * fty - ny * ftx)
                    if WALL_ROLLING:
                        ax, ay, az = rolling_torque(
                            omg[i, 0], omg[i, 1], omg[i, 2], wp[4], f_el, ri
                        )
                        tx += ax
                        ty += ay
                        tz += az
            if GRAVITY:
                fx += mass[i] * gravity[0]
                fy += mass[i] * gravity[1]
                fz += mass[i] * gravity[2]
            frc[i, 0] = fx
            frc[i, 1] = fy
            frc[i, 2] = fz
            if ROTATION:
                trq[i, 0] = tx
                trq[i, 1] = ty
                trq[i, 2] = tz
            if mode == FORCES:
                if not math.isfinite(fx + fy + fz + tx + ty + tz):
                    _flag(chunk_stat, c, NAN, i, -1, 0.0)
                continue
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
            _flag(chunk_stat, c, NAN, i, -1, 0.0)
        elif v2 * dt * dt > (step_frac * ri) ** 2:
            _flag(chunk_stat, c, SPEED, i, -1, math.sqrt(v2) * dt / ri)
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
            disp2 = max(disp2, ex * ex + ey * ey + ez * ez)
    chunk_disp[c] = disp2


@njit(**NJIT)
def run_steps(
    nsteps,
    phase,
    dt,
    pos,
    vel,
    omg,
    frc,
    trq,
    rad,
    mass,
    inv_mass,
    inv_inertia,
    pos_build,
    nbr_start,
    nbr_j,
    entry,
    rev_start,
    rev_k,
    wall_point,
    wall_normal,
    wall_vel,
    wall_hist,
    wall_force,
    pp,
    wp,
    gravity,
    length,
    skin,
    limits,
    wall_acc,
    chunk_stat,
    chunk_disp,
    info,
):
    """The one compiled entry point (so every kernel is compiled once, with one signature).

    ``nsteps > 0``: advance up to that many steps of ``dt`` [s]. ``phase`` 0: the state is at
    a whole step with valid forces; ``phase`` 1: resuming after a neighbour-list rebuild, the
    opening kick and drift of the first step are done. ``nsteps == 0``: evaluate forces and
    torques at the current state, no integration.

    Returns (steps completed, status). ``REBUILD``: some particle has moved more than half the
    skin; the caller rebuilds the list (engine.neighbour, compiled once for every scene) and
    resumes with phase 1. On an instability ``info`` holds the particle ids and the value.
    """
    ovl = limits[0]
    sfrac = limits[1]
    half_skin2 = 0.25 * skin * skin
    if phase == 0 and nsteps > 0:
        parallel_pass(
            np.int64(1),
            pos,
            vel,
            omg,
            rad,
            mass,
            inv_mass,
            inv_inertia,
            frc,
            trq,
            pos_build,
            nbr_start,
            nbr_j,
            rev_start,
            rev_k,
            entry,
            pp,
            length,
            wall_point,
            wall_normal,
            wall_vel,
            wall_hist,
            wp,
            gravity,
            dt,
            np.int64(OPEN),
            sfrac,
            ovl,
            wall_acc,
            chunk_stat,
            chunk_disp,
        )
        st = _status(chunk_stat, info)
        if st != OK:
            return 0, st
        _advance_walls(wall_point, wall_vel, dt)
        if _largest(chunk_disp) > half_skin2:
            return 0, REBUILD
    s = 0
    while True:
        mode = FORCES if nsteps == 0 else (STEP if s < nsteps - 1 else CLOSE)
        for which in range(2):
            parallel_pass(
                which,
                pos,
                vel,
                omg,
                rad,
                mass,
                inv_mass,
                inv_inertia,
                frc,
                trq,
                pos_build,
                nbr_start,
                nbr_j,
                rev_start,
                rev_k,
                entry,
                pp,
                length,
                wall_point,
                wall_normal,
                wall_vel,
                wall_hist,
                wp,
                gravity,
                dt,
                mode,
                sfrac,
                ovl,
                wall_acc,
                chunk_stat,
                chunk_disp,
            )
        _finish_forces(wall_acc, wall_force)
        st = _status(chunk_stat, info)
        if st != OK or nsteps == 0:
            return s, st
        s += 1
        if s >= nsteps:
            return s, OK
        _advance_walls(wall_point, wall_vel, dt)
        if _largest(chunk_disp) > half_skin2:
            return s, REBUILD
