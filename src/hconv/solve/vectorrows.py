"""The numpy engine's path for the rows the row engines cover: :mod:`hconv.solve.rows`, a block at a time.

:func:`hconv.solve.blocks.convert_blocks` sends every block of a run the row engines cover
(:func:`hconv.solve.engines.covers`: ``exact`` or ``refined``, six or nine numbers, float64,
``degenerate="error"``) here first. This does, with one numpy expression per step over all the
block's rows, what :func:`hconv.solve.rows.convert_rows` does row by row: factor once, take the
statuses from the factors and the closed-form moments, refine only where asked, and leave every
row it cannot settle (``fallback``) to the general block converter, which handles them all.
The general converter computes what this one does and more (moments by LAPACK where in doubt,
every status, every method), in more passes over the block; this is the cost of a covered row.

Same bits as the row engines, operation for operation, on every output: ω, ``cond``, status and
``residual``; where the general converter decides its refinement per block, this decides per
row, as the row engines do (docs/engines.md: ``refined``'s ω and the ``residual`` may differ
from the general converter's in the last bits, within one rounding of I⁻¹H).

Shapes: tensors are :class:`hconv.kernels.inertia.Sym3` of ``(n,)`` columns [kg·m²]; H, ω
``(3, n)``, component-major [kg·m²/s, rad/s]; everything else ``(n,)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hconv.kernels import linsolve
from hconv.kernels.inertia import Sym3, max_abs, sum_sq
from hconv.kernels.metrics import relative_error
from hconv.kernels.spectrum import ROOT_RANGE, largest_root, smallest_root
from hconv.solve import rows
from hconv.solve.status import CODE, ILL_CONDITIONED_TOL, TRIANGLE_RTOL

#: The status codes set here, written in the order of status.PRECEDENCE (a later write wins).
_OK, _SINGULAR, _NOT_PHYSICAL = CODE["ok"], CODE["singular"], CODE["not_physical"]
_ILL_CONDITIONED, _INACCURATE = CODE["ill_conditioned"], CODE["inaccurate"]


class Block(NamedTuple):
    """One block's answers. ``fallback`` marks the rows the general converter must convert;
    the other fields are meaningless there."""

    w: np.ndarray  #: (3, n) [rad/s]
    cond: np.ndarray
    code: np.ndarray  #: uint8 status codes
    residual: np.ndarray | None  #: None without diagnostics
    fallback: np.ndarray  #: bool


def convert_block(
    I: Sym3, asym: np.ndarray, H: np.ndarray, refined: bool, diagnostics: bool, cond_limit: float
) -> Block:
    """Every row of one block (``H`` contiguous ``(3, n)``, ``asym`` the rows that are not
    symmetric), as :func:`hconv.solve.rows.convert_rows` converts them."""
    with np.errstate(all="ignore"):  # rows that would warn are fallback or get a status
        fac = linsolve.ldlt_factor(I)
        hi, hi_err = largest_root(I)
        tr = I.xx + I.yy + I.zz
        lo = smallest_root(fac, tr, hi)
        w = linsolve.ldlt_solve(fac, H)
        cond, code, state = _verdict(I, H, fac, hi, hi_err, lo, tr, w, cond_limit)
        answered = state == rows.ANSWER
        fallback = asym | (state == rows.FALLBACK)
        residual = None
        if refined or diagnostics:
            safe = _safe(I, H)
            fallback |= answered & ~safe
            w, residual, final = _refine(I, H, fac, w, answered & safe, refined, diagnostics)
            fallback |= answered & ~final
        w[:, ~answered] = np.nan
        if residual is not None:
            residual[~answered] = np.nan
            # inaccurate takes a row only from ok: it comes after the statuses set above
            inaccurate = (residual > ILL_CONDITIONED_TOL) & (code == _OK)
            code[inaccurate] = _INACCURATE
    return Block(w, cond, code, residual, fallback)


def _verdict(
    I: Sym3,
    H: np.ndarray,
    fac: linsolve.LDLt,
    hi: np.ndarray,
    hi_err: np.ndarray,
    lo: np.ndarray,
    tr: np.ndarray,
    w: np.ndarray,
    cond_limit: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hconv.solve.rows.verdict` of every row: ``cond``, status codes (uint8) and the
    state (rows.FALLBACK, NO_ANSWER or ANSWER)."""
    # x·0 is 0 for a finite x and NaN for NaN or an infinity
    total = I.xx + I.yy
    for c in (I.zz, I.xy, I.xz, I.yz, H[0], H[1], H[2]):
        total += c
    usable = total * 0.0 == 0.0
    big = max_abs(I)
    usable &= (big >= 1.0 / ROOT_RANGE) & (big <= ROOT_RANGE)
    usable &= fac.positive()  # pivots > 0 and l32 finite: LDLᵀ is stable
    usable &= (np.abs(lo) <= rows.MAX) & (lo > 0) & (np.abs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * hi_err)
    mid = tr - hi - lo
    a0, a1, a2 = np.abs(lo), np.abs(mid), np.abs(hi)
    top = np.maximum(a0, a2)
    small = np.minimum(np.minimum(a0, a1), a2)
    positive = small > 0
    cond = np.where(positive, top / np.where(positive, small, 1.0), np.inf)
    code = np.where(cond > cond_limit, np.uint8(_ILL_CONDITIONED), np.uint8(_OK))
    a0 += a1
    a0 += a2
    code[hi - mid - lo > TRIANGLE_RTOL * a0] = _NOT_PHYSICAL
    singular = small <= rows.SINGULAR_LIMIT * top
    code[singular] = _SINGULAR
    state = np.where(usable & _final(w), rows.ANSWER, rows.FALLBACK)
    state[usable & singular] = rows.NO_ANSWER
    return cond, code, state


def _final(w: np.ndarray) -> np.ndarray:
    """ω finite and not on the grid of subnormal numbers (the numpy engine's ``inaccurate``)."""
    wmax = max_abs(w)
    return ((w[0] + w[1] + w[2]) * 0.0 == 0.0) & ((wmax == 0) | (wmax >= rows.GRID))


def _safe(I: Sym3, H: np.ndarray) -> np.ndarray:
    """True on rows whose nine inputs are each 0 or within the double-double residual's safe
    range (:func:`hconv.solve.rows._safe`); one test for the whole block when all are."""
    columns = [*I, *H]
    if linsolve.in_safe_range(columns, np.float64):
        return np.ones(H.shape[1], dtype=bool)
    return _each_safe(columns)


def _each_safe(columns: list[np.ndarray]) -> np.ndarray:
    ok = np.ones(columns[0].shape[0], dtype=bool)
    for c in columns:
        m = np.abs(c)
        ok &= (m == 0.0) | ((m < rows.SAFE) & (m > 1.0 / rows.SAFE))
    return ok


def _refine(
    I: Sym3, H: np.ndarray, fac: linsolve.LDLt, w: np.ndarray, go: np.ndarray, refined: bool, diagnostics: bool
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`hconv.solve.rows._finish_chunk` on the rows ``go``: ``refined``'s answer (else ω
    as given), the residual (with ``diagnostics``) and where both are final; ``(3, n)``,
    ``(n,)`` or None, ``(n,)``. Other rows come back as given, residual NaN."""
    n = H.shape[1]
    sub = slice(None) if go.all() else np.flatnonzero(go)  # all rows: views, no copies
    Ig, fg = I.take(sub), fac.take(sub)
    Hg, wg = np.ascontiguousarray(H[:, sub]), np.ascontiguousarray(w[:, sub])
    split = linsolve.split_sym(Ig)
    x = _refine_from(split, Hg, fg, wg)
    ans = x if refined else wg
    ref = _refine_from(split, Hg, fg, x) if refined and diagnostics else x
    final = np.zeros(n, dtype=bool)
    final[sub] = _final(ans)
    residual = None
    if diagnostics:
        final[sub] &= _each_safe(list(ref))
        residual = np.full(n, np.nan)
        residual[sub] = relative_error(ans, ref)
    if refined:
        w[:, sub] = ans
    return w, residual, final


def _step(split: linsolve.SplitSym, H: np.ndarray, fac: linsolve.LDLt, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hconv.solve.rows.refine_step`: x corrected by the solve of its double-double
    residual, and the correction's size relative to x, squared."""
    dx = linsolve.ldlt_solve(fac, linsolve.residual_dd(split, H, x))
    x = x + dx
    c = sum_sq(dx)
    c /= sum_sq(x)
    return x, c


def _refine_from(split: linsolve.SplitSym, H: np.ndarray, fac: linsolve.LDLt, x: np.ndarray) -> np.ndarray:
    """:func:`hconv.solve.rows.refine` of every row from ``x``: a first step, then more on the
    rows that :func:`hconv.solve.rows.refine_on` takes further, each stopped by its own rule."""
    x, c = _step(split, H, fac, x)
    on = np.asarray(rows.goes_on(c))  # type: ignore[arg-type]  # the row's rule, elementwise
    for _ in range(1, linsolve.MAX_REFINE_STEPS):
        if not on.any():
            break
        if on.all():  # at high cond every row goes on: no gathering
            x, c_next = _step(split, H, fac, x)
            on = _again(c_next, c_next / c)
            c = c_next
            continue
        at = np.flatnonzero(on)
        y, c_next = _step(split.take(at), np.ascontiguousarray(H[:, at]), fac.take(at), np.ascontiguousarray(x[:, at]))
        ratio = c_next / c[at]
        x[:, at] = y
        c[at] = c_next
        on[at] = _again(c_next, ratio)
    return x


def _again(c: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """Whether a row takes another step after one whose correction was ``c``, ``ratio`` times
    the one before (:func:`hconv.solve.rows.refine_on`'s rule)."""
    return (ratio < 0.25) & (c * ratio > rows.STOP) & (c > rows.TINY)
