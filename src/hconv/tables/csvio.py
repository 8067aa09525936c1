"""CSV in (out: :mod:`hconv.tables.csvwrite`). Reading refuses, with the reason, a file that is
not UTF-8 text, reads the columns hconv does not use as text (:attr:`~hconv.tables.inputs.Input.text`) so
that CSV output gives them back exactly as they went in (into Parquet the pipeline gives them
types: :mod:`hconv.tables.csvtypes`), and names the row, column and value of what pyarrow cannot
read.

pyarrow is given native files only (see :func:`open_csv`)."""

from __future__ import annotations

import csv
import dataclasses
import re
from collections.abc import Iterator

import pyarrow as pa
import pyarrow.csv as pacsv

from hconv.errors import HconvError, InputError, UsageError, first_line, option, quoted
from hconv.solve import forms, units
from hconv.tables import csvtypes, layout, sets
from hconv.tables.inputs import FileStat, Input, ReadMarks, changed_while_read, read_batches, unreadable
from hconv.tables.job import DELIMITERS, Job
from hconv.tables.sets import QUANTITY
from hconv.tables.sniff import (
    Dialect,
    comment_lines,
    decimal_comma,
    delimiter_by_name,
    delimiter_hint,
    rename_or_pass,
    sniff_decimal,
    sniff_delimiter,
    what_it_is,
)

CSV_BLOCK_BYTES = 4 << 20


def _sniff_csv(path: str, name: str) -> str:
    """The first 64 KiB of a file as text, whole lines only (a byte-order mark dropped); InputError,
    with the reason, for a file that is not UTF-8 text."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError as exc:
        raise unreadable(name, exc) from None
    if not head:
        return ""  # the empty file has its own message
    what = what_it_is(head, path, name, "csv")
    if what:
        raise InputError(f"{name}: {what}")
    if b"\x00" in head or head.startswith(b"\x89PNG") or head.startswith(b"PAR1"):
        parquet = f" (it looks like Parquet: {rename_or_pass(name, 'parquet')})"
        raise InputError(f"{name}: is not a text file, so not CSV" + (parquet if head.startswith(b"PAR1") else ""))
    cut = head.rfind(b"\n") + 1 if len(head) == 1 << 16 else len(head)
    head = head[: cut or len(head)]
    head = head[3:] if head.startswith(b"\xef\xbb\xbf") else head
    try:
        return head.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = head[: exc.start].count(b"\n") + 1
        raise InputError(
            f"{name}: line {line} is not UTF-8 text; convert the file to UTF-8 first "
            "(for example: iconv -f latin1 -t utf-8)"
        ) from None


#: Rows of the first block the dialect is sniffed from (DuckDB samples more; a block is enough here).
SNIFF_ROWS = 100


def _dialect(head: str, name: str, job: Job) -> tuple[Dialect, list[str]]:
    """The delimiter and comment lines of a CSV whose first lines are ``head`` (the decimal mark
    and a units row are told later, from hconv's columns), and its header and first rows as
    lines. InputError for a blank header line."""
    lines = [ln.rstrip("\r") for ln in head.split("\n")]
    comments = comment_lines(lines)
    if head and comments and not any(ln.strip() for ln in lines[comments:]):
        raise InputError(
            f"{name}: holds only comment lines (starting with #) in its first {comments} lines; "
            "a CSV needs a header line naming the columns"
        )
    body = lines[comments : comments + SNIFF_ROWS + 1]
    if head and not (body[0].strip() if body else ""):
        raise InputError(f"{name}: the first line is blank; a CSV needs a header line naming the columns")
    given = job.delimiter or delimiter_by_name(name)
    delimiter = given or sniff_delimiter(body, name, frozenset(sets.all_names()))
    return Dialect(delimiter=delimiter, decimal=job.decimal or ".", comment_lines=comments), body


def header_names(path: str, job: Job) -> list[str] | None:
    """The column names of the CSV at ``path``, from its first 64 KiB alone (None for an empty
    file); InputError for a file that is not CSV text."""
    head = _sniff_csv(path, path)
    if not head:
        return None
    dialect, body = _dialect(head, path, job)
    return next(csv.reader(body[:1], delimiter=dialect.delimiter), None)


def _looks_numeric(text: str) -> bool:
    """Whether a field reads as a number (or starts as one: ``1 kg``), with either decimal mark."""
    t = text.strip()
    try:
        float(t.replace(",", ".", 1))
    except ValueError:
        return bool(re.match(r"[+-]?\.?\d", t))
    return True


def _units_row(row: list[str], names: list, plan: layout.Layout, name: str) -> tuple:
    """The units a row under the header gives hconv's columns, as (column, unit) pairs: a row in
    which every hconv column holds text that is no number (or nothing) is a row of units, not a
    data row. () for a row that is data; InputError naming the column whose text is no unit of
    its quantity."""
    if len(row) != len(names):
        return ()
    quantity = {c: QUANTITY[g.name] for g in plan.groups.values() for c in g.columns}
    # a null marker (NA, null, #N/A) is a missing value, not a unit: a first data row of them
    # was taken for a row of units that pint could not read
    values = {c: "" if (v := row[names.index(c)].strip()) in csvtypes.NULL_TEXTS else v for c in plan.numeric}
    if not any(values.values()) or any(_looks_numeric(v) for v in values.values() if v):
        return ()
    for c, v in values.items():
        if v:
            try:
                units.factor(
                    quantity[c],
                    v,
                    f"{name}: column {c!r} of the units row under the header",
                )
            except UsageError as exc:
                raise InputError(f"{exc}; or remove that row if it is data") from None
    return tuple((c, v) for c, v in values.items() if v)


def _read_options(d: Dialect) -> pacsv.ReadOptions:
    return pacsv.ReadOptions(
        block_size=CSV_BLOCK_BYTES, skip_rows=d.comment_lines, skip_rows_after_names=1 if d.units_row else 0
    )


def _parse_options(d: Dialect) -> pacsv.ParseOptions:
    return pacsv.ParseOptions(delimiter=d.delimiter)


def _header_hint(names: list, lines: list[str], dialect: Dialect, name: str, given: bool) -> str:
    """Why a header may not have matched: a delimiter it does not have (:func:`delimiter_hint`),
    spaces around names, or a first line that is no header."""
    known = sets.all_names()
    wrong = delimiter_hint(names, lines, dialect.delimiter, name, given, frozenset(known))
    if wrong:
        return wrong
    spaced = [n for n in names if n != n.strip() and n.strip() in known]
    if spaced:
        return f" (the header has spaces around {', '.join(repr(n) for n in spaced[:3])}; remove them)"
    if not any(n.strip() in known or sets.reads_as(n.strip()) for n in names):
        return f" (the first line, {','.join(names)[:50]!r}, names none of hconv's columns: is it a CSV header?)"
    return ""


def _one_line(path: str, name: str) -> bytes | None:
    """The bytes of a CSV file that is one line with no line end (a header and no rows, written
    without its newline), which pyarrow takes for an empty file; None for a file with a line end
    in its first block. InputError for a file with none in its first block: no CSV reader reads
    a line longer than a block, and such a file is rarely a CSV (a 100 MB file without a newline
    was called empty)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
            if not head or b"\n" in head or b"\r" in head:
                return None
            head += f.read(CSV_BLOCK_BYTES + 1 - len(head))
    except OSError as exc:
        raise unreadable(name, exc) from None
    if b"\n" in head or b"\r" in head:
        return None
    if len(head) <= CSV_BLOCK_BYTES:
        return head
    raise InputError(
        f"{name}: has no line end in its first {CSV_BLOCK_BYTES >> 20} MiB; a CSV is a header line and one "
        f"line per row, each shorter than that: is it a CSV?"
    )


def open_csv(path: str, name: str, job: Job) -> Input:
    head = _sniff_csv(path, name)
    dialect, lines = _dialect(head, name, job)
    one_line = _one_line(path, name)
    ropts, popts = _read_options(dialect), _parse_options(dialect)

    def source() -> pa.NativeFile:
        """The file as pyarrow reads it: a native file, never a Python file object. pyarrow reads
        ahead on its own threads, which may still be reading when an error is raised here; one
        that holds a Python object needs the interpreter, and if the interpreter is exiting by
        then the process aborts (SIGABRT, 'terminate called without an active exception', about
        one run in ten on a file with bad UTF-8 in its first block). A native file needs no
        interpreter, and pyarrow keeps it open for as long as its threads use it."""
        if one_line is not None:  # a header without its newline: read it with one
            return pa.BufferReader(one_line + b"\n")
        return pa.OSFile(path)

    try:
        with pacsv.open_csv(source(), read_options=ropts, parse_options=popts) as probe:
            names = probe.schema.names
    except pa.ArrowInvalid as exc:
        if "Empty CSV file" in str(exc):
            raise InputError(
                f"{name}: the file is empty; a CSV needs a header line naming the columns "
                f"{', '.join(sets.VECTOR_SETS['H'])} and the inertia "
                f"({'; or '.join(', '.join(f.columns) for f in forms.FORMS.values() if not f.extends)})"
            ) from None
        # a row that splits into more values than the header: the delimiter given may be wrong
        header = next(csv.reader(lines[:1], delimiter=dialect.delimiter), [])
        known = frozenset(sets.all_names())
        hint = delimiter_hint(header, lines, dialect.delimiter, name, job.delimiter is not None, known)
        raise _csv_parse_error(path, name, exc, _for_errors(dialect, lines, job, name), hint) from None
    except OSError as exc:
        raise unreadable(name, exc) from None
    try:
        plan = layout.plan(pa.schema([(n, pa.float64()) for n in names]), job, name)
    except InputError as exc:
        raise InputError(f"{exc}{_header_hint(names, lines, dialect, name, job.delimiter is not None)}") from None
    rows = [r for r in csv.reader(lines[1:], delimiter=dialect.delimiter) if r]
    found = _units_row(rows[0], names, plan, name) if rows else ()
    if rows and found:
        dialect = dataclasses.replace(dialect, units=found, units_row=True, units_text=tuple(rows[0]))
        rows = rows[1:]
        plan = layout.plan(pa.schema([_with_unit(n, dict(found)) for n in names]), job, name)
        ropts = _read_options(dialect)
    if job.decimal is None and dialect.delimiter != ",":
        at = {c: names.index(c) for c in plan.numeric}
        values = {c: [r[k] for r in rows if len(r) > k] for c, k in at.items()}
        dialect = dataclasses.replace(dialect, decimal=sniff_decimal(values, name))
    nums = set(plan.numeric)
    types = {n: (pa.float64() if n in nums else pa.string()) for n in names}
    # NaN is a float value, not a missing one: pyarrow's default null markers include its
    # spellings, which turned a file's NaN into a null (an empty field in CSV output).
    copts = pacsv.ConvertOptions(
        column_types=types,
        strings_can_be_null=False,
        null_values=csvtypes.NULLS.to_pylist(),
        decimal_point=dialect.decimal,
    )
    try:
        f = source()
        fd = None if one_line is not None else f.fileno()
        at_open = None if fd is None else FileStat.of(fd)
    except OSError as exc:
        raise unreadable(name, exc) from None
    try:  # the reader parses its first block here already, so bad values can show up now
        reader = pacsv.open_csv(f, read_options=ropts, parse_options=popts, convert_options=copts)
    except pa.ArrowInvalid as exc:  # f is left to pyarrow, whose read-ahead may still be using it
        raise changed_while_read(name, fd, at_open) or _csv_value_error(
            path, name, names, dialect, exc, job.decimal is not None
        ) from None
    total = f.size()
    # every column's unit from the row, not only hconv's: the output carries them all (field
    # metadata in Parquet and Arrow), so that no column's numbers lose what they meant
    row_units = {n: u.strip() for n, u in zip(names, dialect.units_text, strict=False) if u.strip()}
    schema = pa.schema([_with_unit(fl, row_units) for fl in reader.schema])
    read = ReadMarks(total, CSV_BLOCK_BYTES)

    def failed(exc: Exception) -> InputError:
        if isinstance(exc, pa.ArrowInvalid):
            return _csv_value_error(path, name, names, dialect, exc, job.decimal is not None)
        return InputError(f"{name}: cannot be read ({first_line(exc)}); check the file")

    def batches() -> Iterator[pa.RecordBatch]:
        # all the reader raises is the input's
        for batch in read_batches(reader, name, fd, at_open, failed, (OSError, pa.ArrowException, MemoryError), False):
            read.add(batch.num_rows)
            yield batch if not row_units else pa.RecordBatch.from_arrays(batch.columns, schema=schema)
        read.done()

    text = tuple(n for n in names if n not in nums)
    return Input(name, schema, batches(), total, read.position, plan, [], text, path, dialect=dialect, marks=read)


def _for_errors(dialect: Dialect, lines: list[str], job: Job, name: str) -> Dialect:
    """``dialect`` with its units row, for naming a bad row in a first block that pyarrow could
    not read (the data rows are counted from under a units row); as it is if that is not known."""
    try:
        rows = [r for r in csv.reader(lines, delimiter=dialect.delimiter) if r]
        plan = layout.plan(pa.schema([(n, pa.float64()) for n in rows[0]]), job, name)
        return dataclasses.replace(dialect, units_row=len(rows) > 1 and bool(_units_row(rows[1], rows[0], plan, name)))
    except (HconvError, IndexError, csv.Error):
        return dialect


def _with_unit(field: str | pa.Field, found: dict) -> pa.Field:
    """A column as a float field (``field``: a name) or as it is, with the unit a units row gave
    it as its metadata: where hconv reads a column's unit from (hconv.tables.layout), and where
    Parquet and Arrow output keep it."""
    f = pa.field(field, pa.float64()) if isinstance(field, str) else field
    return f.with_metadata({"unit": found[f.name]}) if f.name in found else f


def reopen(inp: Input, job: Job) -> Input:
    """A CSV input read again from its first row, as a new Input; ``inp`` must stay open
    meanwhile (for stdin it holds the spooled copy)."""
    return open_csv(inp.path, inp.name, job)


def text_batches(inp: Input) -> Iterator[pa.RecordBatch]:
    """A CSV input's text columns (:attr:`Input.text`) from its first row, block by block, as
    text; stops early where the file stops being readable (reading ``inp`` says why)."""
    dialect = inp.dialect or Dialect()
    copts = pacsv.ConvertOptions(
        column_types=dict.fromkeys(inp.text, pa.string()), include_columns=list(inp.text), strings_can_be_null=False
    )
    try:
        with pacsv.open_csv(
            inp.path, read_options=_read_options(dialect), parse_options=_parse_options(dialect), convert_options=copts
        ) as reader:
            yield from reader
    except (OSError, pa.ArrowException):  # not the output's: reading inp again says what it is
        return


# pyarrow's reader of a part of a file (a cluster's task) puts "Row #N: " before the conversion
_CSV_COLUMN = re.compile(r"In CSV column #(\d+): (?:Row #\d+: )?CSV conversion error to \w+: invalid value '(.*)'")


_CSV_RAGGED = re.compile(r"Expected (\d+) columns, got (\d+)")
_CSV_UTF8 = re.compile(r"In CSV column #(\d+): CSV conversion error to string: invalid UTF8")


def _csv_parse_error(path: str, name: str, exc: Exception, dialect: Dialect, hint: str = "") -> InputError:
    """A row with the wrong number of values, or too long for a block, named by its data row;
    else pyarrow's first line. ``hint``: why the header split wrong (:func:`delimiter_hint`),
    said instead of quoting advice for a row with the wrong number of values."""
    m = _CSV_RAGGED.search(str(exc))
    straddles = "straddl" in str(exc)  # a row longer than a block ("straddles two block boundaries")
    if "out of sync with chunker" in str(exc):  # pyarrow's reader splits a file at line breaks
        return InputError(
            f"{name}: a value in quotes holds a line break, which hconv does not read in CSV; "
            "remove the line breaks from that column, or convert the file from Parquet"
        )
    if not m and not straddles:
        return InputError(f"{name}: not a readable CSV file ({first_line(exc)})")
    expected = int(m.group(1)) if m else 0
    row, k = "", 0
    try:  # the error path only: find the row with Python's csv module
        with open(path, newline="", encoding="utf-8-sig") as f:
            for _ in range(dialect.comment_lines):
                f.readline()
            under = 1 + dialect.units_row  # the header, and a units row under it: no data rows
            for k, fields in enumerate(csv.reader(f, delimiter=dialect.delimiter)):  # noqa: B007 - k: below
                if k == 0:
                    expected = expected or len(fields)
                elif fields and len(fields) != expected and k >= under:
                    k -= under - 1
                    row = f"data row {k}"
                    if any("\n" in v for v in fields):  # a quote that ran on, often to the end of the file
                        return InputError(
                            f"{name}: data row {k} has {len(fields)} values where the header names {expected}, "
                            "one of them running over several lines: a quote opened and never closed? close it"
                        )
                    break
    except csv.Error:  # a value longer than the csv module's limit: pyarrow cut its row at a block's end
        return InputError(
            f"{name}: data row {k + 1} runs on for more than {csv.field_size_limit() >> 10} KiB in one value: "
            "a quote opened and never closed, or a line that is not CSV; fix that row"
        )
    except (OSError, UnicodeDecodeError):
        pass
    if not m:
        return InputError(
            f"{name}: {row or 'a row'} is longer than {CSV_BLOCK_BYTES >> 20} MiB, the longest row hconv reads; "
            "is it a CSV?"
        )
    return InputError(
        f"{name}: {row or 'a row'} has {m.group(2)} values, but the header names {expected} "
        f"column{'' if expected == 1 else 's'}; "
        "every row needs one value per column"
        + (hint or f" (quote a value that holds a {DELIMITERS[dialect.delimiter]})")
    )


def _csv_value_error(
    path: str, name: str, names: list, dialect: Dialect, exc: Exception, decimal_given: bool = False
) -> InputError:
    """Turn pyarrow's conversion error into one naming the column, the value and its row; for a
    number with a decimal comma read with a decimal point, the option that reads it
    (``decimal_given``: the point was given by ``--decimal``, which may be dropped)."""
    u = _CSV_UTF8.search(str(exc))
    if u:
        return InputError(
            f"{name}: column {names[int(u.group(1))]!r} holds text that is not UTF-8; convert the "
            "file to UTF-8 first (for example: iconv -f latin1 -t utf-8)"
        )
    m = _CSV_COLUMN.search(str(exc))
    if not m:
        return _csv_parse_error(path, name, exc, dialect)
    col, value = names[int(m.group(1))], m.group(2)
    where = ""
    try:  # a second pass, on the error path only, to find the row
        copts = pacsv.ConvertOptions(column_types={col: pa.string()}, include_columns=[col], strings_can_be_null=False)
        nulls = set(copts.null_values)
        seen = 0
        ropts, popts = _read_options(dialect), _parse_options(dialect)
        for batch in pacsv.open_csv(path, read_options=ropts, parse_options=popts, convert_options=copts):
            for k, v in enumerate(batch.column(0).to_pylist()):
                if v not in nulls:
                    try:
                        float(v.replace(",", ".") if dialect.decimal == "," and "." not in v else v)
                    except ValueError:
                        where = f" in data row {seen + k + 1}"
                        raise StopIteration from None
            seen += batch.num_rows
    except (StopIteration, OSError, pa.ArrowException):
        pass
    if dialect.decimal == "." and dialect.delimiter != "," and decimal_comma(value):
        drop = f" or drop {option('decimal')}" if decimal_given else ""
        return InputError(
            f"{name}: column {col!r} must be numeric but holds {quoted(value)}{where}, a number written with a "
            f"decimal comma; pass {option('decimal', ',')}{drop}"
        )
    return InputError(
        f"{name}: column {col!r} must be numeric but holds {quoted(value)}{where}; "
        "fix or blank that value (a blank becomes a row with status invalid_input)"
    )
