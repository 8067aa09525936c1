"""Principal moments of inertia tensors, fast and as accurate as the statuses and cond need.

Shapes: tensors are :class:`hconv.kernels.inertia.Sym3` of ``(N,)`` columns [kg·m²]; results ``(3, N)``.
"""

from __future__ import annotations

import numpy as np

from hconv.kernels.inertia import Sym3, max_abs
from hconv.kernels.linsolve import LDLt, ldlt_factor


def eigenvalues(I: Sym3) -> np.ndarray:
    """Principal moments of each tensor, ascending, shape ``(3, N)`` [kg·m²] (component-major, so
    each of the three is a contiguous column). Inputs must be finite.

    Accurate to what the statuses and ``cond`` need, and faster than LAPACK's ``eigvalsh``
    (docs/measurements.md), which it falls back to wherever a decision could be in doubt:

    * Positive definite rows (all LDLᵀ pivots > 0): the largest moment λ₂ from the closed-form
      (trigonometric) root of the characteristic cubic. The other two are the roots of
      x² − s·x + P with s = trace − λ₂ and P = det/λ₂, det being the product of the LDLᵀ pivots;
      the smaller root is taken in the form 2P / (s + √(s² − 4P)), which has no cancellation.
      The smallest moment so keeps the relative accuracy cond·eps that LAPACK gives it, where
      the cubic's own closed-form small root would lose up to 1e7·eps, except where the two
      smaller moments nearly coincide: there the square root costs up to √eps (1.5e-8) relative.
    * The closed form loses accuracy (up to √eps of the spread) only when its two largest roots
      nearly coincide. Rows where that uncertainty could move the triangle-inequality decision,
      and rows that are not positive definite, go to ``eigvalsh``.
    """
    n = I.xx.shape[0]
    lam = np.empty((3, n))
    if n == 0:
        return lam
    fac = ldlt_factor(I)
    fast = fac.positive()
    hi, hi_err = _largest_root(I)
    tr = I.xx + I.yy + I.zz
    lo = smallest_root(fac, tr, hi)
    margin = np.abs(2.0 * hi - tr)
    fast &= np.isfinite(lo) & (lo > 0) & (margin > 1e-9 * tr + 4.0 * hi_err)
    lam[0], lam[2] = lo, hi
    lam[1] = tr - hi - lo
    slow = ~fast
    if slow.any():
        lam[:, slow] = np.linalg.eigvalsh(I.take(slow).matrices()).T
    return lam


def smallest_root(fac: LDLt, tr: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The smallest principal moment of positive definite rows, from their LDLᵀ pivots ``fac``,
    trace ``tr`` and largest moment ``hi`` (:func:`eigenvalues` says how); ``(N,)``."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        # In units of λ₂, so that neither the determinant nor s² can leave the range.
        inv = 1.0 / hi
        s = (tr - hi) * inv
        p = (fac.d1 * inv) * (fac.d2 * inv) * (fac.d3 * inv)
        root = np.sqrt(np.maximum(s * s - 4.0 * p, 0.0))
        return (2.0 * p / (s + root)) * hi


def _largest_root(I: Sym3) -> tuple[np.ndarray, np.ndarray]:
    """Largest eigenvalue of each symmetric tensor from the trigonometric solution of its cubic,
    with no trigonometric call, and a bound on its rounding error; both ``(N,)``.

    With q = tr/3, p² = ‖I − qE‖²_F / 6 and r = det((I − qE)/p) / 2, the largest root is
    q + 2p·c with c = cos(acos(r)/3), the root in [1/2, 1] of 4c³ − 3c = r. Written c = 1/2 + u·t
    with u = √(1 + r), t is the root of t² + (2u/3)·t³ = 1/6, smooth in u on [0, √2] (t from
    0.408 to 0.354): a polynomial start and ROOT_NEWTON_STEPS Newton steps give c within one
    rounding (tests/test_spectrum.py, against mpmath), where acos and cos cost several times more,
    compiled or not (docs/measurements.md). Near r = −1 (the two largest roots meet) the answer is
    ill-conditioned in r itself: the error grows to about p·eps / √(1 − r²), capped at p·√eps.
    The compiled engine's ``largest_root`` (src/hconv/solve/rowcode.c) is the same arithmetic for one
    row.
    """
    # Beyond ROOT_RANGE, scaled by a power of two near the largest entry (exact), so that squares
    # and the determinant neither overflow nor underflow; the exponent is clamped so that s and
    # 1/s stay finite for entries near 1e308 and for subnormal ones. Within it, not scaled: the
    # compiled engine computes the same bits without a call to frexp.
    big = max_abs(I)
    s = np.ldexp(1.0, np.clip(np.frexp(np.where(big > 0, big, 1.0))[1], -1000, 1000))
    s[(big >= 1.0 / ROOT_RANGE) & (big <= ROOT_RANGE)] = 1.0
    if np.all(s == 1.0):  # the usual case: no pass over the six columns
        return largest_root(I)
    inv_s = 1.0 / s
    hi, err = largest_root(Sym3(*(comp * inv_s for comp in I)))
    return hi * s, err * s


def largest_root(I: Sym3) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_largest_root` for tensors whose entries all lie within ROOT_RANGE (not rescaled):
    the largest moment and its error bound, ``(N,)`` each. No call to ``frexp`` or a reduction:
    the arithmetic the compiled engine's ``largest_root`` (src/hconv/solve/rowcode.c) does for one row."""
    a, b, c, d, e, f = I
    q = (a + b + c) * (1.0 / 3.0)
    aq, bq, cq = a - q, b - q, c - q
    p = np.sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (d * d + e * e + f * f)) * (1.0 / 6.0))
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        ip = 1.0 / np.where(p > 0, p, 1.0)
        det = aq * (bq * cq - f * f) - d * (d * cq - f * e) + e * (d * f - bq * e)
        r = np.clip(det * (0.5 * ip * ip * ip), -1.0, 1.0)
    u = np.sqrt(1.0 + r)
    s0, s1, s2, s3, s4 = ROOT_START
    t = s0 + u * (s1 + u * (s2 + u * (s3 + u * s4)))
    k = (2.0 / 3.0) * u
    for _ in range(ROOT_NEWTON_STEPS):
        t2 = t * t
        t -= (t2 + k * t2 * t - (1.0 / 6.0)) / (2.0 * t + 3.0 * k * t2)
    hi = q + p * (1.0 + 2.0 * (u * t))
    eps = np.finfo(np.float64).eps
    err = p * np.minimum(np.sqrt(eps), 16.0 * eps / np.sqrt(np.maximum(1.0 - r * r, eps))) + 8.0 * eps * np.abs(q)
    return hi, err


#: The start for t(u) in :func:`_largest_root`: the degree-4 polynomial closest to t on [0, √2]
#: (fitted in Chebyshev form, here in powers of u, lowest first), within 2.3e-5 relative.
ROOT_START = (
    0.40823894413801404,
    -0.055343001683135766,
    0.01772777887682195,
    -0.005564603285770919,
    0.0009679310171378176,
)
#: Tensors whose largest entry lies within [1/ROOT_RANGE, ROOT_RANGE] kg·m² are not rescaled.
ROOT_RANGE = 2.0**128
#: Newton doubles the correct digits each step: from 2.3e-5 two steps reach rounding.
ROOT_NEWTON_STEPS = 2
