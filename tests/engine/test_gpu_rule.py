"""The GPU benchmark's rule for "the same physics as the CPU" (benchmarks/gpu_speed.py,
``same_physics_bound``): its coverage and power checked by simulation, no GPU needed."""

import numpy as np
import pytest

from benchmarks.gpu_speed import same_physics_bound

SEEDS, METRICS, DRAWS = 3, 5, 40_000


def _pass_rate(bias_sd: float, rng) -> float:
    """How often a GPU run passes on every metric when its metrics are another realisation
    of the reference (normal, seed sd 1) shifted by ``bias_sd`` seed sd; the CPU run is the
    first of the stored seeds, whose spread gives the sd."""
    ref = rng.normal(size=(DRAWS, METRICS, SEEDS))
    sd = ref.std(axis=2, ddof=1)
    gpu = rng.normal(size=(DRAWS, METRICS)) + bias_sd
    bound = same_physics_bound(1.0, SEEDS, METRICS) * sd  # linear in sd
    return float(np.mean(np.all(np.abs(gpu - ref[:, :, 0]) <= bound, axis=1)))


def test_a_correct_backend_passes_at_the_stated_confidence():
    rate = _pass_rate(0.0, np.random.default_rng(7))
    # 95 % family-wise by construction (Bonferroni, Student's t on 2 dof); the CPU run is one
    # of the seeds, so a little conservative; Monte Carlo error about 0.001
    assert 0.95 <= rate <= 0.995


def test_a_gross_bias_on_every_metric_is_caught():
    # what 3 seeds can tell: a shift of 20 seed sd on each metric fails the family often,
    # one of 2 sd almost never (stated in the function's docstring)
    assert _pass_rate(20.0, np.random.default_rng(8)) < 0.05
    assert _pass_rate(2.0, np.random.default_rng(9)) > 0.5


def test_the_bound_needs_two_seeds():
    with pytest.raises(ValueError, match="2 seeds"):
        same_physics_bound(0.01, 1, 5)
