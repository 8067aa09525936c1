"""Relative error and angle against 50-digit arithmetic, at every scale a float64 reaches."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from helpers import EPS

from hconv.kernels.metrics import angle_deg, relative_error


def _mp_rel(x, ref):
    with mpmath.workdps(50):
        d = [mpmath.mpf(float(a)) - mpmath.mpf(float(b)) for a, b in zip(x, ref)]
        return float(mpmath.sqrt(sum(v * v for v in d)) / mpmath.sqrt(sum(mpmath.mpf(float(b)) ** 2 for b in ref)))


def _mp_angle(a, b):
    with mpmath.workdps(50):
        a, b = [mpmath.mpf(float(v)) for v in a], [mpmath.mpf(float(v)) for v in b]
        cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        dot = sum(u * v for u, v in zip(a, b))
        return float(mpmath.degrees(mpmath.atan2(mpmath.sqrt(sum(c * c for c in cross)), dot)))


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1.0, 1e150, 1e300])
def test_relative_error_matches_50_digits_at_every_scale(scale, rng):
    ref = rng.normal(size=(3, 200)) * scale
    x = ref * (1 + rng.normal(size=(3, 200)) * 10.0 ** rng.uniform(-15, -1, 200))
    got = relative_error(x, ref)
    want = np.array([_mp_rel(x[:, k], ref[:, k]) for k in range(200)])
    assert np.all(np.abs(got - want) <= 8 * EPS * want)


def test_relative_error_zero_reference_and_nan():
    ref = np.zeros((3, 3))
    x = np.array([[0.0, 1.0, np.nan], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    got = relative_error(x, ref)
    assert got[0] == 0.0 and got[1] == np.inf and np.isnan(got[2])
    assert np.isnan(relative_error(np.array([[np.nan], [1.0], [1.0]]), np.ones((3, 1))))[0]


@pytest.mark.parametrize("scale", [1e-300, 1.0, 1e300])
def test_angle_matches_50_digits_small_and_large(scale, rng):
    a = rng.normal(size=(3, 100)) * scale
    tilt = 10.0 ** rng.uniform(-12, 0, 100)
    b = (a + rng.normal(size=(3, 100)) * tilt * scale) * rng.uniform(0.5, 2, 100)
    got = angle_deg(a, b)
    want = np.array([_mp_angle(a[:, k], b[:, k]) for k in range(100)])
    # atan2 of the cross product keeps small angles to a few ulps of |a|·|b| (~eps rad)
    assert np.all(np.abs(got - want) <= 1e-12 * want + np.degrees(8 * EPS))


def test_angle_of_zero_vector_is_nan_and_opposite_is_180():
    a = np.array([[1.0, 0.0, 1.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    b = np.array([[-1.0, 1.0, np.inf], [-2.0, 1.0, 0.0], [-3.0, 1.0, 0.0]])
    got = angle_deg(a, b)
    assert got[0] == pytest.approx(180.0, abs=1e-12) and np.isnan(got[1]) and np.isnan(got[2])
