"""The row engine (hconv.solve.rows), interpreted and compiled, against the numpy engine and
against independent references.

The contract (docs/engines.md): ω of ``exact``, ``cond`` and every status are the numpy engine's
bits; ``refined``'s ω and the ``residual`` are allowed to differ in the last bits, because the
row engine decides when refinement stops row by row. Each test also checks that the row engine
computed the rows itself, so that agreement cannot come from handing every row to numpy.
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest
from helpers import assert_same_answers, hard_bodies, mp_solve, physical_bodies, random_rotations, rel_err, spd_bodies

import hconv
from hconv.solve import blocks, rows
from hconv.solve.status import CODE, PRECEDENCE

EPS = np.finfo(float).eps
NUMBA = importlib.util.find_spec("numba") is not None
ENGINES = ["python", pytest.param("numba", marks=pytest.mark.skipif(not NUMBA, reason="needs hconv[fast]"))]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("method", ["exact", "refined"])
@pytest.mark.parametrize("diagnostics", [True, False])
@pytest.mark.parametrize("shape", ["(N,3,3)", "(N,6)"])
def test_convert_rows_same_answers_as_numpy_engine(engine, method, diagnostics, shape, rng, monkeypatch):
    I, H = hard_bodies(rng, shape)
    # the numpy engine's general converter: its path for covered runs is the row code's own
    # arithmetic (tests/test_vectorrows.py), so the reference here is the other path
    monkeypatch.setattr(blocks, "COMMON_PATH", False)
    ref = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy")
    got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine=engine)
    assert got.engine == engine and ref.engine == "numpy"
    # every status the row engine sets itself is in the stack, and more besides
    own = {"ok", "singular", "not_physical"} | ({"ill_conditioned"} if method == "exact" else set())
    assert own <= set(ref.counts())
    assert {"invalid_input", "overflow", "not_positive_definite", "inaccurate"} <= set(ref.counts())
    assert_same_answers(got, ref, method)
    assert (got.residual is None) == (ref.residual is None) == (not diagnostics)


def _fallback(I: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Which rows the row engine hands to numpy, straight from rows.convert_one."""
    out = []
    for M, h in zip(I, H):
        six = M[0, 0], M[1, 1], M[2, 2], M[0, 1], M[0, 2], M[1, 2]
        try:
            out.append(rows.convert_one(*map(float, six), *map(float, h), False, True, 4.5e9)[-1])
        except (ZeroDivisionError, ValueError):
            out.append(True)
    return np.array(out)


def test_convert_one_keeps_the_common_rows_itself(rng):
    """Agreement must come from the row code: physical and ill-conditioned bodies are its own, and
    only the cases it leaves to numpy go there. (Rods, whose two largest moments nearly meet, go
    to numpy where the closed form cannot decide the triangle inequality, as in the numpy engine.)"""
    I = np.concatenate([physical_bodies(rng, 300), spd_bodies(rng, 100, 1e12), spd_bodies(rng, 100, 1e3)])
    assert not _fallback(I, rng.normal(size=(500, 3))).any()
    hard, H = hard_bodies(rng)
    fb = _fallback(hard, H)
    assert 0.1 < fb.mean() < 0.6  # NaN, not definite, extreme scales, ... but not the rest


@pytest.mark.parametrize("engine", ENGINES)
def test_convert_rows_refined_within_two_eps_of_mpmath_to_cond_1e12(engine, rng):
    for cond in (1e4, 1e8, 1e12):
        I, H = spd_bodies(rng, 60, cond), rng.normal(size=(60, 3))
        res = hconv.convert(H, I, method="refined", engine=engine)
        assert res.engine == engine
        assert rel_err(res.w, mp_solve(I, H)).max() <= 2 * EPS


@pytest.mark.parametrize("engine", ENGINES)
def test_convert_rows_exact_error_within_its_bound_and_residual_measures_it(engine, rng):
    """exact's error is K·cond·eps at most, and its residual column is that error (mpmath)."""
    I, H = spd_bodies(rng, 80, 1e8), rng.normal(size=(80, 3))
    res = hconv.convert(H, I, engine=engine)
    true = rel_err(res.w, mp_solve(I, H))
    assert true.max() <= 1e8 * EPS
    np.testing.assert_allclose(res.residual, true, rtol=1e-6, atol=2 * EPS)


@pytest.mark.parametrize("engine", ENGINES)
def test_convert_rows_rotation_covariance(engine, rng):
    """ω of R·I·Rᵀ and R·H is R·ω: an identity independent of either engine's arithmetic."""
    I, H = physical_bodies(rng, 200), rng.normal(size=(200, 3))
    R = random_rotations(rng, 200)
    w = hconv.convert(H, I, engine=engine).w
    w_rot = hconv.convert(np.einsum("nij,nj->ni", R, H), R @ I @ R.transpose(0, 2, 1), engine=engine).w
    assert rel_err(w_rot, np.einsum("nij,nj->ni", R, w)).max() <= 64 * EPS


def test_convert_one_body_uses_the_interpreted_row_engine(monkeypatch):
    monkeypatch.delenv("HCONV_ENGINE", raising=False)  # auto as a new process gets it
    monkeypatch.delitem(sys.modules, "hconv.solve.compiled", raising=False)
    h, i = np.array([1.0, 2.0, 3.0]), np.array([[2.0, 0.1, 0.0], [0.1, 3.0, 0.2], [0.0, 0.2, 4.0]])
    res = hconv.convert(h, i)
    assert res.engine == "python" and res.status == "ok" and res.w.shape == (3,)
    assert np.array_equal(res.w, hconv.convert(h, i, engine="numpy").w)
    assert rel_err(res.w[None], mp_solve(i[None], h[None])).max() <= EPS


def test_convert_rows_uncovered_runs_are_numpy_whatever_is_asked():
    I, H = np.tile(np.diag([1.0, 2.0, 2.5]), (3, 1, 1)), np.ones((3, 3))
    assert hconv.convert(H, I, method="eigen", engine="python").engine == "numpy"
    assert hconv.convert(H, I, precision=32, engine="python").engine == "numpy"
    assert hconv.convert(H, I, degenerate="pinv", engine="python").engine == "numpy"
    assert hconv.convert(H, np.ones((3, 3)), engine="python").engine == "numpy"  # principal moments: a division


def test_rows_status_codes_are_status_py_and_written_in_its_precedence():
    held = (rows.OK, rows.SINGULAR, rows.NOT_PHYSICAL, rows.ILL_CONDITIONED, rows.INACCURATE)
    assert held == tuple(CODE[n] for n in ("ok", "singular", "not_physical", "ill_conditioned", "inaccurate"))
    # verdict writes ill_conditioned, then not_physical, then singular (a later write wins), and
    # inaccurate takes a row only from ok: right only while PRECEDENCE orders them so
    places = [PRECEDENCE.index(n) for n in ("singular", "not_physical", "ill_conditioned", "inaccurate")]
    assert places == sorted(places)
