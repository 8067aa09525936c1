"""Every status, its precedence, and what each method answers on a flagged row."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from helpers import mp_solve, random_rotations

import hconv
from hconv.solve import status
from hconv.solve.methods import _seed_formula

GOOD_I = [2.0, 3.0, 4.0, 0.1, 0.0, 0.0]
ROD_I = [0.0, 2.0, 2.0, 0.0, 0.0, 0.0]  # a thin rod along x: one zero principal moment


@pytest.mark.parametrize("method", list(hconv.METHODS))
@pytest.mark.parametrize("where", ["H", "I", "r"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_status_invalid_input_on_nan_or_inf(method, where, bad):
    H, I, r = [1.0, 2.0, 3.0], list(GOOD_I), [0.1, 0.2, 0.3]
    {"H": H, "I": I, "r": r}[where][1] = bad
    res = hconv.convert(H, I, r, method=method)
    uses_r = hconv.METHODS[method].needs_r
    if where == "r" and not uses_r:
        assert res.status == "ok"  # r is not used by this method
    else:
        assert res.status == "invalid_input"
        assert np.isnan(res.w).all() and np.isnan(res.residual) and np.isnan(res.cond)


def test_status_invalid_input_beyond_float32_range():
    res = hconv.convert([1e39, 0, 0], [1, 1, 1], precision=32)
    assert res.status == "invalid_input"
    assert hconv.convert([1e39, 0, 0], [1, 1, 1], precision=64).status == "ok"


def test_status_not_symmetric_for_asymmetric_matrix():
    I = np.array([[2.0, 0.5, 0.0], [0.4, 3.0, 0.0], [0.0, 0.0, 4.0]])
    res = hconv.convert([1, 2, 3], I)
    assert res.status == "not_symmetric"
    assert np.isnan(res.w).all()


@pytest.mark.parametrize(
    "method,answer",
    [
        ("exact", None),
        ("lapack", None),
        ("cholesky", None),
        ("eigen", [0.0, 1.0, 1.5]),
    ],
)
def test_status_singular_rod(method, answer):
    res = hconv.convert([1.0, 2.0, 3.0], ROD_I, method=method)
    assert res.status == "singular"
    assert np.isinf(res.cond) or res.cond > 1e15
    assert np.isnan(res.residual)  # no I⁻¹H exists to compare with
    if answer is None:
        assert np.isnan(res.w).all()
    else:
        np.testing.assert_allclose(res.w, answer, atol=1e-15)


def test_status_singular_threshold_depends_on_precision():
    I = [1.0, 1.0, 1e-7, 0, 0, 0]  # cond 1e7: fine in float64, beyond float32's digits
    assert hconv.convert([1, 1, 1], I).status == "ok"
    assert hconv.convert([1, 1, 1], I, precision=32).status == "singular"


def test_status_zero_tensor_is_singular():
    res = hconv.convert([1, 2, 3], [0, 0, 0, 0, 0, 0])
    assert res.status == "singular"
    assert np.isnan(res.w).all()


def test_status_not_positive_definite_exact_still_solves():
    I = np.array([[-1.0, 0.2, 0.0], [0.2, 3.0, 0.0], [0.0, 0.0, 4.0]])
    H = np.array([1.0, 2.0, 3.0])
    ref = mp_solve(I[None], H[None])[0]
    for method in ("exact", "lapack", "eigen"):
        res = hconv.convert(H, I, method=method)
        assert res.status == "not_positive_definite"
        np.testing.assert_allclose(res.w, ref, rtol=1e-14)
    chol = hconv.convert(H, I, method="cholesky")
    assert chol.status == "not_positive_definite"
    assert np.isnan(chol.w).all()


def test_status_not_physical_triangle_inequality():
    res = hconv.convert([1, 2, 3], [1, 1, 3, 0, 0, 0])  # 3 > 1 + 1
    assert res.status == "not_physical"
    np.testing.assert_allclose(res.w, [1, 2, 1])  # the answer exists; it is the body that cannot


def test_status_boundary_bodies_are_physical():
    """A thin plate (I3 = I1 + I2 exactly) is on the boundary and must not be flagged."""
    res = hconv.convert([1, 2, 3], [1.0, 2.0, 3.0, 0, 0, 0])
    assert res.status == "ok"


def _float32_bodies(rng, moments):
    """Bodies R·diag(moments)·Rᵀ computed in float32, as an engine in float32 holds them: each
    row's products differ from their transposes by float32's roundings (not symmetrised)."""
    R = random_rotations(rng, 2000).astype(np.float32)
    diag = np.zeros((2000, 3, 3), np.float32)
    diag[:, [0, 1, 2], [0, 1, 2]] = moments
    return R @ diag @ R.transpose(0, 2, 1), rng.normal(size=(2000, 3)).astype(np.float32)


@pytest.mark.parametrize("engine", ["auto", "numpy"])
def test_status_precision_32_takes_float32_tensors_as_symmetric_and_plates_as_physical(engine, rng):
    """With precision 32 the numbers are float32's: a tensor computed in float32 is symmetric
    to its roundings, and a thin plate (I3 = I1 + I2) is on the boundary to them. Both came back
    not_symmetric (no ω) or not_physical from 1e-12 and 1e-9, float64's tolerances. ω is then
    I⁻¹H of the symmetric part, within float32's bound (cond 2.5 here)."""
    for moments in ((1.0, 2.0, 2.5), (1.0, 2.0, 3.0)):
        I, H = _float32_bodies(rng, moments)
        res = hconv.convert(H, I, precision=32, engine=engine)
        assert res.counts() == {"ok": 2000}
        sym = (I.astype(np.float64) + I.transpose(0, 2, 1)) / 2
        ref = np.linalg.solve(sym, H.astype(np.float64)[..., None])[..., 0]
        err = np.linalg.norm(res.w - ref, axis=1) / np.linalg.norm(ref, axis=1)
        assert err.max() < 50 * np.finfo(np.float32).eps
        # the same numbers taken as float64's are flagged, as that precision promises
        flagged = hconv.convert(H, I, engine=engine).counts()
        assert flagged.get("not_symmetric", 0) + flagged.get("not_physical", 0) > 500


def test_status_precision_32_still_flags_what_is_beyond_float32_rounding(rng):
    I, H = _float32_bodies(rng, (1.0, 2.0, 2.5))
    I[:1000, 0, 1] += 1e-4 * np.abs(I[:1000]).max(axis=(1, 2))  # 1e-4 of the largest entry
    assert hconv.convert(H, I, precision=32).counts() == {"not_symmetric": 1000, "ok": 1000}
    plates = np.tile(np.diag(np.float32([1.0, 2.0, 3.001])), (4, 1, 1))  # broken by 1.7e-4 of the trace
    assert hconv.convert(np.ones((4, 3)), plates, precision=32).counts() == {"not_physical": 4}


def test_status_tolerances_are_float64_s_stated_ones_and_64_eps_in_float32():
    assert status.symmetry_rtol(np.float64) == status.SYMMETRY_RTOL
    assert status.triangle_rtol(np.float64) == status.TRIANGLE_RTOL
    assert status.symmetry_rtol(np.float32) == status.triangle_rtol(np.float32) == 64 * 2.0**-23


def test_status_frame_ambiguous_symmetric_top():
    I = [1.0, 1.0, 1.5, 0, 0, 0]  # a cylinder: two equal moments
    res = hconv.convert([1, 2, 3], I, [0.3, 0.5, 0.7], method="document-principal")
    assert res.status == "frame_ambiguous"
    assert hconv.convert([1, 2, 3], I, [0.3, 0.5, 0.7], method="document").status == "ok"
    assert hconv.convert([1, 2, 3], I, method="eigen").status == "ok"  # the exact answer is unique


def test_status_frame_ambiguous_is_real_two_valid_frames_disagree():
    """Why the status exists: for I = diag(1, 1, 1.5) every frame turned about z is principal,
    and the seed's Version 2 answers differently in two of them."""
    S = np.array([[1.0, 1.0, 1.5]])
    H, r = np.array([[1.0, 2.0, 3.0]]), np.array([[0.3, 0.5, 0.7]])
    answers = []
    for theta in (0.0, 0.6):
        c, s = np.cos(theta), np.sin(theta)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        w_p, _ = _seed_formula(S.T, (H @ R).T, (r @ R).T)  # H' = Rᵀ·H, component-major (3, 1)
        answers.append(w_p.T @ R.T)
    assert np.linalg.norm(answers[0] - answers[1]) > 0.01


@pytest.mark.parametrize("r", [[0, 0, 1.0], [2.0, 0, 0], [0, 0, 0], [1e-6, 0, 1.0]])
def test_status_r_on_axis(r):
    res = hconv.convert([1, 2, 3], GOOD_I, r, method="document")
    assert res.status == "r_on_axis"
    assert np.isfinite(res.w).all()
    assert (res.w == 0).any() or np.min(np.abs(res.w)) < 1e-9


def test_status_precedence_first_in_list_wins():
    # NaN in H on a rod: invalid_input beats singular
    assert hconv.convert([np.nan, 1, 1], ROD_I).status == "invalid_input"
    # negative moment that also breaks the triangle inequality: not_positive_definite wins
    assert hconv.convert([1, 1, 1], [-1, 1, 5, 0, 0, 0]).status == "not_positive_definite"
    # a rod with r on an axis under document: singular beats r_on_axis
    assert hconv.convert([1, 1, 1], ROD_I, [0, 0, 1], method="document").status == "singular"


def test_status_flagged_rows_keep_their_place(rng):
    H = rng.normal(size=(6, 3))
    I = np.tile(GOOD_I, (6, 1))
    I[1] = ROD_I
    H[3, 0] = np.nan
    res = hconv.convert(H, I)
    assert list(res.status) == ["ok", "singular", "ok", "invalid_input", "ok", "ok"]
    assert res.counts() == {"ok": 4, "invalid_input": 1, "singular": 1}


def test_residual_equals_true_error(rng):
    """The residual column is the true forward error, as a 50-digit solve measures it."""
    from helpers import rel_err, spd_bodies

    I = spd_bodies(rng, 100, 1e8)
    H = rng.normal(size=(100, 3))
    res = hconv.convert(H, I, method="lapack")
    true = rel_err(res.w, mp_solve(I, H))
    np.testing.assert_allclose(res.residual, true, rtol=1e-3, atol=1e-17)
    assert true.max() > 1e-12  # the comparison is not between zeros


def test_cond_matches_eigenvalue_ratio(rng):
    from helpers import spd_bodies

    I = spd_bodies(rng, 50, 1e6)
    res = hconv.convert(rng.normal(size=(50, 3)), I)
    np.testing.assert_allclose(res.cond, 1e6, rtol=1e-6)


#: The codes as released: outputs, the row engines' compiled constants and users' stored files
#: hold them, so none may move (a new status takes the next code).
PINNED_CODES = {
    "ok": 0,
    "invalid_input": 1,
    "not_symmetric": 2,
    "singular": 3,
    "overflow": 4,
    "not_positive_definite": 5,
    "degenerate": 6,
    "not_physical": 7,
    "unit_suspect": 8,
    "ill_conditioned": 9,
    "inaccurate": 10,
    "cancellation": 11,
    "frame_ambiguous": 12,
    "r_on_axis": 13,
}


def test_status_codes_pinned_unique_and_documented():
    assert status.CODE == PINNED_CODES
    assert sorted(status.CODE.values()) == list(range(len(status.CODE)))  # unique, and index STATUSES
    assert all(status.STATUSES[code] == name for name, code in status.CODE.items())
    assert hconv.STATUSES == status.STATUSES
    # docs/input.md's statuses table gives each code, in order of precedence
    text = (Path(__file__).resolve().parents[1] / "docs" / "input.md").read_text()
    table = re.findall(r"^\| `([a-z_]+)` \| (\d+) \|", text.split("## Statuses")[1].split("\n## ")[0], re.M)
    assert {name: int(code) for name, code in table} == {k: v for k, v in PINNED_CODES.items() if k != "ok"}
    assert tuple(name for name, _ in table) == status.PRECEDENCE


def test_status_precedence_is_its_own_order_not_the_codes():
    assert sorted(status.PRECEDENCE) == sorted(set(status.CODE) - {"ok"})
    for a in status.PRECEDENCE:
        for b in status.PRECEDENCE:
            winner = min(a, b, key=status.PRECEDENCE.index)
            one = np.ones(1, dtype=bool)
            held = np.array([status.CODE[a]], dtype=np.uint8)
            assert status.names(status.merge(held, one, b))[0] == winner
            assert status.names(status.combine(1, {a: one, b: one}))[0] == winner
    codes = np.array([status.CODE[n] for n in ("r_on_axis", "ok", "singular", "r_on_axis")], dtype=np.uint8)
    assert list(status.counts(codes).items()) == [("ok", 1), ("singular", 1), ("r_on_axis", 2)]


def test_status_precedence_decides_with_the_order_changed(monkeypatch):
    # precedence is read from PRECEDENCE alone: reversing it reverses which status wins, codes unchanged
    order = tuple(reversed(status.PRECEDENCE))
    monkeypatch.setattr(status, "PRECEDENCE", order)
    one = np.ones(1, dtype=bool)
    held = np.array([status.CODE["invalid_input"]], dtype=np.uint8)
    assert status.names(status.merge(held, one, "r_on_axis"))[0] == "r_on_axis"
    assert status.names(status.combine(1, {"invalid_input": one, "singular": one}))[0] == "singular"
