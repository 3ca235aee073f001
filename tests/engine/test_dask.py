"""Studies on a Dask cluster (a local one here): the same table as the in-process path, and a
worker killed with SIGKILL mid-run costs a retry, not the study."""

from __future__ import annotations

import os
import signal
import threading
import time
from dataclasses import replace

import pytest

import engine
from tests.engine.test_uniaxial import COHESIVE, tiny

distributed = pytest.importorskip("distributed")


def _spec(**kw):
    return engine.StudySpec(
        reference=tiny(pair_law=COHESIVE, **kw),
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        reference_seeds=(1, 2),
        seeds=(1,),
    )


def _table(res):
    return [{k: v for k, v in r.items() if k not in ("wall_time", "speedup")} for r in res.table]


@pytest.fixture(scope="module")
def cluster():
    with (
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            worker_class=distributed.Nanny,
        ) as c,
        distributed.Client(c) as client,
    ):
        yield c, client


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_dask_cluster_gives_the_in_process_table(cluster):
    _, client = cluster
    spec = _spec()
    here = engine.run_study(spec)
    there = engine.run_study(spec, executor=client.get_executor())
    assert _table(there) == _table(here)

    def verdicts(r):
        return [replace(x, speedup=None) for x in r.report.verdicts]

    assert verdicts(there) == verdicts(here)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_dask_worker_killed_mid_run_costs_a_retry_not_the_study(cluster):
    _, client = cluster
    spec = _spec(dt=5e-6)  # about 84,000 steps, a second or two per run: killed mid-run
    seen = []
    executor = client.get_executor()
    result = {}
    t = threading.Thread(
        target=lambda: result.setdefault(
            "study", engine.run_study(spec, executor=executor, on_run=lambda k, r: seen.append(k))
        )
    )
    t.start()

    def suspicious() -> int:
        # tasks that were running on a worker when it died: the scheduler's count per task
        # prefix, kept after the tasks themselves are forgotten
        return client.run_on_scheduler(
            lambda dask_scheduler: sum(p.suspicious for p in dask_scheduler.task_prefixes.values())
        )

    # kill a busy worker (first when both are busy) until a kill lands in a running task: a
    # run may end between the look at the workers and the kill (a second or two a run here)
    before, kills = suspicious(), 0
    deadline = time.monotonic() + 120
    while t.is_alive() and suspicious() == before and time.monotonic() < deadline:
        busy = [w for w, tasks in client.processing().items() if tasks]
        if len(busy) < (1 if kills else 2):
            time.sleep(0.2)
            continue
        pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
        os.kill(pid, signal.SIGKILL)
        kills += 1
        gone = time.monotonic() + 30  # until the scheduler has seen the worker go
        while busy[0] in client.scheduler_info()["workers"] and time.monotonic() < gone:
            time.sleep(0.1)
    assert suspicious() > before, f"no kill landed in a running task ({kills} kills)"
    t.join(500)
    assert not t.is_alive()
    study = result["study"]
    assert not study.failed and sorted(seen) == sorted(p.key for p in engine.plan(spec).runs)
