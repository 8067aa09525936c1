"""Engines: which code converts a batch of rows, and the rule ``auto`` picks by.

=======  ==========================================================================================
numpy    the vectorised converter (:mod:`hconv.solve.convert`): every method, form, precision and
         mode; always there, no compiler; the reference the others are tested against
numba    :mod:`hconv.solve.rows` compiled by numba (the ``hconv[fast]`` extra), one fused pass
         per row on both cores; computes ``exact`` and ``refined`` on six- and nine-number tensors
         in float64 with ``--degenerate error``; any other run is the numpy engine's, and rows
         outside its common case (not finite, not symmetric, not positive definite, ...) are
         handed to the numpy engine row by row
python   the same row code, interpreted: no numpy call per row, so the cheapest for one body;
         same scope as numba
auto     ``python`` for a single row; ``numba`` when it is installed and the batch has at least
         :data:`AUTO_MIN_ROWS` rows (or the compiled engine is already loaded, so that it costs
         nothing to start); otherwise ``numpy``. The environment variable ``HCONV_ENGINE``
         (numpy, numba or python) makes every ``auto`` that engine, for every size: the test
         suite runs once per engine this way
=======  ==========================================================================================

The answers agree: bit for bit for ``exact``'s ω, ``cond`` and every status; ``refined``'s ω and
the ``residual`` may differ in the last bits (docs/engines.md says by how much, and why).
"""

from __future__ import annotations

import importlib.util
import os
import sys

from hconv.errors import UsageError
from hconv.solve import rows
from hconv.solve.options import check_choice

#: --engine.
ENGINES = ("auto", "numpy", "numba", "python")
#: The fewest rows for which auto loads numba (import and cached code: about 0.3 s the first time
#: in a process, docs/engines.md); below this the numpy engine finishes first.
AUTO_MIN_ROWS = 200_000
_COMPILED = "hconv.solve.compiled"


def numba_installed() -> bool:
    """True when numba can be imported (without importing it)."""
    return importlib.util.find_spec("numba") is not None


def covers(method: str, precision: int, degenerate: str, diagonal: bool) -> bool:
    """True when the row engines compute this run themselves (the rest is the numpy engine's)."""
    return method in rows.METHODS and precision == 64 and degenerate == "error" and not diagonal


def check_engine(engine: str) -> None:
    check_choice("--engine", engine, ENGINES)


def _from_environment() -> str:
    """What ``auto`` means here: HCONV_ENGINE's engine when it is set, else ``auto``."""
    value = os.environ.get("HCONV_ENGINE")
    if not value:
        return "auto"
    if value not in ENGINES:
        raise UsageError(f"HCONV_ENGINE must be one of {', '.join(ENGINES)}, got {value!r}; unset it for auto")
    return value


def resolve(engine: str, n: int, method: str, precision: int, degenerate: str, diagonal: bool) -> str:
    """The engine that converts ``n`` rows: ``"numpy"``, ``"numba"`` or ``"python"``.

    An explicit ``numba`` without numba installed is a UsageError with the fix; a run the row
    engines do not cover goes to numpy whatever was asked (the Result's ``engine`` says so).
    """
    check_engine(engine)
    if engine == "auto":
        engine = _from_environment()
    if engine == "numba" and not numba_installed():
        raise UsageError("--engine numba needs numba: pip install 'hconv[fast]' (or use --engine auto)")
    if engine == "numpy" or not covers(method, precision, degenerate, diagonal):
        return "numpy"
    if engine != "auto":
        return engine
    if n == 1:
        return "python"
    if _COMPILED in sys.modules or (n >= AUTO_MIN_ROWS and numba_installed()):
        return "numba"
    return "numpy"
