"""The CUDA backend (numba-cuda, the optional extra ``gpu``): ``Simulation(...,
backend="cuda")``. Importing this package imports numba-cuda; the CPU engine never does.
See :mod:`engine.cuda.simulation` (the state on the device and what crosses),
:mod:`engine.cuda.device` (the CPU kernels' functions compiled as device functions) and
:mod:`engine.cuda._sources` (the kernels)."""

from .simulation import CudaSimulation

__all__ = ["CudaSimulation"]
