"""The solvers' building blocks: the double-double residual (held to the same bits as
:mod:`hconv.kernels.eft`'s functions, tested in test_eft.py) and when the adaptive refinement
stops. References are exact rational arithmetic (fractions) and 50 digits."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from helpers import EPS, mp_solve, random_rotations, rel_err

from hconv.kernels import eft, linsolve
from hconv.kernels.inertia import Sym3
from hconv.tools.scene import rotate_tensors

BLOCK = 16384


def _bodies(rng, n, cond, middle="log"):
    """n rotated tensors with cond(I) exactly ``cond``; the middle moment spread log-uniformly,
    or just above the smallest (two small moments: the hardest case for the stopping rule)."""
    m2 = 10 ** (-np.log10(cond) * rng.random(n)) if middle == "log" else (1 + 0.001 * rng.random(n)) / cond
    M = rotate_tensors(random_rotations(rng, n), np.stack([np.ones(n), m2, np.full(n, 1 / cond)], axis=1))
    return M, Sym3(*(np.ascontiguousarray(M[:, i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))))


def _residual_by_eft(A, h, x):
    """The residual written with hconv.kernels.eft's functions, in the order the docstring describes."""
    x_hi, x_lo = eft.split(x)
    out = np.empty_like(x)
    for k, row in enumerate(linsolve._ROWS):
        s, err = h[k], None
        for j, c in enumerate(row):
            p, e = eft.two_prod_split(A.entries[c], A.hi[c], A.lo[c], x[j], x_hi[j], x_lo[j])
            s, q = eft.two_diff(s, p)
            err = (q - e) if err is None else err + (q - e)
        out[k] = s + err
    return out


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_residual_dd_same_bits_as_eft_composition(dtype, rng):
    _, I = _bodies(rng, 5000, 1e6)
    I = I.astype(dtype)
    h = rng.normal(size=(3, 5000)).astype(dtype)
    x = linsolve.ldlt_solve(linsolve.ldlt_factor(I), h)
    A = linsolve.split_sym(I)
    np.testing.assert_array_equal(linsolve.residual_dd(A, h, x), _residual_by_eft(A, h, x))


def test_residual_dd_within_eps_squared_of_the_exact_residual(rng):
    """At cond 1e12 the residual is ~1e-12 of the terms it comes from: double-double keeps it."""
    M, I = _bodies(rng, 300, 1e12)
    h = rng.normal(size=(3, 300))
    x = linsolve.ldlt_solve(linsolve.ldlt_factor(I), h)
    r = linsolve.residual_dd(linsolve.split_sym(I), h, x)
    for n in range(300):
        for k in range(3):
            exact = Fraction(h[k, n]) - sum(Fraction(M[n, k, j]) * Fraction(x[j, n]) for j in range(3))
            scale = abs(h[k, n]) + sum(abs(M[n, k, j] * x[j, n]) for j in range(3))
            # the value rounded once, plus the error sum's own rounding (a few eps² of the terms)
            assert abs(Fraction(r[k, n]) - exact) <= EPS * abs(exact) + 8 * EPS**2 * Fraction(scale)


def _counting(monkeypatch):
    calls = []
    real = linsolve.residual_dd

    def counted(A, h, x):
        calls.append(h.shape[1])
        return real(A, h, x)

    monkeypatch.setattr(linsolve, "residual_dd", counted)
    return calls


@pytest.mark.parametrize("middle", ["log", "near-smallest"])
@pytest.mark.parametrize("cond", [1e4, 1e8, 1e10, 1e12])
def test_refine_adaptive_stop_as_good_as_ten_steps(cond, middle, rng):
    """Whole blocks, where one late row would show: the adaptive stop is within one rounding of a
    ten-step refinement everywhere, and its worst rows are within 2·eps of a 50-digit solve."""
    M, I = _bodies(rng, 2 * BLOCK, cond, middle)
    h = rng.normal(size=(3, 2 * BLOCK))
    got, ten = [], []
    for lo in range(0, 2 * BLOCK, BLOCK):
        Ib, hb = I.take(slice(lo, lo + BLOCK)), h[:, lo : lo + BLOCK]
        got.append(linsolve.solve_refined(Ib, hb))
        ten.append(linsolve.solve_refined(Ib, hb, steps=10))
    got, ten = np.concatenate(got, axis=1), np.concatenate(ten, axis=1)
    apart = rel_err(got.T, ten.T)
    assert apart.max() <= EPS
    worst = np.argsort(apart)[-100:]
    assert rel_err(got[:, worst].T, mp_solve(M[worst], h[:, worst].T)).max() <= 2 * EPS


@pytest.mark.parametrize("cond, fewest, most", [(1e3, 1, 1), (1e10, 2, 2), (1e12, 3, 4)])
def test_refine_steps_grow_with_cond(cond, fewest, most, rng, monkeypatch):
    calls = _counting(monkeypatch)
    _, I = _bodies(rng, BLOCK, cond, "near-smallest")
    linsolve.solve_refined(I, rng.normal(size=(3, BLOCK)))
    assert fewest <= len(calls) <= most


def test_refine_rows_without_answer_do_not_hold_the_block(rng, monkeypatch):
    """Zero tensors have no answer (NaN); the well-conditioned rest still stops after one step."""
    calls = _counting(monkeypatch)
    M, I = _bodies(rng, BLOCK, 1e3)
    I = Sym3(*(np.concatenate([c[:-20], np.zeros(20)]) for c in I))
    h = rng.normal(size=(3, BLOCK))
    x = linsolve.solve_refined(I, h)
    assert len(calls) == 1
    assert np.isnan(x[:, -20:]).all()
    assert rel_err(x[:, :100].T, mp_solve(M[:100], h[:, :100].T)).max() <= 2 * EPS


def test_refine_fixed_steps_and_start_are_honoured(rng, monkeypatch):
    calls = _counting(monkeypatch)
    M, I = _bodies(rng, 500, 1e12)
    h = rng.normal(size=(3, 500))
    x0 = linsolve.ldlt_solve(linsolve.ldlt_factor(I), h)
    start = x0.copy()
    one = linsolve.solve_refined(I, h, steps=1, x0=x0)
    assert len(calls) == 1
    np.testing.assert_array_equal(x0, start)  # the caller's start is not written to
    ref = mp_solve(M, h.T)
    # one step from LDLᵀ's answer at cond 1e12 is not yet at rounding; the full refinement is
    assert rel_err(one.T, ref).max() > 10 * EPS
    assert rel_err(linsolve.solve_refined(I, h, x0=x0).T, ref).max() <= 2 * EPS
