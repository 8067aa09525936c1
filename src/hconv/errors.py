"""Errors that end a run, each with a one-line message that names the file or column and the fix.

Exit codes (the CLI's contract): 0 success, even when some rows carry non-ok statuses; 1 an
internal error; 2 a usage error; 3 an input that cannot be read; 4 an output that cannot be
written; 5 rows that are not ok under ``--strict``; 130 interrupted (Ctrl-C or SIGTERM).
"""

from __future__ import annotations

#: What an interrupted run says after ``hconv: error:``, wherever the interrupt lands.
INTERRUPTED = "interrupted; no output was written"


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
