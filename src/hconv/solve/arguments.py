"""The arguments of :func:`hconv.solve.convert.convert`: H, I and r read as float64 numbers in SI
and checked for shape, before any conversion.

The shapes, and how they broadcast, are those of :func:`hconv.solve.convert.convert`'s docstring;
every argument comes out a stack of the same number of rows. Numbers that carry a unit or a mask
are read by the rule in the docstring of :func:`hconv.solve.convert.convert`
(:mod:`hconv.solve.units` finds the units). A wrong shape is
a ValueError, a unit or a type hconv does not read a UsageError, each naming the argument.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from itertools import chain
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hconv.errors import UsageError
from hconv.solve import units


@dataclass(frozen=True)
class Arguments:
    """H, I and r as float64 numbers in SI, stacked, and how they were given."""

    H: np.ndarray  #: (N, 3) [kg·m²/s]
    I: np.ndarray  #: (N, 6), (N, 3, 3) or (N, 3) [kg·m²] (nine numbers come as (N, 3, 3))
    r: np.ndarray | None  #: (N, 3) [m], or None when not given
    single: bool  #: one body, every argument unstacked: its result goes back unstacked
    quantities: list[type]  #: the classes of the pint Quantities given, in argument order


def read(H: ArrayLike, I: ArrayLike, r: ArrayLike | None) -> Arguments:
    """``H``, ``I`` and ``r`` (None: not given) read by :func:`as_float`, their shapes checked and
    broadcast against each other by the rule in :func:`hconv.solve.convert.convert`'s docstring:
    each is one body's (no row axis) or a stack of rows, and stacks of N rows and of one row
    broadcast to N rows, as numpy broadcasts. Nine numbers per tensor are a (3, 3) matrix."""
    quantities: list[type] = []  # the classes of the pint Quantities given, in argument order
    H = as_float("H", H, quantities)
    I = as_float("I", I, quantities)
    r = None if r is None else as_float("r", r, quantities)
    vectors = [(name, a, _vector_rows(name, a)) for name, a in (("H", H), ("r", r)) if a is not None]
    i_rows = _tensor_rows(I, {k for _, _, k in vectors if k is not None})
    given = vectors[:1] + [("I", I, i_rows)] + vectors[1:]
    stacked = [(name, a, k) for name, a, k in given if k is not None]
    many = [(name, a, k) for name, a, k in stacked if k != 1]
    clash = next((x for x in many if x[2] != many[0][2]), None)
    if clash is not None:
        (name0, a0, k0), (name1, a1, k1) = many[0], clash
        raise ValueError(
            f"{name0} of shape {a0.shape} and {name1} of shape {a1.shape} do not broadcast: {name0} has {k0} rows "
            f"and {name1} {k1}; give each the same number of rows, or one body's (or one row) to use for every row"
        )
    n = many[0][2] if many else 1
    if I.shape[-1:] == (9,):  # nine numbers, row-major, as a file's full9 columns give them
        I = I.reshape(I.shape[:-1] + (3, 3))
    H, I = _rows(H, n, k=given[0][2]), _rows(I, n, i_rows)
    if r is not None:
        r = _rows(r, n, vectors[-1][2])
    return Arguments(H, I, r, not stacked, quantities)


#: One body's inertia, by shape: principal moments, six numbers, nine numbers, a matrix.
ONE_BODY_I = ((3,), (6,), (9,), (3, 3))


def _vector_rows(name: str, a: np.ndarray) -> int | None:
    """The rows of vector argument ``name`` (H or r): None for one body's ``(3,)``."""
    if a.shape == (3,):
        return None
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"Expected {name} to have shape (3,) or (N, 3), got {a.shape}")
    return a.shape[0]


def _tensor_rows(I: np.ndarray, others: set) -> int | None:
    """The rows of I: None for one body's tensor. A ``(3, 3)`` I is one body's matrix, except
    beside H or r of three rows, where it could as well be three rows of principal moments: that
    one shape both readings share is refused, as either guess would give some caller a wrong ω."""
    if I.shape == (3, 3):
        if 3 in others and others <= {1, 3}:
            raise ValueError(
                "I of shape (3, 3) beside H or r of three rows could be one tensor or three rows of principal "
                "moments; pass I[None] (shape (1, 3, 3)) for one tensor used for every row, or "
                "I[:, None] * np.eye(3) (three diagonal matrices) for three rows of principal moments"
            )
        return None
    if I.shape in ONE_BODY_I:
        return None
    if (I.ndim == 2 and I.shape[1] in (3, 6, 9)) or (I.ndim == 3 and I.shape[1:] == (3, 3)):
        return I.shape[0]
    if I.ndim <= 1:
        raise ValueError(f"Expected one body's I to have shape (3,), (6,), (9,) or (3, 3), got {I.shape}")
    raise ValueError(
        f"Expected I to have shape (N, 3), (N, 6), (N, 9) or (N, 3, 3), or one body's (3,), (6,), (9,) or (3, 3), "
        f"got {I.shape}"
    )


def _rows(a: np.ndarray, n: int, k: int | None) -> np.ndarray:
    """Argument ``a`` of ``k`` rows (None: one body's, unstacked) as a stack of ``n`` rows; a row
    used for many is copied into each, so that the engines see what a tiled input gives them."""
    a = a[None] if k is None else a
    return a if a.shape[0] == n else np.ascontiguousarray(np.broadcast_to(a, (n,) + a.shape[1:]))


def _masked(a: object) -> bool:
    """Whether ``a`` is a numpy masked array, without importing numpy.ma when nothing has (numpy
    loads it lazily on first use of ``np.ma``, which was 5 % of ``hconv one``'s whole run)."""
    return "numpy.ma" in sys.modules and isinstance(a, np.ma.MaskedArray)


def as_float(name: str, given_a: ArrayLike, quantities: list[type] | None = None) -> np.ndarray:
    """Argument ``name`` (H, I or r) as float64 numbers in SI, appending to ``quantities`` the
    class of the pint Quantity it was, if it was one. The rule for numbers that carry a unit or
    a mask is in the docstring of :func:`hconv.solve.convert.convert`; :mod:`hconv.solve.units` finds the units."""
    a: Any = given_a  # an array, or an object that holds one with a unit or a mask
    scale = 1.0
    if type(a) is not np.ndarray:  # a plain ndarray (the common case) holds bare numbers
        a, scale = _unwrapped(name, a, quantities)
    mask = np.ma.getmaskarray(a) if _masked(a) else None
    try:
        given = np.asarray(np.ma.getdata(a) if mask is not None else a)
        if given.dtype.kind not in "iuf":  # float64 would drop an imaginary part, parse text, count truths
            if given.dtype.kind == "O":
                _refuse_units_numpy_drops(name, list(given.flat))
            raise UsageError(
                f"{name} must hold real numbers, got {_dtype_text(given.dtype)}; {_dtype_fix(name, given.dtype)}"
            )
        out = np.asarray(given, dtype=np.float64)
    except UsageError:
        raise
    except (TypeError, ValueError) as exc:
        if "inhomogeneous" in str(exc):  # numpy's words for nested sequences of unequal lengths
            raise ValueError(f"{name} must be a rectangular array of numbers: its rows differ in length") from None
        raise ValueError(f"{name} must be numeric: {exc}") from None
    if scale != 1.0:
        out = out * scale
    if mask is not None and mask.any():
        out = np.where(mask, np.nan, out)  # a new array: the caller's is never written
    return out


def _unwrapped(name: str, a: Any, quantities: list[type] | None) -> tuple[Any, float]:
    """The numbers that ``a`` holds and the factor from their unit to SI: a pint Quantity's
    magnitude (its class appended to ``quantities``), an array's values in the unit its ``attrs``
    give (an xarray DataArray, a pandas Series); UsageError for numbers whose unit or mask numpy
    would drop and hconv does not read."""
    scale = 1.0
    data = getattr(a, "data", None) if units.is_xarray(a) else None
    labelled = units.labelled_unit(a)
    if units.is_pint(data):
        a = data  # pint-xarray: the Quantity holds the unit
    elif labelled is not None:
        key, unit = labelled
        scale, a = units.factor(name, unit, f"{name}.attrs[{key!r}]"), getattr(a, "values", a)
    if units.is_pint(a):
        if quantities is not None:
            quantities.append(type(a))
        scale, a = units.pint_factor(name, a, name), a.magnitude
    _refuse_units_numpy_drops(name, a)
    return a, scale


def _refuse_units_numpy_drops(name: str, a: object) -> None:
    """UsageError when ``a`` carries a unit hconv does not read, or is a list or tuple holding
    numbers with units or masks, which ``np.asarray`` would make bare numbers of."""
    what = units.foreign(a)
    if what is not None:
        si = units.SI[name]
        raise UsageError(
            f"{name} is {what}, which hconv does not read; pass a pint Quantity "
            f"or plain numbers in {si} (e.g. {name}.to_value({si!r}))"
        )
    if isinstance(a, (list, tuple)):
        held = _held(a)
        if held is not None:
            raise UsageError(f"{name} holds {held}")


def _held(items: list | tuple) -> str | None:
    """What the first item of nested ``items`` that carries a unit or a mask is, and the fix;
    None when there is none. Looked at a nesting level at a time, by the set of the items' types,
    which costs plain numbers (the common case) less than ``np.asarray`` on them
    (docs/measurements.md)."""
    level, kinds = items, set(map(type, items))
    while True:
        for x in level if kinds - _PLAIN else ():
            found = None if type(x) in _PLAIN else _carried(x)
            if found is not None:
                return found
        if not kinds & _NESTED:
            return None
        inner = level if kinds <= _NESTED else [x for x in level if type(x) in _NESTED]
        kinds = set(map(type, chain.from_iterable(inner)))
        if kinds <= _PLAIN - _NESTED:  # plain numbers all: the level need not be built
            return None
        level = list(chain.from_iterable(inner))


def _carried(x: object) -> str | None:
    """What item ``x`` of a list is, and the fix, when numpy would drop its unit or mask."""
    if units.is_pint(x):
        return (
            "pint Quantities, whose units numpy would drop; pass one Quantity of the whole array, "
            "e.g. ureg.Quantity(np.array(values), 'g*cm**2/s')"
        )
    if _masked(x):
        return "masked arrays, whose masks numpy would drop; pass one masked array, e.g. np.ma.stack(...)"
    if units.labelled_unit(x) is not None:
        return "arrays with a unit in their attrs, which numpy would drop; pass one array of them all"
    what = units.foreign(x)
    return (
        None if what is None else f"{what} and others like it, whose units numpy would drop; pass plain numbers in SI"
    )


#: Lists and tuples: :func:`_held` looks inside them.
_NESTED = frozenset({list, tuple})
#: Types that hold a plain number: the items of a list that :func:`_held` passes at once.
_PLAIN = frozenset({float, int, np.float64, np.float32, np.int64, np.int32, np.ndarray, list, tuple})


def _dtype_text(dtype: np.dtype) -> str:
    kinds = {"b": "booleans", "c": "complex", "U": "text", "S": "bytes", "O": "Python objects"}
    return f"{kinds.get(dtype.kind, 'values')} (dtype {dtype})"


def _dtype_fix(name: str, dtype: np.dtype) -> str:
    if dtype.kind == "c":
        return f"pass {name}.real if the imaginary part is meant to be zero"
    return f"convert it to numbers first, e.g. np.asarray({name}, dtype=float)"
