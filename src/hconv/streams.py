"""The command's standard streams, made to fail the way the exit codes promise.

A command started with stdout or stderr closed (``>&-``, ``2>&-``) finds ``sys.stdout`` or
``sys.stderr`` None, and one whose stream is full (``> /dev/full``) gets an OSError that names no
file. Within :func:`standard_streams`:

* stdout names itself: a failed write is an OSError whose filename is ``stdout`` (exit 4 naming
  it), and a closed stdout fails the first write the same way; a reader that went away is still
  BrokenPipeError, which the command takes as the reader's choice;
* stderr never fails the run: what cannot be written there (closed, full) is dropped, so the exit
  code is the run's, and an output already in place stays.
"""

from __future__ import annotations

import errno
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from typing import Any


class _Named:
    """A text stream whose failed writes are OSErrors naming ``name``."""

    def __init__(self, stream: Any, name: str) -> None:
        self._stream, self._name = stream, name

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror or str(exc), self._name) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror or str(exc), self._name) from None

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._stream, attr)


class _Closed:
    """What stdout is when the command started with it closed: every write fails, named."""

    def __init__(self, name: str) -> None:
        self.name = name

    def _fail(self, *_: object) -> Any:
        raise OSError(errno.EBADF, "it was closed when hconv started", self.name)

    write = fileno = _fail

    @property
    def buffer(self) -> _Closed:  # binary writes fail alike
        return self

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


class _Forgiving:
    """A text stream whose failed writes are dropped: diagnostics must not change the exit code."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except (OSError, ValueError):  # ValueError: written after the stream was closed
            return len(text)

    def flush(self) -> None:
        with suppress(OSError, ValueError):
            self._stream.flush()

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._stream, attr)


@contextmanager
def standard_streams() -> Iterator[None]:
    """Within this block, stdout and stderr behave as the module's docstring says."""
    out, err = sys.stdout, sys.stderr
    sink = None
    if err is None:
        sink = open(os.devnull, "w")  # noqa: SIM115 - closed below, after the streams are restored
    sys.stdout = _Closed("stdout") if out is None else _Named(out, "stdout")
    sys.stderr = _Forgiving(sink if err is None else err)
    try:
        yield
    finally:
        sys.stdout, sys.stderr = out, err
        if sink is not None:
            sink.close()
