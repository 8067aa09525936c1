"""Error-free transformations: every sum and product split exactly, checked with exact rational
arithmetic (fractions) over floats spread across many binades."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from hconv.kernels import eft


def _wide(rng, n, spread=60):
    """Floats spread over 2^±spread, both signs."""
    return rng.normal(size=n) * np.ldexp(1.0, rng.integers(-spread, spread, n))


def test_two_diff_is_exact(rng):
    a, b = _wide(rng, 2000), _wide(rng, 2000)
    s, e = eft.two_diff(a, b)
    assert all(Fraction(x) - Fraction(y) == Fraction(p) + Fraction(q) for x, y, p, q in zip(a, b, s, e))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_two_prod_split_is_exact(dtype, rng):
    spread = 60 if dtype == np.float64 else 20  # products and their errors stay normal numbers
    a, b = _wide(rng, 2000, spread).astype(dtype), _wide(rng, 2000, spread).astype(dtype)
    (ah, al), (bh, bl) = eft.split(a), eft.split(b)
    p, e = eft.two_prod_split(a, ah, al, b, bh, bl)
    assert all(
        Fraction(float(x)) * Fraction(float(y)) == Fraction(float(u)) + Fraction(float(v))
        for x, y, u, v in zip(a, b, p, e)
    )


def test_splitter_halves_the_significand():
    # 2**27 + 1 for float64's 53 bits, 2**12 + 1 for float32's 24
    assert eft.splitter(np.float64) == 2.0**27 + 1 and eft.splitter(np.float32) == 2.0**12 + 1
