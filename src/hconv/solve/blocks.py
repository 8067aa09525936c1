"""The numpy engine: :func:`hconv.solve.convert.convert_columns`'s rows converted in blocks, with
every status, ``cond``, the residual and the degenerate rows' pseudo-inverse.

Every block goes by :func:`_convert_block`, which handles every method and option: this engine is
the reference the compiled engine (:mod:`hconv.solve.compiled`) is tested against. A call from the main thread
shares its blocks among the cores (:func:`block_threads`). docs/engines.md has the why and the
figures. The ``ill_conditioned`` bound (:func:`error_k`, :func:`ill_conditioned_above`) is this
engine's, and the compiled engine takes its from it.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from hconv.kernels import frames, linsolve
from hconv.kernels.inertia import Sym3, max_abs, pinv_moments, principal_frame
from hconv.kernels.metrics import relative_error
from hconv.kernels.spectrum import eigenvalues
from hconv.solve import engines, forms, methods, status

#: Rows per kernel block: small enough that a block's temporaries stay in cache.
BLOCK_ROWS = 16384
#: Rows per block when a call's blocks run on threads: fewer numpy calls than BLOCK_ROWS, so
#: less waiting on the GIL, which each call takes between its operations (docs/engines.md).
THREADED_BLOCK_ROWS = 65536
#: Most threads one call's blocks run on: beyond a few, the Python between numpy's operations
#: (which holds the GIL) sets the pace.
MAX_BLOCK_THREADS = 4


def ill_conditioned_above(m: methods.Method, extra_k: float) -> float:
    """cond above which a float64 answer of ``m`` on a full tensor is ``ill_conditioned``."""
    k = extra_k + (m.error_k or {}).get(64, 0.0)
    return status.ILL_CONDITIONED_TOL / (k * float(np.finfo(np.float64).eps)) if k else np.inf


def error_k(m: methods.Method, precision: int, diagonal: bool, extra_k: float = 0.0) -> float:
    """K of the bound K·cond(I)·eps on an exact-family answer's error (``ill_conditioned``), with
    ``extra_k`` for what the caller rounded before (0 for the other methods: no such bound).
    The division is correctly rounded, so on diagonal tensors the method adds nothing that grows
    with cond."""
    if not m.exact:
        return 0.0
    return extra_k if diagonal else extra_k + (m.error_k or {}).get(precision, 0.0)


def convert_blocks(
    n: int,
    opts: Options,
    form: forms.Form,
    I: np.ndarray,
    H: np.ndarray,
    r: np.ndarray | None,
    w: np.ndarray,
    cond: np.ndarray,
    code: np.ndarray,
    residual: np.ndarray | None,
    deg: Degenerate | None,
) -> None:
    """Every block of rows, by :func:`_convert_block`, on
    :func:`block_threads` threads (numpy lets go of the GIL inside each operation on a block, so
    the blocks of one call share the cores)."""
    threads = block_threads(-(-n // THREADED_BLOCK_ROWS))
    size = BLOCK_ROWS if threads == 1 else THREADED_BLOCK_ROWS

    def one(lo: int) -> None:
        sl = slice(lo, min(n, lo + size))
        # every row that would warn gets a status instead; set here, as errstate is per thread
        with np.errstate(all="ignore"):
            _convert_block(
                opts,
                *form.as_sym3(I[:, sl], status.symmetry_rtol(opts.dtype)),
                H[:, sl],
                None if r is None else r[:, sl],
                w[sl],
                cond[sl],
                code[sl],
                None if residual is None else residual[sl],
                None if deg is None else Degenerate(deg.axis[sl], deg.dim[sl]),
            )

    starts = range(0, n, size)
    if threads == 1:
        for lo in starts:
            one(lo)
        return
    pool = ThreadPoolExecutor(threads, thread_name_prefix="hconv-blocks")
    try:
        for _ in pool.map(one, starts):  # re-raises a block's exception here
            pass
    finally:
        # on an exception or Ctrl-C, the blocks not yet started never start
        pool.shutdown(wait=True, cancel_futures=True)


def block_threads(blocks: int) -> int:
    """Threads for a call of ``blocks`` blocks: one per core (at most :data:`MAX_BLOCK_THREADS`)
    when called from the main thread, else 1: a call from another thread is already part of
    its caller's parallelism (the file pipeline's batch threads, a Dask worker's task)."""
    if blocks < 2 or threading.current_thread() is not threading.main_thread():
        return 1
    return max(1, min(blocks, MAX_BLOCK_THREADS, engines.available_cores()))


@dataclass(frozen=True)
class Options:
    m: methods.Method
    dtype: type
    diagonal: bool  #: I holds diagonal tensors (principal moments in their own frame)
    degenerate_rtol: float | None
    extra_k: float


@dataclass(frozen=True)
class Degenerate:
    """Outputs for pinv/lock: views into the caller's arrays."""

    axis: np.ndarray  #: (n, 3)
    dim: np.ndarray  #: (n,) int8


def _convert_block(
    o: Options,
    I: Sym3,
    asym: np.ndarray,
    H: np.ndarray,
    r: np.ndarray | None,
    w_out: np.ndarray,
    cond_out: np.ndarray,
    code_out: np.ndarray,
    res_out: np.ndarray | None,
    deg: Degenerate | None,
) -> None:
    """One block of rows, ``H`` and ``r`` ``(3, n)``; writes into the ``*_out`` views (and
    ``deg``'s, for pinv/lock)."""
    m, dtype = o.m, o.dtype
    n = H.shape[1]
    H = np.ascontiguousarray(H)  # a copy of the block: contiguous rows, and the caller's never written
    r_used = np.ascontiguousarray(r) if m.needs_r else None
    columns = [*I, *H] + ([] if r_used is None else list(r_used))
    limit = np.finfo(dtype).max  # a finite float64 beyond float32's range is no usable input there
    with np.errstate(invalid="ignore"):
        invalid = ~(max_abs(columns) <= limit)  # NaN compares false, so NaN rows are invalid too
    if invalid.any():
        # Stand-ins keep the kernels quiet; these rows' outputs are replaced below.
        keep = ~invalid
        I = Sym3(*(np.where(keep, c, d) for c, d in zip(I, (1.0, 1.0, 1.0, 0.0, 0.0, 0.0))))
        H = np.where(keep, H, 0.0)
        if r_used is not None:
            r_used = np.where(keep, r_used, 1.0)

    if o.diagonal:
        moments = np.stack([I.xx, I.yy, I.zz])
        lam = np.sort(moments, axis=0)
    else:
        lam = eigenvalues(I)  # (3, n), ascending
    a0, a1, a2 = np.abs(lam[0]), np.abs(lam[1]), np.abs(lam[2])
    big = np.maximum(a0, a2)
    small = np.minimum(np.minimum(a0, a1), a2)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(small > 0, big / np.where(small > 0, small, 1.0), np.inf)
    singular = small <= status.singular_rtol(dtype) * big
    tol = np.zeros(n)  # a moment at or below tol counts as zero (degenerate)
    if o.degenerate_rtol is not None:
        tol = o.degenerate_rtol * (a0 + a1 + a2)
        singular |= small <= tol
    tol = np.maximum(tol, status.singular_rtol(dtype) * big)
    dropped = singular & ~invalid & ~asym if deg is not None else np.zeros(n, dtype=bool)
    k_extra = error_k(m, 8 * np.dtype(dtype).itemsize, o.diagonal, o.extra_k)
    cond_limit = status.ILL_CONDITIONED_TOL / (k_extra * float(np.finfo(dtype).eps)) if k_extra else np.inf
    flags = {
        "invalid_input": invalid,
        "not_symmetric": asym & ~invalid,
        "singular": singular & ~dropped,
        "not_positive_definite": (lam[0] < -tol) | ((lam[0] < 0) & ~dropped),
        "degenerate": dropped,
        "not_physical": lam[2] - lam[1] - lam[0] > status.triangle_rtol(dtype) * (a0 + a1 + a2),
        "ill_conditioned": cond > cond_limit,
    }

    if o.diagonal and m.exact:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            w = H.astype(dtype) / moments.astype(dtype)
        own: dict[str, np.ndarray] = {}
    else:
        w, own = m.kernel(I.astype(dtype), H.astype(dtype), None if r_used is None else r_used.astype(dtype))
    for name, mask in own.items():
        flags[name] = flags[name] | mask if name in flags else mask
    if deg is not None and dropped.any():
        flags["singular"] &= ~dropped  # a method's own singular flag does not apply to these rows
        w[:, dropped] = _pseudo_inverse(I.take(dropped), H[:, dropped], tol[dropped], o.diagonal, deg, dropped)
    no_answer = np.zeros(n, dtype=bool)
    for s in m.nan_on:
        if s in flags:
            no_answer |= flags[s]
    # A finite row that still gives a non-finite ω must never pass as ok.
    lost = ~(np.isfinite(w[0]) & np.isfinite(w[1]) & np.isfinite(w[2])) & ~no_answer
    flags["overflow"] = lost & ~invalid
    w[:, no_answer | lost] = np.nan

    if m.exact:
        # ω so small that the spacing of subnormal numbers alone exceeds the promise.
        grid = float(np.finfo(dtype).smallest_subnormal) / status.ILL_CONDITIONED_TOL
        wmax = max_abs(w)
        flags["inaccurate"] = (wmax > 0) & (wmax < grid)
    w_out[:] = w.T
    cond[invalid] = np.nan
    cond_out[:] = cond
    code_out[:] = status.combine(n, flags)
    if res_out is not None:
        # Rows with an answer to measure; the rest keep NaN.
        ok = ~(invalid | flags["not_symmetric"] | flags["singular"] | dropped | no_answer | lost)
        res_out[:] = np.nan
        every = bool(ok.all())
        if every or ok.any():
            rows = slice(None) if every else ok  # a slice copies nothing
            res = _residual(
                o, I if every else I.take(ok), H[:, rows], w[:, rows], moments[:, rows] if o.diagonal else None
            )
            res_out[rows] = res
            if m.exact:
                # The safety net under the a-priori statuses: an exact-family answer measured off
                # by more than the promise (subnormal numbers on the way, say) is never ok.
                bad = np.zeros(n, dtype=bool)
                bad[rows] = res > status.ILL_CONDITIONED_TOL
                code_out[:] = status.merge(code_out, bad, "inaccurate")


def _residual(o: Options, I: Sym3, H: np.ndarray, w: np.ndarray, moments: np.ndarray | None) -> np.ndarray:
    """‖ω − I⁻¹H‖ / ‖I⁻¹H‖ for rows that have an answer: ``H``, ``w`` (and ``moments``) ``(3, k)``;
    returns ``(k,)``.

    The reference I⁻¹H is solved in float64 from the inputs. An exact-family answer is its own
    starting point: the first refinement step's correction is then its error, measured with a
    residual in double precision, and further steps run until the reference is correct to
    rounding; the error so measured is itself right to a relative cond·eps (6 digits at cond 1e10).
    The other methods answer something else, so their reference starts from scratch.
    """
    w = w.astype(np.float64, copy=False)
    if moments is not None:  # H_i / I_i in float64 is the correctly rounded reference
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            ref = H / moments
    else:
        ref = linsolve.solve_refined(I, H, x0=w if o.m.exact else None)
    # H = 0 gives I⁻¹H = 0: an answer of 0 is exact, anything else infinitely off.
    return relative_error(w, ref)


def _pseudo_inverse(
    I: Sym3, H: np.ndarray, tol: np.ndarray, diagonal: bool, deg: Degenerate, rows: np.ndarray
) -> np.ndarray:
    """ω = I⁺·H on degenerate rows, in float64: moments at or below ``tol`` ``(k,)`` are dropped.

    ``H`` is ``(3, k)``; writes the dropped axis (when exactly one) and the count into ``deg``
    at ``rows``. Returns ω as ``(3, k)``.
    """
    # The principal frame: for a diagonal tensor the coordinate axes themselves.
    if diagonal:
        S, R = np.stack([I.xx, I.yy, I.zz]), np.broadcast_to(np.eye(3)[..., None], (3, 3, H.shape[1]))
    else:
        S, R = principal_frame(I)  # (3, k) moments; (3, 3, k) axes, column j for moment j
    inv, zero = pinv_moments(S, tol)
    w = frames.to_world(R, inv * frames.to_body(R, H))
    count = zero.sum(axis=0)
    axis = np.full((3, S.shape[1]), np.nan)
    one = count == 1
    if one.any():
        cols = np.arange(S.shape[1])
        picked = R[:, np.argmax(zero, axis=0), cols]  # (3, k): the axis of the dropped moment
        # A sign is arbitrary for an axis; make its largest component positive, so output is stable.
        sign = np.sign(picked[np.argmax(np.abs(picked), axis=0), cols])
        axis[:, one] = (picked * sign)[:, one]
    deg.axis[rows] = axis.T
    deg.dim[rows] = count
    return w
