"""Arrow IPC in and out: the file format (Feather version 2, ``ARROW1`` at both ends, read through
a memory map) and the stream format (read front to back, as a pipe delivers it), told apart by
their first bytes; Feather version 1 (``FEA1``) read whole. The writer writes the file format to a
file and the stream format to stdout, uncompressed: the fastest hand-over to Polars, pandas and
DuckDB, which map such a file without copying it.

Batches are cut to at most :data:`IPC_BATCH_ROWS` rows (slices, no copy), since a writer may
have put a whole table in one. Whatever pyarrow raises while reading is the input's
(InputError naming the file and the record batch, with its first data row counted from 1); a
file format without ``ARROW1`` at its end is named as truncated before pyarrow reads it."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pyarrow as pa
import pyarrow.feather as feather
import pyarrow.ipc as ipc

from hconv.errors import InputError, first_line
from hconv.tables import layout
from hconv.tables.inputs import FileStat, Input, read_batches, unreadable
from hconv.tables.job import Job
from hconv.tables.sniff import table_format, what_it_is

IPC_BATCH_ROWS = 65536
_FILE_MAGIC = b"ARROW1"


def _not_ipc(path: str, name: str, head: bytes, exc: Exception | None) -> InputError:
    what = what_it_is(head, path, name, "arrow")
    if what:
        return InputError(f"{name}: {what}")
    why = f" ({first_line(exc)})" if exc is not None else ""
    return InputError(
        f"{name}: not a readable Arrow IPC (Feather) file{why}; check that it is Arrow IPC and was completely written"
    )


def _tail(path: str, k: int) -> bytes:
    with open(path, "rb") as f:
        f.seek(max(os.fstat(f.fileno()).st_size - k, 0))
        return f.read(k)


def _truncated(name: str) -> InputError:
    """The file format lists its record batches in a footer at its end, closed by a second
    ``ARROW1``; without it no batch can be found, and reading those before the cut as a stream
    would pass off part of the file as all of it."""
    return InputError(
        f"{name}: the Arrow IPC file is truncated: it starts with ARROW1 but does not end with it, so its "
        "footer (the list of its record batches) is missing and no row can be read; copy or write it again "
        "from its source"
    )


def open_ipc(path: str, name: str, job: Job) -> Input:
    """The Arrow IPC file or stream ``path``, in batches of at most :data:`IPC_BATCH_ROWS` rows."""
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            head = f.read(1 << 12)
    except OSError as exc:
        raise unreadable(name, exc) from None
    if size == 0:
        raise InputError(f"{name}: the file is empty (0 bytes); it is not an Arrow IPC file")
    if table_format(head) != "arrow":
        raise _not_ipc(path, name, head, None)
    try:
        if head.startswith(b"FEA1"):  # Feather version 1: no batches to stream, and rare now
            table = feather.read_table(path)
            return _input(name, table.schema, iter(table.to_batches()), job, table.num_rows, [], None, None, path)
        if head.startswith(_FILE_MAGIC):
            if _tail(path, len(_FILE_MAGIC)) != _FILE_MAGIC:
                raise _truncated(name)
            source: pa.NativeFile = pa.memory_map(path)
            at_open = FileStat.of(source.fileno())
            reader = ipc.open_file(source)
            total = reader.count_rows()  # from the batches' headers
            got: Iterator[pa.RecordBatch] = (reader.get_record_batch(k) for k in range(reader.num_record_batches))
        else:
            source = pa.OSFile(path)
            at_open = FileStat.of(source.fileno())
            stream = ipc.open_stream(source)
            got, total = stream, None
            reader = stream
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, OSError) and exc.errno is not None:
            raise unreadable(name, exc) from None
        raise _not_ipc(path, name, head, exc) from None
    return _input(name, reader.schema, got, job, total, [source.close], source, at_open, path)


def _input(
    name: str,
    schema: pa.Schema,
    got: Iterator[pa.RecordBatch],
    job: Job,
    total: int | None,
    closers: list,
    source: pa.NativeFile | None,
    at_open: FileStat | None,
    path: str,
) -> Input:
    plan = layout.plan(schema, job, name)
    done = [0]
    fd = source.fileno() if source is not None else None

    def batches() -> Iterator[pa.RecordBatch]:
        k = 0

        def failed(exc: Exception) -> InputError:
            return InputError(
                f"{name}: record batch {k + 1} (from data row {done[0] + 1}) cannot be read ({first_line(exc)}); "
                "the file is damaged or was not completely written: write it again from its source"
            )

        for batch in read_batches(got, name, fd, at_open, failed):
            k += 1
            for start in range(0, max(batch.num_rows, 1), IPC_BATCH_ROWS):
                piece = batch.slice(start, IPC_BATCH_ROWS)
                done[0] += piece.num_rows
                yield piece

    it = batches()
    if any(g.is_list and g.size is None for g in plan.groups.values()):
        first = next(it, None)  # a list column's length shows only in the data (as for Parquet)
        if first is not None:
            plan = plan.resolve(pa.Table.from_batches([first]))
            it = _chain(first, it)
    return Input(name, schema, it, total, lambda: done[0], plan, closers, path=path)


def _chain(first: pa.RecordBatch, rest: Iterator[pa.RecordBatch]) -> Iterator[pa.RecordBatch]:
    yield first
    yield from rest


class IpcWriter:
    """Arrow IPC out: the file format into ``path``, or with ``stream`` the stream format (what
    a pipe's reader can take batch by batch) into ``path``."""

    def __init__(self, path: str, schema: pa.Schema, *, stream: bool = False):
        # A stream may go into a pipe, which a native file cannot take (it asks the position);
        # writing reads nothing ahead, so a Python file is safe here.
        self._file = pa.PythonFile(open(path, "wb"), mode="w") if stream else pa.OSFile(path, "wb")  # noqa: SIM115
        self._w = (ipc.new_stream if stream else ipc.new_file)(self._file, schema)

    def write(self, table: pa.Table) -> None:
        self._w.write_table(table)

    def close(self) -> None:
        try:
            self._w.close()
        finally:
            self._file.close()
