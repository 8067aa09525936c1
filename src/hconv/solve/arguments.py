"""The arguments of :func:`hconv.solve.convert.convert`: H, I and r read as float64 numbers in SI
and checked for shape, before any conversion.

The shapes are those of :mod:`hconv.solve.convert`'s docstring; one body given unstacked is read
as a stack of one. Numbers that carry a unit or a mask are read by the rule in the docstring of
:func:`hconv.solve.convert.convert` (:mod:`hconv.solve.units` finds the units). A wrong shape is
a ValueError, a unit or a type hconv does not read a UsageError, each naming the argument.
"""

from __future__ import annotations

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
    I: np.ndarray  #: (N, 6), (N, 3, 3) or (N, 3) [kg·m²]
    r: np.ndarray | None  #: (N, 3) [m], or None when not given
    single: bool  #: one body, given unstacked: its result goes back unstacked
    quantities: list[type]  #: the classes of the pint Quantities given, in argument order


def read(H: ArrayLike, I: ArrayLike, r: ArrayLike | None) -> Arguments:
    """``H``, ``I`` and ``r`` (None: not given) read by :func:`as_float` and checked for shape."""
    quantities: list[type] = []  # the classes of the pint Quantities given, in argument order
    H = as_float("H", H, quantities)
    I = as_float("I", I, quantities)
    single = H.ndim == 1
    if single:
        if H.shape != (3,):
            raise ValueError(f"Expected H to have shape (3,) or (N, 3), got {H.shape}")
        if I.shape not in ((3,), (6,), (3, 3)):
            raise ValueError(f"Expected one body's I to have shape (3,), (6,) or (3, 3), got {I.shape}")
        H, I = H[None], I[None]
        r = None if r is None else as_float("r", r, quantities)[None]
    if H.ndim != 2 or H.shape[1] != 3:
        raise ValueError(f"Expected H to have shape (3,) or (N, 3), got {H.shape}")
    n = H.shape[0]
    if I.ndim not in (2, 3) or I.shape[1:] not in ((3,), (6,), (3, 3)):
        one = "; (3,), (6,) and (3, 3) are one body's, for H of shape (3,)" if I.shape in ((3,), (6,), (3, 3)) else ""
        raise ValueError(
            f"Expected I to have shape ({n}, 3), ({n}, 6) or ({n}, 3, 3) for H of shape {H.shape}, got {I.shape}{one}"
        )
    if I.shape[0] != n:
        one = "; a (3, 3) I is one body's tensor, for H of shape (3,)" if I.shape == (3, 3) else ""
        raise ValueError(f"I holds {_count(I.shape[0], 'tensor')} but H holds {_count(n, 'vector')}{one}")
    if r is not None:
        r = as_float("r", r, quantities)
        if r.shape != (n, 3):
            raise ValueError(
                f"Expected r to have shape {(3,) if single else (n, 3)}, got {r.shape[1:] if single else r.shape}"
            )
    return Arguments(H, I, r, single, quantities)


def as_float(name: str, given_a: ArrayLike, quantities: list[type] | None = None) -> np.ndarray:
    """Argument ``name`` (H, I or r) as float64 numbers in SI, appending to ``quantities`` the
    class of the pint Quantity it was, if it was one. The rule for numbers that carry a unit or
    a mask is in the docstring of :func:`hconv.solve.convert.convert`; :mod:`hconv.solve.units` finds the units."""
    a: Any = given_a  # an array, or an object that holds one with a unit or a mask
    scale = 1.0
    if type(a) is not np.ndarray:  # a plain ndarray (the common case) holds bare numbers
        a, scale = _unwrapped(name, a, quantities)
    mask = np.ma.getmaskarray(a) if isinstance(a, np.ma.MaskedArray) else None
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
    magnitude (its class appended to ``quantities``), an xarray DataArray's values in its
    ``units``; UsageError for numbers whose unit or mask numpy would drop and hconv does not read."""
    scale = 1.0
    if units.is_xarray(a):
        unit, data = units.labelled_unit(a), getattr(a, "data", None)
        if units.is_pint(data):
            a = data  # pint-xarray: the Quantity holds the unit
        elif unit is not None:
            scale, a = units.factor(name, unit, f"{name}.attrs['units']"), a.values
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
    if isinstance(x, np.ma.MaskedArray):
        return "masked arrays, whose masks numpy would drop; pass one masked array, e.g. np.ma.stack(...)"
    if units.labelled_unit(x) is not None:
        return "xarray DataArrays with units, which numpy would drop; pass one DataArray"
    what = units.foreign(x)
    return (
        None if what is None else f"{what} and others like it, whose units numpy would drop; pass plain numbers in SI"
    )


#: Lists and tuples: :func:`_held` looks inside them.
_NESTED = frozenset({list, tuple})
#: Types that hold a plain number: the items of a list that :func:`_held` passes at once.
_PLAIN = frozenset({float, int, np.float64, np.float32, np.int64, np.int32, np.ndarray, list, tuple})


def _count(k: int, noun: str) -> str:
    return f"{k} {noun}" + ("" if k == 1 else "s")


def _dtype_text(dtype: np.dtype) -> str:
    kinds = {"b": "booleans", "c": "complex", "U": "text", "S": "bytes", "O": "Python objects"}
    return f"{kinds.get(dtype.kind, 'values')} (dtype {dtype})"


def _dtype_fix(name: str, dtype: np.dtype) -> str:
    if dtype.kind == "c":
        return f"pass {name}.real if the imaginary part is meant to be zero"
    return f"convert it to numbers first, e.g. np.asarray({name}, dtype=float)"
