"""Ctrl-C and SIGTERM while the hconv command starts: exit 130 with one line, never a traceback;
and :func:`held`, which makes them wait while a few steps that must not be cut finish.

The command spends its first few tenths of a second importing numpy, typer and the rest. A
KeyboardInterrupt raised in there printed a traceback, or, inside numpy's import, an ImportError
and exit 1. Until a command's own code runs (``cli.friendly``) nothing has been written and
nothing needs cleaning up, so the process can simply end; from then on the signals raise
KeyboardInterrupt again, so that a conversion removes its temporary file on the way out.

Only the hconv command (the console script or ``python -m hconv``) does this: a program that
imports hconv as a library keeps its own handlers. This module is the first thing hconv
imports, so it imports only what the interpreter has already loaded (``_signal`` rather than
``signal``, which imports enum; no typing).
"""

from __future__ import annotations

import _signal  # type: ignore[import-not-found]  # signal without its enum import
import os
import sys

from hconv.errors import INTERRUPTED

TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Callable

_MESSAGE = f"hconv: error: {INTERRUPTED}\n".encode()


def _end(signum: int, frame: object) -> None:
    os.write(2, _MESSAGE)
    os._exit(130)


def _is_command() -> bool:
    argv = sys.argv
    if not argv:
        return False
    if argv[0] == "-m":  # python -m NAME ...: argv[0] is "-m" while the package NAME is imported
        orig = getattr(sys, "orig_argv", [])
        k = len(orig) - len(argv)
        return 0 <= k < len(orig) and orig[k].removeprefix("-m") == "hconv"
    return os.path.basename(argv[0]) in ("hconv", "hconv.exe")


def end_quietly_while_starting() -> None:
    """In the hconv command, make Ctrl-C and SIGTERM end the process at once, with one line and
    exit code 130; signals the caller ignores stay ignored."""
    if not _is_command():
        return
    if _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
        _signal.signal(_signal.SIGINT, _end)
    if _signal.getsignal(_signal.SIGTERM) == _signal.SIG_DFL:
        _signal.signal(_signal.SIGTERM, _end)


def starting() -> bool:
    """True while :func:`end_quietly_while_starting`'s handlers are in place."""
    return _signal.getsignal(_signal.SIGTERM) is _end or _signal.getsignal(_signal.SIGINT) is _end


def hand_over(on_sigterm: Callable[[int, object], None]) -> None:
    """A command's own code starts: Ctrl-C raises KeyboardInterrupt again, SIGTERM calls ``on_sigterm``."""
    if _signal.getsignal(_signal.SIGINT) is _end:
        _signal.signal(_signal.SIGINT, _signal.default_int_handler)
    if _signal.getsignal(_signal.SIGTERM) is _end:
        _signal.signal(_signal.SIGTERM, on_sigterm)


def held() -> Held:
    """``with held(): ...``: see :class:`Held`."""
    return Held()


class Held:
    """``with held(): ...``: a Ctrl-C or SIGTERM that arrives inside the block is acted on when the
    block ends (by the handler that was in place), so that the steps inside either all happen or
    none does: a dataset's output renamed into place and recorded for its manifest, say. Keep the
    block short: the interrupt waits for it. Outside the main thread, where no handler runs,
    it does nothing."""

    _SIGNALS = (_signal.SIGINT, _signal.SIGTERM)

    def __enter__(self) -> Held:
        self._caught: list[int] = []
        self._before: dict = {}
        try:
            for s in self._SIGNALS:
                self._before[s] = _signal.signal(s, self._catch)
        except ValueError:  # not the main thread
            self._before.clear()
        return self

    def _catch(self, signum: int, frame: object) -> None:
        self._caught.append(signum)

    def __exit__(self, *exc: object) -> None:
        for s, handler in self._before.items():
            _signal.signal(s, handler)
        if self._caught:
            signum = self._caught[0]
            handler = self._before[signum]
            if callable(handler):  # Python's default for SIGINT raises KeyboardInterrupt; hconv's SIGTERM too
                handler(signum, None)
            elif handler == _signal.SIG_DFL:
                os.kill(os.getpid(), signum)
