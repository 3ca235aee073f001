"""The contact virial over the neighbour list, compiled (``Simulation.pair_stress`` calls it
at every curve sample of a uniaxial run, where numpy's per-call overhead on small beds
would cost more than the sum)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core.config import NJIT


@njit(**NJIT)
def pair_virial(start, j, entry, f_slot, pos, length, periodic, n_entries):
    """Sum over the list's active entries (an entry whose first slot is non-zero, as
    ``Simulation.contacts`` reads them) of f_a l_b [N m]: f the force on the list's owner i
    (minus the stored force slots), l = x_i - x_j at the nearest periodic image. Summed
    owner by owner in list order, so the result does not depend on the thread count."""
    out = np.zeros((3, 3))
    n = start.shape[0] - 1
    for i in range(n):
        for k in range(start[i], min(start[i + 1], n_entries)):
            if entry[k, 0] == 0.0:
                continue
            jj = j[k]
            d = np.empty(3)
            for a in range(3):
                x = pos[i, a] - pos[jj, a]
                if periodic[a]:
                    x -= length[a] * np.floor(x / length[a] + 0.5)
                d[a] = x
            for a in range(3):
                f = -entry[k, f_slot + a]
                for b in range(3):
                    out[a, b] += f * d[b]
    return out


@njit(**NJIT)
def platen_levers(z, rad, bottom, top):
    """Mean lever (radius less overlap) of the particles touching the bottom platen at
    height ``bottom`` (normal +z) and of those touching the top one at ``top`` (normal -z)
    [m], from the particles' heights ``z`` and radii; 0 where none touches."""
    sb = st = 0.0
    nb = nt = 0
    for i in range(z.shape[0]):
        ob = rad[i] - (z[i] - bottom)
        if ob > 0.0:
            sb += rad[i] - ob
            nb += 1
        ot = rad[i] - (top - z[i])
        if ot > 0.0:
            st += rad[i] - ot
            nt += 1
    return (sb / nb if nb else 0.0), (st / nt if nt else 0.0)
