"""``run_study`` refuses, before any run starts, a process pool that forks (issue 22): a
forked child of a process that has run the engine dies at once (GNU OpenMP is not
fork-safe) and the pool breaks."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp

import pytest

import engine
from engine.study.run import check_executor

TINY = {
    "reference": {
        "cell": [0.015, 0.015, 0.03],
        "output_interval": 1e-3,
        "platen_speed": 0.02,
        "unconfined": False,
        "dt": 3e-5,
        "pair_law": {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "f0": -0.05},
    },
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
}


def test_a_forking_process_pool_is_refused_at_once_naming_the_fix():
    spec = engine.StudySpec.from_dict(TINY)
    calls = []
    with cf.ProcessPoolExecutor(1, mp_context=mp.get_context("fork")) as pool:
        with pytest.raises(ValueError, match="spawn") as e:
            engine.run_study(spec, executor=pool, on_run=lambda *a: calls.append(a))
        assert "mp_context=multiprocessing.get_context('spawn')" in str(e.value)
    assert calls == []  # no run started


def test_spawn_forkserver_threads_and_none_are_accepted():
    check_executor(None)
    for method in ("spawn", "forkserver"):
        with cf.ProcessPoolExecutor(1, mp_context=mp.get_context(method)) as pool:
            check_executor(pool)
    with cf.ThreadPoolExecutor(1) as pool:
        check_executor(pool)


@pytest.mark.skipif(
    mp.get_start_method(allow_none=False) != "fork",
    reason="the default start method here does not fork",
)
def test_the_default_pool_on_this_platform_is_refused():
    with cf.ProcessPoolExecutor(1) as pool, pytest.raises(ValueError, match="forks"):
        check_executor(pool)
