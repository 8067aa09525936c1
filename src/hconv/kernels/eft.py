"""Error-free transformations in plain numpy: exact products and sums of floating-point columns.

``two_diff(a, b)`` returns ``(s, e)`` with ``s = fl(a - b)`` and ``a - b = s + e`` exactly (Knuth's
TwoSum with the negation folded in).
``split(a)`` returns ``(hi, lo)`` with ``a = hi + lo`` and each half short enough that the product
of two halves is exact (Dekker). ``two_prod_split`` then gives ``a·b = p + e`` exactly, valid while
the arguments are well inside the dtype's range (callers equilibrate first). All arrays of one
shape and one dtype, float64 or float32.

These are the readable statement of the arithmetic. :func:`hconv.kernels.linsolve.residual_dd` and
``split_sym`` write the same operations out in place over scratch buffers (a third faster), and
``tests/test_linsolve.py`` holds the two to the same bits and these to exactness.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import DTypeLike


def splitter(dtype: DTypeLike) -> float:
    """Dekker's splitting factor 2**ceil(p/2) + 1 for a p-bit significand: 2**27 + 1 for float64,
    2**12 + 1 for float32."""
    p = np.finfo(dtype).nmant + 1
    return float(2 ** ((p + 1) // 2) + 1)


def two_diff(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a - b = s + e`` exactly."""
    s = a - b
    bb = s - a
    return s, (a - (s - bb)) - (b + bb)


def split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c = a.dtype.type(splitter(a.dtype)) * a
    hi = c - (c - a)
    return hi, a - hi


def two_prod_split(
    a: np.ndarray, ah: np.ndarray, al: np.ndarray, b: np.ndarray, bh: np.ndarray, bl: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``a·b = p + e`` exactly, from ``a``, ``b`` and their splits (so a fixed factor is split once)."""
    p = a * b
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl
