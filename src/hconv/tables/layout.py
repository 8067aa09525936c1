"""Which columns hold what: the input's column sets (:mod:`hconv.tables.sets`), found by name, and
the form of its inertia.

Each of hconv's names is found (:func:`hconv.tables.columns.find`), first to last: by ``--map``; in a column of that
exact name; in one of that name with its unit written after it (``Hx [kg*m^2/s]``, ``Ixx (g*cm^2)``)
or in a struct's field, by its struct's name and its own run together (``H.x``: Hx, so that a
struct ``H`` with fields x, y, z is the set H); then the same without regard to case, for names
of more than one letter. Two columns for one name at the same step are an error naming both and
``--map``. A struct's fields are columns by their dotted path (``--map Hx=L.a``); the struct
itself is never read as a number, and passes through as it was.

A value's unit, first to last: ``--unit`` (by column, by hconv's name, by set); the column's
field metadata ``unit`` (:func:`stored_units`, Spark's schema too); the Job's ``field_units``
(metadata an engine dropped); the unit written in its header; else SI. A header's unit that pint
cannot read, or of another quantity, is an InputError naming the column and the ``--unit`` that
wins over it.

The columns hconv appends (:data:`RESERVED`) carry the Job's ``prefix`` (``--prefix``) before
their names, which a converted table's schema records (:func:`output_name`); an input that has
one of those names already is refused, naming ``--prefix``.

The inertia forms and their columns are :mod:`hconv.solve.forms`' registry. A file uses one form,
chosen by its columns, for every row; two forms at once (``I1`` and ``Ixx``, say) is an error, as
is a set with some of its columns missing. With q present the tensor
is taken to be in the body frame (as engines store it); without q, in the frame of H.

Planning is a pure function of the input's schema and the :class:`~hconv.tables.job.Job`
(:func:`plan`); the :class:`Layout` it returns is immutable, so batches may be read on several
threads at once. The one thing a schema cannot tell, the length of a variable-length list column,
is fixed by :meth:`Layout.resolve` from the first batch, before any batch is converted.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable, Sized
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from hconv.errors import InputError, UsageError, entry, option
from hconv.solve import forms, units
from hconv.tables import arrays, columns
from hconv.tables.job import Job
from hconv.tables.sets import OPTIONAL_SETS, QUANTITY, VECTOR_SETS, all_names, header_name

#: The columns hconv writes after the input's.
W_COLUMNS = ("wx", "wy", "wz")
NULL_COLUMNS = ("null_x", "null_y", "null_z", "null_dim")
OUTPUT_COLUMNS = W_COLUMNS + ("residual", "cond", "status")
#: ω's unit, a column of its own in CSV output (in Parquet it is wx, wy, wz's metadata).
UNIT_COLUMN = "w_unit"
#: Every name hconv writes: an input that has one is refused, naming it, so that no output holds
#: a name twice (or one column of the input and another of hconv under one name).
RESERVED = OUTPUT_COLUMNS + NULL_COLUMNS + (UNIT_COLUMN,)
#: The schema metadata key of a converted table that records the Job's ``prefix`` (only when one
#: was given), so that a writer finds hconv's columns by :func:`output_name`.
PREFIX_KEY = b"hconv.prefix"
T = TypeVar("T")
#: The file metadata key under which Spark stores its schema, field metadata included, in the
#: Parquet files it writes. Spark writes no Arrow schema, so pyarrow reads its fields bare.
SPARK_SCHEMA_KEY = b"org.apache.spark.sql.parquet.row.metadata"


@dataclass(frozen=True)
class Group:
    """One column set as found in the input."""

    name: str  #: the set: H, I, q, r, m, v or w_obs
    columns: tuple  #: the input's column names, one per value; or the one list column
    is_list: bool
    size: int | None  #: values per row; None for a list column whose rows have not been seen
    units: tuple = ()  #: the unit of each value as given (a string; "" means SI)
    factors: tuple = ()  #: to SI, one per value


@dataclass(frozen=True)
class Layout:
    """The input's sets and the inertia form; :meth:`read` turns a batch into SI arrays.

    ``form`` is a name in :data:`hconv.solve.forms.FORMS`, or None for a list column ``I`` whose
    length no row has shown yet.
    """

    groups: dict
    form: str | None
    source: str
    quat_order: str = "wxyz"

    @property
    def numeric(self) -> tuple:
        """The input columns hconv reads as numbers."""
        return tuple(c for g in self.groups.values() for c in g.columns)

    def resolve(self, data: pa.Table, first_row: int = 0) -> Layout:
        """This layout with the length of every variable-length list column fixed from ``data``
        (rows that are null say nothing), so that every later batch is held to it.
        ``first_row``: where ``data`` starts in its file, to name a bad row."""
        groups = dict(self.groups)
        form = self.form
        for name, g in self.groups.items():
            if g.is_list and g.size is None and data.num_rows:
                k = _list_size(columns.column(data, g.columns[0]).combine_chunks(), g, self.source, first_row)
                if k is not None:
                    groups[name] = replace(g, size=k)
                    if name == "I":
                        form = _list_form(k, g, self.source).name
        return replace(self, groups=groups, form=form)

    def read(self, data: pa.Table, first_row: int = 0) -> tuple[dict, str]:
        """The sets of ``data`` as float64 arrays of shape ``(k, N)`` in SI units (NaN for nulls),
        and the inertia form's name.

        The inertia comes back in its form's value order (:mod:`hconv.solve.forms`); q always
        in (w, x, y, z) order. Raises InputError for list columns of the wrong length, naming
        the row: ``first_row`` is where ``data`` starts in its file (0 for the first row).
        """
        layout = (
            self.resolve(data, first_row) if any(g.is_list and g.size is None for g in self.groups.values()) else self
        )
        # A list column still without a length is null in every row seen: its rows are
        # invalid_input whatever the length, so read them at the set's usual length.
        form = forms.get(layout.form) if layout.form else next(f for f in forms.FORMS.values() if f.list_size)
        out = {}
        n = data.num_rows
        for g in layout.groups.values():
            if g.is_list:
                if g.size is None:
                    g = replace(g, size=form.list_size if g.name == "I" else len(VECTOR_SETS[g.name]))
                col = columns.column(data, g.columns[0]).combine_chunks() if n else None
                a = _list_values(col, g, n, self.source, first_row)
            else:
                a = np.empty((len(g.columns), n))
                for k, c in enumerate(g.columns):
                    a[k] = _floats(columns.column(data, c))
                if g.name == "I":
                    a = form.values(a)
            if g.factors and any(f != 1.0 for f in g.factors):
                a = a * np.asarray(g.factors)[:, None] if len(g.factors) == a.shape[0] else a * g.factors[0]
            if g.name == "q" and g.is_list and self.quat_order == "xyzw":
                a = a[[3, 0, 1, 2]]
            out[g.name] = a
        return out, form.name


def output_name(column: str, schema: pa.Schema) -> str:
    """The name hconv's column ``column`` (``wx``, ``status``, ``w_unit``...) has in a converted
    table of ``schema``: with the Job's prefix, which the schema's metadata records."""
    return (schema.metadata or {}).get(PREFIX_KEY, b"").decode() + column


def _list_size(col: pa.Array, g: Group, source: str, first_row: int = 0) -> int | None:
    """Values per row of list column ``col`` (all rows must agree with each other and with the
    group's size, when set; null rows are skipped), or None when every row is null.
    ``first_row``: where ``col`` starts in its file, to name a bad row."""
    if pa.types.is_fixed_size_list(col.type):
        return col.type.list_size
    lengths = arrays.to_numpy(pc.list_value_length(col), null=-1)
    given = np.flatnonzero(lengths >= 0)
    if not given.size:
        return None
    k = g.size if g.size is not None else int(lengths[given[0]])
    bad = given[lengths[given] != k]
    if bad.size:
        row, got = first_row + int(bad[0]) + 1, _values(int(lengths[bad[0]]))
        column = f"{source}: list column {g.columns[0]!r}"
        if g.name != "I":  # the set's own size, whatever the other rows hold
            cols = VECTOR_SETS[g.name]
            raise InputError(
                f"{column} holds {got} in row {row}, but {g.name} needs {len(cols)} ({', '.join(cols)}); "
                f"every row's list must hold {len(cols)} (a null list makes its row invalid_input)"
            )
        # The inertia's size is whatever the first row with a list holds, if it is one of the forms'.
        where = "in the rows before it" if g.size is not None else f"in row {first_row + int(given[0]) + 1}"
        raise InputError(
            f"{column} holds {got} in row {row}, but {k} {where}; every row must hold the same number, "
            f"{forms.list_sizes_text()}"
        )
    return k


def _values(k: int) -> str:
    return "an empty list" if k == 0 else f"{k} value{'s' if k != 1 else ''}"


def _list_form(k: int, g: Group, source: str) -> forms.Form:
    form = forms.by_list_size(k)
    if form is None:
        raise InputError(
            f"{source}: list column {g.columns[0]!r} holds {f'{k} values per row' if k else 'empty lists'}; "
            f"an inertia list holds {forms.list_sizes_text()}"
        )
    return form


def _list_values(col: pa.Array | None, g: Group, n: int, source: str, first_row: int = 0) -> np.ndarray:
    """The list column's values ``(k, n)``, NaN for null rows; held to the group's size (set)."""
    size = g.size
    if size is None:
        raise ValueError(f"the size of list column {g.columns[0]!r} must be set before reading it")
    if col is None:
        return np.empty((size, 0))
    k = _list_size(col, g, source, first_row)
    if k is None:
        return np.full((size, n), np.nan)
    if k != size:
        raise InputError(f"{source}: list column {g.columns[0]!r} must hold {size} values per row, but holds {k}")
    values = np.full((n, k), np.nan)
    if col.null_count < len(col):
        valid = col.is_valid()
        flat = col.filter(valid).flatten() if col.null_count else col.flatten()
        values[arrays.to_numpy(valid)] = _floats(flat).reshape(-1, k)
    return values.T


def _floats(col: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """A numeric column or array as float64 with nulls as NaN, shape ``(N,)``."""
    if pa.types.is_null(col.type):
        return np.full(len(col), np.nan)
    if col.type == pa.float64():  # the cast would only copy it
        return arrays.to_numpy(col, null=np.nan)
    # unsafe: an integer beyond 2^53 rounds to the nearest float64, as the same digits in a CSV do
    return arrays.to_numpy(pc.cast(col, pa.float64(), safe=False), null=np.nan)


def _is_numeric(t: pa.DataType) -> bool:
    return pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t) or pa.types.is_null(t)


def _is_list(t: pa.DataType) -> bool:
    return pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)


def _plural(items: Sized) -> str:
    return "s" if len(items) > 1 else ""


class SchemaMemo:
    """The values last computed from a few schemas (each with a hashable key, such as the Job):
    a dataset's files mostly share one schema, and planning it again cost more than converting
    a file of a few hundred rows. A schema matches only with its metadata, where the units are
    (pyarrow's ``==`` and ``hash`` leave metadata out). Safe on several threads at once (two
    that miss together both compute)."""

    def __init__(self, size: int = 16):
        self._size = size
        self._entries: dict = {}
        self._lock = threading.Lock()

    def value(self, schema: pa.Schema, key: object, compute: Callable[[], T]) -> T:
        """The value for ``schema`` and ``key``: the one kept, else ``compute()``, kept."""
        try:
            k = (hash(schema), key)
            hit = self._entries.get(k)
        except (TypeError, pa.ArrowException):  # a key that cannot be hashed: computed every time
            return compute()
        if hit is not None and hit[0].equals(schema, check_metadata=True):
            return hit[1]
        value = compute()
        with self._lock:
            self._entries[k] = (schema, value)
            while len(self._entries) > self._size:
                del self._entries[next(iter(self._entries))]
        return value


_PLANS = SchemaMemo()


def plan(schema: pa.Schema, job: Job, source: str = "input") -> Layout:
    """Find the column sets ``job`` needs in ``schema``; InputError or UsageError naming the fix.

    A pure function: it reads ``schema`` and ``job`` and returns a new :class:`Layout`; the
    plans of recent schemas are kept (:class:`SchemaMemo`), and given ``source`` for their messages.
    """
    found = _PLANS.value(schema, job, lambda: _plan(schema, job, source))
    return found if found.source == source else replace(found, source=source)


def _plan(schema: pa.Schema, job: Job, source: str) -> Layout:
    """:func:`plan`, computed."""
    names = list(schema.names)
    dupes = sorted({c for c in names if names.count(c) > 1})
    if dupes:
        raise InputError(
            f"{source}: column name{_plural(dupes)} {', '.join(map(repr, dupes))} appear"
            f"{'' if len(dupes) > 1 else 's'} more than once; rename the copies"
        )
    fields = columns.columns_of(schema)
    present = set(fields)
    given = _mapping(job.mapping, present, source)
    mapping = {**columns.find(list(fields), given, source), **given}  # --map, then the names found
    used_elsewhere = set(mapping.values())

    def src(n: str) -> str:
        """The input's column for an hconv name."""
        return mapping.get(n, n)

    def has(n: str) -> bool:
        """The input has hconv's name n (a column that --map gave another name does not count,
        nor a struct, whose fields are read instead)."""
        c = src(n)
        return c in present and (n in mapping or n not in used_elsewhere) and not pa.types.is_struct(fields[c].type)

    def taken(lack: list, also: tuple = ()) -> str:
        """Why a lacking name whose column is there is not read: --map gave the column to another
        name; else the --map that would read it, from a column of a name close to it (``also``:
        :func:`hconv.tables.columns.map_hint`'s)."""
        back = {column: n for n, column in given.items()}
        c = next((c for c in lack if c not in given and c in present and c in back), None)
        if c is None:
            free = [f for f in fields if f not in used_elsewhere and f not in all_names()]
            return columns.map_hint(lack, free, also)
        return (
            f" (column {c!r} is read as {back[c]}: {entry('mapping', back[c], c)}); "
            f"give {c} a column too, e.g. {entry('mapping', c, 'COLUMN')}"
        )

    groups = {}
    need = job.needs()
    # diagnose reads v wherever it is present: its orbital-momentum hypothesis uses it
    optional = OPTIONAL_SETS + (("v",) if job.observed else ())
    for name in VECTOR_SETS:
        if name in optional or name == "H" or name in need:
            why = "H is required" if name == "H" else need.get(name)
            g = _vector_group(name, fields, has, src, source, why, taken)
            if g is not None:
                groups[name] = g
    form, groups["I"] = _inertia_group(fields, has, src, source, taken)

    clash = [] if job.observed else [job.prefix + c for c in RESERVED if job.prefix + c in present]
    if clash:
        again = f"another {option('prefix')}" if job.prefix else option("prefix", "out_")
        raise InputError(
            f"{source}: already has output column{_plural(clash)} {', '.join(clash)}; "
            f"rename or drop {'them' if len(clash) > 1 else 'it'} (hconv's own output?), "
            f"or pass {again} for hconv's new ones"
        )
    for g in groups.values():
        for c in g.columns:
            t = fields[c].type
            if g.is_list:
                if not (_is_list(t) and _is_numeric(t.value_type)):
                    raise InputError(f"{source}: column {c!r} has type {t}, but must be a list of numbers")
            elif not _is_numeric(t):
                raise InputError(
                    f"{source}: column {c!r} has type {t}, but must be numeric; store it as a number (float64)"
                )
    q = groups.get("q")
    if job.quat_order != "wxyz" and q is not None and not q.is_list:
        # qw, qx, qy, qz say their order by name; an order option that did nothing was a trap
        raise UsageError(
            f"{source}: {option('quat_order', job.quat_order)} orders a list column q, but this input names its "
            f"quaternion columns {', '.join(q.columns)}; drop {option('quat_order')}, or point "
            f"{option('mapping')} at the columns that hold w, x, y and z"
        )
    stored = stored_units(schema)
    groups = {k: _with_units(g, stored, job, mapping, source) for k, g in groups.items()}
    _check_unit_keys(job.unit_options, groups, present)
    return Layout(groups, form, source, job.quat_order)


def _mapping(pairs: tuple, present: set, source: str) -> dict:
    """The Job's --map pairs (already checked against hconv's names) against this input."""
    for name, column in pairs:
        if column not in present:
            raise InputError(f"{source}: {entry('mapping', name, column)}, but there is no column {column!r}")
    return dict(pairs)


def _vector_group(
    name: str,
    fields: dict[str, pa.Field],
    has: Callable[[str], bool],
    src: Callable[[str], str],
    source: str,
    why: str | None,
    taken: Callable[[list], str],
) -> Group | None:
    """The set ``name`` if present; ``why`` (the reason it is needed) makes it required."""
    cols = VECTOR_SETS[name]
    found = [c for c in cols if has(c)]
    if found and len(found) < len(cols):
        lack = [c for c in cols if c not in found]
        if why:
            raise InputError(
                f"{source}: missing column{_plural(lack)} {', '.join(lack)}{taken(lack)}; {name} is {', '.join(cols)}"
            )
        raise InputError(
            f"{source}: has {', '.join(found)} but not {', '.join(lack)}{taken(lack)}; "
            f"give all of {', '.join(cols)} or none"
        )
    if found:
        if len(cols) > 1 and has(name) and _is_list(fields[src(name)].type):
            raise InputError(f"{source}: has both {', '.join(cols)} and a list column {src(name)!r}; keep one")
        return Group(name, tuple(src(c) for c in cols), False, len(cols))
    if len(cols) > 1 and has(name) and not _is_list(fields[src(name)].type):
        raise InputError(
            f"{source}: column {src(name)!r} has type {fields[src(name)].type}; {name} is read "
            f"from {', '.join(cols)} or from a list column of {len(cols)} numbers"
        )
    if len(cols) > 1 and has(name) and _is_list(fields[src(name)].type):
        t = fields[src(name)].type
        size = t.list_size if pa.types.is_fixed_size_list(t) else None
        if size is not None and size != len(cols):
            raise InputError(
                f"{source}: list column {src(name)!r} holds {size} values per row, but {name} needs {len(cols)}"
            )
        return Group(name, (src(name),), True, len(cols))
    if why:
        what = f"{', '.join(cols)}" + (f" (or a list column {name})" if len(cols) > 1 else "")
        tail = "" if name == "H" else f"; {why}"
        hint = columns.look_alike(name, list(fields), RESERVED) or taken(list(cols))
        raise InputError(f"{source}: missing column{_plural(cols)} {what}{tail}{hint}")
    return None


def _inertia_group(
    fields: dict[str, pa.Field],
    has: Callable[[str], bool],
    src: Callable[[str], str],
    source: str,
    taken: Callable[..., str],
) -> tuple[str | None, Group]:
    """The one inertia form the schema holds, asking :mod:`hconv.solve.forms`' registry."""
    found = {}
    list_column = has("I") and _is_list(fields[src("I")].type)
    if list_column:
        found["list"] = ["I"]
    for form in forms.FORMS.values():
        parent = forms.get(form.extends).columns if form.extends else ()
        got = [c for c in form.columns if has(c) and c not in parent and not (list_column and c == "I")]
        if got:
            found[form.name] = got
    for form in forms.FORMS.values():  # a form that extends another replaces it
        if form.extends and form.name in found:
            base = forms.get(form.extends)
            if base.name not in found:
                raise InputError(
                    f"{source}: has {', '.join(found[form.name])} but not {', '.join(base.columns)}"
                    f"{taken(list(base.columns))}; "
                    f"the {form.count}-number form is the {base.count} plus "
                    f"{', '.join(c for c in form.columns if c not in base.columns)}"
                )
            del found[base.name]
    if len(found) > 1:
        desc = "; ".join(f"{form}: {', '.join(src(c) for c in cols)}" for form, cols in found.items())
        raise InputError(
            f"{source}: the inertia is given in more than one form ({desc}); keep one form, "
            f"or point {option('mapping')} at the columns to use"
        )
    if not found:
        raise InputError(
            f"{source}: missing the inertia; give {forms.forms_text()}, or a list column I"
            f"{taken([c for c in forms.column_names() if len(c) > 1], ('I',))}"
        )
    ((name, got),) = found.items()
    if name == "list":
        t = fields[src("I")].type
        size = t.list_size if pa.types.is_fixed_size_list(t) else None
        g = Group("I", (src("I"),), True, size)
        return (_list_form(size, g, source).name if size else None), g
    form = forms.get(name)
    own = [c for c in form.columns if c not in (forms.get(form.extends).columns if form.extends else ())]
    lack = [c for c in form.columns if not has(c)]
    if lack:
        raise InputError(
            f"{source}: has {', '.join(got)} but not {', '.join(lack)}{taken(lack)}; "
            f"the {name} form needs {', '.join(own)}"
        )
    return name, Group("I", tuple(src(c) for c in form.columns), False, form.count)


def stored_units(schema: pa.Schema) -> dict[str, str]:
    """Each column's unit as ``schema`` stores it, in the schema's column order: its field
    metadata ``unit``, else the unit Spark's schema (file metadata :data:`SPARK_SCHEMA_KEY`) gives
    it; a struct's fields by their dotted path (:func:`hconv.tables.columns.columns_of`), after the top-level columns.
    Columns without one are left out."""
    found = {}
    try:
        spark = json.loads((schema.metadata or {}).get(SPARK_SCHEMA_KEY, b"{}"))
        for f in spark.get("fields", []):
            unit = (f.get("metadata") or {}).get("unit")
            if isinstance(unit, str) and unit:
                found[f["name"]] = unit
    except (ValueError, AttributeError, TypeError, KeyError):  # not the schema Spark writes: no units from it
        pass
    fields = columns.columns_of(schema)
    for name, f in fields.items():
        meta = f.metadata or {}
        if meta.get(b"unit"):
            found[name] = meta[b"unit"].decode(errors="replace")
    return {c: found[c] for c in fields if c in found}


def _with_units(g: Group, stored: dict, job: Job, mapping: dict, source: str = "input") -> Group:
    """``g`` with the unit of each of its values, by the rule of the module docstring."""
    back = {v: k for k, v in mapping.items()}  # column -> hconv name
    given = dict(job.unit_options)
    dropped = dict(job.field_units)
    us, fs = [], []
    quantity = QUANTITY[g.name]
    for c in g.columns:
        hname = back.get(c, c)
        unit, where = None, None
        for key in (c, hname, g.name):
            if key in given:
                unit, where = given[key], entry("unit_options", key, given[key])
                break
        if unit is None and c in stored:
            unit, where = stored[c], f"column {c!r} (its unit metadata)"
        elif unit is None and c in dropped:
            unit, where = dropped[c], entry("field_units", c, dropped[c])
        elif unit is None and (written := header_name(c)[1]) is not None:
            us.append(written)
            fs.append(_header_factor(quantity, c, written, hname, source))
            continue
        us.append(unit or "")
        fs.append(1.0 if unit is None else units.factor(quantity, unit, where))
    return Group(g.name, g.columns, g.is_list, g.size, tuple(us), tuple(fs))


def _header_factor(quantity: str, c: str, unit: str, hname: str, source: str) -> float:
    """The factor to SI of the unit written in column ``c``'s header; InputError naming the
    column, and the --unit that reads it otherwise, when pint cannot read it or it is another
    quantity's."""
    try:
        return units.factor(quantity, unit, f"{source}: column {c!r} (the unit in its header)")
    except UsageError as exc:
        raise InputError(f"{exc}; or give its unit with {entry('unit_options', hname, 'UNIT')}, which wins") from None


def _check_unit_keys(options: tuple, groups: dict, present: set) -> None:
    known = set(groups) | {c for g in groups.values() for c in g.columns}
    for g in groups.values():
        if not g.is_list:
            known |= set(VECTOR_SETS.get(g.name, ())) | (set(forms.column_names()) | {"I"} if g.name == "I" else set())
    for key, unit in options:
        if key not in known:
            where = "" if key in present else ", nor one of the input"
            raise UsageError(
                f"{entry('unit_options', key, unit)}: {key!r} is not a column hconv reads{where}; "
                f"use a set (H, I, r, m, v, w_obs) or one of its columns"
            )
