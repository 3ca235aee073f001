"""Progress and stop requests across processes (engine.FileChannel with run_study on a
process pool): running tasks report while they run, and a stop ends them promptly."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import time

import pytest

import engine
from engine.study.channel import task_progress
from engine.uniaxial.results import Progress
from tests.engine.test_uniaxial import tiny


def _slow_spec() -> engine.StudySpec:
    # a small time step: each run takes several seconds (about 8 s on 2 cores), long enough
    # to be seen running and stopped
    ref = tiny(dt=4e-7, unconfined=False)
    return engine.StudySpec(
        reference=ref,
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        reference_seeds=(1,),
    )


def test_channel_files_round_trip(tmp_path):
    ch = engine.FileChannel(tmp_path / "ch")
    ch.reset()
    cb = task_progress(ch, "ref-s1")
    assert cb(Progress(0.25, "fill", 0.5, 0.1, 100)) is None
    assert cb(Progress(0.3, "fill", 0.6, 0.12, 120)) is None  # within the interval: not written
    assert ch.read() == {"ref-s1": {"fraction": 0.25, "stage": "fill", "time": 0.1}}
    ch.request_stop()
    assert cb(Progress(1.0, "unloading", 1.0, 2.0, 900)) is False  # the end is always written
    assert ch.read()["ref-s1"]["fraction"] == 1.0
    ch.reset()
    assert ch.read() == {} and not ch.stop_requested()
    # a task on a host without the folder runs on silently
    lost = engine.FileChannel(tmp_path / "missing" / "ch")
    lost.report("ref-s1", 0.5, "fill", 0.1)
    assert not lost.stop_requested()


@pytest.mark.slow
def test_pool_tasks_report_while_running_and_stop_on_request(tmp_path):
    spec = _slow_spec()
    ch = engine.FileChannel(tmp_path / "channel")
    seen, finished = [], []

    def progress(p):
        seen.append((p.fraction, p.stage, p.run_key))
        return not (p.stage == "fill" and p.fraction > 0)  # stop at the first real report

    ctx = mp.get_context("spawn")
    pool = cf.ProcessPoolExecutor(2, mp_context=ctx)
    try:
        with pytest.raises(engine.StopRequested):
            engine.run_study(
                spec,
                progress=progress,
                executor=pool,
                channel=ch,
                poll_interval=0.2,
                on_run=lambda k, r: finished.append(k),
            )
        t_stop = time.monotonic()
        assert ch.stop_requested()
        pool.shutdown(wait=True)  # returns when both running tasks have stopped
        t_end = time.monotonic()
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    assert seen and seen[-1][1] == "fill" and 0 < seen[-1][0] < 0.5
    # stopped at their next report (every 0.5 s), not run to their end: no run finished
    assert finished == []
    assert t_end - t_stop < 3.0


@pytest.mark.slow
def test_pool_with_channel_gives_the_sequential_table(tmp_path):
    spec = engine.StudySpec(
        reference=tiny(unconfined=False),
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        reference_seeds=(1, 2),
    )
    seq = engine.run_study(spec)
    with cf.ProcessPoolExecutor(2, mp_context=mp.get_context("spawn")) as pool:
        par = engine.run_study(
            spec, executor=pool, channel=engine.FileChannel(tmp_path / "c"), poll_interval=0.1
        )

    def table(r):
        return [
            {k: v for k, v in row.items() if k not in ("wall_time", "speedup")} for row in r.table
        ]

    assert table(par) == table(seq)
