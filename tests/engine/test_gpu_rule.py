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


def test_the_reference_item_times_stores_and_checks_a_run(monkeypatch, tmp_path, capsys):
    """The benchmark's reference item end to end without a GPU: the stored CPU run stands in
    for the GPU's (a difference of zero passes), the run is stored and timed against the
    target; a stored run of another test is not compared."""
    from benchmarks import gpu_speed
    from engine.io.store import load_run

    paths = [gpu_speed.STORED_REF / f"ref-s{s}.h5" for s in (1, 2, 3)]
    cpu = load_run(paths[0])
    monkeypatch.setattr(gpu_speed, "run_reference", lambda test, cap: (cpu, 1.0))
    monkeypatch.setattr(gpu_speed, "GPU_STORE", tmp_path)
    checks = []
    gpu_speed.reference_item(cpu.test, paths, "ref", 60.0, 2e7, checks)
    assert (tmp_path / "ref-s1.h5").exists()
    timing, *curves = checks
    assert timing == (f"ref <= 120 s on the GPU: {cpu.scalars['wall_time']:.1f} s", False)
    assert len(curves) == 5 and all(ok for _, ok in curves), curves
    assert "projected" in capsys.readouterr().out
    other = gpu_speed.curve_check(load_run(paths[1]), paths, "ref")
    assert other == [("GPU and CPU ref: not measured (stored CPU run of another test)", None)]


def test_the_series_item_judges_a_run_against_the_stored_seeds(monkeypatch):
    """The series item (``--series``) without a GPU: the stored CPU seed 2 of the outlet
    series' 64 d discharge stands in for the GPU's run of seed 1's test (another realisation:
    within the bound), the same value 30 % higher does not; a size with one stored seed is not
    judged."""
    from types import SimpleNamespace

    from benchmarks import gpu_speed, outlet_series

    key = ("flow", 30.0, 64.0, 1)
    paths = {s: outlet_series.path_of(*key[:-1], s) for s in (1, 2, 3)}
    seed2 = outlet_series.stored(*key[:-1], 2).scalars["discharge_number"]
    args = SimpleNamespace(smoke=True)  # nothing stored
    for factor, ok in ((1.0, True), (1.3, False)):
        res = SimpleNamespace(scalars={"discharge_number": factor * seed2, "steps": 10})
        o = {"particles": 10, "steps": 10, "wall": 1.0, "finished": True, "error": None}
        monkeypatch.setattr(gpu_speed, "timed_any", lambda test, cap, res=res, o=o: (res, o))
        items = [("outlet", outlet_series.test_of(*key), paths, "discharge_number")]
        items.append(("size", outlet_series.test_of(*key), {1: paths[1]}, "discharge_number"))
        monkeypatch.setattr(gpu_speed, "series_runs", lambda smoke, items=items: items)
        checks = gpu_speed.series_item(args, False, 60.0)
        assert [c[1] for c in checks] == [True, ok, True, False], checks
        assert "not judged" in checks[-1][0]
