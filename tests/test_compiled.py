"""The compiled engine (hconv.solve.compiled, its C code in hconv.solve.rowcode) against the numpy
engine and against independent references.

The contract (docs/engines.md): ω of ``exact``, ``cond`` and every status are the numpy engine's
bits; ``refined``'s ω and the ``residual`` may differ in the last bits, because the compiled
engine decides when refinement stops row by row. Each test also checks that the compiled engine
computed the rows itself, so that agreement cannot come from handing every row to numpy.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from helpers import (
    assert_same_answers,
    hard_bodies,
    mp_solve,
    physical_bodies,
    random_rotations,
    rel_err,
    same_bits,
    spd_bodies,
)

import hconv
from hconv.solve import compiled, rowcode
from hconv.solve.status import CODE, PRECEDENCE

EPS = np.finfo(float).eps


def _rows_of(I: np.ndarray, H: np.ndarray, refined: bool = False, diagnostics: bool = True) -> tuple:
    """compiled.convert_rows on an (N, 3, 3) stack and (N, 3) H: (w, cond, code, residual, fallback)."""
    n = len(H)
    out = (np.empty((n, 3)), np.empty(n), np.empty(n, np.uint8), np.empty(n if diagnostics else 0), np.empty(n, bool))
    compiled.convert_rows(I.reshape(n, 9).T, True, H.T, refined, diagnostics, 4.5e9, *out)
    return out


def test_extension_is_built_and_configured():
    """The package carries the built C code (pip builds it at install): no JIT, nothing compiled
    at run time."""
    ext = importlib.import_module("hconv.solve.rowcode")
    assert Path(ext.__file__).suffix in (".so", ".pyd")
    with pytest.raises(KeyError, match="SPLIT missing"):
        ext.configure({})


@pytest.mark.parametrize("method", ["exact", "refined"])
@pytest.mark.parametrize("diagnostics", [True, False])
@pytest.mark.parametrize("shape", ["(N,3,3)", "(N,6)"])
def test_convert_rows_same_answers_as_numpy_engine(method, diagnostics, shape, rng):
    I, H = hard_bodies(rng, shape)
    ref = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy")
    got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="compiled")
    assert got.engine == "compiled" and ref.engine == "numpy"
    # every status the compiled engine sets itself is in the stack, and more besides
    own = {"ok", "singular", "not_physical"} | ({"ill_conditioned"} if method == "exact" else set())
    assert own <= set(ref.counts())
    hard = {"invalid_input", "overflow", "not_positive_definite", "inaccurate"}
    assert hard | ({"not_symmetric"} if shape == "(N,3,3)" else set()) <= set(ref.counts())
    assert_same_answers(got, ref, method)
    assert (got.residual is None) == (ref.residual is None) == (not diagnostics)


def test_convert_rows_keeps_the_common_rows_itself(rng):
    """Agreement must come from the C code: physical and ill-conditioned bodies are its own, and
    only the cases it leaves to numpy go there. (Rods, whose two largest moments nearly meet, go
    to numpy where the closed form cannot decide the triangle inequality, as in the numpy engine.)"""
    I = np.concatenate([physical_bodies(rng, 300), spd_bodies(rng, 100, 1e12), spd_bodies(rng, 100, 1e3)])
    H = rng.normal(size=(500, 3))
    for refined, diagnostics in [(False, False), (False, True), (True, False), (True, True)]:
        assert not _rows_of(I, H, refined, diagnostics)[4].any()
    hard, Hh = hard_bodies(rng)
    fallback = _rows_of(hard, Hh)[4]
    assert 0.1 < fallback.mean() < 0.6  # NaN, not symmetric, not definite, extreme scales, ... but not the rest


def test_convert_rows_near_lamina_decided_by_the_largest_moment_s_exact_error_bound(rng):
    """Bodies whose largest moment exceeds the sum of the other two by delta (a lamina has 0):
    the closed form decides them only where the margin delta beats 1e-9·trace plus four times
    its error bound hi_err, which the C code computes for a row only when a cheaper upper bound
    of hi_err (p·√eps) leaves the row unsure. With moments 1, 2 and 3 + delta, the cheap bound
    clears delta = 1e-7, leaves 2e-8 to hi_err (about 6e-15 here), which clears it, and 1e-9
    fails both (numpy's eigvalsh decides it). Each row as the numpy engine converts it, each
    kept or left as the numpy engine's test says."""
    deltas = np.repeat([1e-7, 2e-8, 1e-9], 40)
    R = random_rotations(rng, len(deltas))
    moments = np.zeros((len(deltas), 3, 3))
    moments[:, 0, 0], moments[:, 1, 1], moments[:, 2, 2] = 1.0, 2.0, 3.0 + deltas
    I = R @ moments @ R.transpose(0, 2, 1)
    I = (I + I.transpose(0, 2, 1)) / 2  # symmetric to the bit, as the C code's nine numbers must be
    H = rng.normal(size=(len(deltas), 3))
    for refined, diagnostics in [(False, False), (False, True), (True, False)]:
        fallback = _rows_of(I, H, refined, diagnostics)[4]
        assert not fallback[deltas > 1e-9].any() and fallback[deltas == 1e-9].all()
        method = "refined" if refined else "exact"
        got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="compiled")
        assert_same_answers(got, hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy"), method)


def test_convert_rows_refined_within_two_eps_of_mpmath_to_cond_1e12(rng):
    for cond in (1e4, 1e8, 1e12):
        I, H = spd_bodies(rng, 60, cond), rng.normal(size=(60, 3))
        res = hconv.convert(H, I, method="refined", engine="compiled")
        assert res.engine == "compiled" and not _rows_of(I, H, refined=True)[4].any()
        assert rel_err(res.w, mp_solve(I, H)).max() <= 2 * EPS
        assert np.all(res.residual <= 2 * EPS)  # the answer's own measured error, within the promise


def test_convert_rows_exact_error_within_its_bound_and_residual_measures_it(rng):
    """exact's error is K·cond·eps at most, and its residual column is that error (mpmath)."""
    I, H = spd_bodies(rng, 80, 1e8), rng.normal(size=(80, 3))
    res = hconv.convert(H, I, engine="compiled")
    true = rel_err(res.w, mp_solve(I, H))
    assert 100 * EPS < true.max() <= 1e8 * EPS  # cond 1e8 leaves exact's error visible
    np.testing.assert_allclose(res.residual, true, rtol=1e-6, atol=2 * EPS)


def test_convert_rows_rotation_covariance(rng):
    """ω of R·I·Rᵀ and R·H is R·ω: an identity independent of either engine's arithmetic."""
    I, H = physical_bodies(rng, 200), rng.normal(size=(200, 3))
    R = random_rotations(rng, 200)
    w = hconv.convert(H, I, engine="compiled").w
    w_rot = hconv.convert(np.einsum("nij,nj->ni", R, H), R @ I @ R.transpose(0, 2, 1), engine="compiled").w
    assert rel_err(w_rot, np.einsum("nij,nj->ni", R, w)).max() <= 64 * EPS


def test_convert_rows_uncovered_runs_are_numpy_whatever_is_asked():
    I, H = np.tile(np.diag([1.0, 2.0, 2.5]), (3, 1, 1)), np.ones((3, 3))
    assert hconv.convert(H, I, method="eigen", engine="compiled").engine == "numpy"
    assert hconv.convert(H, I, precision=32, engine="compiled").engine == "numpy"
    assert hconv.convert(H, I, degenerate="pinv", engine="compiled").engine == "numpy"
    moments = np.ones((4, 3))  # four rows: (3, 3) beside three rows is refused as ambiguous
    assert hconv.convert(np.ones((4, 3)), moments, engine="compiled").engine == "numpy"  # a division


def _outputs(n: int) -> tuple:
    """convert_rows' outputs, filled with values no row gets, so that a row left unwritten shows."""
    return np.full((n, 3), -1.0), np.full(n, -1.0), np.full(n, 255, np.uint8), np.full(n, -1.0), np.ones(n, bool)


def _row_args(I: np.ndarray, H: np.ndarray) -> tuple:
    """The inputs of rowcode.convert and .share for an (N, 3, 3) stack: exact, with the residual."""
    n = len(H)
    return (I.reshape(n, 9).T, True, H.T, False, True, 4.5e9)


def _rows_and_reference(rng: np.random.Generator, n: int) -> tuple[tuple, tuple, np.ndarray, np.ndarray]:
    """n physical bodies and H: (rowcode's inputs, their outputs on one thread, I, H)."""
    I, H = physical_bodies(rng, n), rng.normal(size=(n, 3))
    args = _row_args(I, H)
    ref = _outputs(n)
    rowcode.convert(*args, *ref, False, 0, n)
    return args, ref, I, H


def _no_thread_serving() -> None:
    """Waits until the threads earlier calls left serving have gone back to the pool (LINGER)."""
    for _ in range(3000):
        if rowcode.serving() == 0:
            return
        time.sleep(0.01)
    raise AssertionError("a thread still serves 30 s after its last block")


def _serving(linger: float, threads: int) -> list:
    """``threads`` threads in rowcode.serve(linger), once every one of them is in it."""
    before = rowcode.serving()
    pool = ThreadPoolExecutor(threads)
    futures = [pool.submit(rowcode.serve, linger) for _ in range(threads)]
    pool.shutdown(wait=False)
    for _ in range(3000):
        if rowcode.serving() >= before + threads:
            return futures
        time.sleep(0.01)
    raise AssertionError("the serving threads did not start within 30 s")


def test_convert_rows_same_bits_whatever_the_blocks_and_threads(rng, monkeypatch):
    """Many blocks on several threads give the bits of one call on one thread: rows are
    independent, and each block is converted without the GIL on a thread of its own."""
    I, H = hard_bodies(rng)
    reps = 30
    I, H = np.tile(I, (reps, 1, 1)), np.tile(H, (reps, 1))
    ref = _rows_of(I, H, refined=True)
    assert 0 < ref[4].mean() < 1
    served: list[int] = []
    real = rowcode.serve

    class Recording:
        configure, convert, share = (rowcode.configure, rowcode.convert, rowcode.share)

        @staticmethod
        def serve(linger):
            served.append(real(linger))
            return served[-1]

    monkeypatch.setattr(compiled, "rowcode", Recording)
    monkeypatch.setattr(compiled, "_servers", compiled._Servers())
    for block, cores in ((997, 2), (4096, 3), (len(H), 4)):
        monkeypatch.setattr(compiled, "BLOCK_ROWS", block)
        monkeypatch.setattr(compiled, "available_cores", lambda cores=cores: cores)
        got = _rows_of(I, H, refined=True)
        for a, b in zip(got, ref):
            assert same_bits(a, b)
    # blocks do run on the pool's threads, not only the caller's; on a busy machine a call may end
    # before its pool thread begins (the next test's case), so calls are repeated until one does
    monkeypatch.setattr(compiled, "BLOCK_ROWS", 997)
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    for _ in range(200):
        _no_thread_serving()
        if sum(served) > 0:
            break
        got = _rows_of(I, H, refined=True)
        for a, b in zip(got, ref):
            assert same_bits(a, b)
    assert sum(served) > 0, served


@pytest.mark.parametrize(("n", "linger", "most"), [(20_000, 0.5, 3), (100_000, 0.001, 10)])
def test_convert_rows_calls_in_a_loop_hand_no_task_to_a_thread_already_serving(rng, monkeypatch, n, linger, most):
    """Calls one after another find the pool's thread still serving from the call before (it
    stays in C for LINGER after its last block): the first call hands it a task, the rest none,
    so that no call waits for a thread's wake-up; the answers are the one-thread call's bits.
    Short calls and a long LINGER, and calls longer than LINGER (a thread that counted LINGER
    from the call's start would go back to the pool at the end of every call)."""
    _, ref, I, H = _rows_and_reference(rng, n)
    tasks: list[object] = []
    real_pool = compiled._shared_pool

    class Counting:
        def __init__(self, pool):
            self._pool = pool

        def submit(self, fn, *args):
            tasks.append(fn)
            return self._pool.submit(fn, *args)

    monkeypatch.setattr(compiled, "_shared_pool", lambda threads: Counting(real_pool(threads)))
    monkeypatch.setattr(compiled, "_servers", compiled._Servers())
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    monkeypatch.setattr(compiled, "LINGER", linger)
    _no_thread_serving()
    results = [_rows_of(I, H) for _ in range(20)]
    for got in results:
        for a, b in zip(got, ref):
            assert same_bits(a, b)
    # one task; a busy machine may let a gap between two calls outlast LINGER now and then
    assert 1 <= len(tasks) <= most


def test_convert_rows_thread_that_begins_after_the_rows_are_done_takes_none(rng):
    """A call whose pool threads have not begun (a busy machine) does not wait for them: the
    caller converts every row, and a thread that begins serving afterwards finds no block of that
    call left and writes no row of it."""
    n = 10_000
    args, ref, _, _ = _rows_and_reference(rng, n)
    _no_thread_serving()
    got = _outputs(n)
    lost, own = rowcode.share(*args, *got, False, 1_000)
    assert (lost, own) == (0, n)
    for a, b in zip(got, ref):
        assert same_bits(a, b)
    for out in got:  # a block the late thread took would write over these
        out[...] = 1
    assert _serving(0.05, 1)[0].result(timeout=60) == 0
    assert all((out == 1).all() for out in got)


def test_convert_rows_thread_that_begins_during_a_call_takes_its_blocks(rng):
    """A pool thread woken for a call begins serving once the caller is converting its first
    block: it takes the blocks left, and does not count the call as one it has seen end, which
    once sent it back to the pool after LINGER with the caller left to convert alone."""
    n = 800_000
    args, ref, _, _ = _rows_and_reference(rng, n)
    _no_thread_serving()
    for _ in range(20):
        got = _outputs(n)
        began: list[float] = []
        taken: list[int] = []

        def late(began: list[float] = began, taken: list[int] = taken) -> None:
            time.sleep(0.002)
            began.append(time.perf_counter())
            taken.append(rowcode.serve(0.001))

        thread = threading.Thread(target=late)
        thread.start()
        # four blocks of 200,000 rows: each far longer than the thread's LINGER
        lost, own = rowcode.share(*args, *got, False, 200_000)
        returned = time.perf_counter()
        thread.join()
        for a, b in zip(got, ref):
            assert same_bits(a, b)
        if began[0] < returned - 0.005:  # it began well before the caller was done
            assert taken[0] > 0 and own < n
            return
    raise AssertionError("in 20 calls the thread never began while the caller had blocks left")


def test_convert_rows_child_forked_during_a_call_takes_none_of_its_blocks(rng):
    """A child forked (by another thread: a multiprocessing pool's handler) while its parent's
    main thread converts a call inherits that call's post with blocks left and no caller: its
    serving thread must take none of them, or its own next call counts their rows as its own and
    returns before its rows are written."""
    if not hasattr(os, "fork"):
        pytest.skip("no fork on this platform")
    n_dead, n = 1_000_000, 200_000
    dead = _row_args(np.full((n_dead, 3, 3), np.nan), np.zeros((n_dead, 3)))  # every row falls back
    args, ref, _, _ = _rows_and_reference(rng, n)

    def child() -> None:
        code = 3
        try:
            server = threading.Thread(target=rowcode.serve, args=(0.2,))
            server.start()
            time.sleep(0.005)  # time to take the parent's blocks, were they offered
            got = _outputs(n)
            lost, _ = rowcode.share(*args, *got, False, 10_000)
            whole = all(same_bits(a, b) for a, b in zip(got, ref))
            server.join()
            code = 0 if lost == 0 and whole else 1
        finally:
            os._exit(code)

    for _ in range(3):
        pids: list[int] = []

        def fork_soon(pids: list[int] = pids) -> None:
            time.sleep(0.02)  # a fifth of the way through the call's 50 blocks, on one thread
            pid = os.fork()
            if pid == 0:
                child()
            pids.append(pid)

        outputs = _outputs(n_dead)
        forker = threading.Thread(target=fork_soon)
        forker.start()
        lost, _ = rowcode.share(*dead, *outputs, False, 20_000)
        forker.join()
        assert lost == n_dead
        _, status = os.waitpid(pids[0], 0)
        assert os.waitstatus_to_exitcode(status) == 0


def test_convert_rows_share_and_serve_refuse_what_they_cannot_do(rng):
    """A block size that is not one row at least, or a linger that is not a time (NaN would keep
    the thread forever), is refused; a block size above the rows (even the largest, whose block
    count once overflowed) is one block."""
    n = 50
    args, ref, _, _ = _rows_and_reference(rng, n)
    for size in (1, 7, n, n + 1, sys.maxsize):
        got = _outputs(n)
        assert rowcode.share(*args, *got, False, size)[0] == 0
        assert all(same_bits(a, b) for a, b in zip(got, ref))
    for size in (0, -1):
        with pytest.raises(ValueError, match="block size"):
            rowcode.share(*args, *_outputs(n), False, size)
    for linger in (float("nan"), float("inf"), -1.0):
        with pytest.raises(ValueError, match="linger"):
            rowcode.serve(linger)


def test_convert_rows_when_the_pool_takes_no_more_tasks_converts_on_the_caller(rng, monkeypatch):
    """A large call made while the interpreter shuts down (an atexit handler), whose pool refuses
    new tasks, is converted by its caller alone, not refused."""
    n = 20_000
    _, ref, I, H = _rows_and_reference(rng, n)
    closed = ThreadPoolExecutor(1)
    closed.shutdown()
    monkeypatch.setattr(compiled, "_shared_pool", lambda threads: closed)
    monkeypatch.setattr(compiled, "_servers", compiled._Servers())
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    got = _rows_of(I, H)
    for a, b in zip(got, ref):
        assert same_bits(a, b)


def test_convert_rows_caller_waits_for_the_blocks_other_threads_hold(rng):
    """The caller returns only when every row is done, by whichever thread: when it finds no
    block left to take, a serving thread may still be converting its last one."""
    n = 400_000
    args, ref, _, _ = _rows_and_reference(rng, n)
    server = _serving(0.5, 1)[0]
    owns = []
    for _ in range(12):
        got = _outputs(n)
        # blocks of 50,000 rows: when the caller finds none left, the serving thread's last may
        # have milliseconds to go, more than copying one output takes
        lost, own = rowcode.share(*args, *got, False, 50_000)
        cond_at_return = got[1].copy()
        owns.append(own)
        assert same_bits(cond_at_return, ref[1])
        for a, b in zip(got, ref):
            assert same_bits(a, b)
    assert min(owns) < n  # the serving thread did take blocks
    assert server.result(timeout=60) > 0


def test_convert_rows_shared_blocks_are_each_taken_once(rng):
    """Three serving threads and the caller taking blocks of 7 rows write every row once, with the
    bits of a single call over all rows, and count the fallback rows once (NaN rows fall back)."""
    I, H = physical_bodies(rng, 1_000), rng.normal(size=(1_000, 3))
    H[::97] = np.nan
    n = len(H)
    args = _row_args(I, H)
    ref, got = _outputs(n), _outputs(n)
    lost_ref = rowcode.convert(*args, *ref, False, 0, n)
    servers = _serving(0.5, 3)
    lost, own = rowcode.share(*args, *got, False, 7)
    assert lost == lost_ref == len(range(0, n, 97))
    for a, b in zip(got, ref):
        assert same_bits(a, b)
    # every block taken once: the servers' and the caller's (its rows in blocks of 7, or 6 for the last)
    assert sum(f.result(timeout=60) for f in servers) + -(-own // 7) == -(-n // 7)


def test_convert_rows_calls_in_a_row_never_write_a_returned_call_s_rows(rng):
    """Thousands of shared calls one after another, from two threads at once (the second converts
    alone while the first holds the post), with two threads serving: every call is whole when it
    returns, and no thread writes a row of a call after that call has returned, however late it
    read the call's post (its outputs, overwritten at return, stay so)."""
    sizes = (64, 200, 333)
    made = {n: _rows_and_reference(rng, n) for n in sizes}
    inputs = {n: args for n, (args, _, _, _) in made.items()}
    refs = {n: ref for n, (_, ref, _, _) in made.items()}
    servers = _serving(0.5, 2)
    returned: list[tuple] = []
    wrong: list[int] = []
    shared = [0]  # calls whose blocks a serving thread took part in

    def calls(first: int) -> None:
        k = first
        # until enough calls were shared to have raced (on a busy machine a serving thread runs
        # beside a caller less often), from the first thread; the second keeps it company
        while (shared[0] < 200 and k < 20_000) if first == 0 else k < 1_500:
            n = sizes[k % len(sizes)]
            got = _outputs(n)
            _, own = rowcode.share(*inputs[n], *got, False, 16)
            shared[0] += own < n
            if not all(same_bits(a, b) for a, b in zip(got, refs[n])):
                wrong.append(k)
            for out in got:
                out[...] = 1
            returned.append(got)
            k += 2

    other = threading.Thread(target=calls, args=(1,))
    other.start()
    calls(0)
    other.join()
    assert not wrong
    assert shared[0] > 0
    assert sum(f.result(timeout=60) for f in servers) > 0
    assert all((out == 1).all() for got in returned for out in got)


def test_convert_rows_same_bits_whatever_the_instruction_set(rng):
    """Every version of the chunk code this CPU runs gives the bits of the plain x86-64 one, which
    takes the residual's product errors from Dekker's splits where the others use fma(): within
    the safe range both are the exact error. Rows near that range's edges are in the stack
    (inputs at 2^±120 kg·m², H at 2^±400 kg·m²/s)."""
    I, H = hard_bodies(rng)
    edge = physical_bodies(rng, 200)
    scales = np.repeat([2.0**120, 2.0**-120], 100)
    H_edge = rng.normal(size=(200, 3)) * np.repeat([2.0**400, 2.0**-400], 100)[:, None]
    I, H = np.concatenate([I, edge * scales[:, None, None]]), np.concatenate([H, H_edge])
    names = rowcode.kernels()
    assert "default" in names
    try:
        for refined in (False, True):
            rowcode.use("default")
            ref = _rows_of(I, H, refined=refined)
            assert 0 < ref[4].mean() < 0.5  # the edge rows are the compiled engine's own
            assert not ref[4][-200:].any()
            for name in names:
                rowcode.use(name)
                got = _rows_of(I, H, refined=refined)
                for a, b in zip(got, ref):
                    assert same_bits(a, b), name
    finally:
        rowcode.use(names[0])


def _rows_into_outputs(I: np.ndarray, H: np.ndarray, refined: bool, diagnostics: bool, offset: int) -> tuple:
    """_rows_of, streamed, into compiled.outputs' arrays (on cache lines), or from ``offset`` rows
    into them (off the lines)."""
    n = len(H)
    outs = compiled.outputs(n + offset, diagnostics)
    views = tuple(a[offset:] if len(a) else a for a in outs)  # residual is (0,) without diagnostics
    compiled.convert_rows(I.reshape(n, 9).T, True, H.T, refined, diagnostics, 4.5e9, *views, stream=True)
    return views


@pytest.mark.parametrize("diagnostics", [True, False])
def test_convert_rows_streamed_same_bits_as_stored(rng, diagnostics):
    """Whole chunks streamed past the caches (the outputs of large calls) hold the bits stored
    chunk by chunk, with every version of the chunk code, on one thread or shared between
    threads; outputs off the cache lines are stored as usual, streamed or not."""
    I, H = hard_bodies(rng)
    for reps in (1, 20):  # 480 rows on the caller's thread; 9,600 in blocks on every core
        Ir, Hr = np.tile(I, (reps, 1, 1)), np.tile(H, (reps, 1))
        names = rowcode.kernels()
        try:
            for refined in (False, True):
                ref = _rows_of(Ir, Hr, refined=refined, diagnostics=diagnostics)
                assert 0 < ref[4].mean() < 0.5
                for name in names:
                    rowcode.use(name)
                    for offset in (0, 1):
                        got = _rows_into_outputs(Ir, Hr, refined, diagnostics, offset)
                        assert all(a.ctypes.data % 64 == 0 for a in got if len(a)) == (offset == 0)
                        for a, b in zip(got, ref):
                            assert same_bits(a, b), (name, offset)
        finally:
            rowcode.use(names[0])


def test_outputs_memory_of_a_dropped_result_serves_the_next_call_of_its_size(rng):
    """A call in a loop writes into the memory of the result dropped before it (already mapped,
    so no page fault and no zeroing by the system), and that memory holds the new call's answers
    whole: the numpy engine's bits, nothing left of the old rows."""
    compiled.release()
    n = 200_000  # ω 4.8 MB
    assert 24 * n >= compiled.pool()["least_bytes"]
    I, H = physical_bodies(rng, n), rng.normal(size=(n, 3))
    first = hconv.convert(H, I, engine="compiled")  # HCONV_ENGINE=numpy would make auto numpy
    at = first.w.ctypes.data
    assert first.w.flags.owndata and at % 64 == 0
    del first
    kept = compiled.pool()
    assert kept["blocks"] >= 1 and kept["bytes"] >= 24 * n
    I2, H2 = physical_bodies(rng, n), rng.normal(size=(n, 3))
    second = hconv.convert(H2, I2, engine="compiled")
    assert second.w.ctypes.data == at and compiled.pool()["reused"] > kept["reused"]
    want = hconv.convert(H2, I2, engine="numpy")
    assert same_bits(second.w, want.w) and same_bits(second.status_code, want.status_code)
    second.w[:] = 1.0  # the arrays are the caller's, writable, and own their memory
    del second
    assert compiled.pool()["blocks"] >= 1


def test_outputs_pool_keeps_within_its_limits_and_gives_back_idle_blocks():
    """The pool keeps at most its most_bytes and most_blocks, never a block under least_bytes,
    and gives back a block idle_seconds after it was kept, with no further call (its own thread).
    (Arrays this large are never written here: their pages are not mapped.)"""
    compiled.release()
    lim = compiled.pool()
    n = lim["most_bytes"] // 24 + 1  # ω alone beyond the limit
    for _ in range(3):
        outs = compiled.outputs(n, True)
        del outs
        p = compiled.pool()
        assert p["bytes"] <= lim["most_bytes"] and p["blocks"] <= lim["most_blocks"]
    assert p["bytes"] > 0
    compiled.release()
    n = lim["least_bytes"] // 16  # ω 1.5 times least_bytes, the others under it
    small = [compiled.outputs(n, False) for _ in range(2 * lim["most_blocks"])]
    del small
    p = compiled.pool()
    assert p["blocks"] == lim["most_blocks"]  # cond and fallback are under least_bytes: only ω kept
    assert lim["most_blocks"] * 24 * n <= p["bytes"] < lim["most_blocks"] * (24 * n + 4096)  # pages
    for _ in range(50):  # the pool's thread gives them back after idle_seconds, within a second more
        time.sleep(lim["idle_seconds"] / 10)
        if compiled.pool()["blocks"] == 0:
            break
    assert compiled.pool()["blocks"] == 0


def test_outputs_pool_lends_a_larger_block_and_gives_back_one_two_calls_left_unused():
    """A loop's sizes vary: a request takes a kept block up to twice its size, which comes back
    whole; a block that two calls leave unused (a loop may alternate two kinds of call) is given
    back at the next, so that blocks of sizes no call asks for again do not pile up."""
    compiled.release()
    n = 300_000  # ω 7.2 MB
    first = compiled.outputs(n, False)
    at = first[0].ctypes.data
    del first
    smaller = compiled.outputs(n * 9 // 10, False)
    assert smaller[0].ctypes.data == at
    del smaller
    assert 24 * n <= compiled.pool()["bytes"] < 24 * n + 4096  # the whole block, not the 90 % numpy freed
    again = compiled.outputs(n, False)
    assert again[0].ctypes.data == at
    del again
    for _ in range(2):  # calls that leave the kept block unused
        compiled.outputs(10, False)
        assert compiled.pool()["blocks"] == 1
    compiled.outputs(10, False)
    assert compiled.pool()["blocks"] == 0


def test_outputs_forked_child_starts_with_no_kept_block_and_converts(rng):
    """A child forked while its parent keeps blocks (and while the parent's pool thread may be
    giving them back) starts with none, which it could never give back without that thread, and
    its own large calls are right; the parent keeps its blocks."""
    if not hasattr(os, "fork"):
        pytest.skip("no fork here")
    compiled.release()
    n = 200_000
    I, H = physical_bodies(rng, n), rng.normal(size=(n, 3))
    want = hconv.convert(H, I, engine="numpy").w
    res = hconv.convert(H, I, engine="compiled")
    del res
    assert compiled.pool()["blocks"] >= 1
    pid = os.fork()
    if pid == 0:  # the child: exit code 0 only if every check holds
        ok = compiled.pool()["blocks"] == 0
        ok &= bool(same_bits(hconv.convert(H, I, engine="compiled").w, want))
        os._exit(0 if ok else 1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert compiled.pool()["blocks"] >= 1


def test_outputs_too_large_names_the_array_that_could_not_be_had():
    with pytest.raises(MemoryError, match=r"shape \(1099511627776, 3\)"):
        compiled.outputs(2**40, True)


def test_convert_rows_from_another_thread_stays_on_it(rng, monkeypatch):
    """A call from a thread that is not the main one (the file pipeline's batch threads, a Dask
    task) is already part of its caller's parallelism: it converts on that thread."""
    I, H = physical_bodies(rng, 50), rng.normal(size=(50, 3))
    monkeypatch.setattr(compiled, "BLOCK_ROWS", 8)
    assert compiled._threads(50) >= min(2, compiled.available_cores())
    got = {}
    t = threading.Thread(target=lambda: got.update(threads=compiled._threads(50), out=_rows_of(I, H)))
    t.start()
    t.join()
    assert got["threads"] == 1 and same_bits(got["out"][0], _rows_of(I, H)[0])


def test_compiled_status_codes_are_status_py_and_written_in_its_precedence():
    assert {
        n: CODE[n] for n in ("ok", "singular", "not_physical", "ill_conditioned", "inaccurate")
    } == compiled.OWN_CODES
    # the C code writes ill_conditioned, then not_physical, then singular (a later write wins),
    # and inaccurate takes a row only from ok: right only while PRECEDENCE orders them so
    places = [PRECEDENCE.index(n) for n in ("singular", "not_physical", "ill_conditioned", "inaccurate")]
    assert places == sorted(places)


def test_convert_rows_in_a_forked_child_after_the_parent_used_threads(rng, monkeypatch):
    """A forked process (a multiprocessing or Dask worker) inherits the parent's pool without its
    threads: its first threaded call must start threads of its own, not wait on the parent's."""
    import multiprocessing

    monkeypatch.setattr(compiled, "BLOCK_ROWS", 16)
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    I, H = physical_bodies(rng, 200), rng.normal(size=(200, 3))
    parent = _rows_of(I, H)[0]  # the pool starts here
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(1) as pool:
        child = pool.apply_async(_child_rows, (I, H)).get(timeout=60)
    assert same_bits(child, parent)


def _child_rows(I: np.ndarray, H: np.ndarray) -> np.ndarray:
    return _rows_of(I, H)[0]
