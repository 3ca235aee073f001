"""The test helpers' random sequential addition (tests/naive.py) against the plain loop it
batches: the scenes of the engine's tests depend on it to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from tests import naive

R = 2.5e-3


def _one_try_at_a_time(n, lengths, rmin, rmax, seed, max_overlap, periodic):
    rng = np.random.default_rng(seed)
    lengths = np.asarray(lengths, dtype=float)
    pos, rad, tries = [], [], 0
    while len(pos) < n and tries < 200 * n:
        tries += 1
        r = rng.uniform(rmin, rmax)
        x = rng.uniform(np.where(periodic, 0.0, r), np.where(periodic, lengths, lengths - r))
        if pos:
            p, q = np.array(pos), np.array(rad)
            d = np.linalg.norm(naive.minimum_image(x - p, lengths, periodic), axis=1)
            if np.any(r + q - d > max_overlap * np.minimum(r, q)):
                continue
        pos.append(x)
        rad.append(r)
    return np.array(pos).reshape(-1, 3), np.array(rad)


@pytest.mark.parametrize(
    "n, periodic, max_overlap, dense",
    [
        (40, (True, True, False), 0.1, True),  # the try limit ends it, batches later
        (40, (False, False, False), 0.0, True),
        (12, (True, True, True), 0.3, False),  # all placed, within the first batch
    ],
)
def test_batched_packing_is_the_one_try_at_a_time_packing(n, periodic, max_overlap, dense):
    args = (n, [0.012, 0.012, 0.016], 0.8 * R, R, 3, max_overlap, periodic)
    want = _one_try_at_a_time(*args)
    got = naive.rsa_packing(*args[:5], max_overlap=max_overlap, periodic=periodic)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert (len(want[1]) < n) == dense
    got[0][:] = 0.0  # a copy: the next caller gets the packing intact
    again = naive.rsa_packing(*args[:5], max_overlap=max_overlap, periodic=periodic)
    assert np.array_equal(again[0], want[0])
