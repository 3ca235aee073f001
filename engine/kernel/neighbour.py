"""Cell list and Verlet neighbour list with per-contact history transfer.

Layout (jax-md style: sized in Python, filled in compiled code at fixed capacity):

- half list, CSR: the neighbours of particle i are ``nbr_j[nbr_start[i]:nbr_start[i+1]]``, all
  ``j > i`` and sorted, so every pair appears once;
- ``entry[k, :]``: per-entry slots, the first ``n_hist`` of which are the contact history
  (largest overlap, tangential spring); the rest hold the force and torque on j written by the
  force pass;
- reverse list, CSR: ``rev_k[rev_start[j]:rev_start[j+1]]`` are the entries whose second
  particle is j, in increasing order of the first particle, for the deterministic gather.

The build is serial: it runs every few hundred steps and a serial build keeps the compile
short; its cost is part of the measured particle-steps per second. The grid, a particle's
cell, the sort of a particle's segment with the history carried over and the commit of an
entry are written once here (``NJIT_INLINE``) and are the CUDA backend's too
(engine/cuda/_sources.py, compiled by engine.cuda.device), so both build the same list.

A pair enters the list when its surface gap (minimum image on periodic axes) is below the skin.
Compiled code here and in the step uses plain loops and ``math`` rather than numpy methods:
each numpy function used in compiled code costs its own compile, and the first compile of a
scene is a user-visible wait.
The list stays valid until some particle has moved more than half the skin. A rebuild copies
the history of every pair present in both lists (a merge of two sorted segments per particle);
a pair that is in contact is always in the new list, so no history is ever dropped. When the
new list does not fit, the build returns minus the number of entries it needs and leaves the
old list untouched: the caller grows the buffers and builds again.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.config import NJIT, NJIT_INLINE


@njit(**NJIT)
def wrap_positions(pos, lo, length, periodic, images):
    """Wrap positions into [lo, lo + L) on periodic axes, counting the wraps in ``images``
    (so that ``pos + images * L`` is the unwrapped position) [m]."""
    for i in range(pos.shape[0]):
        wrap_one(i, pos, lo, length, periodic, images)


@njit(**NJIT_INLINE)
def wrap_one(i, pos, lo, length, periodic, images):
    """:func:`wrap_positions` for particle i (also the CUDA backend's, engine.cuda) [m]."""
    for a in range(3):
        if periodic[a]:
            s = math.floor((pos[i, a] - lo[a]) / length[a])
            if s != 0.0:
                pos[i, a] -= s * length[a]
                images[i, a] += np.int64(s)


@njit(**NJIT)
def cell_grid(pos, lo, length, periodic, cut, max_cells):
    """The cell grid of :func:`grid_cells` over the particles' extent: ``grid`` (row 0 the
    cell origin, row 1 the cell size [m]) and the cell counts."""
    bounds = np.empty((3, 2))
    for a in range(3):
        mn = pos[0, a]
        mx = pos[0, a]
        for i in range(1, pos.shape[0]):
            mn = min(mn, pos[i, a])
            mx = max(mx, pos[i, a])
        bounds[a, 0] = mn
        bounds[a, 1] = mx
    grid = np.empty((2, 3))
    ncell = np.empty(3, dtype=np.int64)
    grid_cells(bounds, lo, length, periodic, cut, max_cells, grid, ncell)
    return grid, ncell


@njit(**NJIT_INLINE)
def grid_cells(bounds, lo, length, periodic, cut, max_cells, grid, ncell):
    """A grid whose cells are at least ``cut`` wide [m] into ``grid`` (row 0 the cell origin,
    row 1 the cell size [m]) and ``ncell`` (cells per axis): periodic axes tile the period,
    open axes span ``bounds`` (per axis the smallest and largest coordinate [m]); at most
    ``max_cells`` cells (larger cells when the particles are spread far apart). Both
    backends' (the CUDA one in one thread)."""
    for a in range(3):
        if periodic[a]:
            grid[0, a] = lo[a]
            ext = length[a]
        else:
            grid[0, a] = bounds[a, 0]
            ext = bounds[a, 1] - bounds[a, 0]
        grid[1, a] = ext
        ncell[a] = max(1, int(ext / cut))
    while ncell[0] * ncell[1] * ncell[2] > max_cells:
        a = 0
        for b in range(1, 3):
            if ncell[b] > ncell[a]:
                a = b
        ncell[a] = max(1, ncell[a] // 2)
    for a in range(3):
        ext = grid[1, a]
        grid[1, a] = max(ext / ncell[a], cut) if not periodic[a] else ext / ncell[a]


@njit(**NJIT_INLINE)
def cell_of(i, pos, grid, ncell, cell3):
    """The cell of particle i: its coordinates into ``cell3[i]`` (clamped to the grid), its
    flat index returned."""
    for a in range(3):
        c = int((pos[i, a] - grid[0, a]) / grid[1, a])
        cell3[i, a] = min(max(c, 0), ncell[a] - 1)
    return (cell3[i, 0] * ncell[1] + cell3[i, 1]) * ncell[2] + cell3[i, 2]


@njit(**NJIT_INLINE)
def offsets_and_cursors(start, n):
    """The counting sort's middle step: the counts of the ``n`` buckets in ``start[1:n + 1]``
    (``start[0]`` = 0) become their offsets (a running sum, in place); returns a copy of
    the first ``n`` offsets, each bucket's fill cursor (int64)."""
    for a in range(n):
        start[a + 1] += start[a]
    fill = np.empty(n, dtype=np.int64)
    for a in range(n):
        fill[a] = start[a]
    return fill


@njit(**NJIT_INLINE)
def sort_segment(a, s, e):
    """Sort ``a[s:e]`` in place (insertion sort: the segments are short)."""
    for q in range(s + 1, e):
        v = a[q]
        b = q - 1
        while b >= s and a[b] > v:
            a[b + 1] = a[b]
            b -= 1
        a[b + 1] = v


@njit(**NJIT_INLINE)
def sort_and_carry(i, new_start, new_j, new_entry, start, nbr_j, entry, n_hist):
    """Particle i's segment of the new list sorted, its entries zeroed but for the
    ``n_hist`` history slots of every pair also in the old list (``start``, ``nbr_j``,
    ``entry``), carried over: a merge of two sorted segments. Both backends' (the CUDA one
    in one thread per particle)."""
    s = new_start[i]
    e = new_start[i + 1]
    sort_segment(new_j, s, e)
    o = start[i]
    oe = start[i + 1]
    for k in range(s, e):
        for h in range(new_entry.shape[1]):
            new_entry[k, h] = 0.0
        j = new_j[k]
        while o < oe and nbr_j[o] < j:
            o += 1
        if o < oe and nbr_j[o] == j:
            for h in range(n_hist):
                new_entry[k, h] = entry[o, h]


@njit(**NJIT_INLINE)
def commit_entry(k, new_j, new_entry, nbr_j, entry):
    """Entry k of the new list into the list's arrays; its second particle returned."""
    j = new_j[k]
    nbr_j[k] = j
    for h in range(entry.shape[1]):
        entry[k, h] = new_entry[k, h]
    return j


@njit(**NJIT)
def _neighbour_cell(c, o, n, periodic):
    """Cell coordinate at offset o in {-1, 0, 1} from c on an axis of n cells, or -1 when it
    does not exist or repeats another offset (periodic axes with fewer than 3 cells)."""
    cc = c + o
    if periodic:
        if n == 1 and o != 0:
            return -1
        if n == 2 and o == 1:
            return -1
        return cc % n
    if cc < 0 or cc >= n:
        return -1
    return cc


@njit(**NJIT)
def _scan(i, pos, rad, skin, cell3, ncell, cell_start, cell_list, periodic, length, out, offset):
    """Count the neighbours j > i of i, storing them from ``out[offset]`` while they fit."""
    cnt = 0
    xi = pos[i, 0]
    yi = pos[i, 1]
    zi = pos[i, 2]
    ri = rad[i] + skin
    for ox in range(-1, 2):
        cx = _neighbour_cell(cell3[i, 0], ox, ncell[0], periodic[0])
        if cx < 0:
            continue
        for oy in range(-1, 2):
            cy = _neighbour_cell(cell3[i, 1], oy, ncell[1], periodic[1])
            if cy < 0:
                continue
            for oz in range(-1, 2):
                cz = _neighbour_cell(cell3[i, 2], oz, ncell[2], periodic[2])
                if cz < 0:
                    continue
                c = (cx * ncell[1] + cy) * ncell[2] + cz
                for p in range(cell_start[c], cell_start[c + 1]):
                    j = cell_list[p]
                    if j <= i:
                        continue
                    dx = xi - pos[j, 0]
                    dy = yi - pos[j, 1]
                    dz = zi - pos[j, 2]
                    if periodic[0]:
                        dx -= length[0] * math.floor(dx / length[0] + 0.5)
                    if periodic[1]:
                        dy -= length[1] * math.floor(dy / length[1] + 0.5)
                    if periodic[2]:
                        dz -= length[2] * math.floor(dz / length[2] + 0.5)
                    rc = ri + rad[j]
                    if dx * dx + dy * dy + dz * dz < rc * rc:
                        if offset + cnt < out.shape[0]:
                            out[offset + cnt] = j
                        cnt += 1
    return cnt


@njit(**NJIT)
def build_neighbour_list(
    pos,
    rad,
    lo,
    length,
    periodic,
    skin,
    images,
    nbr_start,
    nbr_j,
    entry,
    n_hist,
    rev_start,
    rev_k,
    pos_build,
):
    """Rebuild the half neighbour list and transfer the contact history.

    Args: positions [m] (wrapped in place on periodic axes), radii [m], box lower corner and
    lengths [m], periodic flags, skin [m], image counters; the list arrays (see module doc),
    the number of history slots, and the positions at the last build (updated on success).
    Returns: the number of entries (>= 0), or minus the number needed when it exceeds the
    capacity ``nbr_j.shape[0]`` (then nothing but the wrapping has changed).
    """
    n = pos.shape[0]
    wrap_positions(pos, lo, length, periodic, images)
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, rad[i])
    grid, ncell = cell_grid(pos, lo, length, periodic, 2.0 * rmax + skin, 4 * n + 64)
    ncells = ncell[0] * ncell[1] * ncell[2]

    # counting sort of particles into cells (each cell lists its particles in increasing id)
    cell3 = np.empty((n, 3), dtype=np.int64)
    key = np.empty(n, dtype=np.int64)
    cell_start = np.zeros(ncells + 1, dtype=np.int64)
    for i in range(n):
        c = cell_of(i, pos, grid, ncell, cell3)
        key[i] = c
        cell_start[c + 1] += 1
    fill = offsets_and_cursors(cell_start, ncells)
    cell_list = np.empty(n, dtype=np.int64)
    for i in range(n):
        c = key[i]
        cell_list[fill[c]] = i
        fill[c] += 1

    # one pass: scan every particle into a buffer of the list's capacity, counting all
    cap = nbr_j.shape[0]
    new_j = np.empty(cap, dtype=nbr_j.dtype)
    new_start = np.empty(n + 1, dtype=np.int64)
    new_start[0] = 0
    for i in range(n):
        new_start[i + 1] = new_start[i] + _scan(
            i,
            pos,
            rad,
            skin,
            cell3,
            ncell,
            cell_start,
            cell_list,
            periodic,
            length,
            new_j,
            new_start[i],
        )
    total = new_start[n]
    if total > cap:
        return -total

    new_entry = np.empty((total, entry.shape[1]))
    for i in range(n):
        sort_and_carry(i, new_start, new_j, new_entry, nbr_start, nbr_j, entry, n_hist)
    for k in range(total):
        commit_entry(k, new_j, new_entry, nbr_j, entry)
    for i in range(n + 1):
        nbr_start[i] = new_start[i]

    reverse_list(nbr_start, nbr_j, rev_start, rev_k)
    for i in range(n):
        for a in range(3):
            pos_build[i, a] = pos[i, a]
    return total


@njit(**NJIT)
def reverse_list(nbr_start, nbr_j, rev_start, rev_k):
    """Fill the reverse list of a half list (see the module doc): the entries whose second
    particle is j, in increasing order of the first."""
    n = nbr_start.shape[0] - 1
    for j in range(n + 1):
        rev_start[j] = 0
    for k in range(nbr_start[n]):
        rev_start[nbr_j[k] + 1] += 1
    rfill = offsets_and_cursors(rev_start, n)
    for i in range(n):
        for k in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr_j[k]
            rev_k[rfill[j]] = k
            rfill[j] += 1


@njit(**NJIT)
def renumber_list(rank, nbr_start, nbr_j, entry, n_hist, f_slot, out_start, out_j, out_entry):
    """The half list with particle i renumbered ``rank[i]``: each pair listed under its smaller
    new id, every segment sorted, the ``n_hist`` history slots carried (slots 1 to
    ``n_hist - 1``, the tangential spring of the first particle against the second [m],
    negated where the two swap roles; slot 0, the largest overlap, kept) and the force on the
    second particle (slots ``f_slot`` to ``f_slot + 2`` [N], negated where they swap: what
    ``Simulation.contacts`` reads). The other slots (torque and rolling moment for the
    second particle) are zeroed: the pair pass writes them before the gather reads them.
    ``out_j``/``out_entry`` have the capacity of ``nbr_j``/``entry``. The same pairs, so
    the list stays valid for the renumbered positions of its last build (its reverse list:
    :func:`reverse_list`)."""
    n = rank.shape[0]
    for a in range(n + 1):
        out_start[a] = 0
    for i in range(n):
        ri = rank[i]
        for k in range(nbr_start[i], nbr_start[i + 1]):
            rj = rank[nbr_j[k]]
            out_start[min(ri, rj) + 1] += 1
    fill = offsets_and_cursors(out_start, n)
    for i in range(n):
        ri = rank[i]
        for k in range(nbr_start[i], nbr_start[i + 1]):
            rj = rank[nbr_j[k]]
            a = min(ri, rj)
            q = fill[a]
            fill[a] += 1
            out_j[q] = max(ri, rj)
            for s in range(entry.shape[1]):
                out_entry[q, s] = 0.0
            out_entry[q, 0] = entry[k, 0]
            sign = 1.0 if ri < rj else -1.0
            for h in range(1, n_hist):
                out_entry[q, h] = sign * entry[k, h]
            for h in range(f_slot, f_slot + 3):
                out_entry[q, h] = sign * entry[k, h]
    width = entry.shape[1]
    row = np.empty(width)
    for a in range(n):
        s = out_start[a]
        e = out_start[a + 1]
        for q in range(s + 1, e):  # insertion sort: segments are short
            v = out_j[q]
            for h in range(width):
                row[h] = out_entry[q, h]
            b = q - 1
            while b >= s and out_j[b] > v:
                out_j[b + 1] = out_j[b]
                for h in range(width):
                    out_entry[b + 1, h] = out_entry[b, h]
                b -= 1
            out_j[b + 1] = v
            for h in range(width):
                out_entry[b + 1, h] = row[h]
