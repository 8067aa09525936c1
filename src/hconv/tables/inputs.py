"""An open input (:class:`Input`: its schema, batches, plan and progress), what tells that its
file changed while it was read (:func:`changed_while_read`), and the message for a file that cannot be
opened. The readers (:mod:`hconv.tables.csvio`, :mod:`hconv.tables.parquetio`) make Inputs;
:func:`hconv.tables.tableio.open_input` picks the reader."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import pyarrow as pa

from hconv.errors import InputError
from hconv.tables import layout


@dataclass
class Input:
    """An open input: its schema, its batches, and how far reading has got (for progress)."""

    name: str
    schema: pa.Schema
    batches: Iterator[pa.RecordBatch]
    total: int | None  #: rows (Parquet) or bytes (CSV); None if unknown
    position: Callable[[], int]  #: rows or bytes read so far
    plan: layout.Layout  #: the input's column sets, planned for the Job
    _closers: list = field(default_factory=list)
    #: CSV: the columns hconv does not use, read as text (Parquet: none); see hconv.tables.csvtypes
    text: tuple = ()
    path: str = ""  #: the file read (for stdin, its spooled copy, which lives as long as this Input)
    first_row: int = 0  #: the file's row that :attr:`batches` starts at (a part of the file: ``rows``)

    def close(self) -> None:
        for c in reversed(self._closers):
            c()
        self._closers.clear()

    def __enter__(self) -> Input:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def unreadable(name: str, exc: OSError) -> InputError:
    return InputError(f"{name}: cannot read it ({exc.strerror or exc}); check the path and its permissions")


@dataclass(frozen=True)
class FileStat:
    """What tells that a file changed while it was read: its size and modification time, as its
    open descriptor sees them (a file replaced by a rename keeps the one being read unchanged)."""

    size: int
    mtime_ns: int

    @staticmethod
    def of(fd: int) -> FileStat:
        st = os.fstat(fd)
        return FileStat(st.st_size, st.st_mtime_ns)


def changed_while_read(name: str, fd: int | None, at_open: FileStat | None, why: str = "") -> InputError | None:
    """InputError if the file open as ``fd`` is no longer as it was when opened (``at_open``):
    rewritten, cut or appended to while hconv read it, so that what was read mixes two versions."""
    if fd is None or at_open is None:
        return None
    try:
        now = FileStat.of(fd)
    except OSError:
        return None
    if now == at_open:
        return None
    return InputError(
        f"{name}: changed while hconv read it (from {at_open.size} to {now.size} bytes{why}); nothing was "
        "written: run again once whatever writes it has finished"
    )
