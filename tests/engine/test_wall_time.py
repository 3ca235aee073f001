"""The limit on a run's wall time holds in this process and on a process pool, and counts
the earlier attempts of a resumed run."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import pickle
import time

import pytest

import engine
from engine.study.results import RunFailed

from .test_uniaxial import COHESIVE, tiny


def spec() -> engine.StudySpec:
    return engine.StudySpec(
        reference=tiny(unconfined=False),
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
    )


def test_a_run_past_its_wall_time_stops_with_the_setting_named():
    with pytest.raises(engine.WallTimeExceeded, match="MY_LIMIT = 1e-09 s") as e:
        engine.run_uniaxial(
            tiny(unconfined=False), max_wall_time=1e-9, wall_time_setting="MY_LIMIT"
        )
    err = pickle.loads(pickle.dumps(e.value))  # crosses process boundaries whole
    assert (err.limit, err.setting) == (1e-9, "MY_LIMIT") and err.elapsed > 1e-9


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), True, "5"])
def test_the_limit_is_checked(bad):
    with pytest.raises(engine.ParameterError, match="max_wall_time"):
        engine.run_uniaxial(tiny(), max_wall_time=bad)
    with pytest.raises(engine.ParameterError, match="RunOptions.max_run_wall_time"):
        engine.run_study(spec(), max_run_wall_time=bad)


@pytest.mark.timeout(300)
@pytest.mark.parametrize("where", ["here", "process pool"])
def test_run_study_applies_the_limit_on_any_executor(where):
    pool = (
        cf.ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) if where != "here" else None
    )
    try:
        with pytest.raises(RunFailed, match="WallTimeExceeded.*LIMIT_X = 1e-06 s"):
            engine.run_study(
                spec(), executor=pool, max_run_wall_time=1e-6, wall_time_setting="LIMIT_X"
            )
    finally:
        if pool is not None:
            pool.shutdown()


def test_a_resumed_run_counts_the_wall_time_of_its_earlier_attempts(tmp_path):
    test = tiny(pair_law=COHESIVE)
    ck = engine.Checkpoint(tmp_path / "r.ckpt", interval=1e-12)
    seen = []

    class Killed(Exception):
        pass

    def stop(p):
        if ck.writes >= 50:
            raise Killed()

    with pytest.raises(Killed):
        engine.run_uniaxial(test, progress=stop, checkpoint=ck)
    t0 = time.perf_counter()
    stored = engine.Checkpoint(ck.path).load(test)
    # the stored attempts' wall time less this load's (the clock runs on from the state's
    # unpickling, and a loaded machine may pause this process in between: a lower bound,
    # where wall_time() alone made the assertion below fail by 4 ms under the suite's load)
    before = stored.wall_time() - (time.perf_counter() - t0)
    assert before > 0
    with pytest.raises(engine.WallTimeExceeded) as e:
        engine.run_uniaxial(
            test,
            progress=seen.append,
            checkpoint=engine.Checkpoint(ck.path),
            max_wall_time=0.9 * before,
        )
    assert e.value.elapsed >= before and seen == []  # refused at its first report


def test_how_to_run_is_one_record():
    # engine.RunOptions: what run_study's keywords set, checked when made; a keyword on top
    # of an options record wins; an unknown keyword is named
    opts = engine.RunOptions(max_run_wall_time=30.0, checkpoints="ckpt")
    assert opts.backend == "cpu" or opts.backend is None or isinstance(opts.backend, str)
    with pytest.raises(engine.ParameterError, match="RunOptions.poll_interval"):
        engine.RunOptions(poll_interval=0)
    with pytest.raises(engine.ParameterError, match="RunOptions.checkpoint_interval"):
        engine.RunOptions(checkpoints="ckpt", checkpoint_interval=-1)
    with pytest.raises(TypeError, match="max_wall_tim"):
        engine.run_study(spec(), options=opts, max_wall_tim=5)
    with pytest.raises(engine.ParameterError, match="RunOptions.max_run_wall_time"):
        engine.run_study(spec(), options=opts, max_run_wall_time=-1.0)
