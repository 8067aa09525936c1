"""The input's column sets and hconv's names for their columns.

Column sets (hconv's names; ``--map NAME=COLUMN`` points a name at a column of another name):

=========  ===============================================  ==================================
set        named columns                                    or one list column (Parquet)
=========  ===============================================  ==================================
H          Hx, Hy, Hz  [kg·m²/s]                            H: 3 values
I          exactly one inertia form (hconv.solve.forms)     I: 3, 6 or 9 values
q          qw, qx, qy, qz (body → world)                    q: 4 values, order --quat-order
r          rx, ry, rz  [m]                                  r: 3 values
m          m  [kg]
v          vx, vy, vz  [m/s]                                v: 3 values
w_obs      wx_obs, wy_obs, wz_obs  [rad/s]                  w_obs: 3 values
=========  ===============================================  ==================================

Kept apart from :mod:`hconv.tables.layout` (which needs pyarrow) so that a Job can check
``--map`` and ``--unit`` when it is made.
"""

from __future__ import annotations

import re

from hconv.solve import forms

VECTOR_SETS = {
    "H": ("Hx", "Hy", "Hz"),
    "q": ("qw", "qx", "qy", "qz"),
    "r": ("rx", "ry", "rz"),
    "m": ("m",),
    "v": ("vx", "vy", "vz"),
    "w_obs": ("wx_obs", "wy_obs", "wz_obs"),
}
#: The fields of a struct named like a vector set, one per column in its order: a struct ``H``
#: with fields x, y, z is Hx, Hy, Hz, and ``w_obs`` {x, y, z} is wx_obs, wy_obs, wz_obs.
STRUCT_FIELDS = {"H": "xyz", "q": "wxyz", "r": "xyz", "v": "xyz", "w_obs": "xyz"}
#: The unit quantity (a key of hconv.solve.units.SI) of each set.
QUANTITY = {"H": "H", "I": "I", "q": "q", "r": "r", "m": "m", "v": "v", "w_obs": "w"}
#: Sets read whenever present (they change the answer or its status); v and w_obs only when needed
#: (and v whenever present for hconv diagnose, whose orbital-momentum hypothesis uses it).
OPTIONAL_SETS = ("q", "r", "m")


def all_names() -> tuple:
    """Every name --map takes: the sets' columns, every registered inertia form's, and the sets."""
    return tuple(
        sorted(
            {n for names in VECTOR_SETS.values() for n in names} | set(forms.column_names()) | set(QUANTITY),
            key=str.lower,
        )
    )


def quantity_of(name: str) -> str | None:
    """The unit quantity of a set or of one of hconv's column names; None for any other name."""
    if name in QUANTITY:
        return QUANTITY[name]
    if name in forms.column_names():
        return QUANTITY["I"]
    return next((QUANTITY[s] for s, cols in VECTOR_SETS.items() if name in cols), None)


#: A unit written after a column's name, in brackets or parentheses: ``Hx [kg*m^2/s]``, ``Ixx (g*cm^2)``.
_HEADER_UNIT = re.compile(r"^(?P<name>.*?)\s*(?:\[(?P<b>[^\[\]]+)\]|\((?P<p>[^()]+)\))\s*$")


def header_name(column: str) -> tuple[str, str | None]:
    """A column's name without the unit written after it, and that unit (None when none is)."""
    m = _HEADER_UNIT.match(column)
    if m is None or not m["name"]:
        return column, None
    return m["name"], (m["b"] or m["p"]).strip()


def reads_as(column: str) -> str | None:
    """The hconv name a column of this name stands for, without its header's unit and, for names
    of more than one letter, without regard to case (the rule of :func:`hconv.tables.columns.find`,
    which also settles two columns for one name); None for a name hconv does not read."""
    bare = header_name(column)[0]
    names = all_names()
    if bare in names:
        return bare
    return next((n for n in names if len(n) > 1 and n.lower() == bare.lower()), None)
