"""JSON lines in (read only): one JSON object per line, each key a column, read by pyarrow's
streaming JSON reader a block (:data:`JSON_BLOCK_BYTES`) at a time.

pyarrow infers each column's type from the first block, and a later block whose values do not
fit fails (``1`` in the first rows, ``1.5`` later); so the columns hconv reads are read as
float64 (lists of float64) whatever the first block holds, and the other columns keep the
first block's types. A line that is not a JSON object, or whose value for a key is of another
JSON type than an earlier line's, is named by its line number: pyarrow's own message counts rows
from 0 within a block, so on that error path the file is read again, line by line, to find it.
pyarrow reads no column whose values change type, not even as text, so such a column hconv does
not read is refused too, named with what to do."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator

import pyarrow as pa
import pyarrow.json as pajson

from hconv.errors import HconvError, InputError, first_line, quoted
from hconv.tables import layout
from hconv.tables.inputs import FileStat, Input, read_batches, unreadable
from hconv.tables.job import Job
from hconv.tables.sniff import what_it_is

JSON_BLOCK_BYTES = 1 << 20


def _bad_line(path: str, name: str, exc: Exception, job: Job, known: set | None = None) -> InputError:
    """The error for a JSON lines file pyarrow could not read: the first line that is not a JSON
    object, or (``known``: the first block's keys) that has a key the first block lacks, or whose
    value is of another JSON type than an earlier line's for that key, by its line number in the
    file (blank lines counted); or else pyarrow's reason. pyarrow's own count is of rows, from 0,
    within a block, which names no line a user can find; and it reads no column whose values
    change type (not even as text), so such a column is named, with what to do."""
    kinds: dict[str, tuple[str, int]] = {}  # key -> the JSON type of its first non-null value, its line
    try:
        with open(path, "rb") as f:
            for number, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    value = json.loads(line)
                except ValueError as err:
                    text = line.decode("utf-8", "replace").strip()
                    return InputError(
                        f"{name}: line {number} is not valid JSON ({str(err).split(':')[0]}): {quoted(text)}; "
                        "JSON lines holds one complete JSON object per line: fix or remove that line"
                    )
                if not isinstance(value, dict):
                    return InputError(
                        f"{name}: line {number} is a JSON {type(value).__name__.replace('dict', 'object')}, "
                        'not an object; JSON lines holds one object per line, {"column": value, ...}'
                    )
                new = sorted(set(value) - known) if known is not None else []
                if new:
                    return InputError(
                        f"{name}: line {number} has the key {new[0]!r}, which no line of the first block "
                        f"({JSON_BLOCK_BYTES >> 20} MiB) has; the first lines fix the columns: give every "
                        "key in the first line (null where it has no value)"
                    )
                changed = _type_change(value, kinds, number)
                if changed:
                    key, kind, (was, at) = changed
                    fix = (
                        f"hconv reads it as numbers: make every line's {key!r} a number (or null)"
                        if key in _read_by_hconv(kinds, job, name)
                        else f"write every {key!r} as one type (text in quotes, or numbers), or leave the "
                        f"column out: jq -c 'del(.[{json.dumps(key)}])' {name}"
                    )
                    return InputError(
                        f"{name}: line {number}: column {key!r} holds {kind} where line {at} holds {was}; {fix}"
                    )
    except OSError as err:
        return unreadable(name, err)
    return InputError(
        f"{name}: cannot be read as JSON lines ({first_line(exc)}); a column's values change type part-way "
        "(the first rows fix each column's type): write that column with one type throughout"
    )


def _kind(value: object) -> str | None:
    """The JSON type of ``value`` as pyarrow tells them apart (an integer and a fraction are both
    numbers); None for null, which fits any."""
    if value is None:
        return None
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, (int, float)):
        return "a number"
    return "text" if isinstance(value, str) else "a list" if isinstance(value, list) else "an object"


def _type_change(row: dict, kinds: dict, number: int) -> tuple[str, str, tuple[str, int]] | None:
    """The first key of ``row`` whose value's JSON type differs from the one ``kinds`` holds for
    it (which this records for keys not seen yet): the key, its kind here, and the first kind and
    its line; or None."""
    for key, value in row.items():
        kind = _kind(value)
        if kind is None:
            continue
        first = kinds.setdefault(key, (kind, number))
        if first[0] != kind:
            return key, kind, first
    return None


def _read_by_hconv(kinds: dict, job: Job, name: str) -> set:
    """The columns among ``kinds``' keys that hconv reads as numbers; empty when those keys are
    not yet a table hconv reads (the message then gives the advice for any column)."""
    listed = pa.list_(pa.float64())
    schema = pa.schema([(k, listed if kind == "a list" else pa.float64()) for k, (kind, _) in kinds.items()])
    try:
        return set(layout.plan(schema, job, name).numeric)
    except HconvError:
        return set()


def _as_float(t: pa.DataType) -> pa.DataType:
    """float64 for the numbers hconv reads, and lists of them."""
    if pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t):
        return pa.list_(pa.float64())
    if pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_null(t):
        return pa.float64()
    return t


def open_jsonl(path: str, name: str, job: Job) -> Input:
    """The JSON lines file ``path``, a block of :data:`JSON_BLOCK_BYTES` at a time."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 12)
    except OSError as exc:
        raise unreadable(name, exc) from None
    if not head.strip():
        raise InputError(f'{name}: the file is empty; JSON lines needs one object per line, {{"column": value, ...}}')
    what = what_it_is(head, path, name, "jsonl")
    if what:
        raise InputError(f"{name}: {what}")
    if head.lstrip().startswith(b"[") and head.lstrip()[1:].lstrip().startswith(b"{"):  # an array of objects
        raise InputError(
            f"{name}: is one JSON array, not JSON lines (one object per line); write a line per object "
            f"first: jq -c '.[]' {name} > {os.path.splitext(name)[0]}-lines.jsonl"
        )
    ropts = pajson.ReadOptions(block_size=JSON_BLOCK_BYTES)
    try:
        with pajson.open_json(pa.OSFile(path), read_options=ropts) as probe:
            first = probe.schema
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, OSError) and exc.errno is not None:
            raise unreadable(name, exc) from None
        raise _bad_line(path, name, exc, job) from None
    plan = layout.plan(first, job, name)
    numeric = set(plan.numeric)
    schema = pa.schema([f.with_type(_as_float(f.type)) if f.name in numeric else f for f in first])
    popts = pajson.ParseOptions(explicit_schema=schema, unexpected_field_behavior="error")
    try:
        source = pa.OSFile(path)
        at_open = FileStat.of(source.fileno())
        reader = pajson.open_json(source, read_options=ropts, parse_options=popts)
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, OSError) and exc.errno is not None:
            raise unreadable(name, exc) from None
        raise _bad_line(path, name, exc, job, set(schema.names)) from None
    done = [0]
    fd = source.fileno()

    def failed(exc: Exception) -> InputError:
        return _bad_line(path, name, exc, job, set(schema.names))

    def batches() -> Iterator[pa.RecordBatch]:
        for batch in read_batches(reader, name, fd, at_open, failed):
            done[0] += batch.num_rows
            yield batch

    it: Iterator[pa.RecordBatch] = batches()
    if any(g.is_list and g.size is None for g in plan.groups.values()):
        head_batch = next(it, None)
        if head_batch is not None:
            plan = plan.resolve(pa.Table.from_batches([head_batch]))
            it = _chain(head_batch, it)
    return Input(name, schema, it, None, lambda: done[0], plan, [reader.close, source.close], path=path)


def _chain(first: pa.RecordBatch, rest: Iterator[pa.RecordBatch]) -> Iterator[pa.RecordBatch]:
    yield first
    yield from rest
