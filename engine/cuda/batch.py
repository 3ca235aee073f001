"""Many runs on one GPU at once: independent simulations side by side, each on a CUDA stream
of its own, so that the card works on several scenes together instead of one small one at a
time (a study's runs are 900 to 107,000 particles; the card saturates near 1M).

Each task runs in a host thread of its own, and every :class:`CudaSimulation` that thread
sends to the device (or that :func:`step_together` hands a stream) launches its kernels and
copies on that thread's stream: while one task waits for its control record, the others'
launches are queued and run. The Python work between launches (a run's loop, a curve
sample's few numbers, see :mod:`engine.cuda.measures`) takes turns under the interpreter's
lock; the kernels of the streams overlap on the device. A simulation's results do not depend
on its stream, nor on what runs beside it: each scene's state is its own, and its sums run
in a fixed order.

- :func:`run_together` runs callables (e.g. ``lambda: engine.run_uniaxial(test,
  backend="cuda")``) side by side and returns their results in order;
- :func:`step_together` advances simulations by a number of steps each;
- :class:`StreamExecutor` is a :class:`concurrent.futures.ThreadPoolExecutor` whose worker
  threads each have a stream: ``engine.run_study(spec, executor=StreamExecutor(8),
  backend="cuda")`` runs a study's runs eight at a time on one card.

Under numba-cuda's simulator kernels run one at a time (a lock in
:meth:`CudaSimulation._go`): the tasks take turns per launch, which keeps the results and
tests the interleaving, not the speed.
"""

from __future__ import annotations

import concurrent.futures as cf
import threading
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from typing import Any

from numba import cuda

from ..core.errors import ParameterError

_local = threading.local()


def current_stream():
    """The CUDA stream of this thread (:func:`on_stream`), or None."""
    return getattr(_local, "stream", None)


@contextmanager
def on_stream(stream=None):
    """Within the block, simulations this thread sends to the device use ``stream`` (a new
    stream when None); yields it."""
    old = current_stream()
    _local.stream = cuda.stream() if stream is None else stream
    try:
        yield _local.stream
    finally:
        _local.stream = old


def _check_tasks(tasks, name: str) -> list:
    tasks = list(tasks)
    if not tasks:
        raise ParameterError(name, "an empty list", "at least one task")
    return tasks


def run_together(tasks: Sequence[Callable[[], Any]], max_workers: int | None = None) -> list:
    """Run the callables ``tasks`` side by side on one device, each in a thread of its own on
    a stream of its own (at most ``max_workers`` at once; None: all), and return their
    results in the order of ``tasks``. Every task runs to its end; then the first exception
    raised (in the order of ``tasks``) is raised again."""
    tasks = _check_tasks(tasks, "run_together.tasks")
    if max_workers is not None and (isinstance(max_workers, bool) or max_workers < 1):
        raise ParameterError("run_together.max_workers", max_workers, "an integer >= 1")
    with StreamExecutor(max_workers or len(tasks)) as pool:
        futures = [pool.submit(t) for t in tasks]
        cf.wait(futures)
    return [f.result() for f in futures]


def step_together(sims: Sequence, steps: int) -> None:
    """Advance each CUDA simulation of ``sims`` by ``steps`` steps, side by side on one
    device: simulation k runs on a stream of its own (kept for its later runs) in a thread
    of its own. The same states as ``for s in sims: s.run(steps)``."""
    sims = _check_tasks(sims, "step_together.sims")
    for k, s in enumerate(sims):
        if getattr(s, "backend", None) != "cuda":
            raise ParameterError(
                f"step_together.sims[{k}]", type(s).__name__, "a Simulation on the cuda backend"
            )
    if len({id(s) for s in sims}) != len(sims):
        raise ParameterError("step_together.sims", "a simulation twice", "distinct simulations")
    for s in sims:
        if s._stream is None:
            s.set_stream(cuda.stream())
    run_together([lambda s=s: s.run(steps) for s in sims])


def _bind_stream() -> None:
    _local.stream = cuda.stream()


class StreamExecutor(cf.ThreadPoolExecutor):
    """A thread pool whose every worker thread has a CUDA stream of its own: the CUDA
    simulations its tasks make run side by side on one device (an executor for
    :func:`engine.run_study` with ``backend="cuda"``; ``task_threads`` does not apply: the
    CPU's engine threads are not used)."""

    def __init__(self, max_workers: int):
        if isinstance(max_workers, bool) or not isinstance(max_workers, int) or max_workers < 1:
            raise ParameterError("StreamExecutor.max_workers", max_workers, "an integer >= 1")
        super().__init__(max_workers, thread_name_prefix="demscale-cuda", initializer=_bind_stream)
