"""Atomic integer operations and waiting for compiled code (numba has neither).

The step kernel's thread team (:mod:`engine.kernel.step_template`) hands out work and meets at
barriers through a small ``int64`` array in shared memory. These intrinsics emit LLVM's atomic
instructions on one element of such an array; every one is sequentially consistent, so the
plain writes a thread makes before an atomic are visible to a thread that reads the result of
that atomic (a barrier publishes the forces written before it).

Waiting: :func:`pause` (the spin hint) and :func:`cycles` (the time-stamp counter) for a short
spin, then :func:`futex_wait` / :func:`futex_wake` (Linux futexes, through the C library's
``syscall``): a thread that has waited a little sleeps in the kernel and gives its core away,
and is woken as soon as the value it waits on changes, as an OpenMP thread with a passive wait
policy is. C functions are called by name, so compiled kernels stay cacheable. Where there is
no futex (not Linux on x86-64 or AArch64) the wait polls with ``usleep``.
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
def cycles(typingctx):
    """The CPU's time-stamp counter [cycles] (``llvm.readcyclecounter``; 0 where none)."""

    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.IntType(64), []), "llvm.readcyclecounter"
        )
        return builder.call(fn, [])

    return types.int64(), codegen


#: Linux ``SYS_futex`` by architecture (no futex elsewhere: waits poll).
_SYS_FUTEX = {"x86_64": 202, "amd64": 202, "aarch64": 98, "arm64": 98}.get(
    platform.machine().lower() if platform.system() == "Linux" else "", 0
)
HAVE_FUTEX = _SYS_FUTEX != 0
_FUTEX_WAIT_PRIVATE = 128
_FUTEX_WAKE_PRIVATE = 129


def _syscall_futex(context, builder, sig, args, op, val):
    i64 = ir.IntType(64)
    fn = cgutils.get_or_insert_function(
        builder.module, ir.FunctionType(i64, [i64], var_arg=True), "syscall"
    )
    ptr = _element_pointer(context, builder, sig, args)
    addr = builder.ptrtoint(ptr, i64)  # the int64's low half (little-endian): the futex word
    builder.call(fn, [i64(_SYS_FUTEX), addr, i64(op), val, i64(0), i64(0), i64(0)])


@intrinsic
def futex_wait(typingctx, arr, idx, expected):
    """Sleep while the low 32 bits of ``arr[idx]`` equal those of ``expected`` (or until a
    :func:`futex_wake`; spurious returns happen, so the caller checks again)."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        if HAVE_FUTEX:
            e = context.cast(builder, args[2], sig.args[2], types.int64)
            low = builder.and_(e, ir.IntType(64)(0xFFFFFFFF))
            _syscall_futex(context, builder, sig, args, _FUTEX_WAIT_PRIVATE, low)
        else:
            i32 = ir.IntType(32)
            fn = cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(i32, [i32]), "usleep"
            )
            builder.call(fn, [i32(50)])
        return context.get_dummy_value()

    return types.none(arr, idx, expected), codegen


@intrinsic
def futex_wake(typingctx, arr, idx):
    """Wake every thread sleeping in :func:`futex_wait` on ``arr[idx]``."""
    _check(arr, idx)

    def codegen(context, builder, sig, args):
        if HAVE_FUTEX:
            everyone = ir.IntType(64)(2**31 - 1)
            _syscall_futex(context, builder, sig, args, _FUTEX_WAKE_PRIVATE, everyone)
        return context.get_dummy_value()

    return types.none(arr, idx), codegen


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
