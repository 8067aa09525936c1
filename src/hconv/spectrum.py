"""Principal moments of inertia tensors, fast and as accurate as the statuses and cond need.

Shapes: tensors are :class:`hconv.inertia.Sym3` of ``(N,)`` columns [kg·m²]; results ``(3, N)``.
"""
from __future__ import annotations

import numpy as np

from hconv.inertia import Sym3, max_abs
from hconv.linsolve import ldlt_factor, ldlt_inverse


def eigenvalues(I: Sym3) -> np.ndarray:
    """Principal moments of each tensor, ascending, shape ``(3, N)`` [kg·m²] (component-major, so
    each of the three is a contiguous column). Inputs must be finite.

    Accurate to what the statuses and ``cond`` need, and about 6× faster (in 16k-row blocks) than LAPACK's
    ``eigvalsh``, which it falls back to wherever a decision could be in doubt:

    * Positive definite rows (all LDLᵀ pivots > 0): the largest moment from the closed-form
      (trigonometric) root of the characteristic cubic; the smallest as 1 / the largest moment of
      I⁻¹ (I⁻¹ from the same LDLᵀ), so that it keeps the relative accuracy cond·eps that LAPACK
      gives it, where a closed-form small root would lose up to 1e7·eps; the middle one from the
      trace.
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
    inv = ldlt_inverse(fac)
    hi, hi_err = _largest_root(I)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv_hi, _ = _largest_root(inv)
        lo = 1.0 / inv_hi
    tr = I.xx + I.yy + I.zz
    margin = np.abs(2.0 * hi - tr)
    fast &= np.isfinite(lo) & (lo > 0) & (margin > 1e-9 * tr + 4.0 * hi_err)
    lam[0], lam[2] = lo, hi
    lam[1] = tr - hi - lo
    slow = ~fast
    if slow.any():
        lam[:, slow] = np.linalg.eigvalsh(I.take(slow).matrices()).T
    return lam


def _largest_root(I: Sym3) -> tuple[np.ndarray, np.ndarray]:
    """Largest eigenvalue of each symmetric tensor by the trigonometric formula, and a bound on its
    rounding error; both ``(N,)``.

    With q = tr/3, p² = ‖I − qE‖²_F / 6 and r = det((I − qE)/p) / 2, the largest root is
    q + 2p·cos(acos(r)/3). acos is ill-conditioned near r = −1 (the two largest roots meet), where
    the error grows to about p·eps / √(1 − r²), capped at p·√eps.
    """
    # Scale by the largest entry so that squares and the determinant neither overflow nor underflow.
    s = max_abs(I)
    s = np.where(s > 0, s, 1.0)
    a, b, c, d, e, f = (comp / s for comp in I)
    q = (a + b + c) / 3.0
    aq, bq, cq = a - q, b - q, c - q
    p = np.sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (d * d + e * e + f * f)) / 6.0)
    sp = np.where(p > 0, p, 1.0)
    ba, bb, bc, bd, be, bf = aq / sp, bq / sp, cq / sp, d / sp, e / sp, f / sp
    r = np.clip((ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be)) / 2.0, -1.0, 1.0)
    hi = q + 2.0 * p * np.cos(np.arccos(r) / 3.0)
    eps = np.finfo(np.float64).eps
    err = p * np.minimum(np.sqrt(eps), 16.0 * eps / np.sqrt(np.maximum(1.0 - r * r, eps))) + 8.0 * eps * np.abs(q)
    return hi * s, err * s
