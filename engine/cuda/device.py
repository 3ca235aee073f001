"""One source, two targets: CUDA device functions and kernels built from the plain Python
functions behind the engine's ``@njit`` kernels.

A numba CPU dispatcher keeps the Python function it compiles (``dispatcher.py_func``). The same
function is compiled here with ``numba.cuda.jit(device=True)``, after rebinding the names it calls:
every global name of its code (and every closure cell) that refers to another ``@njit`` dispatcher
is bound to that callee's device version (built the same way, recursively), every other global (the
scene's compile-time flags and slot constants of a specialised step module, ``math``, the law
families' parameter and switch tuples) keeps its value. The contact laws, their composition
(:func:`engine.contact.compose.composition`) and the integration of
:mod:`engine.kernel.step_template` are thus written once and compiled for both targets, and a
scene's CUDA kernels carry exactly the features its CPU kernel carries.

Only :mod:`numba.cuda` (numba-cuda) is imported here, when this module is: the CPU engine
never imports it.
"""

from __future__ import annotations

import types

from numba import cuda
from numba.core.dispatcher import Dispatcher
from numba.cuda.core import config as cuda_config

#: True under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``): kernels run as Python.
SIMULATOR = bool(cuda_config.ENABLE_CUDASIM)

# device functions are inlined into their callers as the CPU kernels are (NVVM level: the
# scene's constant flags then fold the unused branches away)
_DEVICE_OPTIONS = {} if SIMULATOR else {"forceinline": True}


def _global_names(code: types.CodeType):
    yield from code.co_names
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _global_names(const)


def _contents(cell):
    try:
        return cell.cell_contents
    except ValueError:  # an empty cell
        return None


def rebind(fn: types.FunctionType, bindings: dict, memo: dict) -> types.FunctionType:
    """A copy of ``fn`` whose globals are its module's, with ``bindings`` on top and every
    name (global or closure cell) that refers to a CPU dispatcher bound to that dispatcher's
    device version."""
    g = dict(fn.__globals__)
    g.update(bindings)
    for name in set(_global_names(fn.__code__)):
        obj = g.get(name)
        if isinstance(obj, Dispatcher):
            g[name] = device_function(obj, memo)
    closure = fn.__closure__
    if closure:  # a law family's composition holds its kernels in closure cells
        closure = tuple(
            types.CellType(device_function(c.cell_contents, memo))
            if isinstance(_contents(c), Dispatcher)
            else c
            for c in closure
        )
    new = types.FunctionType(fn.__code__, g, fn.__name__, fn.__defaults__, closure)
    new.__kwdefaults__ = fn.__kwdefaults__
    new.__qualname__ = fn.__qualname__
    new.__module__ = fn.__module__
    new.__doc__ = fn.__doc__
    return new


def device_function(dispatcher, memo: dict):
    """The CUDA device version of a ``@njit`` kernel (memoised in ``memo``, one per family:
    a specialised step module and the modules it calls)."""
    key = id(dispatcher)
    if key not in memo:
        memo[key] = None  # recursion guard (the kernels do not recurse)
        py = rebind(dispatcher.py_func, {}, memo)
        memo[key] = cuda.jit(device=True, **_DEVICE_OPTIONS)(py)
    dev = memo[key]
    if dev is None:
        raise RecursionError(f"{dispatcher.py_func.__qualname__} calls itself")
    return dev


def plain_device_function(fn: types.FunctionType, bindings: dict, memo: dict):
    """A device function from a plain function ``fn`` (a CUDA-side helper of the kernels)."""
    return cuda.jit(device=True, **_DEVICE_OPTIONS)(rebind(fn, bindings, memo))


def kernel(fn: types.FunctionType, bindings: dict, memo: dict):
    """A CUDA kernel (``numba.cuda.jit``) from the plain function ``fn``, its globals bound
    as :func:`rebind` does (``bindings``: the device functions and constants it names)."""
    return cuda.jit(rebind(fn, bindings, memo))
