"""Types for the columns hconv passes through from CSV into Parquet.

CSV holds text only. hconv reads the columns it does not use as text (:mod:`hconv.tables.csvio`),
so that CSV output gives them back byte for byte. Parquet output holds types, so there each such
column gets the type pyarrow's CSV reader would infer for it (:data:`CANDIDATES`, in pyarrow's
order; text that fits none stays text), with these exceptions, each where pyarrow would change a
value:

- an integer written with a leading zero (``007``, ``0x1F``) is an identifier, such as a zip
  code, and its column stays text (pyarrow reads 7 and 31);
- an integer that int64 cannot hold, or a float64 column cannot hold exactly, keeps its column
  text (pyarrow rounds it to a float);
- ``NaN``, ``nan``, ``-NaN`` and ``-nan`` are the float NaN; pyarrow makes them null. The other
  null markers pyarrow knows (:data:`NULLS`: the empty field, ``NA``, ``NULL``, ``#N/A``, …)
  become null, but only in a typed column: a text column keeps them as they are, and so does
  a column of null markers alone (``NA``, ``null``, blanks), which no other value types; only a
  column of blanks alone gets pyarrow's null type;
- a time of day (``12:30:00``) stays text, since pyarrow cannot cast text to time32, and so
  does a number with spaces around it (pyarrow's reader trims them, its cast does not).

Floats are IEEE doubles, rounded to nearest, as any float parser gives them (``1.50`` is 1.5,
``1e3`` is 1000); ``--keep-text`` (``Job(keep_text=True)``) keeps every such column as text.

A type comes from the values, and a file is read in blocks: the first block decides
(:func:`infer`), and :func:`apply` refuses a later block that does not fit by raising
:class:`Retype`, never by changing a value. The file pipeline then takes the type that every
block fits (:func:`whole_file`) and converts again, so that the types are those of the whole
file, as ``pyarrow.csv.read_csv`` would infer them from all of it.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from hconv.tables import arrays

_DEFAULTS = pacsv.ConvertOptions()
#: Text that is a missing value in a typed column: pyarrow's CSV null markers, less its NaN
#: spellings, since NaN is a float value.
_NULL_LIST = [v for v in _DEFAULTS.null_values if v.lstrip("-").lower() != "nan"]
NULLS = arrays.strings(_NULL_LIST)
NULL_TEXTS = frozenset(_NULL_LIST)  #: the same, as Python text
_BOOLS = arrays.strings(list(_DEFAULTS.true_values) + list(_DEFAULTS.false_values))

#: The types a text column may get, in the order pyarrow's CSV reader tries them: the first that
#: every value fits wins, and a column that fits none stays text.
CANDIDATES = (
    pa.null(),
    pa.int64(),
    pa.bool_(),
    pa.date32(),
    pa.timestamp("s"),
    pa.timestamp("ns"),
    pa.timestamp("s", "UTC"),
    pa.timestamp("ns", "UTC"),
    pa.float64(),
)

#: A leading zero before a digit, or a hex prefix: ``007``, ``-01``, ``0x1F``.
_LEADING_ZERO = "^[+-]?0[0-9xX]"
#: A float column's values to look at closely: a leading zero, or an integer of 16 digits or more
#: (from 2**53 on, float64 cannot hold every integer).
_SUSPECT_FLOAT = "^[+-]?(0[0-9xX]|[0-9]{16,}$)"
_LEADING_ZERO_RE = re.compile(_LEADING_ZERO)


class Retype(Exception):
    """A value of ``column`` does not fit the type the column was given; the column needs the type
    of the whole file (:func:`whole_file`). Not an error for users: the pipeline handles it."""

    def __init__(self, column: str, value: str | None):
        super().__init__(f"column {column!r} holds {value!r}, which does not fit its type")
        self.column = column
        self.value = value


def convert(text: pa.Array, to: pa.DataType) -> pa.Array | None:
    """``text`` (a string array) as type ``to``, or None if any value does not fit it exactly."""
    if pa.types.is_string(to):
        return text
    if pa.types.is_null(to):
        # blanks only: nothing written is lost; a null marker written out (NA, null) is text
        return pa.nulls(len(text)) if pc.max(pc.binary_length(text)).as_py() in (None, 0) else None
    try:  # the common case: no null marker in this block
        out = text.cast(to)
    except pa.ArrowInvalid:
        text = pc.if_else(pc.is_in(text, value_set=NULLS), arrays.scalar(None, pa.string()), text)
        try:
            out = text.cast(to)
        except pa.ArrowInvalid:
            return None
    return out if _exact(text, to) else None


def _exact(text: pa.Array, to: pa.DataType) -> bool:
    """No value of ``text`` is changed by reading it as ``to`` beyond a float's rounding."""
    # A regular expression costs 50 ns a value, a prefix or substring test 5: the first picks
    # out the few values the second has to look at.
    if pa.types.is_integer(to):
        zero = pc.or_(pc.starts_with(text, "0"), pc.starts_with(text, "-0"))  # int64 takes no "+"
        return (
            not pc.any(zero).as_py() or not pc.any(pc.match_substring_regex(text.filter(zero), _LEADING_ZERO)).as_py()
        )
    if pa.types.is_floating(to):
        whole = pc.invert(pc.match_substring(text, "."))  # written as an integer (or 1e5, nan, inf)
        if not pc.any(whole).as_py():
            return True
        written = text.filter(whole)
        suspect = pc.match_substring_regex(written, _SUSPECT_FLOAT)
        return not pc.any(suspect).as_py() or all(_exact_float(s) for s in written.filter(suspect).to_pylist())
    if pa.types.is_boolean(to):  # the cast also takes "tRue"; pyarrow's CSV reader takes its lists only
        return pc.all(pc.is_in(text.drop_null(), value_set=_BOOLS)).as_py() is not False
    return True


def _exact_float(s: str) -> bool:
    if _LEADING_ZERO_RE.match(s):
        return False
    n = int(s)
    try:
        return int(float(n)) == n
    except OverflowError:
        return False


def _fitting(text: pa.Array, candidates: Iterable[pa.DataType]) -> list[pa.DataType]:
    return [t for t in candidates if convert(text, t) is not None]


def infer(table: pa.Table | pa.RecordBatch, columns: Iterable[str]) -> dict[str, pa.DataType]:
    """The type of each text column in ``columns``, from the values of ``table`` (a first block)."""
    types = {}
    for name in columns:
        text = _text(table.column(name))
        candidates = CANDIDATES if _has_value(text) else CANDIDATES[:1]  # markers alone: no type but null
        types[name] = next((t for t in candidates if convert(text, t) is not None), pa.string())
    return types


def _has_value(text: pa.Array) -> bool:
    """Some value of ``text`` is not a null marker: a type can be read from it."""
    return pc.all(pc.is_in(text, value_set=NULLS)).as_py() is False


def whole_file(batches: Iterable[pa.RecordBatch]) -> dict[str, pa.DataType]:
    """The type of each text column of ``batches`` that every batch fits: the first candidate
    that fits all of them, else text. Reads every batch once, holding one at a time."""
    alive: dict[str, list[pa.DataType]] = {}
    valued: set[str] = set()  # the columns with a value that is not a null marker
    for batch in batches:
        for name in batch.schema.names:
            text = _text(batch.column(name))
            alive[name] = _fitting(text, alive.get(name, CANDIDATES))
            if name not in valued and _has_value(text):
                valued.add(name)
    return {
        name: (fits[0] if fits and (name in valued or pa.types.is_null(fits[0])) else pa.string())
        for name, fits in alive.items()
    }


def apply(table: pa.Table, types: dict[str, pa.DataType]) -> pa.Table:
    """``table`` with each text column named in ``types`` as its type; :class:`Retype` naming
    the column and a value that does not fit."""
    for name, to in types.items():
        if pa.types.is_string(to):
            continue
        k = table.schema.get_field_index(name)
        text = _text(table.column(k))
        typed = convert(text, to)
        if typed is None:
            raise Retype(name, _misfit(text, to))
        table = table.set_column(k, table.schema.field(k).with_type(to), typed)  # its unit kept
    return table


def _text(col: pa.ChunkedArray | pa.Array) -> pa.Array:
    return col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col


def _misfit(text: pa.Array, to: pa.DataType) -> str | None:
    """The first value of ``text`` that does not fit ``to`` (the fallback's path only). Fitting
    is a property of each value, so a prefix fits exactly when it holds no misfit: bisect."""
    lo, hi = 0, len(text)  # text[:lo] fits; text[:hi] does not
    if convert(text, to) is not None:
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if convert(text.slice(0, mid), to) is None:
            hi = mid
        else:
            lo = mid
    return text[lo].as_py()
