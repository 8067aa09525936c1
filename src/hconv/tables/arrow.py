"""hconv on Arrow data: a :class:`Job` (method, conventions, units), and ``convert_table``.

Input columns are found by name (see :mod:`hconv.tables.layout` for every set and inertia form); any
other column passes through unchanged and in order. Output: the input columns, then ``wx, wy, wz``
(field metadata ``unit``), ``residual``, ``cond``, ``status`` and, with ``--degenerate pinv|lock``,
``null_x, null_y, null_z, null_dim``. In Parquet, every column hconv read also records the unit
it was read in as field metadata ``unit``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import pyarrow as pa

from hconv import __version__
from hconv.solve import bodies
from hconv.tables import layout
from hconv.solve import methods
from hconv.solve import status
from hconv.solve import units
from hconv.errors import InputError, UsageError

W_COLUMNS = ("wx", "wy", "wz")
NULL_COLUMNS = ("null_x", "null_y", "null_z", "null_dim")
OUTPUT_COLUMNS = W_COLUMNS + ("residual", "cond", "status")
RESERVED = OUTPUT_COLUMNS + NULL_COLUMNS
#: The classic six-number layout's columns, for messages and examples.
H_COLUMNS = layout.VECTOR_SETS["H"]
I_COLUMNS = layout.SIX
R_COLUMNS = layout.VECTOR_SETS["r"]

_STATUS_TYPE = pa.dictionary(pa.int8(), pa.string())


@dataclass(frozen=True)
class Job:
    """Everything a conversion needs besides the data. Defaults: hconv's own conventions."""

    method: str = "exact"
    precision: int = 64
    diagnostics: bool = True
    conventions: bodies.Conventions = field(default_factory=bodies.Conventions)
    mapping: tuple = ()  #: (hconv name, column) pairs
    unit_options: tuple = ()  #: (set, hconv name or column; unit) pairs
    quat_order: str = "wxyz"
    omega_unit: str = "rad/s"

    def check(self) -> None:
        """UsageError for options that cannot go together, before any file is touched."""
        try:
            m = methods.get(self.method)
            self.conventions.check(self.method)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        if self.precision not in (64, 32):
            raise UsageError(f"--precision must be 64 or 32, got {self.precision}")
        if m.unit != methods.RAD_S and units.factor("w", self.omega_unit, "--omega-unit") != 1.0:
            raise UsageError(f"--omega-unit {self.omega_unit}: method {self.method!r} gives {m.unit}, "
                             "which is not an angular velocity and cannot be converted")

    def spec(self) -> layout.Spec:
        return layout.Spec(tuple(self.conventions.needs(self.method).items()), self.mapping, self.unit_options, self.quat_order)

    def plan(self, schema: pa.Schema, source: str = "input") -> layout.Layout:
        """The input's column sets for this job; InputError or UsageError naming the fix."""
        return layout.plan(schema, self.spec(), source, reserved=RESERVED)

    @property
    def unit(self) -> str:
        """The unit of ω in the output."""
        m = methods.get(self.method)
        return self.omega_unit if m.unit == methods.RAD_S else m.unit

    def output_fields(self) -> list[pa.Field]:
        """The fields hconv appends, with their units as field metadata."""
        m = methods.get(self.method)
        wtype = pa.float64() if self.precision == 64 else pa.float32()
        meta = {"unit": self.unit, "method": m.name}
        fields = [pa.field(c, wtype, metadata=meta) for c in W_COLUMNS]
        if self.diagnostics:
            fields.append(pa.field("residual", pa.float64(), metadata={
                "unit": "1", "description": "|w - inv(I)H| / |inv(I)H|; for m^2/s methods, of the bare numbers"}))
        fields.append(pa.field("cond", pa.float64(), metadata={"unit": "1", "description": "2-norm condition number of I"}))
        fields.append(pa.field("status", _STATUS_TYPE))
        if self.conventions.degenerate != "error":
            frame = self.conventions.omega_frame or self.conventions.frame
            for c in NULL_COLUMNS[:3]:
                fields.append(pa.field(c, pa.float64(), metadata={
                    "unit": "1", "description": f"unit axis of the dropped principal moment, {frame} frame"}))
            fields.append(pa.field("null_dim", pa.int8(), metadata={"description": "principal moments dropped"}))
        return fields


def output_fields(method: str, precision: int, diagnostics: bool = True) -> list[pa.Field]:
    """The fields a plain conversion appends (see :meth:`Job.output_fields`)."""
    return Job(method, precision, diagnostics).output_fields()


def convert_table(data, method: str = "exact", precision: int = 64, diagnostics: bool = True,
                  *, source: str = "table", job: Optional[Job] = None,
                  plan: Optional[layout.Layout] = None) -> pa.Table:
    """Convert every row of a pyarrow Table or RecordBatch; returns a Table.

    The result holds the input columns unchanged, then ω and the diagnostics (see the module
    docstring). ``job`` carries the conventions, units and mapping (it overrides ``method``,
    ``precision`` and ``diagnostics``); ``plan`` is the input's layout from :meth:`Job.plan`, for a
    caller converting many batches of one file. Raises :class:`hconv.errors.InputError` or
    ``UsageError`` for a schema or options that cannot be used; per-row problems become statuses.
    ``source`` names the data in error messages.
    """
    if isinstance(data, pa.RecordBatch):
        data = pa.Table.from_batches([data])
    if job is None:
        job = Job(method, precision, diagnostics)
        job.check()
    if plan is None:
        plan = job.plan(data.schema, source)
    sets = plan.read(data)
    try:
        res = bodies.solve(sets, plan.form, job.method, job.precision, job.conventions, job.diagnostics)
    except ValueError as exc:  # options that only the data could contradict
        raise InputError(f"{source}: {exc}") from None
    w = res.w
    if job.unit != methods.M2_S:
        scale = units.omega_factor(job.omega_unit)
        if scale != 1.0:
            w = w * w.dtype.type(scale)
    columns = [pa.array(w[:, k]) for k in range(3)]
    if job.diagnostics:
        columns.append(pa.array(res.residual))
    columns.append(pa.array(res.cond))
    columns.append(pa.DictionaryArray.from_arrays(
        pa.array(res.status_code.astype(np.int8), type=pa.int8()), pa.array(status.STATUSES)))
    if job.conventions.degenerate != "error":
        columns += [pa.array(res.null_axis[:, k]) for k in range(3)]
        columns.append(pa.array(res.null_dim, type=pa.int8()))
    meta = dict(data.schema.metadata or {})
    meta.update({b"hconv.method": job.method.encode(), b"hconv.version": __version__.encode()})
    schema = pa.schema(_with_input_units(data.schema, plan) + job.output_fields(), metadata=meta)
    return pa.Table.from_arrays(list(data.columns) + columns, schema=schema)


def _with_input_units(schema: pa.Schema, plan: layout.Layout) -> list[pa.Field]:
    """The input's fields, each column hconv read carrying the unit it was read in."""
    unit_of = {}
    for g in plan.groups.values():
        si = units.SI[layout.QUANTITY[g.name]]
        for k, c in enumerate(g.columns):
            unit_of[c] = (g.units[k] if k < len(g.units) and g.units[k] else si)
    fields = []
    for f in schema:
        if f.name in unit_of and unit_of[f.name]:
            meta = dict(f.metadata or {})
            meta[b"unit"] = unit_of[f.name].encode()
            f = f.with_metadata(meta)
        fields.append(f)
    return fields


def check_schema(schema: pa.Schema, method: str, source: str = "input") -> None:
    """Raise :class:`InputError` if ``schema`` cannot feed ``method`` with default conventions."""
    Job(method).plan(schema, source)
