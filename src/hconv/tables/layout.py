"""Which columns hold what: the input's column sets, found by name, and the form of its inertia.

Column sets (hconv's names; ``--map NAME=COLUMN`` points a name at a column of another name):

=========  ===============================================  ==================================
set        named columns                                    or one list column (Parquet)
=========  ===============================================  ==================================
H          Hx, Hy, Hz  [kg·m²/s]                            H: 3 values
I          exactly one form, below  [kg·m²]                 I: 3, 6 or 9 values
q          qw, qx, qy, qz (body → world)                    q: 4 values, order --quat-order
r          rx, ry, rz  [m]                                  r: 3 values
m          m  [kg]
v          vx, vy, vz  [m/s]                                v: 3 values
w_obs      wx_obs, wy_obs, wz_obs  [rad/s]                  w_obs: 3 values
=========  ===============================================  ==================================

The inertia forms, cheapest first:

* ``scalar``: one number ``I`` per row, for spheres and other isotropic bodies;
* ``principal``: ``I1, I2, I3`` (or a 3-value list ``I``), the principal moments; with q, in the
  body frame whose axes are the principal axes;
* ``sym6``: ``Ixx, Iyy, Izz, Ixy, Ixz, Iyz`` (or a 6-value list in that order);
* ``full9``: ``sym6`` plus ``Iyx, Izx, Izy`` (or a 9-value list, row-major).

A file uses one form, chosen by its columns, for every row; two forms at once (``I1`` and
``Ixx``, say) is an error, as is a set with some of its columns missing. With q present the tensor
is taken to be in the body frame (as engines store it); without q, in the frame of H.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from hconv.solve import units
from hconv.errors import InputError, UsageError

VECTOR_SETS = {
    "H": ("Hx", "Hy", "Hz"),
    "q": ("qw", "qx", "qy", "qz"),
    "r": ("rx", "ry", "rz"),
    "m": ("m",),
    "v": ("vx", "vy", "vz"),
    "w_obs": ("wx_obs", "wy_obs", "wz_obs"),
}
SIX = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
FORMS = {
    "scalar": ("I",),
    "principal": ("I1", "I2", "I3"),
    "sym6": SIX,
    "full9": SIX + ("Iyx", "Izx", "Izy"),
}
LIST_FORMS = {3: "principal", 6: "sym6", 9: "full9"}
#: From the named nine (the six, then Iyx, Izx, Izy) to row-major order.
_NAMED9_TO_ROW_MAJOR = (0, 3, 4, 6, 1, 5, 7, 8, 2)
#: The unit quantity (a key of units.SI) of each set.
QUANTITY = {"H": "H", "I": "I", "q": "q", "r": "r", "m": "m", "v": "v", "w_obs": "w"}
QUAT_ORDERS = ("wxyz", "xyzw")
#: Sets read whenever present (they change the answer or its status); v and w_obs only when needed.
OPTIONAL_SETS = ("q", "r", "m")
ALL_NAMES = tuple(sorted({n for names in VECTOR_SETS.values() for n in names} | set(FORMS["full9"])
                         | set(FORMS["principal"]) | set(QUANTITY), key=str.lower))


@dataclass(frozen=True)
class Spec:
    """What the run asks of its input: the sets it needs and how to find and read them."""

    need: tuple = ()  #: (set, reason) pairs: sets needed besides H and I, e.g. ("r", "method ... needs r")
    mapping: tuple = ()  #: (hconv name, column) pairs from --map
    unit_options: tuple = ()  #: (key, unit) pairs from --unit; key: a set, an hconv name or a column
    quat_order: str = "wxyz"  #: order of a 4-value list column q


@dataclass(frozen=True)
class Group:
    """One column set as found in the input."""

    name: str  #: the set: H, I, q, r, m, v or w_obs
    columns: tuple  #: the input's column names, one per value; or the one list column
    is_list: bool
    size: Optional[int]  #: values per row; None for a list column whose rows have not been seen
    units: tuple = ()  #: the unit of each value as given (a string; "" means SI)
    factors: tuple = ()  #: to SI, one per value


@dataclass
class Layout:
    """The input's sets and the inertia form; ``read`` turns a batch into SI arrays."""

    groups: dict
    form: str
    source: str
    quat_order: str = "wxyz"
    _sizes: dict = field(default_factory=dict)

    @property
    def numeric(self) -> tuple:
        """The input columns hconv reads as numbers."""
        return tuple(c for g in self.groups.values() for c in g.columns)

    def read(self, data: pa.Table) -> dict:
        """The sets of ``data`` as float64 arrays of shape ``(k, N)`` in SI units (NaN for nulls).

        The inertia comes back as ``(1, N)``, ``(3, N)``, ``(6, N)`` or ``(9, N)`` (row-major) for
        its form; q always in (w, x, y, z) order. Raises InputError for list columns of the wrong length.
        """
        out = {}
        n = data.num_rows
        for g in self.groups.values():
            if g.is_list:
                a = self._list_values(data, g)
            else:
                a = np.empty((len(g.columns), n))
                for k, c in enumerate(g.columns):
                    a[k] = _floats(data.column(c))
            if g.factors and any(f != 1.0 for f in g.factors):
                a = a * np.asarray(g.factors)[:, None] if len(g.factors) == a.shape[0] else a * g.factors[0]
            if g.name == "I" and self.form == "full9" and not g.is_list:
                a = a[list(_NAMED9_TO_ROW_MAJOR)]
            if g.name == "q" and g.is_list and self.quat_order == "xyzw":
                a = a[[3, 0, 1, 2]]
            out[g.name] = a
        return out

    def _list_values(self, data: pa.Table, g: Group) -> np.ndarray:
        col = data.column(g.columns[0]).combine_chunks() if data.num_rows else None
        n = data.num_rows
        size = g.size or self._sizes.get(g.name)
        if col is None:
            return np.empty((size or (3 if g.name != "q" else 4), 0))
        if pa.types.is_fixed_size_list(col.type):
            k = col.type.list_size
        else:
            lengths = pc.fill_null(pc.list_value_length(col), -1).to_numpy(zero_copy_only=False)
            given = lengths[lengths >= 0]
            k = size if size is not None else (int(given[0]) if given.size else None)
            bad = np.flatnonzero((lengths >= 0) & (lengths != k)) if k is not None else np.array([], int)
            if bad.size:
                raise InputError(f"{self.source}: list column {g.columns[0]!r} holds {lengths[bad[0]]} values in "
                                 f"one row but {k} in others; every row must hold the same number")
            if k is None:
                return np.full((size or 3, n), np.nan)
        if size is not None and k != size:
            raise InputError(f"{self.source}: list column {g.columns[0]!r} must hold {size} values per row, "
                             f"but holds {k}")
        if g.name == "I" and self.form == "list":
            self.form = LIST_FORMS.get(k, "")
            if not self.form:
                raise InputError(f"{self.source}: list column {g.columns[0]!r} holds {k} values per row; "
                                 "an inertia list holds 3 (principal), 6 (Ixx,Iyy,Izz,Ixy,Ixz,Iyz) or 9 (row-major)")
        self._sizes[g.name] = k
        values = np.full((n, k), np.nan)
        valid = col.is_valid().to_numpy(zero_copy_only=False)
        if valid.any():
            flat = col.filter(pa.array(valid)).flatten() if not valid.all() else col.flatten()
            values[valid] = _floats(flat).reshape(-1, k)
        return values.T


def _floats(col) -> np.ndarray:
    """A numeric column or array as float64 with nulls as NaN, shape ``(N,)``."""
    if pa.types.is_null(col.type):
        return np.full(len(col), np.nan)
    return np.asarray(pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False), dtype=np.float64)


def _is_numeric(t: pa.DataType) -> bool:
    return pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t) or pa.types.is_null(t)


def _is_list(t: pa.DataType) -> bool:
    return pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)


def _plural(items) -> str:
    return "s" if len(items) > 1 else ""


def plan(schema: pa.Schema, spec: Spec, source: str = "input", *, reserved: tuple = ()) -> Layout:
    """Find the column sets of ``spec`` in ``schema``; InputError or UsageError naming the fix.

    ``reserved``: output column names that the input must not already have.
    """
    names = list(schema.names)
    dupes = sorted({c for c in names if names.count(c) > 1})
    if dupes:
        raise InputError(f"{source}: column name{_plural(dupes)} {', '.join(map(repr, dupes))} appear"
                         f"{'' if len(dupes) > 1 else 's'} more than once; rename the copies")
    present = set(names)
    mapping = _mapping(spec.mapping, present, source)
    src = lambda n: mapping.get(n, n)  # noqa: E731 - the input's column for an hconv name
    used_elsewhere = set(mapping.values())
    has = lambda n: src(n) in present and (n in mapping or n not in used_elsewhere)  # noqa: E731

    groups = {}
    need = dict(spec.need)
    for name in VECTOR_SETS:
        if name in OPTIONAL_SETS or name == "H" or name in need:
            why = "H is required" if name == "H" else need.get(name)
            g = _vector_group(name, schema, has, src, source, why)
            if g is not None:
                groups[name] = g
    form, groups["I"] = _inertia_group(schema, has, src, source)
    if spec.quat_order not in QUAT_ORDERS:
        raise UsageError(f"--quat-order must be wxyz or xyzw, got {spec.quat_order!r}")

    clash = [c for c in reserved if c in present]
    if clash:
        raise InputError(f"{source}: already has output column{_plural(clash)} {', '.join(clash)}; "
                         "rename or drop them (is this hconv's own output?)")
    for g in groups.values():
        for c in g.columns:
            t = schema.field(c).type
            if g.is_list:
                if not (_is_list(t) and _is_numeric(t.value_type)):
                    raise InputError(f"{source}: column {c!r} has type {t}, but must be a list of numbers")
            elif not _is_numeric(t):
                raise InputError(f"{source}: column {c!r} has type {t}, but must be numeric; "
                                 "store it as a number (float64)")
    groups = {k: _with_units(g, schema, spec.unit_options, mapping) for k, g in groups.items()}
    _check_unit_keys(spec.unit_options, groups, present)
    return Layout(groups, form, source, spec.quat_order)


def _mapping(pairs, present: set, source: str) -> dict:
    mapping = {}
    for name, column in pairs:
        if name not in ALL_NAMES:
            raise UsageError(f"--map {name}={column}: hconv has no column {name!r}; "
                             f"map one of {', '.join(ALL_NAMES)}")
        if column not in present:
            raise InputError(f"{source}: --map {name}={column}, but there is no column {column!r}")
        if name in mapping and mapping[name] != column:
            raise UsageError(f"--map gives {name} twice ({mapping[name]} and {column}); give it once")
        mapping[name] = column
    seen = {}
    for name, column in mapping.items():
        if column in seen:
            raise UsageError(f"--map points both {seen[column]} and {name} at column {column!r}; one column, one name")
        seen[column] = name
    return mapping


def _vector_group(name: str, schema, has, src, source: str, why: Optional[str]) -> Optional[Group]:
    """The set ``name`` if present; ``why`` (the reason it is needed) makes it required."""
    cols = VECTOR_SETS[name]
    found = [c for c in cols if has(c)]
    if found and len(found) < len(cols):
        lack = [c for c in cols if c not in found]
        if why:
            raise InputError(f"{source}: missing column{_plural(lack)} {', '.join(lack)}; {name} is "
                             f"{', '.join(cols)}")
        raise InputError(f"{source}: has {', '.join(found)} but not {', '.join(lack)}; give all of "
                         f"{', '.join(cols)} or none")
    if found:
        if len(cols) > 1 and has(name) and _is_list(schema.field(src(name)).type):
            raise InputError(f"{source}: has both {', '.join(cols)} and a list column {src(name)!r}; keep one")
        return Group(name, tuple(src(c) for c in cols), False, len(cols))
    if len(cols) > 1 and has(name) and not _is_list(schema.field(src(name)).type):
        raise InputError(f"{source}: column {src(name)!r} has type {schema.field(src(name)).type}; {name} is read "
                         f"from {', '.join(cols)} or from a list column of {len(cols)} numbers")
    if len(cols) > 1 and has(name) and _is_list(schema.field(src(name)).type):
        t = schema.field(src(name)).type
        size = t.list_size if pa.types.is_fixed_size_list(t) else None
        if size is not None and size != len(cols):
            raise InputError(f"{source}: list column {src(name)!r} holds {size} values per row, but {name} needs {len(cols)}")
        return Group(name, (src(name),), True, len(cols))
    if why:
        what = f"{', '.join(cols)}" + (f" (or a list column {name})" if len(cols) > 1 else "")
        tail = "" if name == "H" else f"; {why}"
        raise InputError(f"{source}: missing column{_plural(cols)} {what}{tail}")
    return None


def _inertia_group(schema, has, src, source: str) -> tuple[str, Group]:
    found = {}
    for form, cols in FORMS.items():
        got = [c for c in cols if has(c)]
        if form == "full9":
            got = [c for c in got if c not in SIX]
        if form == "scalar" and got and _is_list(schema.field(src("I")).type):
            found["list"] = got
        elif got:
            found[form] = got
    if "full9" in found and "sym6" not in found:
        raise InputError(f"{source}: has {', '.join(found['full9'])} but not {', '.join(SIX)}; the 9-number form "
                         "is the six plus Iyx, Izx, Izy")
    if "full9" in found:
        del found["sym6"]
    if len(found) > 1:
        desc = "; ".join(f"{form}: {', '.join(src(c) for c in cols)}" for form, cols in found.items())
        raise InputError(f"{source}: the inertia is given in more than one form ({desc}); keep one form, "
                         "or point --map at the columns to use")
    if not found:
        raise InputError(f"{source}: missing the inertia; give I (isotropic), I1, I2, I3 (principal), "
                         f"{', '.join(SIX)} (tensor), these plus Iyx, Izx, Izy, or a list column I")
    (form, got), = found.items()
    if form == "list":
        t = schema.field(src("I")).type
        size = t.list_size if pa.types.is_fixed_size_list(t) else None
        if size is not None and size not in LIST_FORMS:
            raise InputError(f"{source}: list column {src('I')!r} holds {size} values per row; an inertia "
                             "list holds 3 (principal), 6 (Ixx,Iyy,Izz,Ixy,Ixz,Iyz) or 9 (row-major)")
        return (LIST_FORMS[size] if size else "list"), Group("I", (src("I"),), True, size)
    cols = FORMS[form]
    if len(got) < len(cols) - (len(SIX) if form == "full9" else 0):
        need = cols[len(SIX):] if form == "full9" else cols
        lack = [c for c in need if c not in got]
        raise InputError(f"{source}: has {', '.join(got)} but not {', '.join(lack)}; the {form} form needs "
                         f"{', '.join(need)}")
    return form, Group("I", tuple(src(c) for c in cols), False, len(cols))


def _with_units(g: Group, schema: pa.Schema, options, mapping: dict) -> Group:
    """``g`` with the unit of each of its values, from --unit, else field metadata, else SI."""
    back = {v: k for k, v in mapping.items()}  # column -> hconv name
    given = dict(options)
    us, fs = [], []
    quantity = QUANTITY[g.name]
    for c in g.columns:
        hname = back.get(c, c)
        meta = schema.field(c).metadata or {}
        unit, where = None, None
        for key in (c, hname, g.name):
            if key in given:
                unit, where = given[key], f"--unit {key}={given[key]}"
                break
        if unit is None and b"unit" in meta:
            unit, where = meta[b"unit"].decode(errors="replace"), f"column {c!r} (its unit metadata)"
        us.append(unit or "")
        fs.append(1.0 if unit is None else units.factor(quantity, unit, where))
    return Group(g.name, g.columns, g.is_list, g.size, tuple(us), tuple(fs))


def _check_unit_keys(options, groups: dict, present: set) -> None:
    known = set(groups) | {c for g in groups.values() for c in g.columns}
    for g in groups.values():
        if not g.is_list:
            known |= set(VECTOR_SETS.get(g.name, ())) | (set(FORMS["full9"]) | set(FORMS["principal"]) | {"I"}
                                                         if g.name == "I" else set())
    for key, unit in options:
        if key not in known:
            hint = "" if key in present else f"; it is not a column of the input"
            raise UsageError(f"--unit {key}={unit}: {key!r} is not a column hconv reads{hint}; "
                             f"use a set (H, I, r, m, v, w_obs) or one of its columns")
