"""Where a worker runs a study's runs: in its own process (the default), on a local process
pool (``DEMSCALE_RUN_WORKERS``), or as tasks on a Dask cluster
(``DEMSCALE_DASK_SCHEDULER``; dask-jobqueue brings SLURM, PBS and SGE clusters)."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
from collections.abc import Iterator

from .settings import Settings

#: How often a pool process checks that its service worker is alive [s].
PARENT_CHECK_INTERVAL = 1.0


def exit_with_parent(parent: int) -> None:
    """Pool process initializer: exit as soon as the service worker that started the pool is
    gone. A worker killed outright (SIGKILL, out of memory) cannot shut its pool down, and
    the pool's processes would otherwise live on, idle, holding their memory; the study is
    requeued and its runs rerun elsewhere."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


@contextlib.contextmanager
def run_executor(settings: Settings, backend: str | None = None) -> Iterator[cf.Executor | None]:
    """The executor for one study's runs (None: in process), shut down afterwards.
    ``backend``: where the runs go; with ``"cuda"`` and more than one worker, the runs share
    the GPU side by side in this process (:class:`engine.cuda.batch.StreamExecutor`: a
    thread and a CUDA stream each) instead of a process each (separate CUDA contexts, which
    the card runs one at a time)."""
    if settings.dask_scheduler:
        from distributed import Client  # the `dask` extra

        client = Client(settings.dask_scheduler, set_as_default=False)
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    n = settings.run_workers or os.cpu_count() or 1
    if n <= 1:
        yield None
        return
    if backend == "cuda":
        from engine.cuda.batch import StreamExecutor

        streams = StreamExecutor(n)
        try:
            yield streams
        finally:
            streams.shutdown(wait=False, cancel_futures=True)
        return
    # spawn: the worker's own OpenMP threads and database connections are not forked
    pool = cf.ProcessPoolExecutor(
        n, mp_context=mp.get_context("spawn"), initializer=exit_with_parent, initargs=(os.getpid(),)
    )
    try:
        yield pool
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
