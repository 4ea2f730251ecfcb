"""Sequence-lock primitives for compiled plant kernels: ordered loads and stores.

A plant's operating point is staged by another thread into a block of its parameter array
and copied in whole by the kernel at the start of a step, under a sequence lock (the
sequence word is odd while the writer copies). A sequence lock is only correct when the
reader's second read of the sequence word really happens after its copy of the block, and
the writer's stores become visible in order. Plain numba code gives neither guarantee: LLVM
sees two loads of the same array element with no store between them and replaces the second
by the first (found in ``plant_step`` of rigd_drivers.sim: the re-check compiled to
``s1 != s1``), so a writer that came back during the copy went unnoticed and a torn set was
applied (tests/plant/test_plant_kernel.py::test_operating_point_staged_and_swapped_whole).

:func:`load_acquire` and :func:`store_release` are atomic float64 loads and stores of one
element (acquire / release ordering) and :func:`fence` a sequentially consistent fence; each
compiles to one instruction or none on x86-64, and all three forbid the compiler to move
memory accesses across them. :func:`stage_block` is the writer, :func:`read_staged` the
reader, for any kernel's layout.
"""

from __future__ import annotations

import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["fence", "load_acquire", "read_staged", "stage_block", "store_release"]


def _is_f8_vector(ary) -> bool:
    return isinstance(ary, types.Array) and ary.ndim == 1 and ary.dtype == types.float64


def _element_pointer(context, builder, sig, args):
    aryty, idxty = sig.args[0], sig.args[1]
    ary = context.make_array(aryty)(context, builder, args[0])
    idx = context.cast(builder, args[1], idxty, types.intp)
    return cgutils.get_item_pointer(context, builder, aryty, ary, [idx], wraparound=False)


@intrinsic
def load_acquire(typingctx, ary, idx):
    """``ary[idx]`` read as an atomic load with acquire ordering (float64 vector)."""
    if not (_is_f8_vector(ary) and isinstance(idx, types.Integer)):
        return None
    sig = types.float64(ary, idx)

    def codegen(context, builder, sig, args):
        return builder.load_atomic(_element_pointer(context, builder, sig, args),
                                   "acquire", 8)

    return sig, codegen


@intrinsic
def store_release(typingctx, ary, idx, value):
    """``ary[idx] = value`` as an atomic store with release ordering (float64 vector)."""
    if not (_is_f8_vector(ary) and isinstance(idx, types.Integer)
            and isinstance(value, types.Float)):
        return None
    sig = types.void(ary, idx, value)

    def codegen(context, builder, sig, args):
        val = context.cast(builder, args[2], sig.args[2], types.float64)
        builder.store_atomic(val, _element_pointer(context, builder, sig, args),
                             "release", 8)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def fence(typingctx):
    """A sequentially consistent memory fence (no memory access moves across it)."""
    sig = types.void()

    def codegen(context, builder, sig, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, nogil=True)
def stage_block(params, i_seq, start, block):
    """Writer: copy ``block`` into ``params[start:start + len(block)]`` under the sequence
    word ``params[i_seq]`` (odd while writing). One writer at a time (the caller's lock)."""
    seq = load_acquire(params, i_seq)
    store_release(params, i_seq, seq + 1.0)
    fence()                                   # the odd word is visible before any data
    for i in range(block.shape[0]):
        params[start + i] = block[i]
    store_release(params, i_seq, seq + 2.0)   # data visible before the even word


@numba.njit(cache=True, nogil=True)
def read_staged(params, i_seq, applied, stg, scr, act, n):
    """Reader: copy the staged block ``params[stg:stg+n]`` whole into ``params[act:act+n]``
    through the scratch ``params[scr:scr+n]`` when its sequence is new and complete.

    Parameters
    ----------
    params : float64 vector
        The kernel's parameter array.
    i_seq : int
        Index of the sequence word (odd while the writer copies).
    applied : float
        The sequence last applied (from the kernel's state).

    Returns
    -------
    float
        The sequence now applied: ``applied`` when nothing new or the writer was busy (the
        next step tries again), else the sequence of the block just applied.
    """
    s1 = load_acquire(params, i_seq)
    if s1 == applied or (int(s1) & 1) == 1:
        return applied
    for i in range(n):
        params[scr + i] = params[stg + i]
    fence()                                   # the copy is done before the re-check
    if load_acquire(params, i_seq) != s1:     # writer came back meanwhile
        return applied
    for i in range(n):
        params[act + i] = params[scr + i]
    return s1
