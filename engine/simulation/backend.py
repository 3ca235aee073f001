"""Which engine runs a simulation: the CPU kernels (numba) or the CUDA backend
(:mod:`engine.cuda`, numba-cuda, the optional extra ``gpu``).

``"cpu"`` (the default), ``"cuda"`` (an error naming the field when numba-cuda or a usable
device is missing) or ``"auto"`` (the GPU when one is usable, else the CPU; the choice is
logged and kept as ``Simulation.backend``). ``None`` takes the environment variable
``DEMSCALE_BACKEND`` (so a service worker and its pool processes share one setting), else
``"cpu"``. numba-cuda is imported only when a GPU is asked for: the CPU path never needs it.
"""

from __future__ import annotations

import logging
import os

from ..core.errors import ParameterError

BACKENDS = ("cpu", "cuda", "auto")
ENV = "DEMSCALE_BACKEND"
log = logging.getLogger("engine.simulation.backend")
_probe: tuple[bool, str] | None = None


def cuda_status() -> tuple[bool, str]:
    """(usable, what): whether the CUDA backend can run here, and the device's name or why
    not. Imports numba-cuda (once) and asks its driver for a device."""
    global _probe
    if _probe is None:
        try:
            from numba import cuda
            from numba.cuda.core import config
        except ImportError as e:
            _probe = (False, f"numba-cuda is not installed (pip install 'demscale[gpu]'): {e}")
        else:
            try:
                if config.ENABLE_CUDASIM:
                    _probe = (True, "numba-cuda simulator (NUMBA_ENABLE_CUDASIM=1)")
                elif not cuda.is_available():
                    _probe = (False, "no usable CUDA device or driver")
                else:
                    dev = cuda.get_current_device()
                    name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
                    cc = ".".join(str(v) for v in dev.compute_capability)
                    _probe = (True, f"{name} (compute capability {cc})")
            except Exception as e:  # a broken driver or toolkit: not usable
                _probe = (False, f"CUDA unusable: {type(e).__name__}: {e}")
    return _probe


def check_backend(backend: str | None, field: str = "backend") -> str | None:
    """Validate a backend name (None allowed: the environment decides later)."""
    if backend is None:
        return None
    if not isinstance(backend, str) or backend.strip().lower() not in BACKENDS:
        raise ParameterError(field, backend, f"one of {', '.join(BACKENDS)} or None")
    return backend.strip().lower()


def resolve_backend(backend: str | None = None, field: str = "Simulation.backend") -> str:
    """The backend that runs: ``"cpu"`` or ``"cuda"`` (see the module docstring). Raises
    :class:`engine.ParameterError` naming ``field`` when ``"cuda"`` is asked for and cannot
    run here."""
    if backend is None:
        backend = os.environ.get(ENV) or "cpu"
        field = f"{ENV} ({field})"
    name = check_backend(backend, field)
    if name == "cpu":
        return "cpu"
    ok, what = cuda_status()
    if name == "cuda":
        if not ok:
            raise ParameterError(field, backend, "'cpu' or 'auto' here", what)
        return "cuda"
    chosen = "cuda" if ok else "cpu"
    log.info("backend auto: %s (%s)", chosen, what)
    return chosen
