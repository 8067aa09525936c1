"""The numpy engine's path for covered runs (hconv.solve.vectorrows) against the row engine it
vectorises, the general block converter, and independent references.

The contract: the row engine's bits on every output (both decide refinement row by row); the
general converter's bits for ``exact``'s ω, ``cond`` and every status, and ``refined``'s ω and
the ``residual`` within 2 eps of its (it decides refinement per block: docs/engines.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import assert_same_answers, hard_bodies, mp_solve, physical_bodies, rel_err, same_bits, spd_bodies

import hconv
from hconv.kernels.inertia import Sym3
from hconv.solve import blocks, vectorrows

EPS = np.finfo(float).eps


def _general(monkeypatch: pytest.MonkeyPatch, *args: object, **kwargs: object) -> hconv.Result:
    with monkeypatch.context() as m:
        m.setattr(blocks, "COMMON_PATH", False)
        return hconv.convert(*args, **kwargs)


@pytest.mark.parametrize("method", ["exact", "refined"])
@pytest.mark.parametrize("diagnostics", [True, False])
@pytest.mark.parametrize("shape", ["(N,3,3)", "(N,6)"])
def test_convert_block_same_bits_as_row_engine(method, diagnostics, shape, rng):
    I, H = hard_bodies(rng, shape)
    got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy")
    ref = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="python")
    assert got.engine == "numpy" and ref.engine == "python"
    for a, b in [(got.w, ref.w), (got.cond, ref.cond), (got.status_code, ref.status_code)]:
        assert same_bits(a, b)
    assert same_bits(got.residual, ref.residual)


@pytest.mark.parametrize("method", ["exact", "refined"])
@pytest.mark.parametrize("diagnostics", [True, False])
@pytest.mark.parametrize("shape", ["(N,3,3)", "(N,6)"])
def test_convert_block_same_answers_as_general_converter(method, diagnostics, shape, rng, monkeypatch):
    I, H = hard_bodies(rng, shape)
    got = hconv.convert(H, I, method=method, diagnostics=diagnostics, engine="numpy")
    ref = _general(monkeypatch, H, I, method=method, diagnostics=diagnostics, engine="numpy")
    assert {"ok", "singular", "not_physical", "invalid_input", "overflow", "inaccurate"} <= set(ref.counts())
    assert_same_answers(got, ref, method)


def _columns(I: np.ndarray) -> Sym3:
    return Sym3(*(np.ascontiguousarray(I[:, i, j]) for i, j in [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]))


def test_convert_block_keeps_the_common_rows_itself(rng):
    """Agreement must come from this path: physical and ill-conditioned bodies are its own, and
    only the cases the row engine leaves go to the general converter."""
    I = np.concatenate([physical_bodies(rng, 300), spd_bodies(rng, 100, 1e12), spd_bodies(rng, 100, 1e3)])
    H = np.ascontiguousarray(rng.normal(size=(3, 500)))
    for refined, diagnostics in [(False, False), (False, True), (True, True)]:
        b = vectorrows.convert_block(_columns(I), np.zeros(500, bool), H, refined, diagnostics, 4.5e9)
        assert not b.fallback.any()
        assert (b.residual is not None) == diagnostics
    hard, Hh = hard_bodies(rng)
    b = vectorrows.convert_block(
        _columns(hard), np.zeros(len(hard), bool), np.ascontiguousarray(Hh.T), False, True, 4.5e9
    )
    assert 0.1 < b.fallback.mean() < 0.6  # NaN, not definite, extreme scales, ... but not the rest


def test_convert_block_refined_within_two_eps_of_mpmath_to_cond_1e12(rng):
    for cond in (1e4, 1e8, 1e12):
        I, H = spd_bodies(rng, 60, cond), rng.normal(size=(60, 3))
        res = hconv.convert(H, I, method="refined", engine="numpy")
        assert rel_err(res.w, mp_solve(I, H)).max() <= 2 * EPS
        assert np.all(res.residual <= 2 * EPS)  # the answer's own measured error, within the promise


def test_convert_block_residual_is_the_true_error_of_exact(rng):
    I, H = spd_bodies(rng, 80, 1e8), rng.normal(size=(80, 3))
    res = hconv.convert(H, I, engine="numpy")
    true = rel_err(res.w, mp_solve(I, H))
    assert true.max() > 100 * EPS  # cond 1e8 leaves exact's error visible, so the check can fail
    np.testing.assert_allclose(res.residual, true, rtol=1e-6, atol=2 * EPS)


def test_convert_block_residual_of_refined_sees_an_early_stop(rng, monkeypatch):
    """If refined stopped too early, its residual must show it: the reference is a refinement
    of its own, not refined's answer compared with itself."""
    I, H = spd_bodies(rng, 50, 1e10), rng.normal(size=(50, 3))
    real = vectorrows._refine_from
    calls = []

    def early(split, H_, fac, x):
        calls.append(1)
        if len(calls) == 1:  # refined's own answer: one step only
            return vectorrows._step(split, H_, fac, x)[0]
        return real(split, H_, fac, x)

    monkeypatch.setattr(vectorrows, "_refine_from", early)
    res = hconv.convert(H, I, method="refined", engine="numpy")
    assert len(calls) == 2
    true = rel_err(res.w, mp_solve(I, H))
    assert true.max() > 1e-14  # one step is not enough at cond 1e10 ...
    np.testing.assert_allclose(res.residual, true, rtol=1e-2, atol=1e-16)  # ... and the residual says so
