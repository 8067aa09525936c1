"""hconv on Arrow data: the input contract by column name, and ``convert_table``.

Input columns: ``Hx, Hy, Hz`` [kg·m²/s]; ``Ixx, Iyy, Izz, Ixy, Ixz, Iyz`` [kg·m²] (tensor entries,
see :mod:`hconv.inertia`); ``rx, ry, rz`` [m], needed by the document methods and optional
otherwise. Any other column passes through unchanged and in order. Output: the input columns,
then ``wx, wy, wz`` (field metadata ``unit``), ``residual``, ``cond``, ``status``.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from hconv import __version__, core, methods, status
from hconv.errors import InputError

H_COLUMNS = ("Hx", "Hy", "Hz")
I_COLUMNS = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
R_COLUMNS = ("rx", "ry", "rz")
W_COLUMNS = ("wx", "wy", "wz")
OUTPUT_COLUMNS = W_COLUMNS + ("residual", "cond", "status")

_STATUS_TYPE = pa.dictionary(pa.int8(), pa.string())


def required_columns(method: str) -> tuple[str, ...]:
    """The columns ``method`` cannot do without."""
    return H_COLUMNS + I_COLUMNS + (R_COLUMNS if methods.get(method).needs_r else ())


def numeric_columns(schema: pa.Schema, method: str) -> tuple[str, ...]:
    """The input columns hconv reads as numbers: the required ones, and r when it is all there."""
    cols = required_columns(method)
    if all(c in schema.names for c in R_COLUMNS) and R_COLUMNS[0] not in cols:
        cols += R_COLUMNS
    return cols


def _is_numeric(t: pa.DataType) -> bool:
    return pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t) or pa.types.is_null(t)


def check_schema(schema: pa.Schema, method: str, source: str = "input") -> None:
    """Raise :class:`InputError` if ``schema`` cannot feed ``method``; the message names the fix."""
    names = schema.names
    missing = [c for c in required_columns(method) if c not in names]
    if missing:
        need = "H, I and r" if methods.get(method).needs_r else "H and I"
        hint = f"; method {method!r} needs rx, ry, rz" if set(missing) <= set(R_COLUMNS) else ""
        raise InputError(
            f"{source}: missing column{'s' if len(missing) > 1 else ''} {', '.join(missing)}{hint}; "
            f"the {need} columns are {', '.join(required_columns(method))}"
        )
    partial_r = [c for c in R_COLUMNS if c in names]
    if partial_r and len(partial_r) < 3:
        lack = [c for c in R_COLUMNS if c not in names]
        raise InputError(f"{source}: has {', '.join(partial_r)} but not {', '.join(lack)}; give all of rx, ry, rz or none")
    for c in numeric_columns(schema, method):
        t = schema.field(c).type
        if not _is_numeric(t):
            raise InputError(f"{source}: column {c!r} has type {t}, but must be numeric; store it as a number (float64)")
    clash = [c for c in OUTPUT_COLUMNS if c in names]
    if clash:
        raise InputError(
            f"{source}: already has output column{'s' if len(clash) > 1 else ''} {', '.join(clash)}; "
            "rename or drop them (is this hconv's own output?)"
        )


def _floats(data: pa.Table, name: str) -> np.ndarray:
    """A numeric column as float64 with nulls as NaN, shape ``(N,)``."""
    col = data.column(name)
    if pa.types.is_null(col.type):
        return np.full(len(col), np.nan)
    return pc.cast(col, pa.float64()).to_numpy()


def output_fields(method: str, precision: int, diagnostics: bool = True) -> list[pa.Field]:
    """The fields hconv appends, with their units as field metadata."""
    m = methods.get(method)
    wtype = pa.float64() if precision == 64 else pa.float32()
    meta = {"unit": m.unit, "method": m.name}
    fields = [pa.field(c, wtype, metadata=meta) for c in W_COLUMNS]
    if diagnostics:
        fields.append(pa.field("residual", pa.float64(), metadata={
            "unit": "1", "description": "|w - inv(I)H| / |inv(I)H|; for m^2/s methods, of the bare numbers"}))
    fields.append(pa.field("cond", pa.float64(), metadata={"unit": "1", "description": "2-norm condition number of I"}))
    fields.append(pa.field("status", _STATUS_TYPE))
    return fields


def convert_table(data, method: str = "exact", precision: int = 64, diagnostics: bool = True,
                  *, source: str = "table") -> pa.Table:
    """Convert every row of a pyarrow Table or RecordBatch; returns a Table.

    The result holds the input columns unchanged, then ω and the diagnostics (see the module
    docstring). Raises :class:`hconv.errors.InputError` for a schema that cannot be used;
    per-row problems become statuses. ``source`` names the data in error messages.
    """
    if isinstance(data, pa.RecordBatch):
        data = pa.Table.from_batches([data])
    check_schema(data.schema, method, source)
    H = np.column_stack([_floats(data, c) for c in H_COLUMNS]) if data.num_rows else np.empty((0, 3))
    I = np.column_stack([_floats(data, c) for c in I_COLUMNS]) if data.num_rows else np.empty((0, 6))
    r = None
    if all(c in data.schema.names for c in R_COLUMNS):
        r = np.column_stack([_floats(data, c) for c in R_COLUMNS]) if data.num_rows else np.empty((0, 3))
    res = core.convert(H, I, r, method=method, precision=precision, diagnostics=diagnostics)
    columns = [pa.array(res.w[:, k]) for k in range(3)]
    if diagnostics:
        columns.append(pa.array(res.residual))
    columns.append(pa.array(res.cond))
    columns.append(pa.DictionaryArray.from_arrays(
        pa.array(res.status_code.astype(np.int8), type=pa.int8()), pa.array(status.STATUSES)))
    fields = output_fields(method, precision, diagnostics)
    meta = dict(data.schema.metadata or {})
    meta.update({b"hconv.method": method.encode(), b"hconv.version": __version__.encode()})
    schema = pa.schema(list(data.schema) + fields, metadata=meta)
    return pa.Table.from_arrays(list(data.columns) + columns, schema=schema)
