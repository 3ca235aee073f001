"""The CUDA kernels of a scene, compiled from :mod:`engine.cuda._sources` with the device
versions of the scene's specialised CPU step module (:func:`engine.kernel.specialise.load_kernel`)
and of :mod:`engine.kernel.neighbour` bound in (:mod:`engine.cuda.device`).

The per-chunk reductions run over the CPU's chunks (``engine.core.config.CHUNK`` particles) in
the CPU's order; block sizes are launch parameters that change no result (per-element
work, integer work, order-free min/max, or sums in a fixed tree of ``RED_T``).
"""

from __future__ import annotations

import threading
from types import SimpleNamespace

from numba.cuda import types as cuda_types

from ..kernel import mesh, neighbour, state
from ..kernel import specialise as cpu_kernels
from . import _sources
from .device import SIMULATOR, device_function, kernel, plain_device_function

#: threads per block of the element-wise kernels (per particle, entry or cell)
THREADS = 8 if SIMULATOR else 128
#: threads of the one-block reductions (a power of two)
RED_T = 4 if SIMULATOR else 256
#: exclusive scans: threads per block and elements per thread
SCAN_T = 4 if SIMULATOR else 128
SCAN_SEG = 8

_STEP = (
    "reset_ctl",
    "pair_kernel",
    "particle_kernel",
    "chunk_kernel",
    "finish_kernel",
    "steps_kernel",
)
#: CUDA-side helpers of the step kernels, in the order they are built (each sees those above)
_STEP_HELPERS = ("_stop", "_finish_body", "_pair_body", "_particle_body", "_chunk_body")
_SEARCH = (
    "wrap_kernel",
    "bounds_kernel",
    "grid_kernel",
    "cell_kernel",
    "cell_fill_kernel",
    "count_kernel",
    "list_kernel",
    "commit_kernel",
    "rev_fill_kernel",
    "rev_sort_kernel",
    "mesh_count_kernel",
    "mesh_fill_kernel",
    "mesh_clear_kernel",
    "mesh_shift_kernel",
    "zero_kernel",
    "scan_block_kernel",
    "scan_add_kernel",
)
#: The neighbour build's functions both backends run (engine.kernel.neighbour), bound into
#: the search kernels as device functions.
_NEIGHBOUR = (
    "wrap_one",
    "grid_cells",
    "cell_of",
    "_scan",
    "sort_segment",
    "sort_and_carry",
    "commit_entry",
)

_lock = threading.Lock()
_step_cache: dict[tuple, SimpleNamespace] = {}
_search: SimpleNamespace | None = None


def _constants() -> dict:
    return {
        "float64": cuda_types.float64,
        "int64": cuda_types.int64,
        "RED_T": RED_T,
        "SCAN_T": SCAN_T,
        "SCAN_SEG": SCAN_SEG,
        "OK": state.OK,
        "REBUILD": state.REBUILD,
    }


def step_kernels(features: dict[str, bool]) -> SimpleNamespace:
    """The step kernels for ``features`` (those of :data:`engine.kernel.specialise.FEATURES`), with
    the CPU module they are compiled from as ``.cpu`` (for its slot layout and modes)."""
    key = tuple(sorted(features.items()))
    with _lock:
        if key in _step_cache:
            return _step_cache[key]
        mod = cpu_kernels.load_kernel(features)
        memo: dict = {}
        b = _constants()
        for name in ("CHUNK", "OPEN", "WALLS", "MESHES", "FORCES", "STEP", "CLOSE"):
            b[name] = getattr(mod, name)
        for name in ("_pair_setup", "_pair_one", "_wall_setup", "_particle_one"):
            b[name] = device_function(getattr(mod, name), memo)
        b["_advance_walls"] = device_function(state._advance_walls, memo)
        b["mesh_drift2"] = device_function(mesh.mesh_drift2, memo)
        for name in _STEP_HELPERS:
            b[name] = plain_device_function(getattr(_sources, name), b, memo)
        ns = SimpleNamespace(cpu=mod, **{n: kernel(getattr(_sources, n), b, memo) for n in _STEP})
        _step_cache[key] = ns
        return ns


def search_kernels() -> SimpleNamespace:
    """The neighbour-search and scan kernels (the same for every scene)."""
    global _search
    with _lock:
        if _search is None:
            memo: dict = {}
            b = _constants()
            for name in _NEIGHBOUR:
                b[name] = device_function(getattr(neighbour, name), memo)
            b["mesh_scan"] = device_function(mesh.mesh_scan, memo)
            b["clear_rows"] = device_function(mesh.clear_rows, memo)
            _search = SimpleNamespace(**{n: kernel(getattr(_sources, n), b, memo) for n in _SEARCH})
        return _search
