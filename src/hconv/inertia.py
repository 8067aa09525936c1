"""Inertia tensors as column arrays, and the facts about them that decide what can be trusted.

Conventions (stated once, here; every other module relies on them):

* ``H = I·ω``. ``I`` is the rotational inertia tensor [kg·m²] about a point P, expressed in the
  same frame as ``H`` [kg·m²/s] and ``ω`` [rad/s]. ``H`` must be taken about the same point P.
* The products of inertia are *tensor entries*: ``Ixy = -∫ x·y dm`` (likewise ``Ixz``, ``Iyz``),
  as URDF, SDF, Bullet, ODE and most physics engines store them. A CAD report's positive
  "product of inertia" ``Pxy = +∫ x·y dm`` must be negated before it is given to hconv.
* The six-number order is ``(Ixx, Iyy, Izz, Ixy, Ixz, Iyz)``.

A batch of N symmetric tensors is held as a :class:`Sym3` of six arrays of shape ``(N,)``
(structure of arrays), so that the kernels run on contiguous columns.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Sym3(NamedTuple):
    """N symmetric 3×3 tensors as six columns, each of shape ``(N,)`` [kg·m²]."""

    xx: np.ndarray
    yy: np.ndarray
    zz: np.ndarray
    xy: np.ndarray
    xz: np.ndarray
    yz: np.ndarray

    def astype(self, dtype) -> "Sym3":
        return Sym3(*(np.asarray(c, dtype=dtype) for c in self))

    def take(self, rows) -> "Sym3":
        return Sym3(*(c[rows] for c in self))

    def matrices(self) -> np.ndarray:
        """The tensors as a stack of matrices, shape ``(N, 3, 3)``."""
        n = self.xx.shape[0]
        m = np.empty((n, 3, 3), dtype=self.xx.dtype)
        m[:, 0, 0], m[:, 1, 1], m[:, 2, 2] = self.xx, self.yy, self.zz
        m[:, 0, 1] = m[:, 1, 0] = self.xy
        m[:, 0, 2] = m[:, 2, 0] = self.xz
        m[:, 1, 2] = m[:, 2, 1] = self.yz
        return m


def sym_from_array(I: np.ndarray, *, symmetry_rtol: float = 1e-12) -> tuple[Sym3, np.ndarray]:
    """Read tensors given as ``(N, 6)``, ``(N, 3, 3)`` or ``(N, 3)`` (principal/diagonal moments).

    Returns the tensors and a boolean mask of shape ``(N,)`` that is True where a ``(N, 3, 3)``
    input is not symmetric: ``|Iij - Iji| > symmetry_rtol · max|I|`` for that row. Those rows keep
    the mean of the two entries so that the arrays stay finite; the caller flags them.
    """
    I = np.asarray(I, dtype=np.float64)
    n = I.shape[0]
    asym = np.zeros(n, dtype=bool)
    if I.ndim == 2 and I.shape[1] == 6:
        return Sym3(*(np.ascontiguousarray(I[:, k]) for k in range(6))), asym
    if I.ndim == 2 and I.shape[1] == 3:
        zero = np.zeros(n)
        return Sym3(*(np.ascontiguousarray(I[:, k]) for k in range(3)), zero, zero.copy(), zero.copy()), asym
    if I.ndim == 3 and I.shape[1:] == (3, 3):
        scale = np.max(np.abs(I), axis=(1, 2))
        skew = np.max(np.abs(I - np.swapaxes(I, 1, 2)), axis=(1, 2))
        with np.errstate(invalid="ignore"):
            asym = skew > symmetry_rtol * scale
        half = 0.5 * (I + np.swapaxes(I, 1, 2))
        return Sym3(half[:, 0, 0], half[:, 1, 1], half[:, 2, 2], half[:, 0, 1], half[:, 0, 2], half[:, 1, 2]), asym
    raise ValueError(
        f"Expected I to have shape (3,), (6,), (3, 3), (N, 3), (N, 6) or (N, 3, 3), got {I.shape}"
    )


def eigenvalues(I: Sym3) -> np.ndarray:
    """Principal moments of each tensor, ascending, shape ``(3, N)`` [kg·m²] (component-major, so
    each of the three is a contiguous column). Inputs must be finite.

    Accurate to what the statuses and ``cond`` need, and about 5× faster than LAPACK's
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
    from hconv.linsolve import ldlt_factor, ldlt_inverse  # linsolve imports this module

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


def max_abs(columns) -> np.ndarray:
    """Elementwise max of |column| over a few ``(N,)`` columns (chained, no stacking copy)."""
    it = iter(columns)
    m = np.abs(next(it))
    for c in it:
        np.maximum(m, np.abs(c), out=m)
    return m


def principal_axes(I: Sym3) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments ``S`` of shape ``(N, 3)`` (ascending) and axes ``R`` of shape ``(N, 3, 3)``.

    ``I = R·diag(S)·Rᵀ``; column k of ``R`` is the unit axis of moment ``S[:, k]``. LAPACK's
    symmetric solver (``numpy.linalg.eigh``), which keeps the axes orthonormal to rounding.
    """
    S, R = np.linalg.eigh(I.matrices())
    return S, R
