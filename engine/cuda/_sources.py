"""Plain-Python sources of the CUDA kernels (compiled by :mod:`engine.cuda.kernels` with
``numba.cuda.jit`` after their names are bound).

The names they call and read that are not defined here (``_pair_one``, ``_particle_one``, the
scene's flags, the block sizes) are bound per scene: the per-particle bodies are the device
versions of the specialised CPU step module's (:mod:`engine.kernel.step_template`), the
neighbour search's those of :mod:`engine.kernel.neighbour` (its grid, cell, scan, segment sort
with the history merge and entry commit: written once, the CPU build's own). What is here is
only the CUDA-side arrangement: one thread per particle (or entry, or cell), reductions in a
fixed order, the control array that stops the queued kernels of a call when a step asks for a
rebuild or fails.

No float atomics: forces are gathered per particle from the entries (reverse list), chunk
and wall sums run in a fixed order. Integer atomics fill the cell and reverse lists; each
segment is then sorted, so the lists do not depend on the order the atomics ran in.
"""

# ruff: noqa: F821  (names bound per scene, see the module docstring)

import math

from numba import cuda

# control array slots (int64): stop flag, status, steps completed
CTL_STOP = 0
CTL_STATUS = 1
CTL_STEPS = 2
CTL_TOTAL = 3  # neighbour entries counted by the last build


# ---------------------------------------------------------------- stepping
def reset_ctl(ctl):
    if cuda.grid(1) == 0:
        ctl[CTL_STOP] = 0
        ctl[CTL_STATUS] = 0
        ctl[CTL_STEPS] = 0


def _pair_body(i, P, L, prm, stat):
    """Pair pass of particle i: its half list in order (the CPU's :func:`_pair_one`)."""
    law, flags, lx, ly, lz, ilx, ily, ilz = _pair_setup(prm)
    stat[i, 0] = 0.0
    _pair_one(i, i, P, L, prm, stat, law, flags, lx, ly, lz, ilx, ily, ilz)


def _particle_body(i, mode, P, L, W, prm, stat, wpart, disp):
    """Particle pass of particle i (gather in the reverse list's order, walls, rolling,
    gravity, kick, drift: the CPU's :func:`_particle_one`); its squared displacement to
    ``disp``."""
    if mode == OPEN:
        stat[i, 0] = 0.0
    else:
        for w in range(W.point.shape[0]):
            wpart[i, w, 0] = 0.0
            wpart[i, w, 1] = 0.0
            wpart[i, w, 2] = 0.0
    wlaw, wflags = _wall_setup(prm)
    ms = W.mesh  # on the device always the arrays (empty without meshes)
    disp[i] = _particle_one(
        i,
        i,
        mode,
        P.pos,
        P.vel,
        P.omg,
        P.frc,
        P.trq,
        P.roll,
        P.rad,
        P.mass,
        P.inv_mass,
        P.inv_inertia,
        P.pos_build,
        L.rev_start,
        L.rev_k,
        L.entry,
        W.point,
        W.normal,
        W.vel,
        W.hist,
        wpart,
        stat,
        ms.mvert,
        ms.mtri,
        ms.mtri_n,
        ms.medge,
        ms.mvert_start,
        ms.mvert_edge,
        ms.cand_start,
        ms.cand_t,
        ms.mhist,
        ms.mscr,
        ms.box,
        prm.dt,
        prm.max_overlap,
        prm.max_step,
        prm.gravity,
        wlaw,
        wflags,
    )


def _chunk_body(c, mode, stat, wpart, disp, cstat, cdisp, cacc, W, dt):
    """CPU chunk c of ``CHUNK`` particles reduced in particle order, as the CPU chunk
    does: largest displacement (chunk 0 also the meshes' drift since the list build), first
    problem, force on each wall (the particles' in order: the same additions as the CPU's)."""
    lo = c * CHUNK
    hi = min(disp.shape[0], lo + CHUNK)
    m = 0.0
    for q in range(lo, hi):
        m = max(m, disp[q])
    if MESHES:
        if c == 0 and (mode == STEP or mode == OPEN):
            m = max(m, mesh_drift2(W.point, W.vel, W.mesh.mshift0, W.normal.shape[0], dt))
    cdisp[c] = m
    cstat[c, 0] = 0.0
    for q in range(lo, hi):
        if stat[q, 0] != 0.0:
            for s in range(4):
                cstat[c, s] = stat[q, s]
            break
    if (WALLS or MESHES) and mode != OPEN:
        for w in range(wpart.shape[1]):
            for a in range(3):
                acc = 0.0
                for q in range(lo, hi):
                    acc += wpart[q, w, a]
                cacc[c, w, a] = acc


def pair_kernel(ctl, P, L, prm, stat):
    """Pair pass: one thread per particle."""
    i = cuda.grid(1)
    if ctl[CTL_STOP] == 0 and i < P.pos.shape[0]:
        _pair_body(i, P, L, prm, stat)


def particle_kernel(ctl, mode, P, L, W, prm, stat, wpart, disp):
    """Particle pass: one thread per particle."""
    i = cuda.grid(1)
    if ctl[CTL_STOP] == 0 and i < P.pos.shape[0]:
        _particle_body(i, mode, P, L, W, prm, stat, wpart, disp)


def chunk_kernel(ctl, mode, stat, wpart, disp, cstat, cdisp, cacc, W, dt):
    """Chunk reductions: one thread per CPU chunk."""
    c = cuda.grid(1)
    if ctl[CTL_STOP] == 0 and c < cdisp.shape[0]:
        _chunk_body(c, mode, stat, wpart, disp, cstat, cdisp, cacc, W, dt)


def finish_kernel(ctl, s, nsteps, opening, W, prm, cstat, cdisp, cacc, info):
    """End of a step (one block of ``RED_T`` threads): see :func:`_finish_body`."""
    if ctl[CTL_STOP] == 0:
        _finish_body(ctl, s, nsteps, opening, W, prm, cstat, cdisp, cacc, info)


def steps_kernel(
    ctl, s0, s1, nsteps, opening, P, L, W, prm, stat, wpart, disp, cstat, cdisp, cacc, info
):
    """Steps ``s0`` to ``s1 - 1`` of a call (with ``opening``, the opening kick and drift
    first) in one launch: the grid (cooperative, all blocks resident) goes through the same
    passes as the separate kernels, element by element in grid-stride loops, and meets at a
    grid barrier after each; block 0 ends each step (:func:`_finish_body`). Every thread
    reads the control record after a barrier, so all leave together when a step stops."""
    g = cuda.cg.this_grid()
    t = cuda.grid(1)
    nt = cuda.gridsize(1)
    n = P.pos.shape[0]
    nchunk = cdisp.shape[0]
    first_block = cuda.blockIdx.x == 0
    if opening != 0:
        if ctl[CTL_STOP] != 0:
            return
        for i in range(t, n, nt):
            _particle_body(i, OPEN, P, L, W, prm, stat, wpart, disp)
        g.sync()
        for c in range(t, nchunk, nt):
            _chunk_body(c, OPEN, stat, wpart, disp, cstat, cdisp, cacc, W, prm.dt)
        g.sync()
        if first_block:
            _finish_body(ctl, 0, nsteps, 1, W, prm, cstat, cdisp, cacc, info)
        g.sync()
    for s in range(s0, s1):
        if ctl[CTL_STOP] != 0:
            return
        mode = FORCES if nsteps == 0 else (STEP if s < nsteps - 1 else CLOSE)
        for i in range(t, n, nt):
            _pair_body(i, P, L, prm, stat)
        g.sync()
        for i in range(t, n, nt):
            _particle_body(i, mode, P, L, W, prm, stat, wpart, disp)
        g.sync()
        for c in range(t, nchunk, nt):
            _chunk_body(c, mode, stat, wpart, disp, cstat, cdisp, cacc, W, prm.dt)
        g.sync()
        if first_block:
            _finish_body(ctl, s, nsteps, 0, W, prm, cstat, cdisp, cacc, info)
        g.sync()


def _finish_body(ctl, s, nsteps, opening, W, prm, cstat, cdisp, cacc, info):
    """End of a step (one block): the largest displacement and the first problem over the
    chunks, the force on each wall (chunk sums in a fixed tree), then the decision the CPU
    team takes (go on, rebuild, stop) written to ``ctl``; the wall motion. Called by the
    ``RED_T`` threads of one block."""
    t = cuda.threadIdx.x
    nchunk = cdisp.shape[0]
    shm = cuda.shared.array(RED_T, float64)
    shi = cuda.shared.array(RED_T, int64)
    m = 0.0
    first = nchunk
    for c in range(t, nchunk, RED_T):
        m = max(m, cdisp[c])
        if first == nchunk and cstat[c, 0] != 0.0:
            first = c
    shm[t] = m
    shi[t] = first
    cuda.syncthreads()
    stride = RED_T // 2
    while stride > 0:
        if t < stride:
            shm[t] = max(shm[t], shm[t + stride])
            shi[t] = min(shi[t], shi[t + stride])
        cuda.syncthreads()
        stride //= 2
    disp2 = shm[0]
    first = shi[0]
    if (WALLS or MESHES) and opening == 0:
        nw = W.point.shape[0]  # the planes and the meshes
        for w in range(nw):
            for a in range(3):
                cuda.syncthreads()
                acc = 0.0
                for c in range(t, nchunk, RED_T):
                    acc += cacc[c, w, a]
                shm[t] = acc
                cuda.syncthreads()
                stride = RED_T // 2
                while stride > 0:
                    if t < stride:
                        shm[t] = shm[t] + shm[t + stride]
                    cuda.syncthreads()
                    stride //= 2
                if t == 0:
                    W.force[w, a] = shm[0]
    if t != 0:
        return
    st = OK
    if first < nchunk:
        st = int(cstat[first, 0])
        info[0] = cstat[first, 1]
        info[1] = cstat[first, 2]
        info[2] = cstat[first, 3]
    half_skin2 = 0.25 * prm.skin * prm.skin
    if opening != 0:
        if st != OK:
            _stop(ctl, st, 0)
            return
        _advance_walls(W.point, W.vel, prm.dt)
        if disp2 > half_skin2:
            _stop(ctl, REBUILD, 0)
        return
    if st != OK or nsteps == 0:
        _stop(ctl, st, s)
        return
    s1 = s + 1
    if s1 >= nsteps:
        _stop(ctl, OK, s1)
        return
    _advance_walls(W.point, W.vel, prm.dt)
    if disp2 > half_skin2:
        _stop(ctl, REBUILD, s1)
        return
    ctl[CTL_STEPS] = s1


def _stop(ctl, status, steps):
    ctl[CTL_STATUS] = status
    ctl[CTL_STEPS] = steps
    ctl[CTL_STOP] = 1


# ---------------------------------------------------------------- neighbour search
def wrap_kernel(pos, lo, length, periodic, images):
    i = cuda.grid(1)
    if i < pos.shape[0]:
        wrap_one(i, pos, lo, length, periodic, images)


def bounds_kernel(pos, bounds):
    """Smallest and largest coordinate per axis (one block; min and max do not depend on
    the order)."""
    t = cuda.threadIdx.x
    lo = cuda.shared.array(RED_T, float64)
    hi = cuda.shared.array(RED_T, float64)
    n = pos.shape[0]
    for a in range(3):
        mn = math.inf
        mx = -math.inf
        for i in range(t, n, RED_T):
            mn = min(mn, pos[i, a])
            mx = max(mx, pos[i, a])
        lo[t] = mn
        hi[t] = mx
        cuda.syncthreads()
        stride = RED_T // 2
        while stride > 0:
            if t < stride:
                lo[t] = min(lo[t], lo[t + stride])
                hi[t] = max(hi[t], hi[t + stride])
            cuda.syncthreads()
            stride //= 2
        if t == 0:
            bounds[a, 0] = lo[0]
            bounds[a, 1] = hi[0]
        cuda.syncthreads()


def grid_kernel(bounds, lo, length, periodic, cut, max_cells, grid, ncell):
    """The cell grid (one thread: :func:`engine.kernel.neighbour.grid_cells`): cells at least
    ``cut`` wide [m], periodic axes tiling the period, at most ``max_cells`` cells. ``grid``:
    origin (row 0) and cell size (row 1) [m]."""
    if cuda.grid(1) == 0:
        grid_cells(bounds, lo, length, periodic, cut, max_cells, grid, ncell)


def cell_kernel(pos, grid, ncell, cell3, key, count):
    """Cell of each particle (``cell_of``); counts per cell (integer atomics)."""
    i = cuda.grid(1)
    if i < pos.shape[0]:
        c = cell_of(i, pos, grid, ncell, cell3)
        key[i] = c
        cuda.atomic.add(count, c, 1)


def cell_fill_kernel(key, cell_start, fill, cell_list):
    i = cuda.grid(1)
    if i >= key.shape[0]:
        return
    c = key[i]
    cell_list[cell_start[c] + cuda.atomic.add(fill, c, 1)] = i


def count_kernel(pos, rad, skin, cell3, ncell, cell_start, cell_list, periodic, length, cnt, none):
    """Neighbours j > i of each particle within the skin (``_scan`` of engine.kernel.neighbour,
    counting only: ``none`` has length 0)."""
    i = cuda.grid(1)
    if i < pos.shape[0]:
        cnt[i] = _scan(
            i, pos, rad, skin, cell3, ncell, cell_start, cell_list, periodic, length, none, 0
        )


def list_kernel(
    pos,
    rad,
    skin,
    cell3,
    ncell,
    cell_start,
    cell_list,
    periodic,
    length,
    new_start,
    new_j,
    new_entry,
    start,
    nbr_j,
    entry,
    n_hist,
):
    """The new half list of particle i (sorted), with the history of every pair also in the
    old list carried over (``sort_and_carry`` of engine.kernel.neighbour, as the CPU's)."""
    i = cuda.grid(1)
    if i < pos.shape[0]:
        s = new_start[i]
        _scan(i, pos, rad, skin, cell3, ncell, cell_start, cell_list, periodic, length, new_j, s)
        sort_and_carry(i, new_start, new_j, new_entry, start, nbr_j, entry, n_hist)


def commit_kernel(total, new_start, new_j, new_entry, start, nbr_j, entry, rev_count):
    """The new list replaces the old one (``commit_entry``, as the CPU's); the reverse list's
    counts (integer atomics)."""
    k = cuda.grid(1)
    if k < start.shape[0]:
        start[k] = new_start[k]
    if k < total:
        cuda.atomic.add(rev_count, commit_entry(k, new_j, new_entry, nbr_j, entry), 1)


def rev_fill_kernel(total, nbr_j, rev_start, fill, rev_k):
    k = cuda.grid(1)
    if k < total:
        j = nbr_j[k]
        rev_k[rev_start[j] + cuda.atomic.add(fill, j, 1)] = k


def rev_sort_kernel(rev_start, rev_k, pos, pos_build):
    """Entries of each particle j in increasing order (the CPU's gather order, increasing
    first particle: ``sort_segment``); the positions of this build."""
    j = cuda.grid(1)
    if j < pos.shape[0]:
        sort_segment(rev_k, rev_start[j], rev_start[j + 1])
        for a in range(3):
            pos_build[j, a] = pos[j, a]


def mesh_count_kernel(
    pos, rad, skin, wpoint, nw, mvert, mtri, gridf, gridi, cell_start, cell_tri, cnt, none
):
    """Candidate triangles of each particle (``mesh_scan`` of engine.kernel.mesh, counting
    only: ``none`` has length 0)."""
    i = cuda.grid(1)
    if i < pos.shape[0]:
        cnt[i] = mesh_scan(
            i, pos, rad, skin, wpoint, nw, mvert, mtri, gridf, gridi, cell_start, cell_tri, none, 0
        )


def mesh_fill_kernel(
    pos, rad, skin, wpoint, nw, mvert, mtri, gridf, gridi, cell_start, cell_tri, start, cand_t
):
    """Each particle's candidate triangles from ``start[i]`` (increasing, as on the CPU)."""
    i = cuda.grid(1)
    if i < pos.shape[0]:
        mesh_scan(
            i,
            pos,
            rad,
            skin,
            wpoint,
            nw,
            mvert,
            mtri,
            gridf,
            gridi,
            cell_start,
            cell_tri,
            cand_t,
            start[i],
        )


def mesh_clear_kernel(cand_start, mhist):
    """The mesh contact rows of a particle without candidate triangles cleared."""
    i = cuda.grid(1)
    if i < cand_start.shape[0] - 1:
        clear_rows(i, cand_start, mhist)


def mesh_shift_kernel(wpoint, nw, mshift0):
    """The meshes' translations at this list build (one thread)."""
    if cuda.grid(1) == 0:
        for m in range(mshift0.shape[0]):
            for a in range(3):
                mshift0[m, a] = wpoint[nw + m, a]


def zero_kernel(a):
    k = cuda.grid(1)
    if k < a.shape[0]:
        a[k] = 0


# ---------------------------------------------------------------- exclusive scan (int64)
def scan_block_kernel(src, n, dst, sums):
    """Per block of ``SCAN_T * SCAN_SEG`` elements: ``dst[k + 1]`` = the sum of the block's
    ``src`` up to k; the block's total to ``sums``."""
    t = cuda.threadIdx.x
    b = cuda.blockIdx.x
    sh = cuda.shared.array(SCAN_T, int64)
    if b == 0 and t == 0:
        dst[0] = 0
    base = b * SCAN_T * SCAN_SEG + t * SCAN_SEG
    acc = 0
    for q in range(SCAN_SEG):
        if base + q < n:
            acc += src[base + q]
    sh[t] = acc
    cuda.syncthreads()
    off = 1
    while off < SCAN_T:  # Hillis-Steele inclusive scan of the thread totals
        v = sh[t - off] if t >= off else 0
        cuda.syncthreads()
        sh[t] += v
        cuda.syncthreads()
        off *= 2
    run = sh[t] - acc
    for q in range(SCAN_SEG):
        if base + q < n:
            run += src[base + q]
            dst[base + q + 1] = run
    if t == SCAN_T - 1:
        sums[b] = sh[t]


def scan_add_kernel(n, dst, offsets):
    k = cuda.grid(1)
    if k < n:
        dst[k + 1] += offsets[k // (SCAN_T * SCAN_SEG)]
