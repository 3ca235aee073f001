"""The CUDA backend (numba-cuda, the optional extra ``gpu``): ``Simulation(...,
backend="cuda")``. Importing this package imports numba-cuda; the CPU engine never does.
See :mod:`engine.cuda.simulation` (the state on the device and what crosses),
:mod:`engine.cuda.device` (the CPU kernels' functions compiled as device functions),
:mod:`engine.cuda._sources` (the kernels), :mod:`engine.cuda.measures` (a curve sample's
sums on the device) and :mod:`engine.cuda.batch` (simulations side by side on one card)."""

from .batch import StreamExecutor, run_together, step_together
from .simulation import CudaSimulation

__all__ = ["CudaSimulation", "StreamExecutor", "run_together", "step_together"]
