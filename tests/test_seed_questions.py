"""The three questions the seed document closes with, each answered by a test.

1. Is m²/s → rad/s?  No: the document's ω changes with the unit of length; an angular velocity cannot.
2. Is ω = r × v right?  No: for v = ω × r, r × v = |r|²·ω⊥ (m²/s); ω⊥ = (r × v) / |r|².
3. How does it relate to H = I·ω?  It is the diagonal shortcut H_i / I_ii times |r⊥i|²; dividing
   that factor out again (the |r|² that question 2 lost) leaves H_i / I_ii, which is I⁻¹H exactly in
   principal axes. So the formula agrees with I⁻¹H only when every |r⊥i|² happens to be 1 m².
"""

from __future__ import annotations

import numpy as np
from helpers import EPS, physical_bodies, rel_err

import hconv


def test_document_answer_depends_on_length_unit(rng):
    """Re-express the same scene in millimetres: I in kg·mm², H in kg·mm²/s, r in mm."""
    I, H, r = physical_bodies(rng, 50), rng.normal(size=(50, 3)), rng.uniform(-1, 1, (50, 3))
    k = 1000.0  # m → mm
    for method in ("exact", "eigen"):
        w_mm = hconv.convert(H * k * k, I * k * k, method=method).w
        assert rel_err(w_mm, hconv.convert(H, I, method=method).w).max() < 1e-13  # rad/s: unchanged
    for method in ("document", "document-principal"):
        w_m = hconv.convert(H, I, r, method=method).w
        w_mm = hconv.convert(H * k * k, I * k * k, r * k, method=method).w
        assert rel_err(w_mm, w_m * k * k).max() < 1e-13  # scales like a length²: m²/s


def test_r_cross_v_is_not_omega(rng):
    w = rng.normal(size=(100, 3))
    r = rng.normal(size=(100, 3))
    v = np.cross(w, r)  # rigid rotation: v = ω × r
    rxv = np.cross(r, v)
    r2 = np.sum(r * r, axis=1, keepdims=True)
    w_perp = w - np.sum(w * r, axis=1, keepdims=True) * r / r2
    np.testing.assert_allclose(rxv, r2 * w_perp, rtol=1e-12, atol=1e-12)  # |r|²·ω⊥, not ω
    assert rel_err(rxv, w).min() > 1e-3
    np.testing.assert_allclose(np.cross(2 * r, np.cross(w, 2 * r)), 4 * rxv)  # a length² factor


def test_document_is_diagonal_shortcut_times_perpendicular_distance_squared(rng):
    I, H, r = physical_bodies(rng, 100), rng.normal(size=(100, 3)), rng.normal(size=(100, 3))
    perp2 = np.sum(r * r, axis=1, keepdims=True) - r * r
    w_doc = hconv.convert(H, I, r, method="document").w
    w_diag = hconv.convert(H, I, method="diagonal").w
    np.testing.assert_allclose(w_doc, w_diag * perp2, rtol=1e-13)


def test_document_principal_equals_exact_when_every_perpendicular_distance_is_one_metre(rng):
    """r' = (1, 1, 1)/√2 m in the principal frame makes every r_j² + r_k² = 1 m²: then, and only
    by that coincidence of numbers, Version 2 returns I⁻¹H (still labelled m²/s)."""
    I = physical_bodies(rng, 100)
    H = rng.normal(size=(100, 3))
    S, R = np.linalg.eigh(I)
    r = np.einsum("nij,j->ni", R, np.ones(3) / np.sqrt(2.0))
    w_v2 = hconv.convert(H, I, r, method="document-principal").w
    w_exact = hconv.convert(H, I, method="exact").w
    assert rel_err(w_v2, w_exact).max() < 1e3 * EPS
    w_v2_other = hconv.convert(H, I, 2 * r, method="document-principal").w
    np.testing.assert_allclose(w_v2_other, 4 * w_v2, rtol=1e-12)  # any other offset: off by |r⊥|²
