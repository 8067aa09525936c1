"""Error-free transformations in plain numpy: exact products and sums of float64 columns.

``two_sum(a, b)`` returns ``(s, e)`` with ``s = fl(a + b)`` and ``a + b = s + e`` exactly (Knuth).
``two_prod(a, b)`` returns ``(p, e)`` with ``p = fl(a·b)`` and ``a·b = p + e`` exactly (Dekker), valid
while ``|a|, |b| < 2**996`` and the product does not underflow; callers equilibrate first.
All arguments and results are arrays of one shape.
"""
from __future__ import annotations

import numpy as np

_SPLIT = 134217729.0  # 2**27 + 1: splits a float64 into two 26-bit halves (Dekker)


def two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c = _SPLIT * a
    hi = c - (c - a)
    return hi, a - hi


def two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def dot2(terms: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """``Σ a·b`` over the pairs, as accurate as if computed in twice the working precision.

    Ogita–Rump–Oishi "Dot2": each product and running sum is split exactly into value and error;
    the errors are summed in ordinary arithmetic and added once at the end.
    """
    (a0, b0), *rest = terms
    p, s = two_prod(a0, b0)
    for a, b in rest:
        h, r = two_prod(a, b)
        p, q = two_sum(p, h)
        s = s + (q + r)
    return p + s
