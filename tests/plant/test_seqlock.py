"""The plant kernels' sequence lock (rigd_drivers.plant.seqlock): semantics, ordering, races.

The torn operating-point set once seen in CI came from LLVM merging the reader's two loads of
the sequence word; these tests pin the reader's semantics, check that the compiled reader
still reads the word twice with a fence between, and race a compiled writer against a
compiled reader, both without the GIL.
"""

import re
import threading

import numba
import numpy as np

from rigd_drivers.plant.seqlock import load_acquire, read_staged, stage_block

N = 64
STG, SCR, ACT = 1, 1 + N, 1 + 2 * N
DONE = 1 + 3 * N            # set by the racing writer when it has finished
READY = DONE + 1            # set by the racing reader when it runs


def _params():
    return np.zeros(3 + 3 * N)


def test_reader_applies_a_complete_new_block_once_and_never_an_open_one():
    p = _params()
    stage_block(p, 0, STG, np.arange(N, dtype=float))
    assert p[0] == 2.0                                      # even: complete
    applied = read_staged(p, 0, 0.0, STG, SCR, ACT, N)
    assert applied == 2.0
    assert np.array_equal(p[ACT:ACT + N], np.arange(N))
    p[ACT:ACT + N] = -1.0                                   # not applied twice
    assert read_staged(p, 0, applied, STG, SCR, ACT, N) == applied
    assert np.all(p[ACT:ACT + N] == -1.0)
    p[0] = 3.0                                              # writer busy (odd)
    p[STG:STG + N] = 7.0
    assert read_staged(p, 0, applied, STG, SCR, ACT, N) == applied
    assert np.all(p[ACT:ACT + N] == -1.0)


def test_compiled_reader_reads_the_sequence_twice_with_a_fence_between():
    fresh = numba.njit(nogil=True)(read_staged.py_func)
    fresh(_params(), 0, 0.0, STG, SCR, ACT, N)
    ir = next(iter(fresh.inspect_llvm().values()))
    body = ir[ir.index("define"):]
    loads = [m.start() for m in re.finditer(r"load atomic (double|i64)", body)]
    assert len(loads) >= 2, "the re-check of the sequence word was merged with the first read"
    assert loads[0] < body.index("fence seq_cst") < loads[-1]


@numba.njit(nogil=True)
def _race_reader(params):
    applied = 0.0
    torn = 0
    swaps = 0
    params[READY] = 1.0
    last = False
    while not last:
        last = load_acquire(params, DONE) != 0.0    # one more pass after the writer ends
        a = read_staged(params, 0, applied, STG, SCR, ACT, N)
        if a != applied:
            applied = a
            swaps += 1
            v = params[ACT]
            for i in range(N):
                if params[ACT + i] != v:
                    torn += 1
                    break
    return torn, swaps


@numba.njit(nogil=True)
def _race_writer(params, a, b, reps):
    acc = 0.0
    spins = 0
    while load_acquire(params, READY) == 0.0 and spins < 1_000_000_000:   # start together
        spins += 1
    for r in range(reps):
        stage_block(params, 0, STG, a if r % 2 == 0 else b)
        for j in range(50):                                 # leave the reader windows
            acc += params[ACT + j % N] * 1e-12
    params[DONE] = 1.0
    return acc


def test_racing_writer_never_tears_what_the_reader_applies():
    a, b = np.full(N, 1.0), np.full(N, 2.0)
    warm = _params()
    warm[DONE] = 1.0
    _race_reader(warm)
    warm[READY] = 1.0
    _race_writer(warm, a, b, 2)
    p = _params()
    th = threading.Thread(target=_race_writer, args=(p, a, b, 300_000))
    th.start()
    torn, swaps = _race_reader(p)
    th.join()
    assert torn == 0
    assert swaps >= 1
    assert p[ACT] in (1.0, 2.0) and np.all(p[ACT:ACT + N] == p[ACT])
