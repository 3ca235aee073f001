"""Seeded loose packings without overlaps (random sequential addition on a cell grid).

The packings are the starting point of the fill stage: a loose, random, overlap-free cloud in
a cell taller than the sample, which then settles under gravity.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.config import NJIT
from ..core.errors import ParameterError


@njit(**NJIT)
def _rsa(radii, lo, hi, periodic, seed, max_tries):
    """Place spheres of the given radii one after the other at uniform random positions in
    the box [lo, hi) [m] without overlap (periodic along the flagged axes). Returns (positions
    (N, 3) [m], number placed); placement stops at the first sphere that found no room in
    ``max_tries`` attempts."""
    np.random.seed(seed)  # noqa: NPY002 (numba supports only the legacy generator)
    n = radii.shape[0]
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, radii[i])
    size = np.empty(3)
    ncell = np.empty(3, dtype=np.int64)
    for a in range(3):
        ncell[a] = max(1, int((hi[a] - lo[a]) / (2.0 * rmax)))
        size[a] = (hi[a] - lo[a]) / ncell[a]
    head = np.full(ncell[0] * ncell[1] * ncell[2], -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    pos = np.zeros((n, 3))
    cell = np.empty(3, dtype=np.int64)
    x = np.empty(3)
    for k in range(n):
        r = radii[k]
        placed = False
        for _ in range(max_tries):
            for a in range(3):
                if periodic[a]:
                    x[a] = lo[a] + np.random.random() * (hi[a] - lo[a])  # noqa: NPY002
                else:
                    x[a] = lo[a] + r + np.random.random() * (hi[a] - lo[a] - 2.0 * r)  # noqa: NPY002
                cell[a] = min(ncell[a] - 1, int((x[a] - lo[a]) / size[a]))
            ok = True
            for ox in range(-1, 2):
                for oy in range(-1, 2):
                    for oz in range(-1, 2):
                        c0 = cell[0] + ox
                        c1 = cell[1] + oy
                        c2 = cell[2] + oz
                        if periodic[0]:
                            c0 %= ncell[0]
                        elif c0 < 0 or c0 >= ncell[0]:
                            continue
                        if periodic[1]:
                            c1 %= ncell[1]
                        elif c1 < 0 or c1 >= ncell[1]:
                            continue
                        if periodic[2]:
                            c2 %= ncell[2]
                        elif c2 < 0 or c2 >= ncell[2]:
                            continue
                        j = head[(c0 * ncell[1] + c1) * ncell[2] + c2]
                        while j >= 0 and ok:
                            d2 = 0.0
                            for a in range(3):
                                d = x[a] - pos[j, a]
                                if periodic[a]:
                                    length = hi[a] - lo[a]
                                    d -= length * math.floor(d / length + 0.5)
                                d2 += d * d
                            if d2 < (r + radii[j]) ** 2:
                                ok = False
                            j = nxt[j]
            if ok:
                placed = True
                break
        if not placed:
            return pos, k
        for a in range(3):
            pos[k, a] = x[a]
        c = (cell[0] * ncell[1] + cell[1]) * ncell[2] + cell[2]
        nxt[k] = head[c]
        head[c] = k
    return pos, n


def sphere_volume(radius) -> np.ndarray:
    """Volume of spheres of the given radius [m^3]."""
    return 4.0 / 3.0 * math.pi * np.asarray(radius, dtype=float) ** 3


def draw_radii(n: int, radius: float, polydispersity: float, seed: int) -> np.ndarray:
    """``n`` radii uniform in [R (1 - p), R (1 + p)] [m] (all equal to R for p = 0)."""
    if not 0.0 <= polydispersity < 0.5:
        raise ParameterError("polydispersity", polydispersity, "in [0, 0.5)")
    if polydispersity == 0.0:
        return np.full(n, float(radius))
    rng = np.random.default_rng(seed)
    return radius * rng.uniform(1.0 - polydispersity, 1.0 + polydispersity, n)


def loose_packing(
    radii, box, periodic=(True, True, False), seed: int = 0, max_tries: int = 5000
) -> np.ndarray:
    """Overlap-free random positions [m] for spheres of ``radii`` in ``box``
    ((xlo, xhi), (ylo, yhi), (zlo, zhi)) [m]; on open axes the spheres stay inside.

    Raises :class:`engine.ParameterError` when the box cannot hold them (random sequential
    addition jams near a solid fraction of 0.38; aim for 0.3 or less).
    """
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    b = np.asarray(box, dtype=np.float64)
    lo, hi = b[:, 0].copy(), b[:, 1].copy()
    fraction = float(sphere_volume(radii).sum() / np.prod(hi - lo))
    pos, placed = _rsa(radii, lo, hi, np.array(periodic, dtype=np.bool_), int(seed), int(max_tries))
    if placed < len(radii):
        raise ParameterError(
            "loose_packing.box",
            f"solid fraction {fraction:.3f}",
            "large enough to place the particles without overlap",
            f"placed {placed} of {len(radii)}; random sequential addition jams near 0.38, "
            "use a taller fill region",
        )
    return pos
