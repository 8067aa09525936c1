"""Opening a table to read it, batch by batch: a file, a pipe or stdin ("-"), as CSV, Parquet,
Arrow IPC or JSON lines.

Reading never holds more than a batch in memory (stdin, or a pipe given by name, is first
spooled to a temporary file, since Parquet needs to seek). The readers are
:mod:`hconv.tables.csvio`, :mod:`hconv.tables.parquetio`, :mod:`hconv.tables.ipcio` and
:mod:`hconv.tables.jsonio`; telling the format,
:mod:`hconv.tables.sniff`; writing, :mod:`hconv.tables.output`.

Whatever pyarrow raises while reading is the input's (InputError, naming the file, and for
Parquet the row group), and a file that changes while it is read is refused; pyarrow is given
native files only (see :func:`hconv.tables.csvio.open_csv`).
"""

from __future__ import annotations

import os
import sys
from typing import BinaryIO

from hconv.errors import InputError, OutputError, UsageError
from hconv.tables.csvio import open_csv
from hconv.tables.inputs import Input, unreadable
from hconv.tables.ipcio import open_ipc
from hconv.tables.job import Job
from hconv.tables.jsonio import open_jsonl
from hconv.tables.parquetio import open_parquet
from hconv.tables.sniff import input_kind
from hconv.tables.temporaries import temporary_file


def open_input(
    path: str,
    fmt: str,
    job: Job,
    name: str | None = None,
    rows: tuple[int, int] | None = None,
    whole: bool = False,
) -> Input:
    """Open ``path`` ("-" for stdin) as ``fmt``, planned for ``job`` (:func:`hconv.tables.layout.plan`);
    InputError with a fix if it can't be. Stdin, or a pipe given by name, is spooled first.
    ``name``: what messages call the input (default: ``path``), such as the URI of an object
    that was fetched into ``path``. ``rows``: (start, stop), only those rows of a Parquet file
    (:func:`open_parquet`). ``whole``: a small file, read at once (Parquet: :func:`open_parquet`)."""
    closers = []
    name = name or path
    if path == "-":
        name = "stdin"
        if sys.stdin is None or sys.stdin.isatty():
            raise UsageError(
                "input is '-' but stdin is a terminal; pipe a file in, "
                "e.g. `cat in.csv | hconv convert - out.csv --from csv`"
            )
        spooled = spool(sys.stdin.buffer, name)
        closers.append(lambda: os.unlink(spooled))
        path = spooled
    elif input_kind(path) == "pipe":
        try:
            stream = open(path, "rb")  # noqa: SIM115 - closed by the with below, once spooled
        except OSError as exc:
            raise unreadable(name, exc) from None
        with stream:
            if stream.isatty():
                raise UsageError(f"input {name} is a terminal; give a file, or pipe one in")
            spooled = spool(stream, name)
        closers.append(lambda: os.unlink(spooled))
        path = spooled
    try:
        if rows is not None and fmt != "parquet":
            raise ValueError("rows is for Parquet input")
        if fmt == "parquet":
            inp = open_parquet(path, name, job, rows, whole)
        else:
            inp = {"csv": open_csv, "arrow": open_ipc, "jsonl": open_jsonl}[fmt](path, name, job)
    except BaseException:
        for c in closers:
            c()
        raise
    inp._closers[:0] = closers
    return inp


def spool(stream: BinaryIO, name: str) -> str:
    """Copy ``stream`` (stdin, or a pipe) into a temporary file and return its path; the caller
    removes it.

    Reading stdin can take as long as whatever feeds it, so this is where Ctrl-C and SIGTERM
    (raised as KeyboardInterrupt) usually land: any way out but success removes the file.
    """
    fd, spooled = temporary_file("hconv-stdin-")
    try:
        try:
            with os.fdopen(fd, "wb") as f:
                while chunk := _read_chunk(stream, name):
                    f.write(chunk)
        except OSError as exc:  # reading fails as InputError, so this is the temporary directory
            raise OutputError(
                f"{name}: could not be copied to a temporary file in {os.path.dirname(spooled)!r} "
                f"({exc.strerror or exc}); set TMPDIR to a directory with room, or give a file instead of '-'"
            ) from None
    except BaseException:
        os.unlink(spooled)
        raise
    return spooled


def _read_chunk(stream: BinaryIO, name: str) -> bytes:
    try:
        return stream.read(1 << 20)
    except OSError as exc:
        raise InputError(f"{name}: cannot read it ({exc.strerror or exc})") from None
