"""Errors that end a run, each with a one-line message that names the file or column and the fix.

Exit codes (the CLI's contract): 0 success, even when some rows carry non-ok statuses; 1 an
internal error; 2 a usage error; 3 an input that cannot be read; 4 an output that cannot be
written; 5 rows that are not ok under ``--strict``; 130 interrupted (Ctrl-C or SIGTERM).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

#: Who reads the messages: Python callers, who pass keywords (``degenerate_rtol=0.5``), or the
#: command line, whose options are the keywords with dashes (``--degenerate-rtol 0.5``). The CLI
#: switches to its spelling for the length of a command (:func:`command_line`). A module global,
#: not a context variable, so that a message made in a worker thread is spelled the same.
_reader = "python"
#: Python keywords whose command-line option is not the keyword with dashes.
FLAGS = {"mapping": "--map", "unit_options": "--unit", "src_format": "--from", "dst_format": "--to"}
_UNSET = object()


@contextmanager
def command_line() -> Iterator[None]:
    """Within this block, messages name options as the command line spells them."""
    global _reader
    before, _reader = _reader, "cli"
    try:
        yield
    finally:
        _reader = before


def on_command_line() -> bool:
    """Whether messages are for the command line (:func:`command_line`) rather than Python."""
    return _reader == "cli"


def option(name: str, value: object = _UNSET) -> str:
    """Option ``name`` (its Python keyword), with ``value`` if given, as the reader spells it:
    ``--omega-unit deg/s`` on the command line, ``omega_unit='deg/s'`` in Python; a switch given
    True is the flag alone (``--force``, ``force=True``)."""
    if _reader == "cli":
        flag = FLAGS.get(name, "--" + name.replace("_", "-"))
        return flag if value is _UNSET or value is True else f"{flag} {value}"
    return name if value is _UNSET else f"{name}={value!r}"


def entry(name: str, key: str, value: str) -> str:
    """One entry of a mapping option: ``--map Hx=Lx`` on the command line, ``mapping={'Hx': 'Lx'}``
    in Python."""
    return entries(name, {key: value})


def entries(name: str, pairs: dict[str, str]) -> str:
    """Entries of a mapping option: ``--map Hx=Lx,Hy=Ly`` on the command line,
    ``mapping={'Hx': 'Lx', 'Hy': 'Ly'}`` in Python."""
    if _reader == "cli":
        return f"{option(name)} " + ",".join(f"{k}={clip(str(v), ECHOED)}" for k, v in pairs.items())
    return f"{name}={clip(repr(pairs), ECHOED)}"


#: What an interrupted run says after ``hconv: error:``, wherever the interrupt lands.
INTERRUPTED = "interrupted; no output was written"
#: The same, once rows have gone straight into a pipe on stdout (hconv.interrupts.streamed).
INTERRUPTED_STREAMED = "interrupted; the rows before it went to stdout, so what its reader got is incomplete"


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name if it has none), for a one-line error."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


#: The most characters of a value from a file that a message quotes (:func:`quoted`): a value can
#: be megabytes long, and a message is one line a terminal shows whole.
QUOTED = 40
#: The most characters of an entry of a mapping option (:func:`entries`: ``--unit``, ``--map``) or
#: of a unit that a message echoes: the user typed it, so more of it is shown than of a file's
#: value, but a pasted page is not echoed whole. :func:`option` echoes its value whole: messages
#: also use it to spell a fix to copy (a path for ``--root``).
ECHOED = 80


def clip(text: str, limit: int = QUOTED) -> str:
    """``text`` whole if it has at most ``limit`` characters, else its start and its end either
    side of "…", in ``limit`` characters."""
    if len(text) <= limit:
        return text
    tail = (limit - 1) // 3
    return f"{text[: limit - 1 - tail]}…{text[len(text) - tail :]}"


def quoted(value: str, limit: int = QUOTED) -> str:
    """A value from a file as a message quotes it: in quotes, escaped (so that it stays on one
    line), and :func:`clip`-ped to ``limit`` characters."""
    return repr(clip(value, limit))


class HconvError(Exception):
    """Base class; ``exit_code`` is what the CLI exits with."""

    exit_code = 1


class UsageError(HconvError, ValueError):
    exit_code = 2


class InputError(HconvError, ValueError):
    exit_code = 3


class OutputError(HconvError, OSError):
    exit_code = 4


class StrictError(HconvError):
    """``--strict``: a row's status is not ok; the message names the first few such rows."""

    exit_code = 5
