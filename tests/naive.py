"""Slow, obviously-correct reference versions of the engine's kernels (stumpy's naive.py).

Written from docs/PHYSICS.md independently of engine/, in plain Python, for the tests to
compare with.
"""

from __future__ import annotations

import itertools
import math

import numpy as np


def bilinear_force(d: float, dmax: float, k1: float, k2: float, f0: float, kadh: float):
    """docs/PHYSICS.md section 2, branch by branch. Returns (f_hys, dmax)."""
    dmax = max(dmax, d)
    lam = 1.0 - k1 / k2
    dp = lam * dmax
    virgin = f0 + k1 * d
    unload = f0 + k2 * (d - dp)
    adhesive = f0 - kadh * d
    if unload >= virgin:
        return virgin, dmax
    return max(unload, adhesive), dmax


def hertz_force(d: float, e_star: float, r_star: float) -> float:
    return 4.0 / 3.0 * e_star * math.sqrt(r_star) * d**1.5


def minimum_image(dx: np.ndarray, lengths, periodic) -> np.ndarray:
    dx = np.array(dx, dtype=float)
    for a in range(3):
        if periodic[a]:
            dx[..., a] -= lengths[a] * np.round(dx[..., a] / lengths[a])
    return dx


def all_pairs_within(pos, rad, lengths, periodic, gap: float) -> set[tuple[int, int]]:
    """Every pair (i < j) whose surface gap is below ``gap`` (all-pairs search)."""
    out = set()
    n = len(pos)
    for i, j in itertools.combinations(range(n), 2):
        dx = minimum_image(pos[i] - pos[j], lengths, periodic)
        if np.linalg.norm(dx) < rad[i] + rad[j] + gap:
            out.add((i, j))
    return out


def all_pairs_within_by_images(pos, rad, lengths, periodic, gap: float) -> set[tuple[int, int]]:
    """Same as :func:`all_pairs_within`, by brute force over all 27 periodic images instead
    of the minimum-image formula (an independent check of the formula itself)."""
    shifts = [range(-1, 2) if periodic[a] else range(1) for a in range(3)]
    out = set()
    n = len(pos)
    for i, j in itertools.combinations(range(n), 2):
        best = math.inf
        for sx, sy, sz in itertools.product(*shifts):
            s = np.array([sx, sy, sz]) * lengths
            best = min(best, float(np.linalg.norm(pos[i] - pos[j] + s)))
        if best < rad[i] + rad[j] + gap:
            out.add((i, j))
    return out


def rsa_packing(
    n: int,
    lengths,
    rmin: float,
    rmax: float,
    seed: int,
    max_overlap: float = 0.0,
    periodic=(True, True, True),
):
    """Random sequential addition of up to ``n`` spheres (radii uniform in [rmin, rmax]) in a
    box, allowing overlaps up to ``max_overlap`` x the smaller radius."""
    rng = np.random.default_rng(seed)
    lengths = np.asarray(lengths, dtype=float)
    pos = np.zeros((n, 3))
    rad = np.zeros(n)
    m = 0
    tries = 0
    while m < n and tries < 200 * n:
        tries += 1
        r = rng.uniform(rmin, rmax)
        lo = np.where(periodic, 0.0, r)
        hi = np.where(periodic, lengths, lengths - r)
        x = rng.uniform(lo, hi)
        if m:
            d = np.linalg.norm(minimum_image(x - pos[:m], lengths, periodic), axis=1)
            if np.any(r + rad[:m] - d > max_overlap * np.minimum(r, rad[:m])):
                continue
        pos[m] = x
        rad[m] = r
        m += 1
    return pos[:m], rad[:m]
