"""Solvers for ``I·ω = H`` on column arrays: unrolled LDLᵀ, LAPACK on stacks, and refinement.

Shapes: tensors are :class:`hconv.kernels.inertia.Sym3` of ``(N,)`` columns; vectors are ``(3, N)``
(one contiguous row per component: the kernels are elementwise over rows, and contiguous columns
run about twice as fast as strided ones). Units pass straight through: with I in kg·m² and H in
kg·m²/s, ω comes out in rad/s. Rows that cannot be solved come back as NaN; callers set statuses.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import DTypeLike

from hconv.kernels import eft
from hconv.kernels.inertia import Sym3, max_abs, sum_sq


class LDLt(NamedTuple):
    """``I = L·D·Lᵀ`` with unit lower-triangular L, for N tensors; every field has shape ``(N,)``."""

    d1: np.ndarray
    d2: np.ndarray
    d3: np.ndarray
    l21: np.ndarray
    l31: np.ndarray
    l32: np.ndarray

    def positive(self) -> np.ndarray:
        """True where all pivots are positive and finite, i.e. I is numerically positive definite."""
        with np.errstate(invalid="ignore"):
            low = np.minimum(self.d1, self.d2)
            np.minimum(low, self.d3, out=low)
            ok = low > 0
            ok &= np.isfinite(self.l32)
            return ok

    def take(self, rows: slice | np.ndarray) -> LDLt:
        return LDLt(*(f[rows] for f in self))


def ldlt_factor(I: Sym3) -> LDLt:
    """Square-root-free Cholesky, written out for 3×3 so it vectorises over rows (~25 flops/row).

    Scale-safe as written: every l is a ratio and every d a difference of like-scaled terms.
    The fields share one ``(5, N)`` buffer and every step writes in place: fewer temporaries
    make the kernel faster (docs/measurements.md).
    """
    buf = np.empty((5,) + I.xx.shape, dtype=np.result_type(I.xx, I.xy))
    d2, d3, l21, l31, l32 = buf
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d1 = I.xx
        np.divide(I.xy, d1, out=l21)
        np.divide(I.xz, d1, out=l31)
        np.multiply(l21, I.xy, out=d2)
        np.subtract(I.yy, d2, out=d2)
        t = l31 * I.xy
        np.subtract(I.yz, t, out=t)
        np.divide(t, d2, out=l32)
        np.multiply(l31, I.xz, out=d3)
        np.subtract(I.zz, d3, out=d3)
        t *= l32
        d3 -= t
    return LDLt(d1, d2, d3, l21, l31, l32)


def ldlt_solve(f: LDLt, h: np.ndarray) -> np.ndarray:
    """Solve with a factorisation from :func:`ldlt_factor`; h and the result have shape ``(3, N)``."""
    x = np.empty_like(h)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        y1 = h[0]
        y2 = f.l21 * y1
        np.subtract(h[1], y2, out=y2)
        y3 = f.l31 * y1
        np.subtract(h[2], y3, out=y3)
        t = f.l32 * y2
        y3 -= t
        np.divide(y3, f.d3, out=x[2])
        np.divide(y2, f.d2, out=x[1])
        np.multiply(f.l32, x[2], out=t)
        x[1] -= t
        np.divide(y1, f.d1, out=x[0])
        np.multiply(f.l21, x[1], out=t)
        x[0] -= t
        np.multiply(f.l31, x[2], out=t)
        x[0] -= t
    return x


def lapack_solve(I: Sym3, h: np.ndarray) -> np.ndarray:
    """``numpy.linalg.solve`` (LU with partial pivoting) on the ``(N, 3, 3)`` stack; h is ``(3, N)``.

    The stack is first equilibrated by powers of two (exact), so that the determinant used to
    spot singular rows can neither overflow nor underflow at any scale of I. numpy raises for the
    whole stack if one matrix has a zero pivot, so those rows (det = 0, from the same LU) are
    solved against the identity and returned as NaN instead.
    """
    s = pow2_scales(I)
    A = scale_sym(I, s).matrices()
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        det = np.linalg.det(A)
    bad = ~np.isfinite(det) | (det == 0)
    if bad.any():
        A[bad] = np.eye(3, dtype=A.dtype)
    x = np.linalg.solve(A, (h * s).T[..., None])[..., 0].T * s
    x[:, bad] = np.nan
    return np.ascontiguousarray(x)


class SplitSym(NamedTuple):
    """A :class:`Sym3` with each of its six columns split once for exact products (Dekker)."""

    entries: Sym3
    hi: tuple
    lo: tuple

    def take(self, rows: slice | np.ndarray) -> SplitSym:
        return SplitSym(self.entries.take(rows), tuple(h[rows] for h in self.hi), tuple(lo[rows] for lo in self.lo))


def split_sym(I: Sym3) -> SplitSym:
    """:func:`hconv.kernels.eft.split` of each column, written in place into one ``(2, 6, N)`` buffer."""
    halves = np.empty((2, 6) + I.xx.shape, dtype=I.xx.dtype)
    hi, lo = halves
    sp = I.xx.dtype.type(eft.splitter(I.xx.dtype))
    for k, a in enumerate(I):
        np.multiply(a, sp, out=hi[k])  # c = sp·a
        np.subtract(hi[k], a, out=lo[k])  # c − a
        hi[k] -= lo[k]  # hi = c − (c − a)
        np.subtract(a, hi[k], out=lo[k])  # lo = a − hi
    return SplitSym(I, tuple(hi), tuple(lo))


_ROWS = ((0, 3, 4), (3, 1, 5), (4, 5, 2))  # which of (xx, yy, zz, xy, xz, yz) fill each matrix row


def residual_dd(A: SplitSym, h: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``h - A·x`` as accurate as if computed in twice the working precision; shape ``(3, N)``.

    Every product ``A_kj·x_j`` is split exactly into value and error; the values are summed with
    exact two_diffs and all the errors in ordinary arithmetic, added once at the end (Ogita–Rump–
    Oishi's Dot2). With x close to the solution the residual is tiny next to h and A·x, which is
    exactly the cancellation this survives.

    The arithmetic is :func:`hconv.kernels.eft.two_prod_split` and :func:`hconv.kernels.eft.two_diff` written
    out over a fixed set of scratch rows (every intermediate lands in one of them): the same
    operations in the same order, so the same bits, faster than with a fresh array per
    operation (docs/measurements.md).
    """
    n = x.shape[1]
    buf = np.empty((13, n), dtype=x.dtype)
    xh, xl = buf[0:3], buf[3:6]
    p, e, t, bb, q, s_a, s_b = buf[6:13]
    np.multiply(x, x.dtype.type(eft.splitter(x.dtype)), out=xh)  # eft.split, in place
    np.subtract(xh, x, out=xl)
    xh -= xl
    np.subtract(x, xh, out=xl)
    out = np.empty_like(x)
    for k, row in enumerate(_ROWS):
        s, err = h[k], out[k]
        for j, c in enumerate(row):
            a, ah, al = A.entries[c], A.hi[c], A.lo[c]
            # p + e = a·x_j exactly (Dekker)
            np.multiply(a, x[j], out=p)
            np.multiply(ah, xh[j], out=e)
            e -= p
            np.multiply(ah, xl[j], out=t)
            e += t
            np.multiply(al, xh[j], out=t)
            e += t
            np.multiply(al, xl[j], out=t)
            e += t
            # s_new + q = s - p exactly (Knuth), into the row s does not occupy
            s_new = s_b if s is s_a else s_a
            np.subtract(s, p, out=s_new)
            np.subtract(s_new, s, out=bb)
            np.subtract(s_new, bb, out=q)
            np.subtract(s, q, out=q)
            bb += p
            q -= bb
            if j == 0:
                np.subtract(q, e, out=err)
            else:
                q -= e
                err += q
            s = s_new
        err += s
    return out


def pow2_scales(I: Sym3) -> np.ndarray:
    """Powers of two ``s`` of shape ``(3, N)``, in I's dtype, with ``s_i² · |I_ii| ≈ 1``.

    Scaling ``S·I·S`` by powers of two is exact, so it changes no rounding; it only keeps every
    intermediate (determinants, the Dekker splits of :mod:`hconv.kernels.eft`) far from overflow and
    underflow. A zero diagonal entry borrows the row's largest entry.
    """
    diag = np.abs(np.stack([I.xx, I.yy, I.zz]))
    big = max_abs(I)
    ref = np.where(diag > 0, diag, big)
    ref = np.where((ref > 0) & np.isfinite(ref), ref, 1)
    _, e = np.frexp(ref)
    return np.ldexp(np.ones_like(ref), -(e // 2))


def scale_sym(I: Sym3, s: np.ndarray) -> Sym3:
    """``S·I·S`` with ``S = diag(s)``, s of shape ``(3, N)``."""
    sx, sy, sz = s
    return Sym3(I.xx * sx * sx, I.yy * sy * sy, I.zz * sz * sz, I.xy * sx * sy, I.xz * sx * sz, I.yz * sy * sz)


def in_safe_range(arrays: list[np.ndarray], dtype: DTypeLike, skip_nan: bool = False) -> bool:
    """True when every nonzero magnitude is within 2^±(maxexp/2.5): Dekker splits and their
    products can then neither overflow nor underflow, and no equilibration is needed. A NaN
    fails, unless ``skip_nan`` (rows without an answer); an infinity always fails."""
    lim = float(2.0 ** (np.finfo(dtype).maxexp // 2.5))
    for a in arrays:
        m = np.abs(a)
        big = np.fmax.reduce(m, axis=None, initial=0) if skip_nan else m.max(initial=0)
        if not big < lim:
            return False
        # zeros are safe: only when the plain minimum is small, look for a small nonzero one
        if not m.min(initial=lim) > 1 / lim and not np.minimum.reduce(m, axis=None, where=m > 0, initial=lim) > 1 / lim:
            return False
    return True


#: Most refinement steps; with an exact residual each step multiplies the error by ~cond·eps.
MAX_REFINE_STEPS = 6
#: Refinement stops once no row's next correction is predicted above STOP_TOL·eps (relative).
#: A 16× looser value still met the target (docs/measurements.md), so 1 leaves a margin;
#: tests/test_linsolve.py checks the value in use.
STOP_TOL = 1.0


def solve_refined(I: Sym3, h: np.ndarray, steps: int | None = None, x0: np.ndarray | None = None) -> np.ndarray:
    """ω = I⁻¹H to within about one rounding for cond(I) up to ~1e14; h and ω are ``(3, N)``.

    LDLᵀ (LU where I is not positive definite) gives a first answer x₀, unless the caller
    passes one (``x0``, ``(3, N)``, another solver's answer, say); each step computes the
    residual in double the working precision (:func:`residual_dd`) and corrects x by a solve
    with the same factors. ``steps`` fixes the number of steps; by default they stop when no row
    of the block is predicted to move by more than ``STOP_TOL``·eps (relative) in the next step.
    The prediction is Wilkinson's: each step multiplies the error by about the ratio of the last
    two corrections; after the first step, with no ratio yet, by the block's largest first
    correction (x₀'s worst relative error, about cond·eps for LDLᵀ's answer). The steps this
    takes per cond, and its accuracy against ten steps, are in docs/measurements.md.

    Blocks whose magnitudes (I, h or ω) are extreme are solved equilibrated by powers of two.
    """
    if in_safe_range(list(I) + [h], h.dtype):
        x = _refine(I, h, steps, x0)
        if in_safe_range([x], h.dtype, skip_nan=True):
            return x
    s = pow2_scales(I)
    hs = h * s
    # The right-hand side too, per row by a power of two (exact), so that neither it nor the
    # solution sits near the end of the range while the residual is split and multiplied.
    big = np.maximum(np.maximum(np.abs(hs[0]), np.abs(hs[1])), np.abs(hs[2]))
    emax = np.finfo(h.dtype).maxexp - 24  # t itself must stay finite, even for subnormal rows
    t = np.where((big > 0) & np.isfinite(big), np.ldexp(1.0, np.clip(-np.frexp(big)[1], -emax, emax)), 1.0).astype(
        h.dtype
    )
    with np.errstate(over="ignore", invalid="ignore"):
        # ω of the scaled system S·I·S·y = t·S·h is y = t·S⁻¹·ω (powers of two: exact)
        y0 = None if x0 is None else x0 / s * t
        return _refine(scale_sym(I, s), hs * t, steps, y0) * s / t


def _refine(I: Sym3, h: np.ndarray, steps: int | None, x0: np.ndarray | None = None) -> np.ndarray:
    fac = ldlt_factor(I)
    other = ~fac.positive()
    I_o = I.take(other) if other.any() else None

    def solve(rhs: np.ndarray) -> np.ndarray:
        y = ldlt_solve(fac, rhs)
        if I_o is not None:
            y[:, other] = lapack_solve(I_o, rhs[:, other])
        return y

    x = solve(h) if x0 is None else np.array(x0, dtype=h.dtype)  # a copy: x is updated in place
    Isplit = split_sym(I)
    tiny = float(np.finfo(x.dtype).eps) ** 2
    prev = None
    for _ in range(MAX_REFINE_STEPS if steps is None else steps):
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            dx = solve(residual_dd(Isplit, h, x))
            x += dx
            if steps is not None:
                continue
            # c: this step's correction relative to x, squared, per row; it measures the error
            # x had before the step
            c = sum_sq(dx)
            c /= sum_sq(x)
            if prev is None:
                # A row whose first answer was off by half or more, or whose correction later
                # fails to halve, is as good as refinement can make it (cond·eps near 1 or
                # beyond: the caller flags it ill_conditioned or singular); it no longer
                # decides whether the block goes on.
                alive = c < 0.25
                # No ratio yet: each step multiplies the error by about the largest first
                # correction among the other rows (x₀'s worst relative error there).
                pred = c * float(np.max(c, where=alive, initial=0.0))
            else:
                ratio = c / prev  # the error shrinks by the ratio of the last two corrections
                pred = c * ratio
                alive &= ratio < 0.25
            # stop once no row's remaining error is predicted above STOP_TOL·eps; a correction
            # already at the rounding level (c <= eps²) has nothing left to find
            if not np.any((pred > STOP_TOL**2 * tiny) & (c > tiny) & alive):
                break
        prev = c
    return x
