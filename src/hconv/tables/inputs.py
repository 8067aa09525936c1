"""An open input (:class:`Input`: its schema, batches, plan and progress), what tells that its
file changed while it was read (:func:`changed_while_read`), the loop every reader takes its
batches by (:func:`read_batches`), and the message for a file that cannot be opened. The readers
(:mod:`hconv.tables.csvio`, :mod:`hconv.tables.parquetio`, :mod:`hconv.tables.ipcio`,
:mod:`hconv.tables.jsonio`) make Inputs; :func:`hconv.tables.tableio.open_input` picks the reader."""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pyarrow as pa

from hconv.errors import InputError, first_line
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
    #: CSV: how the file is written (:class:`hconv.tables.sniff.Dialect`); None for Parquet
    dialect: Any = None
    #: CSV: where in the file each batch read ends (:class:`ReadMarks`); None: :attr:`position` says
    marks: ReadMarks | None = None

    def reached(self, rows: int) -> int:
        """How far into the input (bytes or rows, as :attr:`total`) the first ``rows`` rows of
        :attr:`batches` go, for progress shown as the rows converted, not as the reader's position
        (which runs ahead of them). Called with ``rows`` that never decrease."""
        return self.marks.reached(rows) if self.marks is not None else self.position()

    def close(self) -> None:
        for c in reversed(self._closers):
            c()
        self._closers.clear()

    def __enter__(self) -> Input:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ReadMarks:
    """Where in a CSV file each batch read so far ends: pyarrow reads up to 16 blocks ahead of
    the batch it hands over, so the file's position is near its end before the first row is
    converted. Each batch is one block of the file, so the k-th ends within a row of k blocks in;
    the last, at the file's end."""

    def __init__(self, total: int, block: int):
        self.total, self.block = total, block
        self._batches = self._rows = 0
        self._marks: deque[tuple[int, int]] = deque()  # (rows read, bytes they reach), oldest first

    def add(self, rows: int) -> None:
        """A batch of ``rows`` rows was read."""
        self._batches += 1
        self._rows += rows
        self._marks.append((self._rows, min(self.total, self._batches * self.block)))

    def done(self) -> None:
        """The reader has reached the file's end."""
        self._marks.append((self._rows, self.total))

    def position(self) -> int:
        """The bytes the batches read so far reach."""
        return self._marks[-1][1] if self._marks else 0

    def reached(self, rows: int) -> int:
        """The bytes the first ``rows`` rows reach, batch by batch (``rows`` never decreases)."""
        while len(self._marks) > 1 and self._marks[1][0] <= rows:
            self._marks.popleft()
        return self._marks[0][1] if self._marks and self._marks[0][0] <= rows else 0


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


def read_batches(
    reader: Iterable[pa.RecordBatch],
    name: str,
    fd: int | None,
    at_open: FileStat | None,
    failed: Callable[[Exception], InputError],
    theirs: tuple[type[Exception], ...] = (Exception,),
    why: bool = True,
) -> Iterator[pa.RecordBatch]:
    """``reader``'s batches, each read here, on the thread that iterates: pyarrow reads and decodes
    lazily, so whatever it raises while reading is the input's. An exception of ``theirs`` (the
    kinds the reader raises about its bytes; any other passes as it is) is the file having changed
    while it was read (``fd``, ``at_open``: :func:`changed_while_read`; ``why``: with the reader's
    first line), else ``failed(exc)``, which names the file and where in it. Once the reader ends,
    a file changed meanwhile is refused too: what was read may mix two versions of it."""
    got = iter(reader)
    while True:
        try:
            batch = next(got)
        except StopIteration:
            break
        except theirs as exc:
            said = f"; {first_line(exc)}" if why else ""
            raise changed_while_read(name, fd, at_open, said) or failed(exc) from None
        yield batch
    changed = changed_while_read(name, fd, at_open)
    if changed:
        raise changed
