"""Engine errors cross process boundaries intact (a study on a process pool or a Dask cluster
receives each run's error and stores it as that run's outcome)."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import pickle

import pytest

from engine.core.errors import InstabilityError, ParameterError, StabilityError, StopRequested
from engine.study.results import RunFailed
from engine.uniaxial.driver import StageError


def _errors():
    return [
        ParameterError("BilinearAdhesive.k2", 1.0, ">= k1", "unloading stiffer than loading"),
        StabilityError("dt too large", dt=1e-5, limit=2e-6),
        InstabilityError(
            "overlap 0.5 R", step=10116, time=0.10116, particles=(1054, 1525), reason="overlap"
        ),
        StageError("fill did not settle", "fill", 400_000),
        RunFailed("r3.75mm-b3-s1", "InstabilityError: overlap 0.5 R"),
        StopRequested("stopped"),
    ]


@pytest.mark.parametrize("error", _errors(), ids=lambda e: type(e).__name__)
def test_every_error_pickles_with_its_fields(error):
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error)
    assert str(back) == str(error)
    assert vars(back) == vars(error)


def _unstable_run():
    raise _errors()[2]


def test_an_unstable_run_on_a_process_pool_reaches_the_caller_as_itself():
    """Before the fix the unpickling failed in the pool's result thread, which broke the
    pool: a 2-worker paper-scale study lost its running reference with one unstable run."""
    with cf.ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        fut = pool.submit(_unstable_run)
        with pytest.raises(InstabilityError) as info:
            fut.result(timeout=120)
        assert pool.submit(int, "7").result(timeout=120) == 7  # the pool still works
    assert info.value.particles == (1054, 1525) and info.value.reason == "overlap"
