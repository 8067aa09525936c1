"""The numba engine: :mod:`hconv.solve.rows` compiled, its row loop shared between the cores.

Importing this module imports numba (about half a second), so only
:func:`hconv.solve.engines.resolve` does, and only when the compiled engine will run. The row
code stays plain Python in :mod:`hconv.solve.rows`; here each of its functions is compiled with
its references to the others pointing at their compiled versions. Compiled code is cached on
disk (numba's ``cache=True``: beside the module, or in a user cache directory where that is
read-only), so only the first run on a machine compiles; docs/engines.md has the cold and warm
start as measured.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

import numba

from hconv.solve import rows

#: The functions of rows that are compiled; convert_rows last, as the one with the parallel loop.
_COMPILED = (
    "sym_of_nine",
    "ldlt",
    "ldlt_solve",
    "largest_root",
    "_safe",
    "_split",
    "_dot_row",
    "refine_step",
    "refine_on",
    "refine",
    "relative_error",
    "numbers",
    "decide",
    "convert_one",
    "_numbers_chunk",
    "_step_chunk",
    "convert_rows",
)


_LOOPS = ("_numbers_chunk", "_step_chunk", "convert_rows", "convert_one")


def _compile() -> dict[str, Any]:
    space = dict(vars(rows))
    space["prange"] = numba.prange
    for name in _COMPILED:
        f = getattr(rows, name)
        g = types.FunctionType(f.__code__, space, name, f.__defaults__, f.__closure__)
        g.__module__, g.__qualname__ = f.__module__, f.__qualname__
        # error_model="numpy": a division by zero gives inf or NaN, as in the numpy engine,
        # instead of raising; fastmath stays off, so every operation rounds as written.
        # The helpers are inlined where they are called (numba's inline="always"), so that a loop
        # over rows is one body the compiler can run several rows of at once.
        loop = name in _LOOPS
        space[name] = numba.njit(
            cache=True,
            nogil=True,
            error_model="numpy",
            parallel=name == "convert_rows",
            inline="never" if loop else "always",
        )(g)
    return space


convert_rows: Callable[..., None] = _compile()["convert_rows"]
