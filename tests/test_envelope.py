"""Each method's documented stability envelope, as tests against a 50-digit reference."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import EPS, mp_solve, physical_bodies, rel_err, slender_bodies, spd_bodies

import hconv
from hconv.solve.status import ILL_CONDITIONED_TOL

EXACT_FAMILY = [m.name for m in hconv.METHODS.values() if m.exact]


@pytest.mark.parametrize("cond", [1e13, 1e14])
def test_envelope_exact_within_twice_lapack_to_cond_1e14(cond, rng):
    I, H = spd_bodies(rng, 200, cond), rng.normal(size=(200, 3))
    ref = mp_solve(I, H)
    e_exact = rel_err(hconv.convert(H, I, method="exact", diagnostics=False).w, ref)
    e_lapack = rel_err(hconv.convert(H, I, method="lapack", diagnostics=False).w, ref)
    assert np.median(e_exact) <= 2 * np.median(e_lapack)
    assert e_exact.max() <= 2 * e_lapack.max()


@pytest.mark.parametrize("cond", [1.0, 1e2, 1e4, 1e6, 1e8, 1e10, 1e12])
def test_envelope_refined_within_two_eps_to_cond_1e12(cond, rng):
    I, H = spd_bodies(rng, 200, cond), rng.normal(size=(200, 3))
    res = hconv.convert(H, I, method="refined")
    assert rel_err(res.w, mp_solve(I, H)).max() <= 2 * EPS
    # these test tensors break the triangle inequality; no numerical status may appear
    assert set(res.status) <= {"ok", "not_physical"}


def test_envelope_refined_holds_1e_minus_6_up_to_singular(rng):
    """Where refined is not flagged at all (below the singular threshold), it stays within 1e-6."""
    I, H = slender_bodies(rng, 200, 5e14), rng.normal(size=(200, 3))
    res = hconv.convert(H, I, method="refined")
    ok = res.status == "ok"
    assert ok.sum() > 150
    assert rel_err(res.w[ok], mp_solve(I[ok], H[ok])).max() <= ILL_CONDITIONED_TOL


SCALES = {64: [1e-150, 1e-100, 1e-50, 1e50, 1e100, 1e150], 32: [1e-15, 1e-10, 1e-5, 1e5, 1e10, 1e15]}


@pytest.mark.parametrize("precision", [64, 32])
@pytest.mark.parametrize("method", EXACT_FAMILY + ["diagonal"])
def test_envelope_same_relative_accuracy_at_every_scale(method, precision, rng):
    """A dust grain to a planet: scaling I and H together changes neither ω nor its accuracy."""
    I, H = physical_bodies(rng, 100), rng.normal(size=(100, 3))
    base = rel_err(hconv.convert(H, I, method=method, precision=precision).w.astype(float), mp_solve(I, H)).max()
    eps = float(np.finfo(np.float64 if precision == 64 else np.float32).eps)
    for s in SCALES[precision]:
        Is, Hs = I * s, H * s
        res = hconv.convert(Hs, Is, method=method, precision=precision)
        assert (res.status != "invalid_input").all() and (res.status != "overflow").all()
        err = rel_err(res.w.astype(float), mp_solve(Is, Hs)).max()
        assert err <= 2 * base + 4 * eps, (s, err, base)


@pytest.mark.parametrize("precision", [64, 32])
@pytest.mark.parametrize("method", EXACT_FAMILY)
def test_envelope_no_ok_row_off_by_more_than_1e_minus_6(method, precision, rng):
    """Sweep cond from 1 to 1e16: every row an exact-family method calls ok is right to 1e-6."""
    flagged, checked = 0, 0
    for cond in 10.0 ** np.arange(0, 17):
        I, H = slender_bodies(rng, 60, cond), rng.normal(size=(60, 3))
        res = hconv.convert(H, I, method=method, precision=precision)
        ok = res.status == "ok"
        flagged += (~ok).sum()
        checked += ok.sum()
        if ok.any():
            assert rel_err(res.w[ok].astype(float), mp_solve(I[ok], H[ok])).max() <= ILL_CONDITIONED_TOL, cond
    assert flagged > 0  # the sweep does reach past the envelope
    assert checked >= 60  # and it does check rows the method calls ok


@pytest.mark.parametrize("method", EXACT_FAMILY)
def test_ill_conditioned_threshold_matches_method_limit(method):
    m = hconv.METHODS[method]
    for precision in (64, 32):
        limit = m.cond_limit(precision)
        if np.isfinite(limit):
            # Six numbers, so that the method's own solver runs (three take the division path).
            below = hconv.convert(
                [1, 1, 1], [1, 1, 2 / limit, 0, 0, 0], method=method, precision=precision
            )  # cond = limit/2
            above = hconv.convert(
                [1, 1, 1], [1, 1, 0.5 / limit, 0, 0, 0], method=method, precision=precision
            )  # cond = 2·limit
            assert below.status == "ok"
            assert above.status == "ill_conditioned"


@pytest.mark.parametrize("precision", [64, 32])
def test_convert_diagonal_form_correctly_rounded_at_any_cond(precision):
    # Principal moments given as three numbers: ω_i = H_i / I_i, one rounding per component, so
    # the error stays at half an ulp however ill-conditioned I is, and no row is flagged.
    rng = np.random.default_rng(7)
    n = 300
    dtype = np.float64 if precision == 64 else np.float32
    tiny = 10.0 ** rng.uniform(-6 if precision == 32 else -14, 0, n)  # cond up to 1e6 / 1e14
    base = rng.uniform(0.5, 2.0, n)
    moments = np.stack([tiny * base, base, base * (1 + tiny * rng.uniform(-1, 1, n))], axis=1)
    moments = rng.permuted(moments, axis=1).astype(dtype).astype(float)  # physical: a thin body
    H = rng.normal(size=(n, 3)).astype(dtype).astype(float)
    for method in EXACT_FAMILY:
        res = hconv.convert(H, moments, method=method, precision=precision)
        assert set(res.status) == {"ok"}, method
        got = res.w.astype(float)
        want = mp_solve(np.stack([np.diag(m) for m in moments]), H)
        per_component = np.abs(got - want) / np.abs(want)
        assert per_component.max() <= 0.5 * np.finfo(dtype).eps * (1 + 1e-9), method


def test_ill_conditioned_not_applied_to_approximations():
    I = [1, 1, 1e-12, 0, 0, 0]
    for method in ("diagonal", "document"):
        assert hconv.convert([1, 1, 1], I, [0.3, 0.5, 0.7], method=method).status == "ok"
    assert hconv.convert([1, 1, 1], I, method="exact").status == "ill_conditioned"


def test_residual_of_refined_is_measured_against_a_longer_refinement(rng, monkeypatch):
    """If refined stopped too early, its residual must show it, not compare it with itself.
    The early stop is planted in the numpy engine, so the test runs that."""
    from hconv.kernels import linsolve

    I, H = spd_bodies(rng, 50, 1e10), rng.normal(size=(50, 3))
    assert np.nanmax(hconv.convert(H, I, method="refined", engine="numpy").residual) <= 2 * EPS
    real = linsolve.solve_refined

    def one_step_when_adaptive(I_, h_, steps=None, x0=None):  # a refined that stops after one step
        return real(I_, h_, steps=1 if steps is None and x0 is None else steps, x0=x0)

    monkeypatch.setattr(linsolve, "solve_refined", one_step_when_adaptive)
    res = hconv.convert(H, I, method="refined", engine="numpy")
    true = rel_err(res.w, mp_solve(I, H))
    assert true.max() > 1e-14  # one step is not enough at cond 1e10 ...
    np.testing.assert_allclose(res.residual, true, rtol=1e-2, atol=1e-16)  # ... and the residual says so
