"""Engines: which code converts a batch of rows, and the rule ``auto`` picks by.

=======  ==========================================================================================
numpy    the vectorised converter (:mod:`hconv.solve.convert`): every method, form, precision and
         mode; always there, no compiler; the reference the others are tested against
numba    :mod:`hconv.solve.rows` compiled by numba (the ``hconv[fast]`` extra), one fused pass
         per row on both cores; computes the methods registered with ``row_engine`` (``exact``
         and ``refined``) on six- and nine-number tensors in float64 with ``--degenerate
         error``; any other run is the numpy engine's, and rows outside its common case (not
         finite, not symmetric, not positive definite, ...) are handed to the numpy engine row
         by row
python   the same row code, interpreted: no numpy call per row, so the cheapest for one body;
         same scope as numba
auto     ``numba`` once it is loaded in the process; before that, ``python`` for a single row, and
         ``numba`` when it is installed, its code is compiled (in
         numba's cache, :func:`compiled_ready`) and the work pays for loading it: a batch of at
         least :data:`AUTO_MIN_ROWS` rows, or a process that has already spent
         :data:`START_COST` seconds in the numpy engine on work numba covers (many small calls),
         or numba already loaded. Otherwise ``numpy``. auto never compiles: that takes seconds
         once per machine (``hconv engines --compile``, or any run with ``--engine numba``).
         For a file conversion (``hconv convert``), auto means numpy: see :func:`for_files`.
         The environment variable ``HCONV_ENGINE`` (numpy, numba or python) makes every
         ``auto`` that engine, for every size: the test suite runs once per engine this way
=======  ==========================================================================================

The answers agree: bit for bit for ``exact``'s ω, ``cond`` and every status; ``refined``'s ω and
the ``residual`` may differ in the last bits (docs/engines.md says by how much, and why).
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

from hconv.errors import UsageError, option
from hconv.solve import methods, rows
from hconv.solve.options import check_choice

#: --engine.
ENGINES = ("auto", "numpy", "numba", "python")
#: A batch this large loads the compiled engine at once: the numpy engine would spend longer on
#: it than numba takes to start from its cache (docs/engines.md).
AUTO_MIN_ROWS = 200_000
#: Seconds of numpy-engine time on covered work after which auto loads numba: about what loading
#: it costs, so that many small calls pay at most twice the best choice (rent or buy).
START_COST = 0.5
_COMPILED = "hconv.solve.compiled"
NUMBA_FIX = "pip install 'hconv[fast]'"

_spent = 0.0
_ready: bool | None = None


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def numba_installed() -> bool:
    """True when numba can be imported (without importing it)."""
    return importlib.util.find_spec("numba") is not None


def covers(
    method: methods.Method, precision: int, degenerate: str, form: str, degenerate_rtol: float | None = None
) -> bool:
    """True when the row engines compute this run themselves (the rest is the numpy engine's):
    their methods (registered with ``row_engine``) and inertia forms
    (:data:`hconv.solve.rows.FORMS`), float64, ``--degenerate error`` with its default threshold."""
    return (
        method.row_engine
        and form in rows.FORMS
        and precision == 64
        and degenerate == "error"
        and degenerate_rtol is None
    )


def scope_text() -> str:
    """What the row engines (numba, python) compute themselves, for a reader who asked for one."""
    covered = [m.name for m in methods.METHODS.values() if m.row_engine]
    return (
        f"--method {' or '.join(covered)} on {' or '.join(rows.FORMS)} tensors, --precision 64, "
        "--degenerate error at its default threshold"
    )


def check_engine(engine: str) -> None:
    """The choice, and numba installed when it is asked for by name."""
    check_choice("engine", engine, ENGINES)
    if engine == "numba" and not numba_installed():
        raise UsageError(f"{option('engine', 'numba')} needs numba: {NUMBA_FIX} (or use {option('engine', 'auto')})")


def spend(seconds: float) -> None:
    """Count numpy-engine time on work the compiled engine covers (the rent in auto's rule)."""
    global _spent
    _spent += seconds


def marker_path() -> Path:
    """Where hconv notes that numba has compiled this very row code: one file per copy of hconv's
    row code (its text and its place), numba and Python, in the user's cache directory."""
    import hashlib  # here, not at the top: `hconv one` never needs them (30 ms)
    import importlib.metadata

    here = Path(rows.__file__).resolve()
    source = here.read_bytes()
    numba_version = importlib.metadata.version("numba") if numba_installed() else "none"
    # the file's place too: numba caches beside each copy of the source, so another checkout or
    # environment with the same rows.py has compiled nothing for this one
    key = hashlib.sha256(source + f"{here} {numba_version} {sys.version}".encode()).hexdigest()[:16]
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "hconv" / f"compiled-{key}.json"


def compiled_ready() -> bool:
    """True when numba's cache holds the compiled row code (loading it then takes a fraction of a
    second, compiling it several seconds): the marker :mod:`hconv.solve.compiled` writes, whose
    cache files still exist."""
    global _ready
    import json

    if _ready is None:
        try:
            files = json.loads(marker_path().read_text())["index"]
            _ready = bool(files) and all(Path(f).exists() for f in files)
        except (OSError, ValueError, KeyError, TypeError):
            _ready = False
    return _ready


def forget_ready() -> None:
    """Look at the marker again next time (after a compile)."""
    global _ready
    _ready = None


def _from_environment() -> str:
    """What ``auto`` means here: HCONV_ENGINE's engine when it is set, else ``auto``."""
    value = os.environ.get("HCONV_ENGINE")
    if not value:
        return "auto"
    if value not in ENGINES:
        raise UsageError(f"HCONV_ENGINE must be one of {', '.join(ENGINES)}, got {value!r}; unset it for auto")
    return value


def for_files(engine: str) -> str:
    """The engine a file conversion runs: auto there means numpy, unless HCONV_ENGINE says
    otherwise. Reading, the Arrow work and writing take most of a file's time on both cores, and
    the compiled engine would save less than it costs to load, and a core from that overlap
    (docs/engines.md: 2M rows 1.9 s numpy, 2.6 s numba; 20M rows 22 s and 28 s)."""
    if engine != "auto":
        return engine
    chosen = _from_environment()
    return "numpy" if chosen == "auto" else chosen


def resolve(
    engine: str,
    n: int,
    method: methods.Method,
    precision: int,
    degenerate: str,
    form: str,
    degenerate_rtol: float | None = None,
) -> str:
    """The engine that converts ``n`` rows: ``"numpy"``, ``"numba"`` or ``"python"``.

    An explicit ``numba`` without numba installed is a UsageError with the fix; a run the row
    engines do not cover goes to numpy whatever was asked (the Result's ``engine`` says so).
    """
    if engine == "auto":
        engine = _from_environment()
        if engine == "numba" and not numba_installed():
            raise UsageError(f"HCONV_ENGINE=numba needs numba: {NUMBA_FIX} (or unset HCONV_ENGINE)")
    check_engine(engine)
    if engine == "numpy" or not covers(method, precision, degenerate, form, degenerate_rtol):
        return "numpy"
    if engine != "auto":
        return engine
    if _COMPILED in sys.modules:  # loaded already: the fastest at every size, one body included
        return "numba"
    if n == 1:
        return "python"
    if (n >= AUTO_MIN_ROWS or _spent >= START_COST) and numba_installed() and compiled_ready():
        return "numba"
    return "numpy"


def listing() -> list[tuple[str, ...]]:
    """The engines as ``hconv engines`` lists them: ``(name, what it covers, its state, ...)``,
    paragraphs to wrap (a no-break space keeps a number with its unit)."""
    installed = numba_installed()
    ready = installed and compiled_ready()
    numba_state = "not installed: " + NUMBA_FIX
    if installed:
        numba_state = "installed, compiled" if ready else "installed, not compiled: run hconv engines --compile"
    auto = (
        f"python for one body; numba for {AUTO_MIN_ROWS:,}+ rows once compiled, or after "
        f"{START_COST}\xa0s of numpy time; else numpy. Files: numpy"
    )
    forced = os.environ.get("HCONV_ENGINE")
    return [
        ("numpy", "every method and option; always there (the reference)"),
        ("numba", "exact and refined on tensors, in float64, on every core", numba_state),
        ("python", "the numba engine's code, interpreted: one body at a time"),
        ("auto", auto, *([f"HCONV_ENGINE={forced}: every auto is {forced}"] if forced else [])),
    ]
