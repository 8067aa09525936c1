"""The numba engine: :mod:`hconv.solve.rows` compiled, its row loop shared between the cores.

Importing this module imports numba (about half a second), so it is imported only where the
compiled engine runs, after :func:`hconv.solve.engines.resolve` has chosen it. The row
code stays plain Python in :mod:`hconv.solve.rows`; here each of its functions is compiled with
its references to the others pointing at their compiled versions. Compiled code is cached on
disk (numba's ``cache=True``: beside the module, or in a user cache directory where that is
read-only), so only the first run on a machine compiles; docs/engines.md has the cold and warm
start as measured.
"""

from __future__ import annotations

import json
import os
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numba
import numpy as np

from hconv.solve import engines, rows


def _compile() -> dict[str, Any]:
    space = dict(vars(rows))
    space["prange"] = numba.prange
    for name in rows.COMPILED:
        f = getattr(rows, name)
        g = types.FunctionType(f.__code__, space, name, f.__defaults__, f.__closure__)
        g.__module__, g.__qualname__ = f.__module__, f.__qualname__
        # error_model="numpy": a division by zero gives inf or NaN, as in the numpy engine,
        # instead of raising; fastmath stays off, so every operation rounds as written.
        # The arithmetic is inlined where it is called (numba's inline="always"), so that a loop
        # over rows is one body the compiler can run several rows of at once.
        inline: Literal["always", "never"] = "always" if name in rows.INLINE else "never"
        space[name] = numba.njit(
            cache=True, nogil=True, error_model="numpy", parallel=name == "convert_rows", inline=inline
        )(g)
    return space


_convert_rows: Callable[..., Any] = _compile()["convert_rows"]
_marked = False
#: One parallel loop at a time: it already runs on every core, and numba's fallback threading
#: layer (workqueue, where neither OpenMP nor TBB is found) must not be entered from two threads,
#: as the file pipeline's batch threads would. The loop releases the GIL, so reading and writing
#: go on meanwhile.
_one_at_a_time = threading.Lock()


def convert_rows(*args: Any) -> None:
    """:func:`hconv.solve.rows.convert_rows`, compiled; its arguments."""
    with _one_at_a_time:
        _convert_rows(*args)


def mark() -> None:
    """Note, for :func:`hconv.solve.engines.compiled_ready`, that numba's cache now holds the row
    code: the marker lists the cache's index files, so that it stops counting once they go."""
    global _marked
    if _marked:
        return
    _marked = True
    path = engines.marker_path()
    cache = Path(_convert_rows.stats.cache_path)  # type: ignore[attr-defined]
    index = sorted(str(p) for p in cache.glob("rows.convert_rows-*.nbi"))
    if path.exists() or not index:  # no index: numba could not write its cache anywhere
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}")
        tmp.write_text(json.dumps({"index": index}))
        os.replace(tmp, path)
    except OSError:  # a read-only home: auto then keeps to numpy unless numba is asked for
        return
    engines.forget_ready()


def warm() -> tuple[float, bool]:
    """Compile (or load from numba's cache) the row code for the array layouts hconv passes it:
    column-major stacks from ``hconv.convert``, row-major blocks from tables. Returns the seconds
    taken and whether anything was compiled (False: all of it came from the cache)."""
    start = time.perf_counter()
    stats = _convert_rows.stats  # type: ignore[attr-defined]
    misses = sum(stats.cache_misses.values())
    n = 2
    I = np.tile(np.array([2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 4.0]), (n, 1))
    H = np.ones((n, 3))
    for I_k, H_k in ((I.T, H.T), (np.ascontiguousarray(I.T), np.ascontiguousarray(H.T))):
        outputs = (np.empty((n, 3)), np.empty(n), np.empty(n, np.uint8), np.empty(n), np.zeros(n, bool))
        convert_rows(I_k, True, H_k, False, True, np.inf, *outputs)
    mark()
    return time.perf_counter() - start, sum(stats.cache_misses.values()) > misses
