"""Ctrl-C and SIGTERM in the hconv command: exit 130 with one line and no output, or, once the
output is in place, no effect: never a traceback, never death by the signal. And :func:`held`,
which makes them wait while a few steps that must not be cut finish.

The command spends its first few tenths of a second importing numpy, typer and the rest. A
KeyboardInterrupt raised in there printed a traceback, or, inside numpy's import, an ImportError
and exit 1. Until a command's own code runs (``commandline.friendly``) nothing has been written and
nothing needs cleaning up, so the process can simply end; from then on the signals raise
KeyboardInterrupt again, so that a conversion removes its temporary file on the way out.

Once the command's own code runs, the rule is: the run either ends with its output in place and
its own exit code, or exits 130 having written nothing. So the first interrupt raises
KeyboardInterrupt and any later one is ignored while that unwinds (a second Ctrl-C cannot cut the
removal of a temporary file short); and once the output is committed the run is *settled*
(:func:`settle`, inside the :func:`held` block of the commit): an interrupt from then on is
ignored, so that a caller never sees 130 with OUT complete, then fails its retry on OUT existing.
At the very end (:func:`ending`) the signals are ignored outright: while the interpreter shuts
down it resets a Python handler to the default, under which a late signal would kill the process.

Only the hconv command (the console script or ``python -m hconv``) does this: a program that
imports hconv as a library keeps its own handlers. This module is the first thing hconv
imports, so it imports only what the interpreter has already loaded (``_signal`` rather than
``signal``, which imports enum; no typing).
"""

from __future__ import annotations

import _signal  # type: ignore[import-not-found]  # signal without its enum import
import _thread
import os
import sys

from hconv.errors import INTERRUPTED, INTERRUPTED_STREAMED

_MESSAGE = f"hconv: error: {INTERRUPTED}\n".encode()
#: The tests' handshake (:func:`point`): ``W:R``, file descriptors to announce on and to wait on.
_POINTS = os.environ.get("HCONV_TEST_POINTS")
_MAIN_THREAD = _thread.get_ident()  # hconv is imported on the main thread, where handlers run


#: The command's outcome is decided (:func:`settle`, or a first interrupt is unwinding): a
#: Ctrl-C or SIGTERM is then ignored by :func:`_interrupt`.
_settled = False
#: Whether committing the output settles the command (:func:`commit_settles`).
_commit_settles = False


#: Whether rows have gone straight to stdout, a pipe (hconv.tables.output): a run that stops
#: after that has written part of its output, and says so.
_streamed = False


def streamed() -> None:
    """Rows have gone into a pipe on stdout: from here an interrupt says its output is incomplete."""
    global _streamed, _MESSAGE
    if not _streamed:
        _streamed = True
        _MESSAGE = f"hconv: error: {INTERRUPTED_STREAMED}\n".encode()


def went_to_stdout() -> bool:
    """Whether rows have gone straight into a pipe on stdout (:func:`streamed`)."""
    return _streamed


def interrupted() -> str:
    """What an interrupted run says after ``hconv: error:``: whether rows went to stdout first."""
    return INTERRUPTED_STREAMED if _streamed else INTERRUPTED


def _end(signum: int, frame: object) -> None:
    if _settled:  # a usage error, its exit code decided before the command ran
        return
    os.write(2, _MESSAGE)
    os._exit(130)


def _interrupt(signum: int, frame: object) -> None:
    """The command's handler for Ctrl-C and SIGTERM while its own code runs: KeyboardInterrupt,
    once, unless the run is settled."""
    global _settled
    if _settled:
        return
    _settled = True
    raise KeyboardInterrupt


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


def hand_over() -> None:
    """A command's own code starts: Ctrl-C and SIGTERM raise KeyboardInterrupt (once), so that
    the run removes its temporary files on the way out."""
    global _settled, _commit_settles
    _settled = _commit_settles = False
    for s in (_signal.SIGINT, _signal.SIGTERM):
        if _signal.getsignal(s) is _end:
            _signal.signal(s, _interrupt)
    point("start")


def settle() -> None:
    """The command's outcome is decided (its output is committed, or it is failing): from here a
    Ctrl-C or SIGTERM is ignored. Call it inside the :func:`held` block that commits the output,
    so that an interrupt that arrived during the commit is dropped rather than raised after it.
    Outside the hconv command (a program using hconv) it changes nothing."""
    global _settled
    _settled = True


def commit_settles() -> None:
    """The output this command commits next is its last step: :func:`committed` then settles it."""
    global _commit_settles
    _commit_settles = True


def committed() -> None:
    """An output was committed (in a :func:`held` block): it settles the command if it was the
    command's last step (:func:`commit_settles`); a dataset's files, say, are not."""
    if _commit_settles:
        settle()


def ending() -> None:
    """The command ends, its exit code decided: ignore Ctrl-C and SIGTERM outright, since the
    interpreter resets a Python handler to the default while it shuts down."""
    point("exit")
    for s in (_signal.SIGINT, _signal.SIGTERM):
        if _signal.getsignal(s) in (_interrupt, _end):  # _end: a usage error, before the command ran
            _signal.signal(s, _signal.SIG_IGN)
    if _POINTS:
        import atexit

        atexit.register(point, "shutdown")


def point(name: str) -> None:
    """A named moment of a run, for tests that interrupt it there (tests/test_interrupts.py):
    with HCONV_TEST_POINTS=W:R set, the main thread writes ``name`` and a newline to descriptor W,
    then waits for a byte on R; a signal sent meanwhile lands at this moment. Otherwise nothing."""
    if _POINTS is None or _thread.get_ident() != _MAIN_THREAD:
        return
    w, r = (int(fd) for fd in _POINTS.split(":"))
    os.write(w, name.encode() + b"\n")
    os.read(r, 1)


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
