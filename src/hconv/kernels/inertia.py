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

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numpy.typing import DTypeLike


class Sym3(NamedTuple):
    """N symmetric 3×3 tensors as six columns, each of shape ``(N,)`` [kg·m²]."""

    xx: np.ndarray
    yy: np.ndarray
    zz: np.ndarray
    xy: np.ndarray
    xz: np.ndarray
    yz: np.ndarray

    def astype(self, dtype: DTypeLike) -> Sym3:
        return Sym3(*(np.asarray(c, dtype=dtype) for c in self))

    def take(self, rows: slice | np.ndarray) -> Sym3:
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


def max_abs(columns: Iterable[np.ndarray]) -> np.ndarray:
    """Elementwise max of |column| over a few ``(N,)`` columns (chained, no stacking copy)."""
    it = iter(columns)
    m = np.abs(next(it))
    for c in it:
        np.maximum(m, np.abs(c), out=m)
    return m


def sum_sq(v: np.ndarray) -> np.ndarray:
    """``v[0]² + v[1]² + v[2]²``, summed in that order, for v of shape ``(3, N)``."""
    out = v[0] * v[0]
    t = v[1] * v[1]
    out += t
    np.multiply(v[2], v[2], out=t)
    out += t
    return out


def principal_frame(I: Sym3) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments ``S`` of shape ``(3, N)`` (ascending) and axes ``R`` of shape ``(3, 3, N)``.

    ``I = R·diag(S)·Rᵀ``; column k of ``R`` is the unit axis of moment ``S[k]``, so ``R`` turns
    principal-frame vectors into the frame of I (:func:`hconv.kernels.frames.to_world` with R,
    and ``to_body`` back). LAPACK's symmetric solver (``numpy.linalg.eigh``), which keeps the axes
    orthonormal to rounding.
    """
    S, R = np.linalg.eigh(I.matrices())
    return np.ascontiguousarray(S.T), np.moveaxis(R, 0, -1)


def pinv_moments(S: np.ndarray, tol: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1/S for moments ``S`` ``(3, N)``, with every moment whose magnitude is at or below ``tol``
    (``(N,)`` or a scalar) set to 0: the pseudo-inverse in the principal frame. Returns the
    inverses (S's dtype) and the ``(3, N)`` mask of the moments dropped."""
    zero = np.abs(S) <= tol
    with np.errstate(divide="ignore"):
        inv = np.where(zero, S.dtype.type(0), 1 / np.where(zero, S.dtype.type(1), S))
    return inv, zero
