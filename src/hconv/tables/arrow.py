"""hconv on Arrow data: ``convert_table`` for a pyarrow Table or RecordBatch and a
:class:`~hconv.tables.job.Job`, and the fields it appends.

Input columns are found by name (see :mod:`hconv.tables.layout` for every set and inertia form); any
other column passes through unchanged and in order. Output: the input columns, then ``wx, wy, wz``
(field metadata ``unit``), ``residual``, ``cond``, ``status`` and, with ``--degenerate pinv|lock``,
``null_x, null_y, null_z, null_dim``. In Parquet, every column hconv read also records the unit
it was read in as field metadata ``unit``.

:func:`output_schema` gives that result's schema from the input's alone, for engines that must
declare it before they run (Dask, Spark, Ray); :func:`convert_batch` builds every result on the
same function, so the two cannot drift apart. :func:`units_of` reads the units a schema or a set
of Parquet files stores, for an engine that drops field metadata on its way to hconv (DuckDB,
Polars, pandas, Spark) and for a reader of what such an engine wrote.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from hconv.errors import InputError, UsageError, first_line
from hconv.solve import bodies, methods, options, status, units
from hconv.tables import arrays, layout, storage
from hconv.tables.job import Job
from hconv.tables.sets import QUANTITY
from hconv.version import __version__

_STATUS_TYPE = pa.dictionary(pa.int8(), pa.string())
_STATUSES = arrays.strings(status.STATUSES)  #: the status column's dictionary


def output_fields(job: Job) -> list[pa.Field]:
    """The fields a conversion with ``job`` appends, with their units as field metadata."""
    m = methods.get(job.method)
    wtype = pa.float64() if job.precision == 64 else pa.float32()
    meta = {"unit": job.unit, "method": m.name}
    fields = [pa.field(c, wtype, metadata=meta) for c in layout.W_COLUMNS]
    if job.diagnostics:
        fields.append(
            pa.field(
                "residual",
                pa.float64(),
                metadata={
                    "unit": "1",
                    "description": "|w - inv(I)H| / |inv(I)H|; for m^2/s methods, of the bare numbers",
                },
            )
        )
    fields.append(pa.field("cond", pa.float64(), metadata={"unit": "1", "description": "2-norm condition number of I"}))
    fields.append(pa.field("status", _STATUS_TYPE))
    if job.conventions.degenerate != "error":
        for c in layout.NULL_COLUMNS[:3]:
            fields.append(
                pa.field(
                    c,
                    pa.float64(),
                    metadata={
                        "unit": "1",
                        "description": f"unit axis of the dropped principal moment, {job.conventions.w_frame} frame",
                    },
                )
            )
        fields.append(pa.field("null_dim", pa.int8(), metadata={"description": "principal moments dropped"}))
    return [f.with_name(job.prefix + f.name) for f in fields] if job.prefix else fields


def convert_table(
    data: Any,
    method: str | None = None,
    precision: int | None = None,
    diagnostics: bool | None = None,
    *,
    source: str = "table",
    job: Job | None = None,
    plan: layout.Layout | None = None,
    prefix: str | None = None,
) -> Any:
    """Convert every row of a table; returns the same kind of table.

    ``data``: a pyarrow Table or RecordBatch, or any object that speaks the Arrow PyCapsule
    interface (a pandas >= 2.2 or polars DataFrame, a DuckDB relation, a pyarrow
    RecordBatchReader). A polars DataFrame gives a polars DataFrame, a pandas DataFrame a pandas
    one with the same index; anything else a pyarrow Table.

    The result holds the input columns unchanged, then ω and the diagnostics (see the module
    docstring). ``method`` (default exact), ``precision`` (64) and ``diagnostics`` (True) make
    the run configuration; or ``job`` carries it whole, with conventions, units and mapping (then
    they are refused beside it, rather than one silently winning); ``plan`` is the input's layout from
    :func:`hconv.tables.layout.plan`, for a caller converting many batches of one file. Raises
    :class:`hconv.errors.InputError` or
    ``UsageError`` for a schema or options that cannot be used; per-row problems become statuses.
    ``source`` names the data in error messages. ``prefix`` goes before the name of every column
    hconv appends (:class:`~hconv.tables.job.Job`'s ``prefix``).
    """
    given = data
    table = _as_table(data)
    job = options.configure(
        Job, "convert_table", job, method=method, precision=precision, diagnostics=diagnostics, prefix=prefix
    )
    return _as_given(convert_batch(table, job, plan, source)[0], given)


def _as_table(data: object) -> pa.Table:
    """``data`` as a pyarrow Table: a Table, a RecordBatch, or any object that speaks the Arrow
    PyCapsule interface (``__arrow_c_stream__`` or ``__arrow_c_array__``: pandas >= 2.2, polars,
    DuckDB relations, pyarrow's readers), read without a copy where its library allows."""
    if isinstance(data, pa.Table):
        return data
    if isinstance(data, pa.RecordBatch):
        return pa.Table.from_batches([data])
    kind = f"{type(data).__module__.split('.')[0]}.{type(data).__name__}"
    if hasattr(data, "__arrow_c_stream__") or hasattr(data, "__arrow_c_array__"):
        try:
            return pa.table(data)
        except (pa.ArrowException, TypeError, ValueError) as exc:
            raise UsageError(
                f"convert_table takes a table; {kind} gives Arrow data that is not one ({first_line(exc)}): "
                "pass a DataFrame (a Series is one column: make a frame of H, I and the rest)"
            ) from None
    lazy = " (call .collect() first)" if hasattr(data, "collect") else ""
    raise UsageError(
        f"convert_table takes a pyarrow Table or RecordBatch, got {type(data).__name__}{lazy}; or any table that "
        "speaks Arrow: a pandas (2.2 or later) or polars DataFrame, a DuckDB relation"
    )


def _as_given(result: pa.Table, given: object) -> object:
    """``result`` as the kind of table ``given`` was: a polars or pandas DataFrame for one (its
    index kept), else the pyarrow Table."""
    module = type(given).__module__.split(".")[0]
    if module == "polars" and type(given).__name__ == "DataFrame":
        import polars

        return polars.from_arrow(result)
    if module == "pandas" and type(given).__name__ == "DataFrame":
        frame = result.to_pandas()
        frame.index = given.index  # type: ignore[attr-defined]
        return frame
    return result


def output_schema(
    input_schema: pa.Schema,
    method: str | None = None,
    precision: int | None = None,
    diagnostics: bool | None = None,
    *,
    source: str = "schema",
    job: Job | None = None,
    prefix: str | None = None,
) -> pa.Schema:
    """The schema :func:`convert_table` returns for a table of ``input_schema``, converting nothing.

    Equal to ``convert_table(table, ...).schema`` for any table of that schema, metadata included:
    the input's fields in order (each column hconv reads with its ``unit``), then ``wx, wy, wz``
    (float64, or float32 with ``precision=32``; metadata ``unit`` and ``method``), ``residual``,
    ``cond``, ``status`` (``dictionary<int8, string>``) and, with a degenerate mode, the null axis;
    the schema's metadata is the input's plus ``hconv.method`` and ``hconv.version``. Takes the
    keywords of :func:`convert_table`, and raises its errors for a schema it could not convert
    (a missing column, two inertia forms, an output name already taken). Engines that declare a
    result's schema before running (Dask's ``to_parquet(schema=...)``, Spark's ``mapInArrow``)
    take it from here.
    """
    if not isinstance(input_schema, pa.Schema):
        hint = "; pass its .schema" if hasattr(input_schema, "schema") else ""
        raise UsageError(f"output_schema takes a pyarrow Schema, got {type(input_schema).__name__}{hint}")
    job = options.configure(
        Job, "output_schema", job, method=method, precision=precision, diagnostics=diagnostics, prefix=prefix
    )
    return result_schema(input_schema, job, layout.plan(input_schema, job, source))


def units_of(source: pa.Schema | str | os.PathLike, *, endpoint_url: str | None = None) -> dict[str, str]:
    """Each column's unit, ``{column: unit}`` in column order, as ``source`` stores it: a pyarrow
    Schema, or Parquet files (one file, a directory, a glob or a URI, as ``hconv convert`` takes
    them; ``endpoint_url`` as there). A column's unit is its field metadata ``unit`` (what hconv
    and pyarrow write), else the one in the field metadata of Spark's schema (what Spark writes,
    which pyarrow reads without); a column with neither is left out.

    For an engine that drops field metadata before hconv sees the data, ``Job(field_units=
    units_of(files))`` gives hconv the units the files carry; for a reader, the units of what
    such an engine wrote. Of many files, only the footers are read, and a column stored in two
    units is an InputError naming both files: an engine that drops the metadata would mix them.
    """
    if isinstance(source, pa.Schema):
        return layout.stored_units(source)
    if not isinstance(source, (str, os.PathLike)):
        raise UsageError(f"units_of takes a pyarrow Schema or the path of Parquet files, got {type(source).__name__}")
    spec = os.fspath(source)
    src = storage.source(spec, endpoint_url)
    found: dict[str, tuple[str, str]] = {}  # column -> (unit, the file that gave it)
    names: list[str] = []
    for f in src.files(None):
        if storage.format_by_name(f.rel) != "parquet":
            continue
        name = src.place.name(f.rel)
        try:
            schema = pq.read_schema(src.place.path(f.rel), filesystem=src.place.fs)
        except (OSError, pa.ArrowException) as exc:
            raise InputError(f"{name}: cannot read its Parquet footer ({first_line(exc)})") from None
        for column, unit in layout.stored_units(schema).items():
            if column not in found:
                found[column] = (unit, name)
                names.append(column)
            elif found[column][0] != unit:
                raise InputError(
                    f"{name}: column {column!r} is in {unit}, but in {found[column][0]} in {found[column][1]}; "
                    "convert such files separately, each with its own units"
                )
    return {c: found[c][0] for c in names}


#: result schemas of recent (input schema, Job, plan): one for each batch cost a small file 0.1 ms
_RESULTS = layout.SchemaMemo()


def result_schema(schema: pa.Schema, job: Job, plan: layout.Layout) -> pa.Schema:
    """The schema of a conversion of a table of ``schema`` planned as ``plan``: the one owner of
    it, for :func:`output_schema` and for every converted batch."""
    # plan.groups is kept with the value, so that its id names it while the value is kept
    # (a plan of the memo of plans shares its groups across files)
    groups, result = _RESULTS.value(
        schema, (job, id(plan.groups)), lambda: (plan.groups, _result_schema(schema, job, plan))
    )
    return result if groups is plan.groups else _result_schema(schema, job, plan)


def _result_schema(schema: pa.Schema, job: Job, plan: layout.Layout) -> pa.Schema:
    meta = dict(schema.metadata or {})
    meta.update({b"hconv.method": methods.get(job.method).name.encode(), b"hconv.version": __version__.encode()})
    meta.pop(layout.PREFIX_KEY, None)  # an input hconv wrote with a prefix: this run's is its own
    if job.prefix:
        meta[layout.PREFIX_KEY] = job.prefix.encode()
    return pa.schema(_with_input_units(schema, plan) + output_fields(job), metadata=meta)


def convert_batch(
    data: pa.Table, job: Job, plan: layout.Layout | None = None, source: str = "table", first_row: int = 0
) -> tuple[pa.Table, str]:
    """:func:`convert_table` on a checked Table and Job, and the engine that converted it
    (``numpy`` or ``compiled``), which the file pipeline reports. ``first_row``: where
    ``data`` starts in its file, so that an error names the file's row."""
    if plan is None:
        plan = layout.plan(data.schema, job, source)
    sets, form = plan.read(data, first_row)
    res = bodies.solve(sets, form, job.method, job.precision, job.conventions, job.diagnostics, job.engine)
    w = res.w
    scale = job.omega_scale
    if scale != 1.0:
        w = w * w.dtype.type(scale)
    columns = [arrays.from_numpy(w[:, k]) for k in range(3)]
    if job.diagnostics:
        assert res.residual is not None  # a solve with diagnostics has its residual
        columns.append(arrays.from_numpy(res.residual))
    columns.append(arrays.from_numpy(res.cond))
    columns.append(pa.DictionaryArray.from_arrays(arrays.from_numpy(res.status_code.astype(np.int8)), _STATUSES))
    if res.null_axis is not None and res.null_dim is not None:  # degenerate pinv or lock: both set
        columns += [arrays.from_numpy(res.null_axis[:, k]) for k in range(3)]
        columns.append(arrays.from_numpy(res.null_dim.astype(np.int8, copy=False)))
    return pa.Table.from_arrays(list(data.columns) + columns, schema=result_schema(data.schema, job, plan)), res.engine


def _with_input_units(schema: pa.Schema, plan: layout.Layout) -> list[pa.Field]:
    """The input's fields, each column hconv read carrying the unit it was read in."""
    unit_of = {}
    for g in plan.groups.values():
        si = units.SI[QUANTITY[g.name]]
        for k, c in enumerate(g.columns):
            unit_of[c] = g.units[k] if k < len(g.units) and g.units[k] else si
    fields = []
    for f in schema:
        if f.name in unit_of and unit_of[f.name]:
            meta = dict(f.metadata or {})
            meta[b"unit"] = unit_of[f.name].encode()
            f = f.with_metadata(meta)
        fields.append(f)
    return fields
