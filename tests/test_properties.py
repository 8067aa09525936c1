"""Property-based tests (hypothesis) over physically valid random bodies."""

from __future__ import annotations

import numpy as np
from helpers import EPS, rel_err
from hypothesis import given, settings
from hypothesis import strategies as st

import hconv

EXACT_FAMILY = [m.name for m in hconv.METHODS.values() if m.exact]
positive = st.floats(min_value=1e-3, max_value=1.0)
unit = st.floats(min_value=-1.0, max_value=1.0)
# ω components of physical size: 0 or 1e-3..1 in magnitude (subnormal ω carries fewer digits)
component = st.one_of(st.just(0.0), st.floats(1e-3, 1.0), st.floats(-1.0, -1e-3))


@st.composite
def bodies(draw):
    """A physical body: second moments c of a mass distribution (I1 = c2 + c3, ...), turned by a
    random rotation, at a random scale, with a random ω. Returns I (3, 3), ω (3,), cond."""
    c = np.array([draw(positive) for _ in range(3)])
    moments = np.array([c[1] + c[2], c[0] + c[2], c[0] + c[1]])
    q = np.array([draw(unit) for _ in range(4)])
    if np.linalg.norm(q) < 1e-3:
        q = np.array([1.0, 0.0, 0.0, 0.0])
    w_, x, y, z = q / np.linalg.norm(q)
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w_ * z), 2 * (x * z + w_ * y)],
            [2 * (x * y + w_ * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w_ * x)],
            [2 * (x * z - w_ * y), 2 * (y * z + w_ * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    scale = 10.0 ** draw(st.integers(min_value=-12, max_value=12))
    I = scale * (R @ np.diag(moments) @ R.T)
    I = 0.5 * (I + I.T)
    omega = np.array([draw(component) for _ in range(3)]) * 10.0 ** draw(st.integers(-3, 3))
    return I, omega, moments.max() / moments.min()


def _rel(a, b):
    return float(rel_err(np.atleast_2d(a), np.atleast_2d(b))[0])  # safe for subnormal and huge ω


@settings(max_examples=150, deadline=None)
@given(bodies(), st.sampled_from(EXACT_FAMILY))
def test_property_round_trip_omega_to_h_to_omega(body, method):
    I, omega, cond = body
    if not np.any(omega):
        return
    res = hconv.convert(I @ omega, I, method=method)
    assert res.status == "ok"
    assert _rel(res.w, omega) <= 16 * cond * EPS  # H = I·ω itself is rounded: cond·eps is the limit


@settings(max_examples=150, deadline=None)
@given(bodies(), st.sampled_from(EXACT_FAMILY), st.lists(unit, min_size=4, max_size=4))
def test_property_rotation_covariance(body, method, qv):
    I, omega, cond = body
    H = I @ omega
    q = np.array(qv) if np.linalg.norm(qv) > 1e-3 else np.array([1.0, 0, 0, 0])
    w_, x, y, z = q / np.linalg.norm(q)
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w_ * z), 2 * (x * z + w_ * y)],
            [2 * (x * y + w_ * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w_ * x)],
            [2 * (x * z - w_ * y), 2 * (y * z + w_ * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    a = hconv.convert(R @ H, R @ I @ R.T, method=method).w
    b = R @ hconv.convert(H, I, method=method).w
    if np.any(b):
        assert _rel(a, b) <= 32 * cond * EPS


@settings(max_examples=150, deadline=None)
@given(bodies(), st.sampled_from(EXACT_FAMILY))
def test_property_kinetic_energy_not_negative(body, method):
    """2T = ω·H = Hᵀ·I⁻¹·H ≥ |H|² / I_max > 0 for a physical body."""
    I, omega, cond = body
    H = I @ omega
    w = hconv.convert(H, I, method=method).w
    lam_max = np.linalg.eigvalsh(I).max()
    assert float(w @ H) >= (H @ H) / lam_max * (1 - 16 * cond * EPS)
