"""A curve sample's measures on the device: the sums a uniaxial sample reads (contact counts,
the contact virial over all contacts and over the interior window, the interior slab's solid
volume and coordination inputs, the platens' levers, the kinetic energy) computed by kernels
next to the state, so that only :data:`NV` numbers cross to the host instead of the whole
state (docs/GPU.md: on an H200 the copies of whole states took about 250 s of the 344 s
paper-scale reference).

One thread per particle writes the particle's row of :data:`COLUMNS` (its own half-list
entries, as :func:`engine.kernel.virial.pair_virial` sums them, and its reverse-list entries
for its contact count); the rows are summed per CPU chunk (``CHUNK`` particles in particle
order, one thread per chunk and column), then the chunk sums of each column by one block of
``RED_T`` threads in a fixed tree (as the wall forces of a step): the result does not depend
on thread scheduling, and two samples of the same state are bit-identical. The host's
measures sum the same terms in another order (particle by particle, contact by contact in
the sorted order of :meth:`engine.Simulation.contacts`): the two agree to float64 round-off
(tests/engine/test_cuda_measures.py).

The kernels are plain Python below, compiled with ``numba.cuda.jit`` by :func:`kernels`
(:mod:`engine.cuda.device`); ``CHUNK``, ``NV`` and ``RED_T`` are bound at compile time.
"""

# ruff: noqa: F821  (CHUNK, NV, RED_T and float64 are bound at compile time)

from __future__ import annotations

import math
import threading
from collections import namedtuple
from types import SimpleNamespace

import numpy as np
from numba import cuda
from numba.cuda import types as cuda_types

from ..core.config import CHUNK
from .device import kernel

#: The sums of one sample, in the order of the kernels' rows [SI]:
#: ``trans`` sum m v^2 [J x 2], ``rot`` sum omega^2 / (1 / I) [J x 2] (driven particles,
#: inverse inertia 0, left out), ``inside`` the particles whose centre heights above
#: ``bottom`` lie in [lo, hi], ``solid`` their spheres' volume inside that slab [m^3],
#: ``counts`` sum of the particles' contact counts (twice the contacts), ``counts_in`` the
#: same over the interior particles, ``lever_b``/``n_b`` and ``lever_t``/``n_t`` the sum
#: of (radius less overlap) [m] and the number of the particles touching the bottom and top
#: platens, ``virial`` (9, row-major a, b) sum over contacts of f_a l_b [N m] (as
#: :func:`engine.kernel.virial.pair_virial`), ``szz_in`` sum over contacts of the interior
#: particles' levers times n_z f_z [N m] (as
#: :func:`engine.uniaxial.measures.interior_axial_stress`).
COLUMNS = (
    "trans",
    "rot",
    "inside",
    "solid",
    "counts",
    "counts_in",
    "lever_b",
    "n_b",
    "lever_t",
    "n_t",
    *(f"virial_{a}{b}" for a in "xyz" for b in "xyz"),
    "szz_in",
)
NV = len(COLUMNS)
_V0 = COLUMNS.index("virial_xx")

SampleSums = namedtuple(
    "SampleSums",
    "trans rot inside solid counts counts_in lever_b n_b lever_t n_t virial szz_in",
)
SampleSums.__doc__ = """A sample's sums (see :data:`COLUMNS`), ``virial`` a (3, 3) array."""


def sums_from(out: np.ndarray) -> SampleSums:
    """The :class:`SampleSums` of the kernels' output row ``out`` (:data:`NV` values)."""
    v = np.array(out[_V0 : _V0 + 9], dtype=np.float64).reshape(3, 3)
    f = [float(x) for x in out]
    return SampleSums(*f[:_V0], v, f[_V0 + 9])


# ---------------------------------------------------------------- kernel sources
def measure_rows_kernel(
    pos, vel, omg, rad, mass, inv_inertia, start, nbr_j, entry, rev_start, rev_k, nent, f_slot,
    length, periodic, bottom, top, lo, hi, rows,
):  # fmt: skip
    """Row i of ``rows``: particle i's part of each sum of :data:`COLUMNS`: its kinetic
    energies, whether it is inside the slab and its volume there, its contact count (own
    half-list entries before ``nent`` whose first slot is non-zero, and the reverse list's),
    its platen levers, and over its own half-list contacts the virial and the interior
    stress's lever-weighted n_z f_z."""
    i = cuda.grid(1)
    n = pos.shape[0]
    if i >= n:
        return
    for q in range(NV):
        rows[i, q] = 0.0
    r = rad[i]
    zi = pos[i, 2] - bottom
    in_i = 1.0 if (zi >= lo and zi <= hi) else 0.0
    v2 = vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] + vel[i, 2] * vel[i, 2]
    rows[i, 0] = mass[i] * v2
    if inv_inertia[i] > 0.0:
        w2 = omg[i, 0] * omg[i, 0] + omg[i, 1] * omg[i, 1] + omg[i, 2] * omg[i, 2]
        rows[i, 1] = w2 / inv_inertia[i]
    rows[i, 2] = in_i
    # the sphere's volume in the slab: F(b) - F(a), F(u) = pi (r^2 u - u^3 / 3)
    a = min(max(lo - zi, -r), r)
    b = min(max(hi - zi, -r), r)
    fa = math.pi * (r * r * a - a * a * a / 3.0)
    fb = math.pi * (r * r * b - b * b * b / 3.0)
    rows[i, 3] = max(fb - fa, 0.0)
    ob = r - (pos[i, 2] - bottom)
    if ob > 0.0:
        rows[i, 6] = r - ob
        rows[i, 7] = 1.0
    ot = r - (top - pos[i, 2])
    if ot > 0.0:
        rows[i, 8] = r - ot
        rows[i, 9] = 1.0
    count = 0
    szz = 0.0
    vxx = 0.0
    vxy = 0.0
    vxz = 0.0
    vyx = 0.0
    vyy = 0.0
    vyz = 0.0
    vzx = 0.0
    vzy = 0.0
    vzz = 0.0
    for k in range(start[i], min(start[i + 1], nent)):
        if entry[k, 0] == 0.0:
            continue
        count += 1
        jj = nbr_j[k]
        dx = pos[i, 0] - pos[jj, 0]
        dy = pos[i, 1] - pos[jj, 1]
        dz = pos[i, 2] - pos[jj, 2]
        if periodic[0]:
            dx -= length[0] * math.floor(dx / length[0] + 0.5)
        if periodic[1]:
            dy -= length[1] * math.floor(dy / length[1] + 0.5)
        if periodic[2]:
            dz -= length[2] * math.floor(dz / length[2] + 0.5)
        fx = -entry[k, f_slot]
        fy = -entry[k, f_slot + 1]
        fz = -entry[k, f_slot + 2]
        vxx += fx * dx
        vxy += fx * dy
        vxz += fx * dz
        vyx += fy * dx
        vyy += fy * dy
        vyz += fy * dz
        vzx += fz * dx
        vzy += fz * dy
        vzz += fz * dz
        zj = pos[jj, 2] - bottom
        in_j = 1.0 if (zj >= lo and zj <= hi) else 0.0
        if in_i != 0.0 or in_j != 0.0:
            dist = math.sqrt(dx * dx + dy * dy + dz * dz)
            half = 0.5 * (r + rad[jj] - dist)
            lever = (r - half) * in_i + (rad[jj] - half) * in_j
            szz += lever * (dz / dist) * fz
    for q in range(rev_start[i], rev_start[i + 1]):
        k = rev_k[q]
        if k < nent and entry[k, 0] != 0.0:
            count += 1
    rows[i, 4] = count
    rows[i, 5] = count * in_i
    rows[i, 10] = vxx
    rows[i, 11] = vxy
    rows[i, 12] = vxz
    rows[i, 13] = vyx
    rows[i, 14] = vyy
    rows[i, 15] = vyz
    rows[i, 16] = vzx
    rows[i, 17] = vzy
    rows[i, 18] = vzz
    rows[i, 19] = szz


def measure_chunk_kernel(rows, csum):
    """Chunk c's sum of column q (``CHUNK`` rows in particle order): thread c * NV + q."""
    t = cuda.grid(1)
    nchunk = csum.shape[0]
    if t >= nchunk * NV:
        return
    c = t // NV
    q = t - c * NV
    lo = c * CHUNK
    hi = min(rows.shape[0], lo + CHUNK)
    acc = 0.0
    for p in range(lo, hi):
        acc += rows[p, q]
    csum[c, q] = acc


def measure_final_kernel(csum, out):
    """Column ``blockIdx.x``'s sum over the chunks: thread t sums chunks t, t + RED_T, ...
    in order, then a fixed tree of the ``RED_T`` partial sums."""
    q = cuda.blockIdx.x
    t = cuda.threadIdx.x
    sh = cuda.shared.array(RED_T, float64)
    acc = 0.0
    for c in range(t, csum.shape[0], RED_T):
        acc += csum[c, q]
    sh[t] = acc
    cuda.syncthreads()
    stride = RED_T // 2
    while stride > 0:
        if t < stride:
            sh[t] = sh[t] + sh[t + stride]
        cuda.syncthreads()
        stride //= 2
    if t == 0:
        out[q] = sh[0]


def cap_kernel(vel, cap, flag):
    """Scale the velocity of every particle faster than ``cap`` [m/s] down to ``cap`` (the
    host's formula: v cap / |v|); ``flag[0]`` = 1 where any was."""
    i = cuda.grid(1)
    if i >= vel.shape[0]:
        return
    s = math.sqrt(vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] + vel[i, 2] * vel[i, 2])
    if s > cap:
        f = cap / s
        vel[i, 0] *= f
        vel[i, 1] *= f
        vel[i, 2] *= f
        flag[0] = 1


def park_kernel(
    pos,
    vel,
    omg,
    rad,
    inv_mass,
    inv_inertia,
    pos_build,
    images,
    start,
    entry,
    rev_start,
    rev_k,
    whist,
    nplanes,
    mhist,
    mrows,
    order,
    height,
    o,
    a,
    nx,
    ny,
):
    """Park every live particle whose centre lies below ``height`` [m] at its site of the
    lattice (origin ``o`` (3,), spacing ``a`` (3,), ``nx``, ``ny``; the site of scene id
    ``order[i]``) and delete its contacts: its pair entries and its reverse list's (two
    parked partners both write the same zeros), its ``nplanes`` plane rows of ``whist`` and
    its ``mrows`` mesh rows of ``mhist`` (0 without meshes): the host's
    ``Simulation.park_below``."""
    i = cuda.grid(1)
    if i >= pos.shape[0]:
        return
    if pos[i, 2] < height and rad[i] > 0.0:
        s = order[i]
        x = o[0] + (s % nx) * a[0]
        y = o[1] + ((s // nx) % ny) * a[1]
        z = o[2] - (s // (nx * ny)) * a[2]
        pos[i, 0] = x
        pos[i, 1] = y
        pos[i, 2] = z
        for c in range(3):
            pos_build[i, c] = pos[i, c]
            vel[i, c] = 0.0
            omg[i, c] = 0.0
            images[i, c] = 0
        rad[i] = 0.0
        inv_mass[i] = 0.0
        inv_inertia[i] = 0.0
        for k in range(start[i], start[i + 1]):
            for c in range(entry.shape[1]):
                entry[k, c] = 0.0
        for q in range(rev_start[i], rev_start[i + 1]):
            k = rev_k[q]
            for c in range(entry.shape[1]):
                entry[k, c] = 0.0
        for r in range(i * nplanes, (i + 1) * nplanes):
            for c in range(whist.shape[1]):
                whist[r, c] = 0.0
        for r in range(i * mrows, (i + 1) * mrows):
            for c in range(mhist.shape[1]):
                mhist[r, c] = 0.0


_lock = threading.Lock()
_kernels: SimpleNamespace | None = None


def kernels() -> SimpleNamespace:
    """The measure kernels (the same for every scene; compiled at their first launch)."""
    global _kernels
    from .kernels import RED_T

    with _lock:
        if _kernels is None:
            b = {"CHUNK": CHUNK, "NV": NV, "RED_T": RED_T, "float64": cuda_types.float64}
            memo: dict = {}
            _kernels = SimpleNamespace(
                rows=kernel(measure_rows_kernel, b, memo),
                chunk=kernel(measure_chunk_kernel, b, memo),
                final=kernel(measure_final_kernel, b, memo),
                cap=kernel(cap_kernel, b, memo),
                park=kernel(park_kernel, b, memo),
            )
        return _kernels
