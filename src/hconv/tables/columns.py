"""Finding hconv's names among an input's columns: by name as written, with a unit in the header,
as a struct's field, without regard to case (the order is :mod:`hconv.tables.layout`'s docstring);
a struct's fields as columns by their dotted path; and the ``--map`` a message suggests for a set
that is missing.
"""

from __future__ import annotations

import difflib

import pyarrow as pa

from hconv.errors import InputError, entries, entry
from hconv.tables.sets import STRUCT_FIELDS, VECTOR_SETS, all_names, header_name


def columns_of(schema: pa.Schema) -> dict[str, pa.Field]:
    """Every column of ``schema`` hconv may read, by name: the top-level fields, and the fields of
    structs by their dotted path (``H.x``; a top-level field of that name comes first)."""
    out: dict[str, pa.Field] = {}

    def add(prefix: str, f: pa.Field) -> None:
        name = prefix + f.name
        out.setdefault(name, f)
        if pa.types.is_struct(f.type):
            for k in range(f.type.num_fields):
                add(name + ".", f.type.field(k))

    for f in schema:
        out[f.name] = f
    for f in schema:
        if pa.types.is_struct(f.type):
            for k in range(f.type.num_fields):
                add(f.name + ".", f.type.field(k))
    return out


def column(data: pa.Table, name: str) -> pa.ChunkedArray:
    """Column ``name`` of ``data``: a top-level column, or a struct's field by its dotted path
    (:func:`columns_of`); a row whose struct is null is null in each of its fields."""
    k = data.schema.get_field_index(name)  # -1 if missing or not unique; a list of the names cost 10x
    if k >= 0:
        return data.column(k)
    if name in data.column_names:
        return data.column(name)
    for top in data.column_names:
        if name.startswith(top + ".") and pa.types.is_struct(data.schema.field(top).type):
            col, rest = data.column(top), name[len(top) + 1 :]
            while True:
                t = col.type
                k = next((i for i in range(t.num_fields) if rest == t.field(i).name), None)
                if k is not None:
                    return col.flatten()[k]
                k = next(i for i in range(t.num_fields) if rest.startswith(t.field(i).name + "."))
                col, rest = col.flatten()[k], rest[len(t.field(k).name) + 1 :]
    raise KeyError(name)


def stands_for(name: str) -> set:
    """The hconv names a column of this name can stand for, before case: its name without a unit
    in its header and, for a struct's field, the struct's name and the field's run together
    (``H.x``: Hx, ``I.xx``: Ixx), or the set's column for that field (``w_obs.x``: wx_obs)."""
    bare = header_name(name)[0]
    keys = {bare}
    if "." in bare:
        parent, _, child = bare.rpartition(".")
        struct = parent.rpartition(".")[2]
        keys.add(struct + child)
        axes = STRUCT_FIELDS.get(struct, "")
        if child in axes:
            keys.add(VECTOR_SETS[struct][axes.index(child)])
    return keys


def find(columns: list, given: dict, source: str) -> dict:
    """hconv's names that no column has exactly, each found in the one column that stands for it
    (:func:`stands_for`): first as written, then without regard to case. ``given``: the --map pairs,
    whose names and columns are not looked for. Two columns for one name: InputError naming both.
    Case is not looked past for the one-letter names: ``M`` or ``V`` in a file is seldom a mass or
    a velocity."""
    free = [c for c in columns if c not in set(given.values())]
    exact = set(columns)
    out: dict = {}
    keyed = [(c, stands_for(c)) for c in free]
    for n in all_names():
        if n in given or n in exact:
            continue
        hits = [c for c, keys in keyed if n in keys]
        if not hits and len(n) > 1:  # a one-letter name (m, r, v, H) in another case is another quantity's
            hits = [c for c, keys in keyed if n.lower() in {k.lower() for k in keys}]
        if len(hits) > 1:
            raise InputError(
                f"{source}: columns {hits[0]!r} and {hits[1]!r} could both be {n}; "
                f"say which with {entry('mapping', n, hits[0])}"
            )
        if hits and hits[0] not in out.values():
            out[n] = hits[0]
    return out


def _unclosed(column: str) -> tuple[str, str] | None:
    """A column's name before a unit whose bracket or parenthesis is not closed (``Hx [kg*m^2/s``),
    and the column's name closed; None for any other column."""
    for left, right in ("[]", "()"):
        at = column.rfind(left)
        if at > 0 and right not in column[at:]:
            return column[:at].strip(), column.rstrip() + right
    return None


def map_hint(lack: list, free: list, also: tuple = ()) -> str:
    """For the first lacking name a column may hold: a column that is the name with its unit's
    bracket not closed; else the --map that would read it from a column that is the name in
    another case (``also``: names looked for only so, such as the one-letter I); else from a column
    whose name is close to it; else the --map to give."""
    for n in lack:
        for c in free:
            cut = _unclosed(c)
            if cut and cut[0].lower() == n.lower():
                return f"; column {c!r} is {n} with its unit's bracket not closed: rename it {cut[1]!r}"
    for n in (*lack, *also):
        c = next((c for c in free if header_name(c)[0].lower() == n.lower()), None)
        if c is not None:
            return f"; if column {c!r} holds {n}, give {entry('mapping', n, c)}"
    for n in lack:
        close = difflib.get_close_matches(n.lower(), [c.lower() for c in free], n=1, cutoff=0.6)
        if close:
            c = next(c for c in free if c.lower() == close[0])
            return f"; if column {c!r} holds {n}, give {entry('mapping', n, c)}"
    return f"; if another column holds {lack[0]}, give {entry('mapping', lack[0], 'COLUMN')}"


def look_alike(name: str, names: list, written: tuple) -> str:
    """A hint for a missing vector set whose components the input may hold under other names: the
    columns ``Px, Py, Pz`` (``Pw`` too for q) that no hconv name reads, for each such prefix P."""
    cols = VECTOR_SETS[name]
    if len(cols) == 1 or any(not c.startswith(name) for c in cols):
        return ""  # m, and w_obs (wx_obs...), whose names are not a prefix and an axis letter
    axes = [c[len(name) :] for c in cols]
    ours = set(all_names()) | set(written)  # columns hconv reads by their names, or writes
    free = [f for f in names if f not in ours]
    prefixes = sorted(
        {f[: -len(axes[0])] for f in free if f.endswith(axes[0]) and len(f) > len(axes[0])}
        - {n for n in VECTOR_SETS if n != name}
        - {"w"}  # wx, wy, wz: hconv's own output
    )
    found = [p for p in prefixes if all(p + a in free for a in axes)]
    if not found:
        return ""
    maps = " or ".join(entries("mapping", {c: p + a for c, a in zip(cols, axes)}) for p in found[:2])
    held = " or ".join(", ".join(p + a for a in axes) for p in found[:2])
    return f"; if {held} hold {name}, give {maps}"
