"""Units: factors from the units a file uses to SI, and the unit-slip check.

hconv computes in SI: H [kg·m²/s], I [kg·m²], r [m], m [kg], v [m/s], ω [rad/s]. A unit given by
``--unit COLUMN=UNIT`` or by a Parquet field's ``unit`` metadata is turned into a factor to SI;
ω can be written in another unit (``--omega-unit``). SI spellings are recognised without pint;
anything else goes through pint, a dependency that is imported only then, so a run in SI (and
``hconv one``'s start-up) never pays for it. Only multiplicative units are accepted (no offsets such as °C).

Numbers handed to ``hconv.convert`` may carry their unit, and numpy would drop it without a word
(``np.asarray`` of a pint Quantity keeps the magnitude; astropy's Quantity and unyt's arrays are
ndarray subclasses, read as bare numbers). The rule, applied by :func:`hconv.solve.convert.convert`:

* a pint Quantity is read in its own unit (:func:`pint_factor`: its registry's factor to SI, the
  same number a file's column in that unit is multiplied by); a unit of another quantity is a
  UsageError naming the argument;
* an array whose ``attrs`` hold a unit (an xarray DataArray, a pandas Series; the key ``units``
  or ``unit`` in any case) is read in that unit, as ``--unit`` would read it (:func:`factor`); a
  DataArray that wraps a pint Quantity (pint-xarray) is that Quantity;
* any other array that carries a unit (astropy, unyt, anything numpy reads as an array that has
  a ``unit`` or ``units`` attribute) is refused (:func:`foreign`): pass a pint Quantity or plain
  numbers in SI.

All of these are told apart by their classes' modules and attributes, so hconv imports none of
these libraries (nor pint, when no Quantity is passed).
"""

from __future__ import annotations

import functools
import re
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np

from hconv.errors import ECHOED, UsageError, option, quoted
from hconv.solve.status import UNIT_DENSITY_BAND

#: The SI unit of each quantity, written as pint parses it.
SI = {
    "H": "kg*m**2/s",
    "I": "kg*m**2",
    "r": "m",
    "m": "kg",
    "v": "m/s",
    "w": "rad/s",
    "q": "",
}
QUANTITY = {
    "H": "angular momentum",
    "I": "inertia",
    "r": "length",
    "m": "mass",
    "v": "velocity",
    "w": "angular velocity",
    "q": "a quaternion (no unit)",
}

# Spellings of the SI units that need no pint: with spaces, '·', '^' and '²' normalised away.
_SI_SPELLINGS = {
    "H": {"kg*m**2/s", "kgm**2/s", "kg*m**2*s**-1", "n*m*s", "nms", "j*s", "js"},
    "I": {"kg*m**2", "kgm**2"},
    "r": {"m", "meter", "metre", "meters", "metres"},
    "m": {"kg", "kilogram", "kilograms"},
    "v": {"m/s", "m*s**-1"},
    "w": {"rad/s", "1/s", "s**-1", "radian/second", "radians/second"},
    "q": {"", "1", "dimensionless"},
}


def _normal(unit: str) -> str:
    u = unit.strip().lower().replace(" ", "*").replace("·", "*").replace("^", "**")
    u = u.replace("²", "**2").replace("³", "**3").replace("⁻¹", "**-1")
    return re.sub(r"\*+(?=\*\*)", "", re.sub(r"\*{3,}", "**", u))


#: Set by the hconv command (:mod:`hconv.cli`), a process that runs no one else's code: pint is
#: then imported without its optional support of dask arrays, which the command never hands it,
#: and whose import (dask's core, where dask is installed) cost a run with units about a third of
#: a second. In a library caller's process pint is left as pint makes itself.
PINT_WITHOUT_DASK = False


def _import_pint() -> Any:
    """pint; in the command (:data:`PINT_WITHOUT_DASK`), imported as where dask is absent."""
    if not PINT_WITHOUT_DASK or "pint" in sys.modules or "dask" in sys.modules:
        import pint

        return pint
    sys.modules["dask"] = None  # type: ignore[assignment]  # `import dask` fails: pint goes without
    try:
        import pint
    finally:
        del sys.modules["dask"]  # a later import of dask (a --cluster run) finds it as ever
    return pint


@functools.cache
def _registry() -> Any:
    try:
        pint = _import_pint()
    except ImportError:
        raise UsageError(
            "units other than SI need pint, which is missing from this installation; "
            "reinstall hconv: pip install --force-reinstall hconv"
        ) from None
    return pint.UnitRegistry()


@functools.cache
def factor(quantity: str, unit: str, where: str = "unit") -> float:
    """The factor that turns a value in ``unit`` into the SI unit of ``quantity`` (a key of SI).

    ``where`` names the source of the unit in error messages (an option, or a file's column).
    """
    if _normal(unit) in _SI_SPELLINGS[quantity]:
        return 1.0
    ureg = _registry()
    try:
        one = ureg.Quantity(1.0, unit)
    except Exception:  # pint raises several kinds for text it cannot parse
        raise UsageError(
            f"{where}: pint does not understand the unit {quoted(unit, ECHOED)}; write it like g*cm**2 or lb*ft**2/s"
        ) from None
    return _to_si(quantity, one, repr(unit), where)


def _to_si(quantity: str, one: Any, unit: str, where: str) -> float:
    """The magnitude of pint Quantity ``one`` (1 of ``unit``) in the SI unit of ``quantity``."""
    import pint  # loaded already: ``one`` is its Quantity

    try:
        value = one.to(SI[quantity] or "dimensionless").magnitude
    except pint.errors.DimensionalityError:
        raise UsageError(
            f"{where}: {unit} is not a unit of {QUANTITY[quantity]} ({SI[quantity] or 'no unit'})"
        ) from None
    except pint.errors.OffsetUnitCalculusError:
        raise UsageError(f"{where}: {unit} has an offset; give a unit without one") from None
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise UsageError(f"{where}: {unit} gives a factor of {value}; give a positive unit")
    return value


def _package(cls: type) -> str:
    return cls.__module__.partition(".")[0]


def is_pint(value: object) -> bool:
    """Whether ``value`` is a pint Quantity, told without importing pint: none exists before pint
    is loaded, and its classes come from pint's modules."""
    return (
        "pint" in sys.modules
        and any(_package(c) == "pint" for c in type(value).__mro__)
        and hasattr(value, "magnitude")
        and hasattr(value, "units")
    )


def pint_factor(quantity: str, value: Any, where: str) -> float:
    """The factor from pint Quantity ``value``'s unit to the SI unit of ``quantity``: computed in
    the Quantity's own registry (which may define units hconv's does not) as :func:`factor` does
    in hconv's; UsageError naming ``where`` for a unit of another quantity."""
    unit = value.units
    return _to_si(quantity, type(value)(1.0, unit), repr(format(unit, "~") or "dimensionless"), where)


def is_xarray(value: object) -> bool:
    """Whether ``value`` is an xarray object (told by its class's module, without importing xarray)."""
    return _package(type(value)) == "xarray"


#: The keys of an ``attrs`` mapping that hold a unit (compared without regard to case): xarray's
#: CF convention writes ``units``, and people write ``unit`` (hconv's own Parquet field metadata).
UNIT_KEYS = ("units", "unit")


def labelled_unit(value: object) -> tuple[str, str] | None:
    """``(key, unit)``: the unit in the ``attrs`` mapping of an array-like (an xarray DataArray,
    a pandas Series), under a key of :data:`UNIT_KEYS` in any case; None without one."""
    attrs = getattr(value, "attrs", None)
    if not isinstance(attrs, Mapping) or not _array_like(value):
        return None
    for key, unit in attrs.items():
        if isinstance(key, str) and key.lower() in UNIT_KEYS and unit is not None:
            return key, str(unit)
    return None


def _array_like(value: object) -> bool:
    return isinstance(value, np.ndarray) or hasattr(value, "__array__")


def foreign(value: object) -> str | None:
    """What ``value`` is, e.g. ``"astropy's Quantity in g cm2 / s"``, when it carries a unit that
    hconv does not read (anything but pint's, and a unit in ``attrs``); None for anything else.
    Found without importing those libraries: their packages' names, or the ``unit`` or ``units``
    attribute of anything numpy can read as an array."""
    cls = type(value)
    package = _package(cls)
    if package in ("pint", "xarray") or not (_array_like(value) or package in ("astropy", "unyt")):
        return None
    unit = getattr(value, "unit", None)
    if unit is None:
        unit = getattr(value, "units", None)
    if unit is None:
        return None
    return f"{package}'s {cls.__name__} in {unit}"


def omega_factor(unit: str) -> float:
    """The factor from rad/s to ``unit`` (``--omega-unit``), e.g. 180/π for deg/s."""
    return 1.0 / factor("w", unit, option("omega_unit"))


def implausible(trace: np.ndarray, m: np.ndarray, both_sides: bool = True) -> np.ndarray:
    """Rows whose inertia no solid of mass ``m`` could have: a unit slip, most likely.

    ``trace``: Σ of the principal moments about the centre of mass ``(N,)`` [kg·m²]; ``m``:
    ``(N,)`` [kg]. The radius of gyration ρ_g = √(Σλ / 2m) is the root-mean-square distance of the
    mass from the centre; a uniform cube with the same mass and ρ_g has side 2ρ_g. A row is
    implausible when that cube's density m / (2ρ_g)³ lies outside
    :data:`hconv.solve.status.UNIT_DENSITY_BAND` (only above it, with ``both_sides=False``). Rows
    without a positive mass or trace are not judged (False).
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        side = 2.0 * np.sqrt(trace / (2.0 * m))
        density = m / side**3
    lo, hi = UNIT_DENSITY_BAND
    judged = (m > 0) & (trace > 0) & np.isfinite(density)
    return judged & ((density > hi) | ((density < lo) if both_sides else False))
