"""Parquet in and out: the reader (batches of :data:`PARQUET_BATCH_ROWS` rows, pages streamed and
their checksums checked, a part of a file by its rows; a damaged page named by its row group), a
file's shape from its footer, parts joined into one file, and hconv's Parquet settings
(:func:`parquet_write_options`, public as ``hconv.parquet_write_options``)."""

from __future__ import annotations

import io
import itertools
import os
from collections.abc import Iterator
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from hconv.errors import InputError, first_line
from hconv.tables import layout
from hconv.tables.inputs import FileStat, Input, changed_while_read, read_batches, unreadable
from hconv.tables.job import Job
from hconv.tables.sniff import rename_or_pass, what_it_is

PARQUET_BATCH_ROWS = 65536


def _not_parquet(path: str, name: str, exc: Exception) -> InputError:
    """Why a file pyarrow cannot open as Parquet is not Parquet, when its first bytes tell."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 12)
    except OSError:
        head = b""
    what = what_it_is(head, path, name, "parquet")
    if what:
        return InputError(f"{name}: {what}")
    first = head.split(b"\n", 1)[0]
    looks_csv = b"," in first and b"\x00" not in head and not head.startswith(b"PAR1")
    if looks_csv:
        return InputError(f"{name}: is CSV text, not Parquet: {rename_or_pass(name, 'csv')}")
    # pyarrow's "Parquet magic bytes not found in footer. Either the file is corrupted or ...", said short
    why = "no Parquet footer" if "magic bytes not found in footer" in str(exc) else first_line(exc)
    return InputError(
        f"{name}: not a readable Parquet file ({why}); check that it is Parquet and was completely written"
    )


def open_parquet(path: str, name: str, job: Job, rows: tuple[int, int] | None = None, whole: bool = False) -> Input:
    """The Parquet file ``path``, in batches of :data:`PARQUET_BATCH_ROWS` rows counted from its
    first row; with ``rows`` (start, stop), only those rows, reading only the row groups that hold
    them, in the batches the whole file's reading gives them when ``start`` is a multiple of
    :data:`PARQUET_BATCH_ROWS` (so that a part's output row groups are the whole file's:
    :func:`hconv.tables.parts.split`). ``whole``: a small file (a dataset's), read into memory
    at once, then decoded from there: the same batches, without a buffered read per column."""
    closers: list = []
    try:
        if whole:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_BINARY", 0))
            closers.append(lambda: os.close(fd))
            at_open = FileStat.of(fd)  # before the read: a change while it reads is one while the file is read
            data = _read_whole(fd, at_open.size)
            changed = changed_while_read(name, fd, at_open) if data.size < at_open.size else None
            if changed:  # cut while read: not "no Parquet footer", which would blame the file
                raise changed
            source: pa.NativeFile = pa.BufferReader(data)
        else:
            source = pa.OSFile(path)
            fd = source.fileno()
            at_open = FileStat.of(fd)
        closers.append(source.close)
        if at_open.size == 0:
            raise InputError(f"{name}: the file is empty (0 bytes); it is not a Parquet file")
        # Stream pages rather than pre-buffering whole row groups, so that peak memory does not
        # grow with the writer's row-group size (docs/measurements.md); a whole file in memory
        # needs no buffer. Pages that carry a checksum (pyarrow writes them with
        # write_page_checksum=True) are checked: a damaged page of plain floats otherwise reads
        # as other numbers, silently.
        buffered = {} if whole else {"pre_buffer": False, "buffer_size": 1 << 20}
        pf = pq.ParquetFile(source, page_checksum_verification=True, **buffered)
        closers.append(pf.close)
        schema = pf.schema_arrow  # a footer whose column metadata is damaged fails here
        meta = pf.metadata
    except BaseException as exc:
        for close in reversed(closers):
            close()
        if isinstance(exc, pa.ArrowException):
            raise _not_parquet(path, name, exc) from None
        if isinstance(exc, OSError):
            if exc.errno is None and os.path.isfile(path):  # pyarrow's own errors about the bytes
                raise _not_parquet(path, name, exc) from None
            raise unreadable(name, exc) from None
        raise
    try:
        return _opened(pf, fd, at_open, schema, meta, name, job, rows, closers, whole)
    except BaseException:
        for close in reversed(closers):
            close()
        raise


def _read_whole(fd: int, size: int) -> pa.Buffer:
    """The first ``size`` bytes of the file open as ``fd`` (fewer if it ends sooner), in a buffer
    of Arrow's memory pool: its allocator keeps freed memory for the next file, where the bytes
    of ``readall`` were fresh pages from the system, each faulted in on first touch."""
    data = pa.allocate_buffer(size)
    view = memoryview(data).cast("B")
    got = 0
    with io.FileIO(fd, closefd=False) as f:
        while got < size:
            n = f.readinto(view[got:])
            if not n:
                break
            got += n
    view.release()
    return data if got == size else data.slice(0, got)


def _opened(
    pf: pq.ParquetFile,
    fd: int,
    at_open: FileStat,
    schema: pa.Schema,
    meta: pq.FileMetaData,
    name: str,
    job: Job,
    rows: tuple[int, int] | None,
    closers: list,
    whole: bool,
) -> Input:
    """:func:`open_parquet`'s Input, once the file is open as ``pf`` (and as ``fd``, which tells
    whether it changes while read)."""
    plan = layout.plan(schema, job, name)
    done = [0]
    start, stop = rows if rows is not None else (0, meta.num_rows)
    groups, skip = _row_groups(meta, start, stop)

    def read(row_groups: list[int]) -> Iterator[pa.RecordBatch]:
        """``pf``'s batches of ``row_groups``; a page pyarrow cannot read is named by its row group
        (before, a damaged page's OSError reached the CLI as the output's, exit 4)."""
        n = 0  #: rows read, from the first of row_groups

        def failed(exc: Exception) -> InputError:
            return _damaged(pf, name, row_groups, n, exc)

        # a small file's columns decoded on this thread: handing each to Arrow's pool cost more
        got = pf.iter_batches(batch_size=PARQUET_BATCH_ROWS, row_groups=row_groups, use_threads=not whole)
        for batch in read_batches(got, name, fd, at_open, failed):
            n += batch.num_rows
            yield batch

    def read_all() -> Iterator[pa.RecordBatch]:
        got = read(groups)
        for batch in got if rows is None else _rebatched(got, skip, stop - start):
            done[0] += batch.num_rows
            yield batch
        # read checks, once its row groups are read, that the file did not change meanwhile; a
        # part ends inside its last row group, before that check
        changed = changed_while_read(name, fd, at_open) if rows is not None else None
        if changed:
            raise changed

    batches = read_all()
    if any(g.is_list and g.size is None for g in plan.groups.values()):
        # A variable-length list column's length shows only in the data: the file's first batch
        # fixes it, here on the reading thread, so every batch (of every part) is held to the same plan.
        first = next(batches, None) if start == 0 else next(read([0]), None)
        if first is not None:
            plan = plan.resolve(pa.Table.from_batches([first]))
            if start == 0:
                batches = itertools.chain([first], batches)
    return Input(name, schema, batches, stop - start, lambda: done[0], plan, closers, first_row=start)


def _damaged(pf: pq.ParquetFile, name: str, groups: list[int], read: int, exc: Exception) -> InputError:
    """The error for a Parquet file whose pages pyarrow could not read after ``read`` rows of the
    row groups ``groups``, naming the row group that fails: the next batch may span several, so
    each that it touches is read again, alone (on this error path only)."""
    meta = pf.metadata
    firsts = list(itertools.accumulate((meta.row_group(k).num_rows for k in range(meta.num_row_groups)), initial=0))
    bad, n = None, 0
    for k in groups:
        rows = meta.row_group(k).num_rows
        if n + rows > read and n < read + PARQUET_BATCH_ROWS:  # the failing batch touches it
            bad = bad if bad is not None else k  # at worst the first it touches
            try:
                for _ in pf.iter_batches(batch_size=PARQUET_BATCH_ROWS, row_groups=[k]):
                    pass
            except Exception:  # noqa: BLE001 - any failure names this row group
                bad = k
                break
        n += rows
    if bad is None:
        return InputError(f"{name}: cannot be read ({first_line(exc)}); the file is damaged: write it again")
    return InputError(
        f"{name}: row group {bad + 1} of {meta.num_row_groups} (data rows {firsts[bad] + 1}-{firsts[bad + 1]}) "
        f"cannot be read ({first_line(exc)}); the file is damaged or was not completely written: "
        "write it again from its source"
    )


def _row_groups(meta: pq.FileMetaData, start: int, stop: int) -> tuple[list[int], int]:
    """The row groups holding rows [start, stop), and how many rows of the first precede ``start``."""
    groups: list[int] = []
    skip = first = 0
    for k in range(meta.num_row_groups):
        n = meta.row_group(k).num_rows
        if first < stop and first + n > start:
            if not groups:
                skip = start - first
            groups.append(k)
        first += n
    return groups, skip


def _rebatched(batches: Iterator[pa.RecordBatch], skip: int, count: int) -> Iterator[pa.RecordBatch]:
    """``count`` rows after the first ``skip`` of ``batches``, in batches of
    :data:`PARQUET_BATCH_ROWS` (the last shorter): the reader's batches start at a row group's
    first row, the whole file's at the file's."""
    held: list[pa.RecordBatch] = []
    n = 0
    for batch in batches:
        if skip >= batch.num_rows:
            skip -= batch.num_rows
            continue
        batch = batch.slice(skip, min(batch.num_rows - skip, count))
        skip = 0
        count -= batch.num_rows
        held.append(batch)
        n += batch.num_rows
        while n >= PARQUET_BATCH_ROWS:
            whole = pa.concat_batches(held) if len(held) > 1 else held[0]
            yield whole.slice(0, PARQUET_BATCH_ROWS)
            rest = whole.slice(PARQUET_BATCH_ROWS)
            held, n = ([rest] if rest.num_rows else []), rest.num_rows
        if count <= 0:
            break
    if n:
        yield pa.concat_batches(held) if len(held) > 1 else held[0]


def parquet_shape(source: str | Any) -> tuple[int, int]:
    """(rows, row groups) of a Parquet file, a path or an open file, from its footer alone."""
    with pq.ParquetFile(source) as pf:
        return pf.metadata.num_rows, pf.metadata.num_row_groups


def join_parquet(parts: list[str], path: str) -> None:
    """Write the Parquet files ``parts`` (the parts of one output, in order, each written by
    hconv's writer) into ``path`` as one file, row group by row group: the same schema, metadata
    and writer options, so that the file is the one the whole conversion writes
    (:func:`hconv.tables.parts.join_parts`)."""
    writer: ParquetWriter | None = None
    try:
        for part in parts:
            with pq.ParquetFile(part) as pf:
                if writer is None:
                    writer = ParquetWriter(path, pf.schema_arrow)
                for k in range(pf.metadata.num_row_groups):
                    writer.write(pf.read_row_group(k))
    finally:
        if writer is not None:
            writer.close()


def parquet_write_options(schema: pa.Schema) -> dict:
    """hconv's Parquet settings for a table of ``schema``, as keyword arguments of
    ``pyarrow.parquet.ParquetWriter`` and ``pyarrow.parquet.write_table`` (and of what passes
    them on: Dask's ``to_parquet``, Ray's ``arrow_parquet_args``); hconv's own writer uses them.

    Float columns plain: no dictionary, no compression. Every other column (ids, labels,
    ``status``) dictionary-encoded and snappy-compressed. The settings name top-level columns, so
    the values of a list column get pyarrow's writer defaults: no dictionary, no compression.
    """
    # Dictionary encoding and compression pay for labels and statuses. On floats that rarely
    # repeat, dictionaries only cost time and snappy saves little space for much writing
    # time (docs/measurements.md), so float columns are written plain.
    floats = {f.name for f in schema if pa.types.is_floating(f.type)}
    others = [f.name for f in schema if f.name not in floats]
    return {
        "use_dictionary": others or False,
        "compression": {f.name: "none" if f.name in floats else "snappy" for f in schema},
    }


#: The writer's buffer: pyarrow writes each page and each column chunk's header with a call of
#: its own, dozens of system calls for a small file's output, which the buffer makes one.
WRITE_BUFFER_BYTES = 1 << 20


class ParquetWriter:
    """hconv's Parquet writer: :func:`parquet_write_options`, through :data:`WRITE_BUFFER_BYTES`."""

    def __init__(self, path: str, schema: pa.Schema):
        self._file = pa.OSFile(path, "wb")
        try:
            self._sink = pa.BufferedOutputStream(self._file, WRITE_BUFFER_BYTES)
            self._w = pq.ParquetWriter(self._sink, schema, **parquet_write_options(schema))
        except BaseException:
            self._file.close()
            raise

    def write(self, table: pa.Table) -> None:
        self._w.write_table(table)

    def close(self) -> None:
        try:
            self._w.close()
            self._sink.close()  # flushes the buffer: a full disk may refuse it here
        finally:
            self._file.close()
