"""CSV out: the columns CSV can hold, minimal quoting at pyarrow's writing speed, ω's unit in a
``w_unit`` column, tabs into ``.tsv``, and a row of units under the header where the input carried
units (:func:`units_row`).

Quoting is minimal: a value is quoted only if it holds the delimiter, a quote or a line break, or
if it is the empty text in a column that also holds nulls (``""``; a null is a blank field). All
values are formatted by pyarrow's writer (the same cast its own ``CSVWriter`` uses), which quotes
either every text value or none, and refuses a value that needs quotes when told to quote none.
So the values that need quotes are given to it quoted already, with stand-ins for the characters
it refuses (:data:`STAND_INS`), which are put back in the bytes it wrote.

pyarrow's writer formats on one thread, without the GIL: a table of many rows is cut into pieces,
one per core, each formatted into a buffer of its own on a thread of a pool shared by every writer
(:func:`_shared_pool`), and the buffers go to the file in order, so the bytes are those of one
thread's writing."""

from __future__ import annotations

import csv
import io
import os
import re
import stat
import threading
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from hconv.errors import InputError
from hconv.solve.engines import SharedPool, available_cores
from hconv.tables import arrays, layout
from hconv.tables.job import Job
from hconv.tables.sets import header_name

UNIT_COLUMN = layout.UNIT_COLUMN

#: Control bytes that stand for a quote, the delimiter, a line feed and a carriage return inside a
#: value written quoted (one byte each, so that the bytes around them do not move). A table whose
#: text holds one of them is written by joining its rows instead (:func:`_csv_rows`).
STAND_INS = b"\x01\x02\x03\x04"


def check_csv_columns(schema: pa.Schema, name: str) -> None:
    """InputError, before anything is converted, for a column CSV cannot hold: a struct, map or
    union (lists are written as text, :func:`_list_as_text`)."""
    for f in schema:
        t = f.type.value_type if pa.types.is_dictionary(f.type) else f.type
        if pa.types.is_struct(t) or pa.types.is_map(t) or pa.types.is_union(t):
            raise InputError(_csv_cannot_hold(name, f))


def _csv_cannot_hold(name: str, f: pa.Field, why: str = "") -> str:
    return (
        f"{name + ': ' if name else ''}column {f.name!r} is {f.type}{why}, which CSV cannot hold; "
        "write Parquet instead (OUT named .parquet), or drop the column first"
    )


def _binary_as_text(col: pa.ChunkedArray, f: pa.Field) -> pa.ChunkedArray:
    """A binary column as text, which it must be to go into CSV: InputError if it holds bytes that
    are not UTF-8 (a Parquet byte array without the string annotation usually is text)."""
    try:
        return col.cast(pa.string())
    except pa.ArrowInvalid:
        raise InputError(_csv_cannot_hold("", f, " and holds bytes that are not UTF-8 text")) from None


def _list_as_text(col: pa.ChunkedArray) -> pa.ChunkedArray | pa.Array:
    """A list column as text, ``[1.5, 2.0, 3.0]``, since CSV has no lists; other columns as they are."""
    t = col.type
    if not (pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)):
        return col
    return arrays.strings([None if v is None else "[" + ", ".join(repr(x) for x in v) + "]" for v in col.to_pylist()])


def _needs_quotes(delimiter: str) -> str:
    """The characters that make a value need quotes: the delimiter, a quote, a line break."""
    return "[" + re.escape(delimiter) + '"\\r\\n]'


def _marks(delimiter: str) -> bytes:
    """The bytes of :func:`_needs_quotes`."""
    return delimiter.encode() + b'"\n\r'


def _is_number(t: pa.DataType) -> bool:
    """A type whose text never holds a delimiter, a quote or a line break."""
    return pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_boolean(t)


def _is_text(t: pa.DataType) -> bool:
    return pa.types.is_string(t) or pa.types.is_large_string(t)


def _empty_beside_null(col: pa.ChunkedArray) -> bool:
    """A text column holding both nulls and empty strings, which unquoted CSV would merge."""
    if not (_is_text(col.type) and col.null_count > 0):
        return False
    return bool(pc.any(pc.equal(col, arrays.scalar("", col.type))).as_py())


def _csv_rows(t: pa.Table, delimiter: str, with_nulls: frozenset) -> pa.Buffer:
    """``t`` as CSV rows, each value quoted only if it must be (the module's docstring; a column
    with nulls: ``with_nulls``, their indices in the whole table written), joined by pyarrow's
    compute functions rather than its writer: the last column gets the line end, then each row's
    values are joined into one text whose data buffer is the rows' bytes. The values are
    formatted by the cast pyarrow's writer uses, so the bytes are its writer's. For a table whose
    text holds a stand-in (:data:`STAND_INS`)."""

    def text_of(v: str) -> pa.Scalar:
        return arrays.scalar(v, pa.large_string())

    cols = []
    for k, col in enumerate(t.columns):
        text = pc.cast(col, pa.large_string())  # 64-bit offsets: a block's text may pass 2 GiB
        if not _is_number(col.type):
            needs = pc.match_substring_regex(text, _needs_quotes(delimiter))
            if pc.any(needs).as_py():
                quoted = pc.binary_join_element_wise(
                    text_of('"'), pc.replace_substring(text, '"', '""'), text_of('"'), text_of("")
                )
                text = pc.if_else(needs, quoted, text)
        if k in with_nulls:
            text = pc.if_else(pc.equal(text, text_of("")), text_of('""'), text)
        cols.append(pc.fill_null(text, text_of("")))
    if not cols:
        return pa.py_buffer(b"\n" * t.num_rows)
    cols[-1] = pc.binary_join_element_wise(cols[-1], text_of("\n"), text_of(""))
    lines = pc.binary_join_element_wise(*cols, text_of(delimiter)) if len(cols) > 1 else cols[0]
    lines = lines.combine_chunks() if isinstance(lines, pa.ChunkedArray) else lines
    if len(lines) == 0:
        return pa.py_buffer(b"")
    offsets = np.frombuffer(lines.buffers()[1], dtype=np.int64)
    return lines.buffers()[2][int(offsets[lines.offset]) : int(offsets[lines.offset + len(lines)])]


#: Rows joined at once by :func:`_csv_rows`: a slice's text stays in the CPU's cache, as pyarrow's
#: writer formats 1024 rows at a time (a whole 4 MB block's text did not, and cost more).
_QUOTED_ROWS = 8192


def _text_of(col: pa.ChunkedArray) -> pa.Array:
    """A column that is not numbers as one text array (its chunks combined)."""
    text = col if _is_text(col.type) else pc.cast(col, pa.string())
    return text.combine_chunks() if isinstance(text, pa.ChunkedArray) else text


def _bytes_of(text: pa.Array) -> np.ndarray:
    """The bytes of a text array's values, from its first value's to its last's end."""
    data = text.buffers()[2]
    if data is None or len(text) == 0:
        return np.zeros(0, np.uint8)
    offsets = np.frombuffer(text.buffers()[1], np.int64 if pa.types.is_large_string(text.type) else np.int32)
    start, stop = int(offsets[text.offset]), int(offsets[text.offset + len(text)])
    return np.frombuffer(data, np.uint8)[start:stop]


def _scan(t: pa.Table, delimiter: str) -> tuple[dict[int, pa.Array], bool]:
    """The columns of ``t`` whose values may need quotes, as text by column index (a value holding
    the delimiter, a quote or a line break; an empty text beside a null), and whether any text of
    ``t`` holds a stand-in. Looked for in each text column's bytes at once, by memchr."""
    marks, found, stand_in = _marks(delimiter), {}, False
    for k, col in enumerate(t.columns):
        if _is_number(col.type):
            continue
        text = _text_of(col)
        raw = _bytes_of(text).tobytes()  # a copy, then memchr for each byte looked for
        if any(bytes((m,)) in raw for m in marks) or (text.null_count and _empty_beside_null(col)):
            found[k] = text
        stand_in = stand_in or any(bytes((s,)) in raw for s in STAND_INS)
    return found, stand_in


def _rows_to_quote(text: pa.Array, delimiter: str, with_null: bool) -> np.ndarray:
    """Which values of ``text`` must be quoted (the module's docstring), as a boolean mask: the
    positions of the marks in its bytes, mapped to the rows whose value holds them."""
    n = len(text)
    data = _bytes_of(text)
    lut = np.zeros(256, bool)
    lut[list(_marks(delimiter))] = True
    hits = np.flatnonzero(lut[data])
    mask = np.zeros(n, bool)
    if len(hits):
        wide = np.int64 if pa.types.is_large_string(text.type) else np.int32
        offsets = np.frombuffer(text.buffers()[1], wide)[text.offset : text.offset + n + 1].astype(np.int64)
        mask[np.searchsorted(offsets, hits + offsets[0], side="right") - 1] = True
    if text.null_count:
        mask &= arrays.to_numpy(text.is_valid())  # a null's slot may hold bytes: it is written blank all the same
    if with_null:  # the table's column holds nulls, though this slice of it may hold none
        lengths = pc.binary_length(text)
        mask |= arrays.to_numpy(lengths.fill_null(arrays.scalar(1, lengths.type))) == 0
    return mask


def _quoted_with_stand_ins(values: pa.Array, delimiter: str) -> pa.Array:
    """``values`` quoted as CSV quotes them (a quote doubled, the whole in quotes), each quote,
    delimiter and line break written as its stand-in."""
    quote, delimiter_by, lf_by, cr_by = (chr(b) for b in STAND_INS)
    for ch, by in (('"', quote * 2), (delimiter, delimiter_by), ("\n", lf_by), ("\r", cr_by)):
        values = pc.replace_substring(values, ch, by)
    wrap = arrays.scalar(quote, values.type)
    return pc.binary_join_element_wise(wrap, values, wrap, arrays.scalar("", values.type))


def _given_quoted(text: pa.Array, delimiter: str, with_null: bool) -> pa.Array:
    """``text`` with the values that need quotes (:func:`_rows_to_quote`) quoted with stand-ins."""
    mask = arrays.from_numpy(_rows_to_quote(text, delimiter, with_null))
    quoted = _quoted_with_stand_ins(pc.filter(text, mask), delimiter)
    return pc.replace_with_mask(text, mask, quoted.cast(text.type))


def _put_back(a: np.ndarray, delimiter: str) -> None:
    """Each stand-in in the bytes ``a`` replaced, in place, by what it stands for."""
    real = np.arange(256, dtype=np.uint8)
    real[list(STAND_INS)] = np.frombuffer(b'"' + delimiter.encode() + b"\n\r", np.uint8)
    at = np.flatnonzero(a <= max(STAND_INS))  # a NUL byte in a text is written as it is
    a[at] = real[a[at]]


def units_row(schema: pa.Schema, plan: layout.Layout, job: Job, written: tuple[str, ...] = ()) -> dict[str, str] | None:
    """What goes under the header of CSV output converted from an input of ``schema`` read as
    ``plan``: None for no row of units, else the texts to write as they were, by column (the rest
    come from the converted table's field metadata, :func:`units_line`). ``written``: the input's
    own row of units, one text a column, or () for none.

    A row is written when the input carried a unit its header does not say (a row of units, field
    metadata: Parquet, Arrow, Spark's schema; ``field_units``), or ``--unit`` read a column in
    another unit than its header says: the numbers mean what they meant only with it, and hconv
    reads its own output back in the units it read the input in. An input that said no unit, read
    with ``--unit`` or not, gets none, as it came. A text of the input's row is kept, but not under
    a column ``--unit`` read in another unit: there the table's metadata names the one it was read in."""
    row = dict(zip(schema.names, written, strict=False))
    kept, overridden = dict(row), False
    for g in plan.groups.values():
        for column, read_in in zip(g.columns, g.units, strict=False):
            # the unit a reader takes the column to be in, without --unit: the row's, else the header's
            said = row.get(column, "").strip() or header_name(column)[1] or ""
            if said != read_in:
                kept.pop(column, None)
                overridden = overridden or bool(said)
    if not (
        written
        or job.field_units
        or overridden
        or _STORES_UNITS.value(schema, None, lambda: bool(layout.stored_units(schema)))
    ):
        return None
    return kept


#: whether recent schemas store a unit: looking costs more than the memo (Spark's schema is parsed),
#: and a dataset's files mostly share one schema
_STORES_UNITS = layout.SchemaMemo()


def units_line(schema: pa.Schema, units: Mapping[str, str]) -> list[str]:
    """The row of units under the header of a table of ``schema``: ``units`` for the input's
    columns (what the input's row of units said, as it said it: :func:`units_row`), else the
    ``unit`` in each column's field metadata (the unit hconv read it in, the input's own for a
    column it passed through, ω's, ``1`` for a ratio), blank for the rest."""
    row = []
    for f in schema:
        if f.name in units:
            row.append(units[f.name])
        else:
            meta = f.metadata or {}
            row.append(meta[b"unit"].decode() if b"unit" in meta else "")
    return row


#: Rows formatted into one of the writer's buffers at once, which bounds its size (a Parquet or
#: Arrow IPC input may hand the writer a whole row group or record batch); fewer at a time cost more.
_SLICE_ROWS = 65_536
#: The fewest rows a piece formatted on a thread of its own has: below, handing it to a thread
#: costs more than it saves, and a table of fewer than twice as many stays on one thread.
_PIECE_ROWS = 4096
#: Pieces a thread formats of a slice (:func:`_pieces`).
_PIECES_PER_THREAD = 4

#: The threads of the process's writers, started by the first table cut into pieces.
_shared_pool = SharedPool("hconv-csv")


def _threads(n: int) -> int:
    """Threads that format ``n`` rows: one per core, with :data:`_PIECE_ROWS` rows each at least."""
    return max(1, min(available_cores(), n // _PIECE_ROWS))


def _pieces(n: int, threads: int) -> int:
    """Pieces ``n`` rows are cut into for ``threads``: :data:`_PIECES_PER_THREAD` each, of
    :data:`_PIECE_ROWS` rows at least (one piece a thread left the others waiting for a thread
    the busy machine ran late; with several, it holds them up by one small piece)."""
    return 1 if threads == 1 else max(threads, min(_PIECES_PER_THREAD * threads, n // _PIECE_ROWS))


def _on_threads(jobs: int, threads: int, job: Callable[[int], None]) -> None:
    """``job(0)`` … ``job(jobs - 1)`` on ``threads``, the caller's and the pool's, each taking the next
    until none is left (a pool thread that starts late, on a busy machine, leaves its share to
    the others rather than the caller waiting for it); returns when every job has ended, so that
    none still writes into a buffer, and re-raises the first job's exception."""
    if threads == 1:
        for j in range(jobs):
            job(j)
        return
    taken = iter(range(jobs))
    lock = threading.Lock()

    def take() -> None:
        while True:
            with lock:
                j = next(taken, None)
            if j is None:
                return
            try:
                job(j)
            except BaseException:
                with lock:  # the rows are written another way: the jobs left are not needed
                    for _ in taken:
                        pass
                raise

    futures: list[Future[None]] = [_shared_pool(threads - 1).submit(take) for _ in range(threads - 1)]
    error: BaseException | None = None
    try:
        take()
    except BaseException as exc:  # every piece ended first: the pool's may still write
        error = exc
    for f in futures:  # one still queued behind another writer's (the pool is shared) is not waited for
        if not f.cancel():
            error = error or f.exception()
    if error is not None:
        raise error


class CsvWriter:
    """CSV with a minimal-quoting header, ``status`` as text and ω's unit in a ``w_unit`` column;
    ``delimiter``: a comma, or a tab for ``.tsv``; ``units``: the texts of a row of units under
    the header, by column (:func:`units_row`; the other columns' from their field metadata,
    :func:`units_line`), or None for no such row.

    Where no value needs quotes, pyarrow's own writer writes the rows straight into the file (it
    formats 1024 rows at a time, in the CPU's cache): pyarrow's speed. Where one does, it writes
    the table into a buffer, used again for every table (a new one each time costs its pages),
    the values that need quotes given quoted with stand-ins (the module's docstring), and the
    buffer goes to the file. So does a table into a pipe, which cannot seek, as a native file needs."""

    def __init__(self, path: str, schema: pa.Schema, delimiter: str = ",", units: Mapping[str, str] | None = None):
        self._delimiter, self._path = delimiter, path
        # a pipe (stdout straight to its reader) cannot seek, which a native file needs: its
        # rows go through the buffer, so that a late refusal has written none of them
        self._seekable = not os.path.exists(path) or stat.S_ISREG(os.stat(path).st_mode)
        self._f: Any = pa.OSFile(path, "wb") if self._seekable else open(path, "wb")  # noqa: SIM115 - close() closes it
        self._bufs: list[pa.Buffer | None] = []  # one a piece of a slice, used again for every table
        wx, self._unit_column = layout.output_name("wx", schema), layout.output_name(UNIT_COLUMN, schema)
        meta = schema.field(wx).metadata or {} if wx in schema.names else {}
        self._unit = meta[b"unit"].decode() if b"unit" in meta else None  # only tables with ω have one
        names = schema.names + ([self._unit_column] if self._unit else [])
        buf = io.StringIO()
        lines = csv.writer(buf, lineterminator="\n", delimiter=delimiter)
        lines.writerow(names)
        if units is not None:
            lines.writerow(units_line(schema, units) + ([""] if self._unit else []))
        self._f.write(buf.getvalue().encode())
        self._plain = pacsv.WriteOptions(include_header=False, quoting_style="none", delimiter=delimiter)

    def write(self, table: pa.Table) -> None:
        check_csv_columns(table.schema, "")  # the callers check the input first, naming it
        cols = [
            c.cast(pa.string())
            if pa.types.is_dictionary(c.type)
            else _binary_as_text(c, f)
            if pa.types.is_binary(f.type) or pa.types.is_large_binary(f.type) or pa.types.is_fixed_size_binary(f.type)
            else _list_as_text(c)
            for c, f in zip(table.columns, table.schema, strict=True)
        ]
        names = table.schema.names
        if self._unit:
            cols.append(pa.repeat(arrays.scalar(self._unit, pa.string()), table.num_rows))
            names = names + [self._unit_column]
        t = pa.Table.from_arrays(cols, names=names)
        # decided on the whole table, so that its slices are written alike
        marked, stand_in = _scan(t, self._delimiter)
        if marked and stand_in:
            self._joined(t, 0)
            return
        if marked or not self._seekable or _threads(t.num_rows) > 1:
            self._through_buffer(t, marked)
            return
        at = self._f.tell()
        try:
            pacsv.write_csv(t, self._f, self._plain)
        except pa.ArrowInvalid:  # a value pyarrow would quote after all: take back its rows, quote those values
            self._f.close()
            os.truncate(self._path, at)
            self._f = pa.OSFile(self._path, "ab")
            self._joined(t, 0)

    def _through_buffer(self, t: pa.Table, marked: dict[int, pa.Array]) -> None:
        """``t`` written through the buffers a slice at a time, :data:`_SLICE_ROWS` rows a thread,
        its pieces (:func:`_pieces`) formatted on threads (:func:`_threads`) and written in order;
        the values of the ``marked`` columns (their text, by index) that need quotes given quoted
        with stand-ins, which are put back (the module's docstring)."""
        step = _SLICE_ROWS * _threads(t.num_rows)
        for k in range(0, t.num_rows, step):
            rows = min(step, t.num_rows - k)
            threads = _threads(rows)
            pieces = _pieces(rows, threads)
            size = -(-rows // pieces)
            written: list[pa.Buffer] = [pa.py_buffer(b"")] * pieces

            def format_piece(j: int, first: int = k, rows: int = rows, size: int = size, out: list = written) -> None:
                at, stop = first + j * size, first + rows
                length = max(0, min(size, stop - at))  # the slice's last piece may be short, or empty
                piece = t.slice(at, length)
                for c, text in marked.items():  # null beside empty: decided on the whole table
                    given = _given_quoted(text.slice(at, length), self._delimiter, text.null_count > 0)
                    piece = piece.set_column(c, t.schema.names[c], given)
                buf, n = self._formatted(piece, j)
                if marked:
                    _put_back(np.frombuffer(buf, np.uint8)[:n], self._delimiter)
                out[j] = buf.slice(0, n)

            if len(self._bufs) < pieces:
                self._bufs += [None] * (pieces - len(self._bufs))
            try:
                _on_threads(pieces, threads, format_piece)
            except pa.ArrowInvalid:  # a value pyarrow refuses unquoted that the scan did not see
                self._joined(t, k)  # the rows before it are written alike either way
                return
            for buf in written:
                self._f.write(buf)

    def _formatted(self, t: pa.Table, j: int) -> tuple[pa.Buffer, int]:
        """``t``'s rows as pyarrow's writer formats them, in buffer ``j`` (made larger while they
        do not fit), and their size. Only one thread at a time formats into a given buffer."""
        while True:
            buf = self._bufs[j]
            if buf is None:
                buf = self._bufs[j] = pa.allocate_buffer(3 * t.nbytes + (64 << 10))  # a float64's text: up to 25 bytes
            sink = pa.FixedSizeBufferWriter(buf)
            try:
                pacsv.write_csv(t, sink, self._plain)
            except OSError as exc:
                if "out of bounds" not in str(exc):  # pyarrow's "Write out of bounds": no room left
                    raise
                self._bufs[j] = pa.allocate_buffer(2 * buf.size)
                continue
            return buf, sink.tell()

    def _joined(self, t: pa.Table, first: int) -> None:
        """The rows of ``t`` from ``first`` on, joined by :func:`_csv_rows`."""
        with_nulls = frozenset(k for k, c in enumerate(t.columns) if c.null_count)
        for k in range(first, t.num_rows, _QUOTED_ROWS):
            self._f.write(_csv_rows(t.slice(k, _QUOTED_ROWS), self._delimiter, with_nulls))

    def close(self) -> None:
        self._f.close()
