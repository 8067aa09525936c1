"""The row engine: :func:`hconv.solve.convert.convert_columns` for one row at a time, in plain scalar Python.

This is the code the compiled engine runs: :mod:`hconv.solve.compiled` hands these functions to
numba, which turns :func:`convert_rows` into a loop over rows on both cores. Run interpreted
(engine ``python``), the same code answers one body without numpy's per-call overhead. It is
written for both: scalars and ``math`` only, no containers, every helper returns a tuple.

It covers the common case and nothing else, and says so per row: the methods registered with
``row_engine`` (``exact``, and ``refined``: ``refined=True`` here) on symmetric, finite, positive
definite tensors, in float64, with ``degenerate="error"``. Every other row (not finite, not
symmetric, not positive definite, principal moments too close for the closed form to decide,
magnitudes beyond the safe range of the double-double residual, ω not finite or subnormal) is
marked ``fallback`` and its caller converts it with the numpy engine, which handles them all.
The statuses this engine sets itself are ``ok``, ``singular``, ``not_physical``,
``ill_conditioned`` and ``inaccurate``.

Every operation is the numpy engine's (:mod:`hconv.kernels.linsolve`, :mod:`hconv.kernels.spectrum`,
:mod:`hconv.kernels.metrics`), in the same order, so ω of ``exact``, ``cond`` and every status
are the same bits. Two things differ by design, both documented in docs/engines.md: the
refinement decides when to stop row by row, where the numpy engine decides per block of rows,
so ``refined``'s ω and the ``residual`` reference can differ in the last bits (both within one
rounding of I⁻¹H).

Conventions and shapes are those of :mod:`hconv.solve.convert`: I is ``(k, N)`` in its form's
value order (six numbers or nine row-major), H ``(3, N)`` [kg·m²/s], ω ``(N, 3)`` [rad/s].
"""

from __future__ import annotations

import math

import numpy as np

from hconv.kernels.eft import splitter
from hconv.kernels.linsolve import MAX_REFINE_STEPS, STOP_TOL
from hconv.kernels.spectrum import ROOT_NEWTON_STEPS, ROOT_RANGE, ROOT_START
from hconv.solve.status import (
    CODE,
    ILL_CONDITIONED_TOL,
    SINGULAR_RTOL_EPS,
    SYMMETRY_RTOL,
    TRIANGLE_RTOL,
)

#: The inertia forms this engine reads, each with whether its numbers are nine row-major (else
#: the six). Its methods are those registered with ``row_engine`` (hconv.solve.methods).
FORMS = {"sym6": False, "full9": True}

prange = range  # the compiled engine makes this numba.prange: rows shared between the cores

#: For the compiled engine (hconv.solve.compiled), kept here so that changing them changes this
#: file, which is what numba's cache is checked against: the functions that convert_rows calls,
#: compiled (decide and convert_one serve the interpreted engine only) ...
COMPILED = (
    "sym_of_nine",
    "ldlt",
    "ldlt_solve",
    "largest_root",
    "_safe",
    "_split",
    "_dot_row",
    "refine_step",
    "relative_error",
    "goes_on",
    "numbers",
    "verdict",
    "_numbers_chunk",
    "_step_chunk",
    "_on_chunk",
    "_finish_chunk",
    "convert_rows",
)

#: ... and those inlined where they are called: the arithmetic of the loops that run several rows
#: at once (inlining the rest too made the first compile several times longer), and the
#: refinement loops, whose column arguments must become constants for the compiler to prove
#: their reads and writes apart.
INLINE = (
    "_step_chunk",
    "_on_chunk",
    "ldlt",
    "ldlt_solve",
    "largest_root",
    "_safe",
    "_split",
    "_dot_row",
    "numbers",
    "verdict",
    "refine_step",
    "relative_error",
    "goes_on",
)

_EPS = float(np.finfo(np.float64).eps)
MAX = float(np.finfo(np.float64).max)
_SPLIT = splitter(np.float64)
#: A row is singular when its smallest |moment| is at most this times its largest.
SINGULAR_LIMIT = SINGULAR_RTOL_EPS * _EPS
#: ω below this magnitude is on the grid of subnormal numbers (status inaccurate): the numpy engine's test.
GRID = float(np.finfo(np.float64).smallest_subnormal) / ILL_CONDITIONED_TOL
#: The double-double residual's safe range, :func:`hconv.kernels.linsolve.in_safe_range`'s.
SAFE = float(2.0 ** (np.finfo(np.float64).maxexp // 2.5))
_SQRT_EPS = math.sqrt(_EPS)
#: A refinement correction (relative, squared) at or below this has nothing left to find; one
#: predicted at or below STOP ends the refinement of its row (linsolve._refine's rule, per row).
TINY = _EPS * _EPS
STOP = STOP_TOL * STOP_TOL * TINY
_S0, _S1, _S2, _S3, _S4 = ROOT_START

#: The status codes this engine sets, status.py's (compiled in as constants). It writes them in
#: the order of status.PRECEDENCE (a later write wins), and inaccurate, after the other three
#: there, takes a row only from ok.
OK = CODE["ok"]
SINGULAR = CODE["singular"]
NOT_PHYSICAL = CODE["not_physical"]
ILL_CONDITIONED = CODE["ill_conditioned"]
INACCURATE = CODE["inaccurate"]


def sym_of_nine(
    a0: float, a1: float, a2: float, a3: float, a4: float, a5: float, a6: float, a7: float, a8: float
) -> tuple[float, float, float, float, float, float, bool]:
    """Nine row-major numbers: the six of their symmetric part, and whether they are not
    symmetric (:func:`hconv.solve.forms._sym3_of_nine`'s test)."""
    skew = max(max(abs(a1 - a3), abs(a2 - a6)), abs(a5 - a7))
    scale = max(max(max(abs(a0), abs(a1)), max(abs(a2), abs(a3))), max(max(abs(a4), abs(a5)), max(abs(a6), abs(a7))))
    scale = max(scale, abs(a8))
    asym = skew > SYMMETRY_RTOL * scale or skew != skew  # NaN rows fall back too
    return a0, a4, a8, 0.5 * (a1 + a3), 0.5 * (a2 + a6), 0.5 * (a5 + a7), asym


def ldlt(xx: float, yy: float, zz: float, xy: float, xz: float, yz: float) -> tuple[float, ...]:
    """:func:`hconv.kernels.linsolve.ldlt_factor`: ``(d1, d2, d3, l21, l31, l32)``."""
    d1 = xx
    l21 = xy / d1
    l31 = xz / d1
    d2 = yy - l21 * xy
    t = yz - l31 * xy
    l32 = t / d2
    d3 = zz - l31 * xz
    d3 -= t * l32
    return d1, d2, d3, l21, l31, l32


def ldlt_solve(
    d1: float, d2: float, d3: float, l21: float, l31: float, l32: float, h0: float, h1: float, h2: float
) -> tuple[float, float, float]:
    """:func:`hconv.kernels.linsolve.ldlt_solve` for one right-hand side."""
    y1 = h0
    y2 = h1 - l21 * y1
    y3 = h2 - l31 * y1
    y3 -= l32 * y2
    x2 = y3 / d3
    x1 = y2 / d2
    x1 -= l32 * x2
    x0 = y1 / d1
    x0 -= l21 * x1
    x0 -= l31 * x2
    return x0, x1, x2


def largest_root(xx: float, yy: float, zz: float, xy: float, xz: float, yz: float) -> tuple[float, float]:
    """:func:`hconv.kernels.spectrum._largest_root` for a tensor within its ROOT_RANGE (which it does
    not rescale): the largest eigenvalue and its error bound. No branch, so that a compiled loop
    over rows runs several at once."""
    q = (xx + yy + zz) * (1.0 / 3.0)
    aq, bq, cq = xx - q, yy - q, zz - q
    p = math.sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (xy * xy + xz * xz + yz * yz)) * (1.0 / 6.0))
    ip = 1.0 / (p if p > 0 else 1.0)
    det = aq * (bq * cq - yz * yz) - xy * (xy * cq - yz * xz) + xz * (xy * yz - bq * xz)
    r = min(max(det * (0.5 * ip * ip * ip), -1.0), 1.0)
    u = math.sqrt(1.0 + r)
    # c = cos(acos(r)/3) = 1/2 + u·t, t the root of t² + (2u/3)·t³ = 1/6 (spectrum.py says why)
    t = _S0 + u * (_S1 + u * (_S2 + u * (_S3 + u * _S4)))
    k = (2.0 / 3.0) * u
    for _ in range(ROOT_NEWTON_STEPS):
        t2 = t * t
        t -= (t2 + k * t2 * t - (1.0 / 6.0)) / (2.0 * t + 3.0 * k * t2)
    hi = q + p * (1.0 + 2.0 * (u * t))
    err = p * min(_SQRT_EPS, 16.0 * _EPS / math.sqrt(max(1.0 - r * r, _EPS))) + 8.0 * _EPS * abs(q)
    return hi, err


def _safe(v: float) -> bool:
    """True when |v| is 0 or within the double-double residual's safe range."""
    m = abs(v)
    return (m == 0.0) | ((m < SAFE) & (m > 1.0 / SAFE))  # no branch: verdict's loop runs it


def _split(a: float) -> tuple[float, float]:
    c = _SPLIT * a
    hi = c - (c - a)
    return hi, a - hi


def _dot_row(
    s: float,
    a0: float,
    a1: float,
    a2: float,
    x0: float,
    x1: float,
    x2: float,
    xh0: float,
    xh1: float,
    xh2: float,
    xl0: float,
    xl1: float,
    xl2: float,
) -> float:
    """``s − (a0·x0 + a1·x1 + a2·x2)`` in double the precision: one row of
    :func:`hconv.kernels.linsolve.residual_dd`, operation for operation."""
    err = 0.0
    for j in range(3):
        if j == 0:
            a, xj, xhj, xlj = a0, x0, xh0, xl0
        elif j == 1:
            a, xj, xhj, xlj = a1, x1, xh1, xl1
        else:
            a, xj, xhj, xlj = a2, x2, xh2, xl2
        ah, al = _split(a)
        p = a * xj
        e = ah * xhj - p
        e += ah * xlj
        e += al * xhj
        e += al * xlj
        s_new = s - p
        bb = s_new - s
        q = s - (s_new - bb)
        bb += p
        q -= bb
        if j == 0:
            err = q - e
        else:
            q -= e
            err += q
        s = s_new
    return err + s


def refine_step(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    f: tuple[float, float, float, float, float, float],
    h0: float,
    h1: float,
    h2: float,
    x0: float,
    x1: float,
    x2: float,
) -> tuple[float, float, float, float]:
    """One step of :func:`hconv.kernels.linsolve._refine` for one positive definite row (factors
    ``f``): x corrected by the solve of its double-double residual, and the correction's size
    relative to x, squared. No branch."""
    d1, d2, d3, l21, l31, l32 = f
    xh0, xl0 = _split(x0)
    xh1, xl1 = _split(x1)
    xh2, xl2 = _split(x2)
    r0 = _dot_row(h0, xx, xy, xz, x0, x1, x2, xh0, xh1, xh2, xl0, xl1, xl2)
    r1 = _dot_row(h1, xy, yy, yz, x0, x1, x2, xh0, xh1, xh2, xl0, xl1, xl2)
    r2 = _dot_row(h2, xz, yz, zz, x0, x1, x2, xh0, xh1, xh2, xl0, xl1, xl2)
    dx0, dx1, dx2 = ldlt_solve(d1, d2, d3, l21, l31, l32, r0, r1, r2)
    x0 += dx0
    x1 += dx1
    x2 += dx2
    c = dx0 * dx0 + dx1 * dx1 + dx2 * dx2
    c /= x0 * x0 + x1 * x1 + x2 * x2
    return x0, x1, x2, c


def refine_on(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    f: tuple[float, float, float, float, float, float],
    h0: float,
    h1: float,
    h2: float,
    x0: float,
    x1: float,
    x2: float,
    c: float,
) -> tuple[float, float, float]:
    """The rest of :func:`refine` after its first step (which gave ``x`` and ``c``)."""
    # _refine's stopping rule applied to this row alone: stop when the next correction is
    # predicted below STOP_TOL·eps, or when a correction fails to shrink fourfold.
    if not c < 0.25:
        return x0, x1, x2
    pred = c * c
    for _ in range(1, MAX_REFINE_STEPS):
        if not (pred > STOP and c > TINY):
            break
        prev = c
        x0, x1, x2, c = refine_step(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, x0, x1, x2)
        ratio = c / prev
        if not ratio < 0.25:
            break
        pred = c * ratio
    return x0, x1, x2


def refine(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    f: tuple[float, float, float, float, float, float],
    h0: float,
    h1: float,
    h2: float,
    x0: float,
    x1: float,
    x2: float,
) -> tuple[float, float, float]:
    """:func:`hconv.kernels.linsolve._refine` from ``x`` for one positive definite row."""
    x0, x1, x2, c = refine_step(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, x0, x1, x2)
    return refine_on(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, x0, x1, x2, c)


def relative_error(x0: float, x1: float, x2: float, r0: float, r1: float, r2: float) -> float:
    """:func:`hconv.kernels.metrics.relative_error` for one row; no branch."""
    d0, d1, d2 = x0 - r0, x1 - r1, x2 - r2
    unit = max(max(abs(r0), abs(r1)), abs(r2))
    unit = unit if (unit > 0) & (unit <= MAX) else 1.0
    d0, d1, d2, r0, r1, r2 = d0 / unit, d1 / unit, d2 / unit, r0 / unit, r1 / unit, r2 / unit
    num = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    den = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    ratio = num / (den if den > 0 else 1.0)
    return ratio if den > 0 else (0.0 if num == 0 else num * math.inf)


def goes_on(c: float) -> bool:
    """True when :func:`refine_on` takes another step after a first step whose correction was c."""
    return (c < 0.25) & (c * c > STOP) & (c > TINY)


def numbers(
    xx: float, yy: float, zz: float, xy: float, xz: float, yz: float, h0: float, h1: float, h2: float
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float]:
    """The arithmetic of one row, with no branch: ``(hi, hi_err, lo, d1, d2, d3, l21, l31, l32,
    w0, w1, w2)``: the largest and smallest principal moments (spectrum.eigenvalues' closed form,
    meaningful where the pivots are positive), the LDLᵀ factors and the LDLᵀ answer."""
    d1, d2, d3, l21, l31, l32 = ldlt(xx, yy, zz, xy, xz, yz)
    hi, hi_err = largest_root(xx, yy, zz, xy, xz, yz)
    tr = xx + yy + zz
    inv = 1.0 / hi
    s = (tr - hi) * inv
    p = (d1 * inv) * (d2 * inv) * (d3 * inv)
    root = math.sqrt(max(s * s - 4.0 * p, 0.0))
    lo = (2.0 * p / (s + root)) * hi
    w0, w1, w2 = ldlt_solve(d1, d2, d3, l21, l31, l32, h0, h1, h2)
    return hi, hi_err, lo, d1, d2, d3, l21, l31, l32, w0, w1, w2


#: What :func:`verdict` says of a row: the numpy engine must convert it, it has no answer
#: (singular), or it has one.
FALLBACK, NO_ANSWER, ANSWER = 0.0, 1.0, 2.0


def verdict(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    h0: float,
    h1: float,
    h2: float,
    hi: float,
    hi_err: float,
    lo: float,
    d1: float,
    d2: float,
    d3: float,
    l32: float,
    w0: float,
    w1: float,
    w2: float,
    cond_limit: float,
) -> tuple[float, float, float, float]:
    """The statuses of one row from its :func:`numbers`, with no branch (``&`` and selects, not
    ``and`` and ``if``): ``(cond, status code, FALLBACK | NO_ANSWER | ANSWER, safe)``, ``safe``
    1.0 where the inputs lie within the double-double residual's range (0.0 otherwise). Each test
    is the numpy engine's (blocks._convert_block, spectrum.eigenvalues), and a row that any of
    them cannot settle is FALLBACK."""
    # x·0 is 0 for a finite x and NaN for NaN or an infinity (max and comparisons would skip a NaN)
    finite = (xx + yy + zz + xy + xz + yz + h0 + h1 + h2) * 0.0 == 0.0
    big = max(max(max(abs(xx), abs(yy)), max(abs(zz), abs(xy))), max(abs(xz), abs(yz)))
    usable = finite & (big >= 1.0 / ROOT_RANGE) & (big <= ROOT_RANGE)
    usable &= (min(min(d1, d2), d3) > 0) & (abs(l32) <= MAX)  # positive definite: LDLᵀ is stable
    # where the closed form cannot decide, the numpy engine asks LAPACK
    tr = xx + yy + zz
    usable &= (abs(lo) <= MAX) & (lo > 0) & (abs(2.0 * hi - tr) > 1e-9 * tr + 4.0 * hi_err)
    mid = tr - hi - lo
    a0, a1, a2 = abs(lo), abs(mid), abs(hi)
    top = max(a0, a2)
    small = min(min(a0, a1), a2)
    cond = top / (small if small > 0 else 1.0) if small > 0 else math.inf
    code = ILL_CONDITIONED if cond > cond_limit else OK
    code = NOT_PHYSICAL if hi - mid - lo > TRIANGLE_RTOL * (a0 + a1 + a2) else code
    singular = small <= SINGULAR_LIMIT * top
    code = SINGULAR if singular else code
    # overflow, or ω on the grid of subnormal numbers (inaccurate): the numpy engine's rules
    wmax = max(max(abs(w0), abs(w1)), abs(w2))
    w_ok = ((w0 + w1 + w2) * 0.0 == 0.0) & ((wmax == 0) | (wmax >= GRID))
    state = (NO_ANSWER if singular else (ANSWER if w_ok else FALLBACK)) if usable else FALLBACK
    safe = _safe(xx) & _safe(yy) & _safe(zz) & _safe(xy) & _safe(xz) & _safe(yz) & _safe(h0) & _safe(h1) & _safe(h2)
    return cond, float(code), state, 1.0 if safe else 0.0


def decide(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    h0: float,
    h1: float,
    h2: float,
    f: tuple[float, float, float, float, float, float],
    w0: float,
    w1: float,
    w2: float,
    step: tuple[float, float, float, float],
    cond: float,
    code: int,
    state: float,
    safe: bool,
    refined: bool,
    diagnostics: bool,
) -> tuple[float, float, float, float, int, float, bool]:
    """One row from its :func:`numbers`, :func:`verdict` and the first :func:`refine_step` from
    LDLᵀ's ω (``step``, used by ``refined`` and ``diagnostics`` only): ``(w0, w1, w2, cond,
    status code, residual, fallback)``; with ``fallback`` True the rest is meaningless and the
    caller converts the row with the numpy engine."""
    nan = math.nan
    no = (nan, nan, nan, nan, OK, nan, True)
    if state == FALLBACK:
        return no
    if state == NO_ANSWER:
        return nan, nan, nan, cond, code, nan, False  # no answer, so no residual either
    if (refined or diagnostics) and not safe:
        return no
    if refined:
        w0, w1, w2 = refine_on(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, step[0], step[1], step[2], step[3])
        wmax = max(max(abs(w0), abs(w1)), abs(w2))
        if not ((w0 + w1 + w2) * 0.0 == 0.0 and (wmax == 0 or wmax >= GRID)):
            return no
    res = nan
    if diagnostics:
        if refined:  # the reference starts from the refined answer
            x0, x1, x2 = refine(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, w0, w1, w2)
        else:  # from LDLᵀ's answer, where the first step has been taken
            x0, x1, x2 = refine_on(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, step[0], step[1], step[2], step[3])
        if not (_safe(x0) and _safe(x1) and _safe(x2)):
            return no
        res = relative_error(w0, w1, w2, x0, x1, x2)
        if res > ILL_CONDITIONED_TOL and code == OK:
            code = INACCURATE
    return w0, w1, w2, cond, code, res, False


def convert_one(
    xx: float,
    yy: float,
    zz: float,
    xy: float,
    xz: float,
    yz: float,
    h0: float,
    h1: float,
    h2: float,
    refined: bool,
    diagnostics: bool,
    cond_limit: float,
) -> tuple[float, float, float, float, int, float, bool]:
    """One row, as :func:`decide` returns it."""
    hi, hi_err, lo, d1, d2, d3, l21, l31, l32, w0, w1, w2 = numbers(xx, yy, zz, xy, xz, yz, h0, h1, h2)
    cond, code, state, safe = verdict(
        xx, yy, zz, xy, xz, yz, h0, h1, h2, hi, hi_err, lo, d1, d2, d3, l32, w0, w1, w2, cond_limit
    )
    f = (d1, d2, d3, l21, l31, l32)
    step = (math.nan, math.nan, math.nan, math.nan)
    if (refined or diagnostics) and state == ANSWER and safe:
        step = refine_step(xx, yy, zz, xy, xz, yz, f, h0, h1, h2, w0, w1, w2)
    return decide(
        xx,
        yy,
        zz,
        xy,
        xz,
        yz,
        h0,
        h1,
        h2,
        f,
        w0,
        w1,
        w2,
        step,
        cond,
        int(code),
        state,
        safe == 1.0,
        refined,
        diagnostics,
    )


#: Rows per chunk of :func:`convert_rows`: its scratch (37 numbers a row) stays in the L1 cache.
CHUNK = 128
#: The scratch's columns, each CHUNK numbers: the inputs (I's six at 0, H at _H); LDLᵀ's factors
#: and answer (_NUMBERS); verdict's cond, code, state, safe (_VERDICT); a refinement's x, last
#: correction c and whether it goes on (_X for the answer's, _R for the reference's); and the
#: final ω, residual and whether they are final (_FINAL).
_H, _NUMBERS, _VERDICT, _X, _R, _FINAL, _COLUMNS = 6, 9, 18, 22, 27, 32, 37


def _numbers_chunk(a: np.ndarray, m: int, cond_limit: float) -> None:
    """:func:`numbers` and :func:`verdict` of the ``m`` rows in scratch ``a``. One flat array,
    indexed by constant offsets, so that the compiler can prove the columns apart and run several
    rows at once (this loop and the others here have no branch)."""
    for j in range(m):
        xx, yy, zz = a[j], a[CHUNK + j], a[2 * CHUNK + j]
        xy, xz, yz = a[3 * CHUNK + j], a[4 * CHUNK + j], a[5 * CHUNK + j]
        h0, h1, h2 = a[_H * CHUNK + j], a[(_H + 1) * CHUNK + j], a[(_H + 2) * CHUNK + j]
        hi, hi_err, lo, d1, d2, d3, l21, l31, l32, w0, w1, w2 = numbers(xx, yy, zz, xy, xz, yz, h0, h1, h2)
        cond, code, state, safe = verdict(
            xx, yy, zz, xy, xz, yz, h0, h1, h2, hi, hi_err, lo, d1, d2, d3, l32, w0, w1, w2, cond_limit
        )
        k = _NUMBERS * CHUNK + j
        a[k], a[k + CHUNK], a[k + 2 * CHUNK] = d1, d2, d3
        a[k + 3 * CHUNK], a[k + 4 * CHUNK], a[k + 5 * CHUNK] = l21, l31, l32
        a[k + 6 * CHUNK], a[k + 7 * CHUNK], a[k + 8 * CHUNK] = w0, w1, w2
        k = _VERDICT * CHUNK + j
        a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK] = cond, code, state, safe


def _step_chunk(a: np.ndarray, m: int, src: int, dst: int) -> None:
    """The first :func:`refine_step` of every row from the x at column ``src`` into ``dst`` (x,
    c, and whether :func:`refine_on` would go on), for rows with an answer and safe inputs."""
    for j in range(m):
        k = _NUMBERS * CHUNK + j
        f = (a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK], a[k + 4 * CHUNK], a[k + 5 * CHUNK])
        x0, x1, x2, c = refine_step(
            a[j], a[CHUNK + j], a[2 * CHUNK + j], a[3 * CHUNK + j], a[4 * CHUNK + j], a[5 * CHUNK + j], f,
            a[_H * CHUNK + j], a[(_H + 1) * CHUNK + j], a[(_H + 2) * CHUNK + j],
            a[src * CHUNK + j], a[(src + 1) * CHUNK + j], a[(src + 2) * CHUNK + j],
        )  # fmt: skip
        usable = (a[(_VERDICT + 2) * CHUNK + j] == ANSWER) & (a[(_VERDICT + 3) * CHUNK + j] == 1.0)
        k = dst * CHUNK + j
        a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK] = x0, x1, x2, c
        a[k + 4 * CHUNK] = 1.0 if usable & goes_on(c) else 0.0


def _on_chunk(a: np.ndarray, m: int, at: int) -> None:
    """:func:`refine_on` for every row of the chunk at once, from the step at column ``at``: each
    round takes a step on every row and keeps it where the row goes on, so that each row ends
    where refine_on would have stopped it; rounds stop when no row goes on."""
    for _ in range(1, MAX_REFINE_STEPS):
        going = 0
        for j in range(m):
            going += a[(at + 4) * CHUNK + j] == 1.0
        if going == 0:
            break
        for j in range(m):
            k = _NUMBERS * CHUNK + j
            f = (a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK], a[k + 4 * CHUNK], a[k + 5 * CHUNK])
            k = at * CHUNK + j
            x0, x1, x2, c = a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK]
            y0, y1, y2, c_next = refine_step(
                a[j], a[CHUNK + j], a[2 * CHUNK + j], a[3 * CHUNK + j], a[4 * CHUNK + j], a[5 * CHUNK + j], f,
                a[_H * CHUNK + j], a[(_H + 1) * CHUNK + j], a[(_H + 2) * CHUNK + j], x0, x1, x2,
            )  # fmt: skip
            on = a[k + 4 * CHUNK] == 1.0
            ratio = c_next / c
            a[k] = y0 if on else x0
            a[k + CHUNK] = y1 if on else x1
            a[k + 2 * CHUNK] = y2 if on else x2
            a[k + 3 * CHUNK] = c_next if on else c
            a[k + 4 * CHUNK] = 1.0 if on & (ratio < 0.25) & (c_next * ratio > STOP) & (c_next > TINY) else 0.0


def _finish_chunk(a: np.ndarray, m: int, refined: bool, diagnostics: bool) -> None:
    """``refined``'s answer and the residual for the ``m`` rows in scratch ``a``, as
    :func:`decide` computes them row by row: ω, the residual and whether they are final (1.0; 0.0
    sends the row to the numpy engine) into column _FINAL."""
    _step_chunk(a, m, _NUMBERS + 6, _X)  # from LDLᵀ's answer
    _on_chunk(a, m, _X)
    w_at = _X if refined else _NUMBERS + 6
    if refined and diagnostics:  # the reference starts again from the refined answer
        _step_chunk(a, m, _X, _R)
        _on_chunk(a, m, _R)
    r_at = _R if refined else _X
    for j in range(m):
        w0, w1, w2 = a[w_at * CHUNK + j], a[(w_at + 1) * CHUNK + j], a[(w_at + 2) * CHUNK + j]
        wmax = max(max(abs(w0), abs(w1)), abs(w2))
        final = ((w0 + w1 + w2) * 0.0 == 0.0) & ((wmax == 0) | (wmax >= GRID))
        res = math.nan
        if diagnostics:
            r0, r1, r2 = a[r_at * CHUNK + j], a[(r_at + 1) * CHUNK + j], a[(r_at + 2) * CHUNK + j]
            final &= _safe(r0) & _safe(r1) & _safe(r2)
            res = relative_error(w0, w1, w2, r0, r1, r2)
        k = _FINAL * CHUNK + j
        a[k], a[k + CHUNK], a[k + 2 * CHUNK], a[k + 3 * CHUNK] = w0, w1, w2, res
        a[k + 4 * CHUNK] = 1.0 if final else 0.0


def convert_rows(
    I: np.ndarray,
    nine: bool,
    H: np.ndarray,
    refined: bool,
    diagnostics: bool,
    cond_limit: float,
    w: np.ndarray,
    cond: np.ndarray,
    code: np.ndarray,
    residual: np.ndarray,
    fallback: np.ndarray,
) -> None:
    """Every row of ``I`` ``(6, N)`` or, with ``nine``, ``(9, N)`` row-major, and ``H`` ``(3, N)``,
    into ``w`` ``(N, 3)``, ``cond``, ``code``, ``residual`` (written only with ``diagnostics``) and
    ``fallback`` ``(N,)``, which marks the rows left for the numpy engine.

    Chunk by chunk: the inputs into a scratch block; then :func:`numbers` and :func:`verdict`, and
    (for ``refined`` and ``diagnostics``) the refinement, each in a loop with no branch over the
    chunk's rows, which the compiler runs several at a time; then the outputs. The same
    arithmetic as :func:`convert_one`, row for row.
    """
    n = H.shape[1]
    more = refined or diagnostics
    for c in prange((n + CHUNK - 1) // CHUNK):
        start = c * CHUNK
        m = min(CHUNK, n - start)
        a = np.empty(_COLUMNS * CHUNK)
        asym = np.zeros(CHUNK, dtype=np.bool_)
        for j in range(m):
            i = start + j
            if nine:
                xx, yy, zz, xy, xz, yz, asym[j] = sym_of_nine(
                    I[0, i], I[1, i], I[2, i], I[3, i], I[4, i], I[5, i], I[6, i], I[7, i], I[8, i]
                )
            else:
                xx, yy, zz, xy, xz, yz = I[0, i], I[1, i], I[2, i], I[3, i], I[4, i], I[5, i]
            a[j], a[CHUNK + j], a[2 * CHUNK + j] = xx, yy, zz
            a[3 * CHUNK + j], a[4 * CHUNK + j], a[5 * CHUNK + j] = xy, xz, yz
            a[_H * CHUNK + j], a[(_H + 1) * CHUNK + j], a[(_H + 2) * CHUNK + j] = H[0, i], H[1, i], H[2, i]
        _numbers_chunk(a, m, cond_limit)
        w_at = _NUMBERS + 6
        if more:
            _finish_chunk(a, m, refined, diagnostics)
            w_at = _FINAL
        for j in range(m):
            i = start + j
            state = a[(_VERDICT + 2) * CHUNK + j]
            answered = state == ANSWER
            k = int(a[(_VERDICT + 1) * CHUNK + j])
            lost = asym[j] | (state == FALLBACK)
            if more:
                # refinement needs safe inputs, and its answer must pass the checks again
                lost |= answered & ((a[(_VERDICT + 3) * CHUNK + j] != 1.0) | (a[(_FINAL + 4) * CHUNK + j] != 1.0))
            w[i, 0] = a[w_at * CHUNK + j] if answered else math.nan
            w[i, 1] = a[(w_at + 1) * CHUNK + j] if answered else math.nan
            w[i, 2] = a[(w_at + 2) * CHUNK + j] if answered else math.nan
            if diagnostics:
                res = a[(_FINAL + 3) * CHUNK + j] if answered else math.nan
                residual[i] = res
                k = INACCURATE if (res > ILL_CONDITIONED_TOL) & (k == OK) else k
            cond[i] = a[_VERDICT * CHUNK + j]
            code[i] = k
            fallback[i] = lost
