"""The compiled engine (hconv.solve.compiled, its C code in hconv.solve.rowcode) against the numpy
engine and against independent references.

The contract (docs/engines.md): ω of ``exact``, ``cond`` and every status are the numpy engine's
bits; ``refined``'s ω and the ``residual`` may differ in the last bits, because the compiled
engine decides when refinement stops row by row. Each test also checks that the compiled engine
computed the rows itself, so that agreement cannot come from handing every row to numpy.
"""

from __future__ import annotations

import importlib
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
from hconv.solve import compiled
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


def test_convert_rows_same_bits_whatever_the_blocks_and_threads(rng, monkeypatch):
    """Many blocks on several threads give the bits of one call on one thread: rows are
    independent, and each block is converted without the GIL on a thread of its own."""
    I, H = hard_bodies(rng)
    reps = 30
    I, H = np.tile(I, (reps, 1, 1)), np.tile(H, (reps, 1))
    ref = _rows_of(I, H, refined=True)
    assert 0 < ref[4].mean() < 1
    names: set = set()
    real = compiled.rowcode.convert

    class Recording:
        configure = compiled.rowcode.configure

        @staticmethod
        def convert(*args):
            names.add(threading.current_thread().name)
            return real(*args)

    monkeypatch.setattr(compiled, "rowcode", Recording)
    for block, cores in ((997, 2), (4096, 3), (len(H), 4)):
        monkeypatch.setattr(compiled, "BLOCK_ROWS", block)
        monkeypatch.setattr(compiled, "available_cores", lambda cores=cores: cores)
        got = _rows_of(I, H, refined=True)
        for a, b in zip(got, ref):
            assert same_bits(a, b)
    # blocks did run on several threads: the caller's and the pool's
    assert "MainThread" in names and any(n.startswith("hconv-rows") for n in names)


def test_convert_rows_caller_takes_the_blocks_a_late_thread_has_not_begun(rng, monkeypatch):
    """A pool thread held up before its first block (a busy machine) leaves every block to the
    caller, who converts them meanwhile: the call waits for no thread that has not begun, and the
    late thread, when it comes, finds the counter past the last row."""
    I, H = physical_bodies(rng, 10_000), rng.normal(size=(10_000, 3))
    ref = _rows_of(I, H)
    caller_done = threading.Event()
    late_found: list[bool] = []
    calls: list[np.ndarray] = []  # the counter of the call under test
    real = compiled.rowcode.convert

    class HeldUp:
        configure = compiled.rowcode.configure

        @staticmethod
        def convert(*args):
            if threading.current_thread() is threading.main_thread():
                calls.append(args[-3])
                lost = real(*args)
                caller_done.set()
                return lost
            caller_done.wait(timeout=30)  # the pool's thread: held until the caller is done
            counter, stop = args[-3], args[-4]
            if counter is calls[0]:  # not a thread an earlier call left behind
                late_found.append(int(counter[0]) >= stop)
            return real(*args)

    monkeypatch.setattr(compiled, "rowcode", HeldUp)
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    got = _rows_of(I, H)
    assert caller_done.is_set()
    for _ in range(3000):  # the call did not wait for the late thread: it comes after
        if late_found:
            break
        time.sleep(0.01)
    assert late_found == [True]
    for a, b in zip(got, ref):
        assert same_bits(a, b)


def test_convert_rows_caller_waits_for_a_block_another_thread_holds(rng):
    """A caller with ``wait`` returns only when every row is done: here after another thread's
    long first block, which it did not take, while its own block was short."""
    n = 400_000
    I, H = physical_bodies(rng, n), rng.normal(size=(n, 3))
    args = (I.reshape(n, 9).T, True, H.T, False, True, 4.5e9)
    got = (np.full((n, 3), -1.0), np.full(n, -1.0), np.full(n, 255, np.uint8), np.full(n, -1.0), np.ones(n, bool))
    counter, size = np.zeros(3, np.int64), n - 1_000
    with ThreadPoolExecutor(1) as pool:
        other = pool.submit(compiled.rowcode.convert, *args, *got, 0, n, counter, size, False)
        while counter[0] == 0:  # the other thread has taken rows 0..size
            time.sleep(0)
        compiled.rowcode.convert(*args, *got, 0, n, counter, size, True)
        whole = counter[1] == n and (got[1] != -1.0).all()
        other.result()
    assert whole


def test_convert_rows_shared_counter_blocks_are_each_taken_once(rng):
    """Three threads taking blocks of 7 rows from one counter write every row once, with the bits
    of a single call over all rows, and count the fallback rows once (NaN rows fall back)."""
    I, H = physical_bodies(rng, 1_000), rng.normal(size=(1_000, 3))
    H[::97] = np.nan
    n = len(H)

    def outputs() -> tuple:
        return np.full((n, 3), -1.0), np.full(n, -1.0), np.full(n, 255, np.uint8), np.full(n, -1.0), np.ones(n, bool)

    args = (I.reshape(n, 9).T, True, H.T, False, True, 4.5e9)
    ref, got = outputs(), outputs()
    lost_ref = compiled.rowcode.convert(*args, *ref, 0, n)
    counter = np.zeros(3, np.int64)
    with ThreadPoolExecutor(3) as pool:
        lost = sum(pool.map(lambda k: compiled.rowcode.convert(*args, *got, 0, n, counter, 7, k == 0), range(3)))
    assert lost == lost_ref == counter[2] == len(range(0, n, 97)) and counter[1] == n
    for a, b in zip(got, ref):
        assert same_bits(a, b)


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
    names = compiled.rowcode.kernels()
    assert "default" in names
    try:
        for refined in (False, True):
            compiled.rowcode.use("default")
            ref = _rows_of(I, H, refined=refined)
            assert 0 < ref[4].mean() < 0.5  # the edge rows are the compiled engine's own
            assert not ref[4][-200:].any()
            for name in names:
                compiled.rowcode.use(name)
                got = _rows_of(I, H, refined=refined)
                for a, b in zip(got, ref):
                    assert same_bits(a, b), name
    finally:
        compiled.rowcode.use(names[0])


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
