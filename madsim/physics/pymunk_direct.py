"""The contact narrow phase's pymunk calls from compiled code: chipmunk's C functions called by
address, so that a consultation costs one compiled call instead of a numba dispatch, three
cffi calls and the Python between them.

`ContactSolver` fills a (NP_LEN,) int64 table `ptrs` with the addresses (`P_*`) of its held
space, of chipmunk's `cpSpaceEachBody`, `cpSpaceStep`, `cpSpaceEachCachedArbiter`, of
pymunk.batch's set and get iterators and of its two request structs and their arrays.
`narrow_direct` then does what `ContactSolver._narrow` does on a consultation where no car
enters or leaves the space and the space's body set has not changed since its last step: the
membership counters, the poses into the set buffer, the poses into pymunk, one step, the
arbiters into the get buffers. The calls, their order and their arguments are the same as
the Python path's (bit-identical results). Addresses are arguments, never constants, so the
compiled code is cached on disk like any other.

The struct layouts read here (pymunk 7.x `pmBatchedData`'s arrays: int num at 0, int max at
4, data pointer at 8) are checked against pymunk's own cffi types at import of contact.py
(`check_layout`)."""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from madsim.array_table import f8_ptr, i8_ptr
from madsim.physics.contact_kernels import IDLE_CALLS, _membership_poses

(P_SPACE, P_EACH_BODY, P_STEP, P_EACH_ARB, P_SET_FN, P_GET_FN, P_SET_REQ, P_ARB_REQ,
 P_SET_FLOATS, P_ARB_INTS, P_ARB_FLOATS) = range(11)
NP_LEN = 11
ARB_INTS, ARB_FLOATS = 3, 12
"""Per arbiter in the get buffers: (a id, b id, count), (normal, 2 x (pa, pb, dist))."""
"""Rows of the address table `ptrs`."""

ARRAY_NUM, ARRAY_MAX, ARRAY_DATA = 0, 4, 8
"""Byte offsets in pymunk.batch's pmIntArray / pmFloatArray: count (int), capacity (int),
data pointer."""


def check_layout(ffi) -> None:
    """Raise if pymunk's batch arrays are not laid out as `narrow_direct` reads them."""
    for name in ("pmFloatArray", "pmIntArray"):
        fields = dict(ffi.typeof(name).fields)
        got = (fields["num"].offset, fields["max"].offset, fields["arr"].offset,
               ffi.sizeof(fields["num"].type))
        if got != (ARRAY_NUM, ARRAY_MAX, ARRAY_DATA, 4):
            raise ImportError(f"pymunk.batch's {name} layout {got} is not the one madsim reads")


_I8P = ir.IntType(8).as_pointer()


@intrinsic
def _call_ppp(typingctx, fn, a, b, c):
    """fn(a, b, c) for a C function void (*)(void *, void *, void *) at address fn."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_I8P, _I8P, _I8P])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(v, _I8P) for v in args[1:]])
        return context.get_dummy_value()
    return sig, codegen


@intrinsic
def _call_pd(typingctx, fn, a, d):
    """fn(a, d) for a C function void (*)(void *, double) at address fn."""
    sig = types.void(types.int64, types.int64, types.float64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_I8P, ir.DoubleType()])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], _I8P), args[2]])
        return context.get_dummy_value()
    return sig, codegen


@intrinsic
def _peek_i32(typingctx, addr):
    """The int at address addr, as int64."""
    sig = types.int64(types.int64)

    def codegen(context, builder, signature, args):
        p = builder.inttoptr(args[0], ir.IntType(32).as_pointer())
        return builder.sext(builder.load(p), ir.IntType(64))
    return sig, codegen


@intrinsic
def _poke_i32(typingctx, addr, value):
    """Store value (int64, truncated) as an int at address addr."""
    sig = types.void(types.int64, types.int64)

    def codegen(context, builder, signature, args):
        p = builder.inttoptr(args[0], ir.IntType(32).as_pointer())
        builder.store(builder.trunc(args[1], ir.IntType(32)), p)
        return context.get_dummy_value()
    return sig, codegen


@intrinsic
def _peek_i64(typingctx, addr):
    """The 8-byte integer (a pointer) at address addr."""
    sig = types.int64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.load(builder.inttoptr(args[0], ir.IntType(64).as_pointer()))
    return sig, codegen


@numba.njit(cache=True, inline="always")
def arbiter_ints(ptrs, n):
    """The first n ints of the get request's int array (a view of pymunk's memory)."""
    return numba.carray(i8_ptr(_peek_i64(ptrs[P_ARB_INTS] + ARRAY_DATA)), n)


@numba.njit(cache=True, inline="always")
def arbiter_floats(ptrs):
    """The floats written into the get request's float array (a view of pymunk's memory)."""
    n = _peek_i32(ptrs[P_ARB_FLOATS] + ARRAY_NUM)
    return numba.carray(f8_ptr(_peek_i64(ptrs[P_ARB_FLOATS] + ARRAY_DATA)), n)


@numba.njit(cache=True, inline="always")
def _membership_stable(flags, member, idle):
    """True if `_membership` on these arrays would put no car in the space and take none out."""
    for i in range(flags.shape[0]):
        if flags[i]:
            if not member[i]:
                return False
        elif member[i] and idle[i] + 1 > IDLE_CALLS:
            return False
    return True


@numba.njit(cache=True)
def narrow_direct(ptrs, flags, member, idle, add, drop, slots, x, y, yaw, poses, dt):
    """`ContactSolver._narrow`'s consultation from compiled code (see the module's text) when no
    car enters or leaves the space: returns the number of arbiter ints written to the get
    request's int array (its floats: `_ARB_FLOATS / _ARB_INTS` times as many), or -1, having
    changed nothing, when a car would enter or leave (the caller takes the Python path)."""
    if not _membership_stable(flags, member, idle):
        return -1
    _membership_poses(flags, member, idle, add, drop, slots, x, y, yaw, poses)
    space = ptrs[P_SPACE]
    _poke_i32(ptrs[P_SET_FLOATS] + ARRAY_NUM, 0)          # the poses are read from the start
    _call_ppp(ptrs[P_EACH_BODY], space, ptrs[P_SET_FN], ptrs[P_SET_REQ])
    _call_pd(ptrs[P_STEP], space, dt)
    _poke_i32(ptrs[P_ARB_INTS] + ARRAY_NUM, 0)
    _poke_i32(ptrs[P_ARB_FLOATS] + ARRAY_NUM, 0)
    _call_ppp(ptrs[P_EACH_ARB], space, ptrs[P_GET_FN], ptrs[P_ARB_REQ])
    return _peek_i32(ptrs[P_ARB_INTS] + ARRAY_NUM)


NARROW_TABLE = (
    ("contact_table", "i8", 2, "C"), ("ptrs", "i8", 1, "C"), ("member", "b1", 1, "C"),
    ("idle", "i8", 1, "C"), ("add", "i8", 1, "C"), ("drop", "i8", 1, "C"), ("slots", "i8", 1, "C"),
    ("poses", "f8", 1, "C"), ("direct", "i8", 1, "C"),
)
"""The rows of the address table a compiled tick reads to consult pymunk itself
(`world_tick.contact_direct`): the World's `CONTACT_TABLE` table, then the solver's `ptrs`,
membership arrays, pose buffer and `direct` (D_*)."""
(N_CTABLE, N_PTRS, N_MEMBER, N_IDLE, N_ADD, N_DROP, N_SLOTS, N_POSES, N_DIRECT) = (
    np.int64(k) for k in range(len(NARROW_TABLE)))
D_READY, D_NARROWED, D_CALLS = range(3)
"""`direct` (3,) int64: the solver holds a space whose body set is unchanged since its last
step (1: a compiled consultation may run), the arbiters of the last consultation are in the get
buffers and not yet responded to (set by the compiled tick when it hands the rest of a tick to
Python), the consultations made from compiled code (counted into `ContactSolver.stats`)."""


def address(ffi, cdata) -> int:
    """A cffi pointer's address as a Python int."""
    return int(ffi.cast("uintptr_t", cdata))


def empty_ptrs() -> np.ndarray:
    return np.zeros(NP_LEN, dtype=np.int64)
