"""JSON lines in (read only): one JSON object per line, each key a column, read by pyarrow's
streaming JSON reader a block (:data:`JSON_BLOCK_BYTES`) at a time.

pyarrow infers each column's type from the first block, and a later block whose values do not
fit fails (``1`` in the first rows, ``1.5`` later); so the columns hconv reads are read as
float64 (lists of float64) whatever the first block holds, and the other columns keep the
first block's types. A line that is not a JSON object is named by its line number: pyarrow's
own message counts rows within a block, so on that error path the file is read again, line by
line, to find it."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator

import pyarrow as pa
import pyarrow.json as pajson

from hconv.errors import InputError, first_line
from hconv.tables import layout
from hconv.tables.inputs import FileStat, Input, changed_while_read, unreadable
from hconv.tables.job import Job
from hconv.tables.sniff import what_it_is

JSON_BLOCK_BYTES = 1 << 20


def _bad_line(path: str, name: str, exc: Exception, known: set | None = None) -> InputError:
    """The error for a JSON lines file pyarrow could not read: the first line that is not a JSON
    object, or (``known``: the first block's keys) that has a key the first block lacks, by
    number; or else pyarrow's reason (a column whose values change type)."""
    try:
        with open(path, "rb") as f:
            for number, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    value = json.loads(line)
                except ValueError as err:
                    text = line.decode("utf-8", "replace").strip()
                    shown = text if len(text) <= 60 else text[:57] + "..."
                    return InputError(
                        f"{name}: line {number} is not valid JSON ({str(err).split(':')[0]}): {shown!r}; "
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
    except OSError as err:
        return unreadable(name, err)
    return InputError(
        f"{name}: cannot be read as JSON lines ({first_line(exc)}); a column's values change type part-way "
        "(the first rows fix each column's type): write that column with one type throughout"
    )


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
        raise _bad_line(path, name, exc) from None
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
        raise _bad_line(path, name, exc, set(schema.names)) from None
    done = [0]
    fd = source.fileno()

    def batches() -> Iterator[pa.RecordBatch]:
        while True:
            try:
                batch = reader.read_next_batch()
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - only pyarrow's reading runs in this try
                raise changed_while_read(name, fd, at_open, f"; {first_line(exc)}") or _bad_line(
                    path, name, exc, set(schema.names)
                ) from None
            done[0] += batch.num_rows
            yield batch
        changed = changed_while_read(name, fd, at_open)
        if changed:
            raise changed

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
