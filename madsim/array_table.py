"""Many arrays handed to a compiled function as one: a table of their addresses and shapes.

Why: numba's dispatcher unboxes each array argument on every call, ~50-80 ns apiece here; the
SCR server's tick reads about sixty arrays, so passing them one by one cost 4-5 us per tick
(a third of the tick), and 7-9 us as nested tuples. `address_table` checks every array
against its declared dtype, dimensions and memory order and writes (address, shape) rows; a
compiled function rebuilds views with the `*_vector` / `*_matrix` functions (`numba.carray`
on the address: 1-d, or 2- and 3-d in C order). The owner of the table keeps the arrays alive and rebuilds the table
whenever one of them is replaced; the views are only valid during the call.
"""

from __future__ import annotations

import numba
import numpy as np
from numba.core import types
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic

DTYPES = {"f8": np.float64, "f4": np.float32, "i8": np.int64, "u1": np.uint8, "i1": np.int8,
          "b1": np.bool_}


def address_table(arrays, spec) -> np.ndarray:
    """(K, 1 + the largest ndim) int64 rows (address, shape[0], shape[1] or 0, ...) of `arrays`,
    checked against `spec`: one (name, dtype key of DTYPES, ndim, order 'C' or 'F') per array.
    Raises ValueError naming the array that does not match (a wrong view would read the wrong
    memory)."""
    arrays = list(arrays)
    if len(arrays) != len(spec):
        raise ValueError(f"address_table: {len(arrays)} arrays for {len(spec)} entries")
    table = np.zeros((len(arrays), 1 + max(ndim for _, _, ndim, _ in spec)), dtype=np.int64)
    for k, (a, (name, dtype, ndim, order)) in enumerate(zip(arrays, spec)):
        contiguous = a.flags.c_contiguous if order == "C" else a.flags.f_contiguous
        if not (isinstance(a, np.ndarray) and a.dtype == DTYPES[dtype] and a.ndim == ndim and contiguous):
            raise ValueError(f"address_table: {name} must be a {order}-contiguous {ndim}-d {dtype} "
                             f"array, got {getattr(a, 'dtype', type(a))} {getattr(a, 'shape', '')}")
        table[k, 0] = a.ctypes.data
        table[k, 1:1 + ndim] = a.shape
    return table


def _pointer_intrinsic(item):
    @intrinsic
    def pointer(typingctx, address):
        sig = types.CPointer(item)(types.int64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
        return sig, codegen
    return pointer


_POINTERS = {"f8": _pointer_intrinsic(types.float64), "f4": _pointer_intrinsic(types.float32),
             "i8": _pointer_intrinsic(types.int64),
             "u1": _pointer_intrinsic(types.uint8), "i1": _pointer_intrinsic(types.int8),
             "b1": _pointer_intrinsic(types.boolean)}
f8_ptr, f4_ptr, i8_ptr, u1_ptr, i1_ptr, b1_ptr = (_POINTERS[k] for k in ("f8", "f4", "i8", "u1", "i1",
                                                                         "b1"))


# views of row k of a table, one function per dtype and shape (an intrinsic is no argument).
# Called, not inlined, with k an int64 (not a literal constant): each compiles once, and LLVM
# inlines the calls; inlined by numba they were typed again at each of the tick's ~60 call
# sites (1 s of a cold start), and a literal k would compile one copy per row.
@numba.njit(cache=True)
def f8_vector(table, k):
    return numba.carray(f8_ptr(table[k, 0]), (table[k, 1],))


@numba.njit(cache=True)
def f8_matrix(table, k):
    return numba.carray(f8_ptr(table[k, 0]), (table[k, 1], table[k, 2]))


@numba.njit(cache=True)
def f8_tensor(table, k):
    """A 3-d C-order view (the table has four columns)."""
    return numba.carray(f8_ptr(table[k, 0]), (table[k, 1], table[k, 2], table[k, 3]))


@numba.njit(cache=True)
def f4_matrix(table, k):
    return numba.carray(f4_ptr(table[k, 0]), (table[k, 1], table[k, 2]))


@numba.njit(cache=True)
def i8_vector(table, k):
    return numba.carray(i8_ptr(table[k, 0]), (table[k, 1],))


@numba.njit(cache=True)
def i8_matrix(table, k):
    return numba.carray(i8_ptr(table[k, 0]), (table[k, 1], table[k, 2]))


@numba.njit(cache=True)
def u1_vector(table, k):
    return numba.carray(u1_ptr(table[k, 0]), (table[k, 1],))


@numba.njit(cache=True)
def u1_matrix(table, k):
    return numba.carray(u1_ptr(table[k, 0]), (table[k, 1], table[k, 2]))


@numba.njit(cache=True)
def i1_vector(table, k):
    return numba.carray(i1_ptr(table[k, 0]), (table[k, 1],))


@numba.njit(cache=True)
def b1_vector(table, k):
    return numba.carray(b1_ptr(table[k, 0]), (table[k, 1],))


@numba.njit(cache=True)
def b1_matrix(table, k):
    return numba.carray(b1_ptr(table[k, 0]), (table[k, 1], table[k, 2]))


@intrinsic
def readonly(typingctx, arr):
    """The same view typed read-only: the World hands the track's tables to the kernels as
    read-only arrays, and a view of another type would compile every kernel a second time."""
    if not isinstance(arr, types.Array):
        return None
    sig = arr.copy(readonly=True)(arr)

    def codegen(context, builder, signature, args):
        return impl_ret_borrowed(context, builder, signature.return_type, args[0])
    return sig, codegen
