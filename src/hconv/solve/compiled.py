"""The compiled engine: hconv's row code in C (``src/hconv/solve/rowcode.c``, built when hconv is
installed), one fused pass per row, its blocks of rows on every core.

It covers the common case and says so per row: the methods registered with ``row_engine``
(``exact``, and ``refined``) on symmetric, finite, positive definite tensors of six or nine
numbers (:data:`hconv.solve.engines.FORMS`), in float64, with ``degenerate="error"`` at its default threshold
(:func:`hconv.solve.engines.covers`). Every other row (not finite, not symmetric, not positive
definite, principal moments too close for the closed form to decide, magnitudes beyond the safe
range of the double-double residual, ω not finite or subnormal) is marked ``fallback``, and its
caller converts it with the numpy engine, which handles them all. The statuses this engine sets
itself are ``ok``, ``singular``, ``not_physical``, ``ill_conditioned`` and ``inaccurate``.

Every operation is the numpy engine's (:mod:`hconv.kernels.linsolve`, :mod:`hconv.kernels.spectrum`,
:mod:`hconv.kernels.metrics`, :mod:`hconv.solve.blocks`), in the same order, so ω of ``exact``,
``cond`` and every status are the same bits. One thing differs by design: the refinement decides
when to stop row by row, where the numpy engine decides per block of rows, so ``refined``'s ω and
the ``residual`` can differ in the last bits (both within one rounding of I⁻¹H; docs/engines.md).

The constants the C code uses are read here from the modules that own them and handed to it once
(:func:`_configure`), so that each is stated in one place.

Shapes: I ``(k, N)`` in its form's value order (six numbers or nine row-major), H ``(3, N)``
[kg·m²/s], any strides; ω ``(N, 3)`` [rad/s], ``cond``, ``code``, ``residual``, ``fallback``
``(N,)``.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from concurrent.futures import Future

import numpy as np

from hconv.kernels.eft import splitter
from hconv.kernels.linsolve import MAX_REFINE_STEPS, STOP_TOL
from hconv.kernels.spectrum import ROOT_NEWTON_STEPS, ROOT_RANGE, ROOT_START
from hconv.solve import rowcode  # the C extension (setup.py)
from hconv.solve.engines import SharedPool, available_cores
from hconv.solve.status import CODE, ILL_CONDITIONED_TOL, SINGULAR_RTOL_EPS, symmetry_rtol, triangle_rtol

#: Rows per thread below which a call stays on its caller's thread (handing rows to another
#: thread would cost more than it saves).
BLOCK_ROWS = 4096
#: A large call's blocks per thread (docs/measurements.md).
PARTS_PER_THREAD = 8
#: Rows from which a call streams its outputs to memory past the caches (34 bytes a row or more,
#: well beyond a core's cache): at this size stores that first read each line cost more than
#: finding the outputs in a cache would save (docs/engines.md).
STREAM_ROWS = 1 << 20
#: Blocks are whole chunks of the C code's rows, so that each starts on a cache line of every
#: output and can be streamed.
_CHUNK_ROWS = rowcode.CHUNK_ROWS
#: How long a pool thread that served a call stays in C, spinning, for the next call's blocks
#: before it goes back to wait in the pool (seconds): calls in a loop find it there, where a
#: thread woken for each call cost a wake-up of the system's and the GIL (docs/engines.md); the
#: price is at most this much of a core after the last call.
LINGER = 0.001

_EPS = float(np.finfo(np.float64).eps)
#: The status codes this engine sets, status.py's. The C code writes them in the order of
#: status.PRECEDENCE (a later write wins), and inaccurate, after the other three there, takes a
#: row only from ok.
OWN_CODES = {name: CODE[name] for name in ("ok", "singular", "not_physical", "ill_conditioned", "inaccurate")}


def constants() -> dict[str, float]:
    """What the C code computes with, from the modules that state each."""
    tiny = _EPS * _EPS
    s0, s1, s2, s3, s4 = ROOT_START
    return {
        "SPLIT": float(splitter(np.float64)),
        # a row is singular when its smallest |moment| is at most this times its largest
        "SINGULAR_LIMIT": SINGULAR_RTOL_EPS * _EPS,
        # ω below this magnitude is on the grid of subnormal numbers (status inaccurate)
        "GRID": float(np.finfo(np.float64).smallest_subnormal) / ILL_CONDITIONED_TOL,
        # the double-double residual's safe range, hconv.kernels.linsolve.in_safe_range's
        "SAFE": float(2.0 ** (np.finfo(np.float64).maxexp // 2.5)),
        # a correction (relative, squared) at or below TINY has nothing left to find; one
        # predicted at or below STOP ends the refinement of its row (linsolve._refine's rule)
        "TINY": tiny,
        "STOP": STOP_TOL * STOP_TOL * tiny,
        **{f"S{k}": float(v) for k, v in enumerate((s0, s1, s2, s3, s4))},
        "ROOT_NEWTON_STEPS": float(ROOT_NEWTON_STEPS),
        "ROOT_RANGE": float(ROOT_RANGE),
        "MAX_REFINE_STEPS": float(MAX_REFINE_STEPS),
        # float64's: the engine converts float64 only (precision 32 is the numpy engine's)
        "SYMMETRY_RTOL": symmetry_rtol(np.float64),
        "TRIANGLE_RTOL": triangle_rtol(np.float64),
        "ILL_CONDITIONED_TOL": ILL_CONDITIONED_TOL,
        "EPS": _EPS,
        "SQRT_EPS": math.sqrt(_EPS),
        "MAX": float(np.finfo(np.float64).max),
        **{name.upper(): float(code) for name, code in OWN_CODES.items()},
    }


def _configure() -> None:
    rowcode.configure(constants())


_configure()
#: The process's threads for blocks of rows.
_shared_pool = SharedPool("hconv-rows")


def _threads(n: int) -> int:
    """Threads for ``n`` rows: one per core (a block each at least) from the main thread; 1 from
    any other thread, which is already part of its caller's parallelism (the file pipeline's
    batch threads, a Dask worker's task)."""
    blocks = -(-n // BLOCK_ROWS)
    if blocks < 2 or threading.current_thread() is not threading.main_thread():
        return 1
    return max(1, min(blocks, available_cores()))


#: ``one(I, nine, H, refined, diagnostics, cond_limit)``: one body, ``I`` ``(3, 3)`` or ``(6,)``
#: and ``H`` ``(3,)`` contiguous float64, in the caller's thread: ``(w (3,), cond, status code,
#: residual or None, fallback)``, numpy scalars as a stacked Result's rows hold them, or None for
#: arrays of another layout. The C function itself: a wrapper would add a sixth to a one-body call.
one = rowcode.one
#: ``outputs(n, diagnostics)``: new ``(w (n, 3), cond, code (uint8), residual ((n,) with
#: diagnostics, else (0,)), fallback (bool))`` for :func:`convert_rows`, starting on cache lines,
#: from memory the C code keeps: the large blocks numpy frees (a dropped result's) are kept, to a
#: limit, for the next calls, which then write to memory already mapped; each is given back once
#: a whole call has left it unused, or a while after it was kept (:data:`pool` gives the limits;
#: rowcode.c and docs/engines.md the rules). The arrays own their data.
outputs = rowcode.outputs
#: ``pool()``: what :data:`outputs` keeps now, the requests it has served, and its limits.
pool = rowcode.pool
#: ``release()``: give back every block :data:`outputs` keeps.
release = rowcode.release
#: ``stack(I, H, refined, diagnostics, cond_limit)``: a small stack as numpy users hold it, ``I``
#: ``(N, 3, 3)`` or ``(N, 6)`` and ``H`` ``(N, 3)`` float64, on the caller's thread into new
#: arrays: ``(w (N, 3), cond, status codes, residual or None)``; None when a row is left to the
#: numpy engine, or for another layout. The C function itself, as ``one``.
stack = rowcode.stack


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
    stream: bool | None = None,
) -> int:
    """Every row of ``I`` ``(6, N)`` or, with ``nine``, ``(9, N)`` row-major, and ``H`` ``(3, N)``,
    into ``w`` ``(N, 3)``, ``cond``, ``code`` (uint8), ``residual`` (written only with
    ``diagnostics``; else any length) and ``fallback`` (bool) ``(N,)``, which marks the rows
    left for the numpy engine; returns how many those are. Blocks of rows run on every core, the
    caller's thread taking one, each without the GIL; the bits do not depend on the blocks or the
    threads (rows are independent). ``stream`` (default: from :data:`STREAM_ROWS` rows) stores
    whole chunks past the caches where the outputs start on cache lines (as :data:`outputs`'
    do); the bits are the same either way."""
    n = H.shape[1]
    stream = n >= STREAM_ROWS if stream is None else stream
    args = (I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, stream)
    threads = _threads(n)
    if threads == 1:
        return rowcode.convert(*args, 0, n)
    # Every thread, the caller's too, takes the next block until none is left (blocks handed out
    # in advance left the caller one block and a single pool thread all the others), by the C
    # code, so that no thread comes back to Python between blocks (each return took the GIL,
    # which the other threads wanted too). Blocks are small enough, at most PARTS_PER_THREAD a
    # thread and a few chunks at least, that a thread which starts late or runs slow (a busy
    # machine) holds up the call by little. The pool's threads stay in C for LINGER after their
    # last block, and the caller returns once every row is done, not when they are back in
    # Python; a thread that has not begun when the rows are done takes none.
    size = -(-max(BLOCK_ROWS // 16, -(-n // (PARTS_PER_THREAD * threads))) // _CHUNK_ROWS) * _CHUNK_ROWS
    _servers.enlist(threads - 1)
    lost, _ = rowcode.share(*args, size)
    return lost


class _Servers:
    """The pool's threads in ``rowcode.serve``, each until no call has come for :data:`LINGER`:
    a call that shares its rows starts as many more as it wants beyond those still serving or
    about to (a thread of the pool already serving is not woken again)."""

    def __init__(self) -> None:
        self._running: list[Future[int]] = []
        self._pid = 0

    def enlist(self, threads: int) -> None:
        pool = _shared_pool(threads)
        if self._pid != os.getpid():  # a forked child has none of its parent's threads
            self._running, self._pid = [], os.getpid()
        running = [f for f in self._running if not f.done()]
        with contextlib.suppress(RuntimeError):  # the interpreter is shutting down: the caller converts alone
            running += [pool.submit(rowcode.serve, LINGER) for _ in range(threads - len(running))]
        self._running = running


_servers = _Servers()
