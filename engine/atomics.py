"""Atomic integer operations and waiting for compiled code (numba has neither).

The step kernel's thread team (:mod:`engine._step_template`) hands out work and meets at
barriers through a small ``int64`` array in shared memory. These intrinsics emit LLVM's atomic
instructions on one element of such an array; every one is sequentially consistent, so the
plain writes a thread makes before an atomic are visible to a thread that reads the result of
that atomic (a barrier publishes the forces written before it).

Waiting (:func:`pause`, :func:`yield_cpu`, :func:`sleep_us`): a spin hint, then the C
library's ``sched_yield`` and ``usleep`` (called by name, so compiled kernels stay cacheable):
a thread that has waited a little gives its core away instead of spinning, which matters on a
machine whose cores other processes share.
"""

from __future__ import annotations

import platform

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic


def _element_pointer(context, builder, sig, args):
    arr_t, _ = sig.args[0], sig.args[1]
    arr, idx = args[0], args[1]
    ary = context.make_array(arr_t)(context, builder, arr)
    return cgutils.get_item_pointer(context, builder, arr_t, ary, [idx], wraparound=False)


def _check(arr, idx):
    if not (isinstance(arr, types.Array) and arr.dtype == types.int64 and arr.ndim == 1):
        raise TypingError("atomics act on a 1-d int64 array")
    if not isinstance(idx, types.Integer):
        raise TypingError("atomics take an integer index")


@intrinsic
def atomic_add(typingctx, arr, idx, val):
    """``arr[idx] += val`` atomically; returns the value before the addition."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        ptr = _element_pointer(context, builder, sig, args)
        v = context.cast(builder, args[2], sig.args[2], types.int64)
        return builder.atomic_rmw("add", ptr, v, "seq_cst")

    return types.int64(arr, idx, val), codegen


@intrinsic
def atomic_load(typingctx, arr, idx):
    """``arr[idx]``, read atomically."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        ptr = _element_pointer(context, builder, sig, args)
        return builder.load_atomic(ptr, "seq_cst", 8)

    return types.int64(arr, idx), codegen


@intrinsic
def atomic_store(typingctx, arr, idx, val):
    """``arr[idx] = val``, written atomically."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        ptr = _element_pointer(context, builder, sig, args)
        v = context.cast(builder, args[2], sig.args[2], types.int64)
        builder.store_atomic(v, ptr, "seq_cst", 8)
        return context.get_dummy_value()

    return types.none(arr, idx, val), codegen


@intrinsic
def atomic_cas(typingctx, arr, idx, expected, new):
    """If ``arr[idx] == expected`` set it to ``new``, atomically; returns True if it did."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        ptr = _element_pointer(context, builder, sig, args)
        e = context.cast(builder, args[2], sig.args[2], types.int64)
        n = context.cast(builder, args[3], sig.args[3], types.int64)
        res = builder.cmpxchg(ptr, e, n, "seq_cst", "seq_cst")
        return builder.extract_value(res, 1)

    return types.boolean(arr, idx, expected, new), codegen


_X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")


@intrinsic
def pause(typingctx):
    """A spin-wait hint to the core (x86 ``pause``; nothing elsewhere)."""

    def codegen(context, builder, sig, args):
        if _X86:
            fn = cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(ir.VoidType(), []), "llvm.x86.sse2.pause"
            )
            builder.call(fn, [])
        return context.get_dummy_value()

    return types.none(), codegen


@intrinsic
def yield_cpu(typingctx):
    """``sched_yield()`` of the C library: let another runnable thread have this core."""

    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.IntType(32), []), "sched_yield"
        )
        builder.call(fn, [])
        return context.get_dummy_value()

    return types.none(), codegen


@intrinsic
def sleep_us(typingctx, us):
    """``usleep(us)`` of the C library: sleep ``us`` microseconds [us]."""
    if not isinstance(us, types.Integer):
        raise TypingError("sleep_us takes an integer number of microseconds")

    def codegen(context, builder, sig, args):
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i32, [i32]), "usleep")
        builder.call(fn, [builder.trunc(args[0], i32) if args[0].type.width > 32 else args[0]])
        return context.get_dummy_value()

    return types.none(us), codegen
