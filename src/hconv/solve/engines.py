"""Engines: which code converts a batch of rows, and the rule ``auto`` picks by.

========  =========================================================================================
compiled  hconv's row code in C (:mod:`hconv.solve.compiled`, built when hconv is installed), one
          fused pass per row on every core; computes the methods registered with ``row_engine``
          (``exact`` and ``refined``) on six- and nine-number tensors (:data:`FORMS`) in float64
          with ``--degenerate error``; any other run is the numpy engine's, and rows outside its
          common case (not finite, not symmetric, not positive definite, ...) are handed to the
          numpy engine row by row
numpy     the vectorised converter (:mod:`hconv.solve.blocks`): every method, form, precision and
          mode; the reference the compiled engine is tested against
auto      the default: ``compiled`` for every run it covers, at every size, files included;
          ``numpy`` for the rest. The environment
          variable ``HCONV_ENGINE`` (numpy or compiled) makes every ``auto`` that engine: the
          test suite runs once per engine this way
========  =========================================================================================

The answers agree: bit for bit for ``exact``'s ω, ``cond`` and every status; ``refined``'s ω and
the ``residual`` may differ in the last bits (docs/engines.md says by how much, and why).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

from hconv.errors import UsageError, option
from hconv.solve import methods
from hconv.solve.options import check_choice

#: --engine.
ENGINES = ("auto", "numpy", "compiled")
#: Engines hconv once had: asked for by name, a one-line UsageError naming what replaced them.
GONE = {"numba": "compiled", "python": "compiled"}
#: The inertia forms the compiled engine reads, each with whether its numbers are nine row-major
#: (else the six). Its methods are those registered with ``row_engine`` (hconv.solve.methods).
FORMS = {"sym6": False, "full9": True}


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


class SharedPool:
    """One thread pool for the process, for one kind of work (``name`` prefixes its threads'
    names): started by the first call that needs it (a pool per call would start threads every
    time), again with more threads when a call needs more, and again in a process forked from it
    (a multiprocessing or Dask worker), which inherits the pool but not its threads."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._pool: ThreadPoolExecutor | None = None
        self._threads = 0
        self._pid = 0
        self._lock = threading.Lock()

    def __call__(self, threads: int) -> ThreadPoolExecutor:
        """The pool, with ``threads`` threads at least."""
        with self._lock:
            if self._pool is None or self._threads < threads or self._pid != os.getpid():
                self._pool = ThreadPoolExecutor(threads, thread_name_prefix=self._name)
                self._threads, self._pid = threads, os.getpid()
            return self._pool


def covers(
    method: methods.Method, precision: int, degenerate: str, form: str, degenerate_rtol: float | None = None
) -> bool:
    """True when the compiled engine computes this run itself (the rest is the numpy engine's):
    its methods (registered with ``row_engine``) and inertia forms (:data:`FORMS`), float64,
    ``--degenerate error`` with its default threshold."""
    return method.row_engine and form in FORMS and precision == 64 and degenerate == "error" and degenerate_rtol is None


def scope_text() -> str:
    """What the compiled engine computes itself, for a reader who asked for it."""
    covered = [m.name for m in methods.METHODS.values() if m.row_engine]
    return (
        f"--method {' or '.join(covered)} on {' or '.join(FORMS)} tensors, --precision 64, "
        "--degenerate error at its default threshold"
    )


def check_engine(engine: str) -> None:
    """One of :data:`ENGINES`; an engine hconv no longer has is refused naming its successor."""
    if engine in GONE:
        raise UsageError(
            f"{option('engine', engine)} is gone: the compiled engine is built into hconv now; "
            f"use {option('engine', GONE[engine])} (or {option('engine', 'auto')})"
        )
    check_choice("engine", engine, ENGINES)


_KEY = os.environ.encodekey("HCONV_ENGINE")


def forced() -> str | None:
    """HCONV_ENGINE's value, None when it is not set. Looked up in os.environ's own mapping first:
    ``os.environ.get`` of a name that is not set raises and catches a KeyError inside, which cost
    a third of a one-body ``hconv.convert`` (1.5 µs of 5)."""
    if _KEY not in os.environ._data:  # type: ignore[attr-defined]  # os._Environ's mapping
        return None
    return os.environ.get("HCONV_ENGINE")


def _from_environment() -> str:
    """What ``auto`` means here: HCONV_ENGINE's engine when it is set, else ``auto``."""
    value = forced()
    if not value:
        return "auto"
    if value in GONE:  # scripts and CI configurations written for the engines hconv had
        raise UsageError(
            f"HCONV_ENGINE={value} is gone: the compiled engine is built into hconv now; "
            f"use HCONV_ENGINE={GONE[value]} (or unset it for auto)"
        )
    if value not in ENGINES:
        raise UsageError(f"HCONV_ENGINE must be one of {', '.join(ENGINES)}, got {value!r}; unset it for auto")
    return value


def resolve_environment() -> str:
    """What ``auto`` resolves to for a run the compiled engine covers: ``compiled``, unless
    HCONV_ENGINE says otherwise."""
    chosen = _from_environment()
    return "compiled" if chosen == "auto" else chosen


def resolve(
    engine: str,
    n: int,
    method: methods.Method,
    precision: int,
    degenerate: str,
    form: str,
    degenerate_rtol: float | None = None,
) -> str:
    """The engine that converts ``n`` rows: ``"numpy"`` or ``"compiled"``. A run the compiled
    engine does not cover goes to numpy whatever was asked (the Result's ``engine`` says so)."""
    if engine == "auto":
        engine = _from_environment()
    check_engine(engine)
    if engine == "numpy" or not covers(method, precision, degenerate, form, degenerate_rtol):
        return "numpy"
    return "compiled"


def listing() -> list[tuple[str, ...]]:
    """The engines as ``hconv engines`` lists them: ``(name, what it covers, its state, ...)``,
    paragraphs to wrap."""
    forced = os.environ.get("HCONV_ENGINE")
    return [
        ("compiled", "exact and refined on tensors, in float64, on every core", "built in"),
        ("numpy", "every method and option; always there (the reference)"),
        (
            "auto",
            "compiled for every run it covers (one body, arrays and files); else numpy",
            *([f"HCONV_ENGINE={forced}: every auto is {forced}"] if forced else []),
        ),
    ]
