"""Slow, obviously-correct reference versions of the engine's kernels (stumpy's naive.py).

Written from docs/PHYSICS.md independently of engine/, in plain Python, for the tests to
compare with.
"""

from __future__ import annotations

import functools
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
    box, allowing overlaps up to ``max_overlap`` x the smaller radius; at most ``200 n``
    tries.

    Each try draws its radius, then its position (``rng.uniform``'s formula, ``lo + (hi - lo)
    u``, on the generator's doubles in that order), and is kept when it overlaps no sphere
    kept before it by more than the limit. The tries are drawn and checked against the
    spheres already kept in batches (the checks of a late, dense packing were seconds of
    per-try overhead); a batch's survivors are then taken one by one, each checked against
    the batch's earlier keepers: the same spheres, to the bit, as one try at a time. A
    packing is made once per process and handed out as copies."""
    lengths, periodic = tuple(map(float, lengths)), tuple(map(bool, periodic))
    pos, rad = _rsa_packing(n, lengths, rmin, rmax, seed, max_overlap, periodic)
    return pos.copy(), rad.copy()


@functools.cache
def _rsa_packing(n, lengths, rmin, rmax, seed, max_overlap, periodic):
    rng = np.random.default_rng(seed)
    lengths = np.asarray(lengths, dtype=float)
    periodic = np.asarray(periodic, dtype=bool)
    pos = np.zeros((n, 3))
    rad = np.zeros(n)
    m = 0
    tries = 0
    limit = 200 * n
    while m < n and tries < limit:
        batch = min(256, limit - tries)
        u = rng.random((batch, 4))
        r = rmin + (rmax - rmin) * u[:, 0]
        lo = np.where(periodic, 0.0, r[:, None])
        hi = np.where(periodic, lengths, lengths - r[:, None])
        x = lo + (hi - lo) * u[:, 1:]
        m0 = m
        bad = _overlapping(x, r, pos[:m0], rad[:m0], lengths, periodic, max_overlap)
        for j in range(batch):
            tries += 1
            if (
                bad[j]
                or _overlapping(
                    x[j : j + 1], r[j : j + 1], pos[m0:m], rad[m0:m], lengths, periodic, max_overlap
                )[0]
            ):
                continue
            pos[m] = x[j]
            rad[m] = r[j]
            m += 1
            if m == n:
                break
    return pos[:m], rad[:m]


def _overlapping(x, r, pos, rad, lengths, periodic, max_overlap) -> np.ndarray:
    """For each candidate (rows of ``x``, radii ``r``): does it overlap a sphere of ``pos``,
    ``rad`` by more than ``max_overlap`` x the smaller radius?"""
    if len(pos) == 0:
        return np.zeros(len(x), dtype=bool)
    d = np.linalg.norm(minimum_image(x[:, None, :] - pos[None, :, :], lengths, periodic), axis=2)
    rj = r[:, None]
    return np.any(rj + rad[None, :] - d > max_overlap * np.minimum(rj, rad[None, :]), axis=1)
