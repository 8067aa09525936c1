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
from helpers import mp_solve, physical_bodies, random_rotations, rel_err, slender_bodies, spd_bodies

import hconv
from hconv.solve import rows
from hconv.solve.status import CODE
from hconv.tools.scene import cylinder_moments, rotate_tensors

EPS = np.finfo(float).eps
NUMBA = importlib.util.find_spec("numba") is not None
ENGINES = ["python", pytest.param("numba", marks=pytest.mark.skipif(not NUMBA, reason="needs hconv[fast]"))]


def _hard_bodies(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A stack that holds every status and every hard case, with H; ``(n, 3, 3)`` and ``(n, 3)``."""
    n = 40
    parts = [
        physical_bodies(rng, n),
        *(spd_bodies(rng, n, c) for c in (1e2, 1e6, 1e9, 1e12, 1e14, 1e16)),  # ill_conditioned, singular
        slender_bodies(rng, n, 1e6),
        slender_bodies(rng, n, 1e12),  # physical, so ill_conditioned shows (not_physical would win)
        rotate_tensors(
            random_rotations(rng, n), cylinder_moments(1.0, rng.uniform(0.01, 1, n), rng.uniform(0.01, 2, n))
        ),
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 1.0], (n, 1))),  # spheres
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 2.0], (n, 1))),  # plates: the triangle's edge
        rotate_tensors(random_rotations(rng, n), np.tile([1.0, 1.0, 3.0], (n, 1))),  # not_physical
        rotate_tensors(random_rotations(rng, n), np.tile([-1.0, 2.0, 3.0], (n, 1))),  # not_positive_definite
        physical_bodies(rng, n) * 1e150,
        physical_bodies(rng, n) * 1e-150,
        physical_bodies(rng, n) * 2.0**130,  # just beyond the closed form's unscaled range
        np.zeros((n, 3, 3)),
    ]
    I = np.concatenate(parts)
    H = rng.normal(size=(I.shape[0], 3))
    H[-3 * n : -2 * n] *= 1e150
    H[-2 * n : -n] *= 1e-150
    I[0, 0, 1] = np.nan  # invalid_input
    I[1, 2, 2] = np.inf
    H[2, 1] = np.nan
    I[3, 0, 1] += 0.5  # not_symmetric
    H[4] = 0.0  # ω = 0 exactly
    I[5], H[5] = np.diag([1e-300, 1e-300, 1e-300]), 1e10  # ω beyond the range: overflow
    H[6] = 1e-320  # ω on the subnormal grid: inaccurate
    return I, H


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is None and b is None or np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("method", ["exact", "refined"])
@pytest.mark.parametrize("diagnostics", [True, False])
@pytest.mark.parametrize("shape", ["(N,3,3)", "(N,6)"])
def test_convert_rows_same_answers_as_numpy_engine(engine, method, diagnostics, shape, rng):
    I, H = _hard_bodies(rng)
    if shape == "(N,6)":
        I = I.reshape(-1, 9)[:, [0, 4, 8, 1, 2, 5]]
        I[3, 3] += 0.5  # the planted asymmetry has no six-number spelling: another finite body
    ref = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy")
    got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine=engine)
    assert got.engine == engine and ref.engine == "numpy"
    assert np.array_equal(got.status_code, ref.status_code)
    assert _same(got.cond, ref.cond)
    # every status the row engine sets itself is in the stack, and more besides
    own = {"ok", "singular", "not_physical"} | ({"ill_conditioned"} if method == "exact" else set())
    assert own <= set(ref.counts())
    assert {"invalid_input", "overflow", "not_positive_definite", "inaccurate"} <= set(ref.counts())
    if method == "exact":
        assert _same(got.w, ref.w)
    else:  # both within a rounding of I⁻¹H, so within 2 eps of each other (docs/engines.md)
        ok = np.isfinite(ref.w).all(axis=1)
        assert np.array_equal(ok, np.isfinite(got.w).all(axis=1))
        assert rel_err(got.w[ok], ref.w[ok]).max() <= 2 * EPS
    if diagnostics:
        measured = np.isfinite(ref.residual)
        assert np.array_equal(measured, np.isfinite(got.residual))
        assert np.all(np.abs(got.residual - ref.residual)[measured] <= 2 * EPS)
    else:
        assert got.residual is None and ref.residual is None


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
    hard, H = _hard_bodies(rng)
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
    assert CODE["ok"] == 0  # the row engine's OK is the first status
