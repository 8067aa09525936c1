"""Inertia forms: every way hconv reads an inertia tensor, one registry entry each.

A form is how a file (or ``hconv one``) gives the tensor: one isotropic moment, three principal
moments, six numbers or nine. Every module that must tell forms apart asks this registry; none
compares form names or indexes the numbers itself. Adding a form is one :func:`register` call.

Conventions are those of :mod:`hconv.kernels.inertia` (tensor entries, ``Ixy = -∫xy dm``, about
the point and in the frame stated there). Inside hconv a form's numbers are one component-major
array ``I`` of shape ``(k, N)`` [kg·m²], in the form's *value order* (below), so that every
number is one contiguous column:

==========  ==================================================  ========================  ===========
form        named columns                                       value order (k)           list column
==========  ==================================================  ========================  ===========
scalar      ``I``                                               I (1)                     no
principal   ``I1, I2, I3``                                      I1, I2, I3 (3)            3 values
sym6        ``Ixx, Iyy, Izz, Ixy, Ixz, Iyz``                    the same (6)              6 values
full9       the six plus ``Iyx, Izx, Izy``                      row-major (9)             9 values
==========  ==================================================  ========================  ===========

``scalar`` and ``principal`` are *diagonal*: moments about the axes they are given in, so they
have no products and are solved by division.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hconv.kernels.inertia import Sym3, max_abs
from hconv.registry import Registry

#: The six numbers' order, and the name of each entry.
SIX = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")


@dataclass(frozen=True)
class Form:
    """One inertia form and everything hconv needs to know to read it."""

    name: str
    columns: tuple  #: named columns, in the order they are read
    description: str  #: how messages name its columns, e.g. "I1, I2, I3 (principal)"
    note: str  #: what its numbers are, in a word: "principal", "row-major", ...
    diagonal: bool  #: moments about the given axes only (no products): solved by division
    #: values per row in a list column ``I``; None when the form has no list spelling
    list_size: int | None
    #: ``(k, N)``, symmetry tolerance → the one internal representation: a :class:`Sym3` of
    #: contiguous ``(N,)`` columns, and the ``(N,)`` mask of rows whose nine numbers are not
    #: symmetric within the tolerance (:func:`hconv.solve.status.symmetry_rtol`; those rows keep
    #: the mean of the two entries, so that the arrays stay finite; the caller flags them)
    as_sym3: Callable[[np.ndarray, float], tuple[Sym3, np.ndarray]]
    #: ``(k, N)`` → the three diagonal entries and the three products ``(xy, xz, yz)`` as
    #: :class:`Sym3`-ordered rows ``(6, N)``; products are averaged for a nine-number form
    as_six: Callable[[np.ndarray], np.ndarray]
    #: ``(k, N)`` with the products' sign flipped (``--products positive``)
    flip_products: Callable[[np.ndarray], np.ndarray]
    #: ``(k, N)`` + a parallel-axis shift :class:`Sym3` → (form name, ``(k', N)``) about the pivot
    shifted: Callable[[np.ndarray, Sym3], tuple[str, np.ndarray]]

    #: the form this one extends: its columns must be present too (full9 extends sym6)
    extends: str | None = None
    #: position in :attr:`columns` of each value, in value order; None when they coincide
    value_order: tuple | None = None

    @property
    def count(self) -> int:
        """Numbers per row."""
        return len(self.columns)

    def values(self, named: np.ndarray) -> np.ndarray:
        """The numbers as read from :attr:`columns` ``(k, N)``, in value order."""
        return named if self.value_order is None else named[list(self.value_order)]

    def trace(self, I: np.ndarray) -> np.ndarray:
        """|trace(I)| ``(N,)``: Σ|λ| for a positive semi-definite tensor, which is all the unit
        check needs (rows that are not are flagged not_positive_definite, which takes precedence)."""
        six = self.as_six(I)
        return np.abs(six[0] + six[1] + six[2])

    def offdiag(self, I: np.ndarray) -> np.ndarray:
        """max over i≠j of |Iij| / √(Iii·Ijj) per row ``(N,)``: how far I is from diagonal in
        the axes it is given in (0 for the diagonal forms)."""
        if self.diagonal:
            return np.zeros(I.shape[1])
        s = self.as_six(I)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios = [
                np.abs(s[3]) / np.sqrt(np.abs(s[0] * s[1])),
                np.abs(s[4]) / np.sqrt(np.abs(s[0] * s[2])),
                np.abs(s[5]) / np.sqrt(np.abs(s[1] * s[2])),
            ]
        return np.fmax(np.fmax(ratios[0], ratios[1]), ratios[2])


FORMS: Registry[Form] = Registry("inertia form")


def register(form: Form) -> Form:
    return FORMS.add(form.name, form)


def get(name: str) -> Form:
    """The form called ``name``; UsageError (a ValueError) naming the choices otherwise."""
    return FORMS.get_checked(name)


def from_array(I: np.ndarray) -> tuple[Form, np.ndarray]:
    """The form and values ``(k, N)`` (views) of tensors given as numpy users hold them: ``(N, 3)``
    principal moments, ``(N, 6)`` six numbers or ``(N, 3, 3)`` matrices; ValueError otherwise."""
    if I.ndim == 2 and I.shape[1] == 3:
        return FORMS["principal"], I.T
    if I.ndim == 2 and I.shape[1] == 6:
        return FORMS["sym6"], I.T
    if I.ndim == 3 and I.shape[1:] == (3, 3):
        return FORMS["full9"], I.reshape(I.shape[0], 9).T
    raise ValueError(f"Expected I to have shape (3,), (6,), (3, 3), (N, 3), (N, 6) or (N, 3, 3), got {I.shape}")


def by_count(k: int) -> Form | None:
    """The first registered form with ``k`` numbers per row (``hconv one --I``), or None."""
    return next((f for f in FORMS.values() if f.count == k), None)


def by_list_size(k: int) -> Form | None:
    """The form a list column ``I`` of ``k`` values per row holds, or None."""
    return next((f for f in FORMS.values() if f.list_size == k), None)


def column_names() -> tuple:
    """Every column name of every form, for ``--map`` and ``--unit``."""
    return tuple(dict.fromkeys(c for f in FORMS.values() for c in f.columns))


def _either(items: list) -> str:
    return ", ".join(items[:-1]) + " or " + items[-1] if len(items) > 1 else "".join(items)


def counts_text() -> str:
    """``1 (isotropic), 3 (principal), ... or 9 (row-major)``: what ``hconv one --I`` takes."""
    return _either([f"{f.count} ({f.note})" for f in FORMS.values() if by_count(f.count) is f])  # first per count


def list_sizes_text() -> str:
    """``3 (principal), 6 (...) or 9 (row-major)``: what a list column ``I`` may hold."""
    return _either([f"{f.list_size} ({f.note})" for f in FORMS.values() if f.list_size])


def forms_text() -> str:
    """Every form's columns, for the message that finds none."""
    return ", ".join(f.description for f in FORMS.values())


# --- the entries ---------------------------------------------------------------------------


def _shift_diagonal(diag: np.ndarray, d: Sym3) -> tuple[str, np.ndarray]:
    return "sym6", np.stack([diag[0] + d.xx, diag[1] + d.yy, diag[2] + d.zz, d.xy, d.xz, d.yz])


def _no_products(I: np.ndarray) -> np.ndarray:
    return I


def _six_of_diagonal(diag: np.ndarray) -> np.ndarray:
    zero = np.zeros_like(diag[0])
    return np.stack([diag[0], diag[1], diag[2], zero, zero, zero])


def _sym3_of_diagonal(diag: np.ndarray, rtol: float) -> tuple[Sym3, np.ndarray]:  # no products: symmetric
    n = diag.shape[1]
    xx, yy, zz = (np.ascontiguousarray(d, dtype=np.float64) for d in diag)
    return Sym3(xx, yy, zz, np.zeros(n), np.zeros(n), np.zeros(n)), np.zeros(n, dtype=bool)


def _sym3_of_six(I: np.ndarray, rtol: float) -> tuple[Sym3, np.ndarray]:
    xx, yy, zz, xy, xz, yz = (np.ascontiguousarray(c, dtype=np.float64) for c in I)
    return Sym3(xx, yy, zz, xy, xz, yz), np.zeros(I.shape[1], dtype=bool)


def _sym3_of_nine(I: np.ndarray, rtol: float) -> tuple[Sym3, np.ndarray]:
    """The symmetric part of row-major nine numbers, and where they are not symmetric:
    |Iij − Iji| > rtol · max|I| on that row."""
    skew = np.abs(I[1] - I[3])
    with np.errstate(invalid="ignore"):
        np.maximum(skew, np.abs(I[2] - I[6]), out=skew)
        np.maximum(skew, np.abs(I[5] - I[7]), out=skew)
        # The largest entry is at least the largest diagonal one, so a row whose skew is within
        # tolerance of that is symmetric: only the others (and NaN rows) need all nine.
        doubt = ~(skew <= rtol * max_abs([I[0], I[4], I[8]]))
        asym = np.zeros(skew.shape, dtype=bool)
        if doubt.any():
            rows = np.flatnonzero(doubt)
            # row by row: a reduction over the strided axis of an (N, 3, 3) stack is slow
            asym[rows] = skew[rows] > rtol * max_abs(I[:, rows])
    return Sym3(
        I[0].copy(), I[4].copy(), I[8].copy(), 0.5 * (I[1] + I[3]), 0.5 * (I[2] + I[6]), 0.5 * (I[5] + I[7])
    ), asym


register(
    Form(
        "scalar",
        ("I",),
        "I (isotropic)",
        "isotropic",
        diagonal=True,
        list_size=None,
        as_sym3=lambda I, rtol: _sym3_of_diagonal(np.repeat(I, 3, axis=0), rtol),
        as_six=lambda I: _six_of_diagonal(np.repeat(I, 3, axis=0)),
        flip_products=_no_products,
        shifted=lambda I, d: _shift_diagonal(np.repeat(I, 3, axis=0), d),
    )
)

register(
    Form(
        "principal",
        ("I1", "I2", "I3"),
        "I1, I2, I3 (principal)",
        "principal",
        diagonal=True,
        list_size=3,
        as_sym3=_sym3_of_diagonal,
        as_six=_six_of_diagonal,
        flip_products=_no_products,
        shifted=_shift_diagonal,
    )
)

register(
    Form(
        "sym6",
        SIX,
        f"{', '.join(SIX)} (tensor)",
        ",".join(SIX),
        diagonal=False,
        list_size=6,
        as_sym3=_sym3_of_six,
        as_six=lambda I: I,
        flip_products=lambda I: np.concatenate([I[:3], -I[3:]]),
        shifted=lambda I, d: ("sym6", I + np.stack(list(d))),
    )
)

#: Row-major positions of the nine-number form's off-diagonal entries.
_OFF9 = (1, 2, 3, 5, 6, 7)


def _flip9(I: np.ndarray) -> np.ndarray:
    I = I.copy()
    I[list(_OFF9)] *= -1
    return I


register(
    Form(
        "full9",
        SIX + ("Iyx", "Izx", "Izy"),
        "the six plus Iyx, Izx, Izy",
        "row-major",
        diagonal=False,
        list_size=9,
        extends="sym6",
        # the named nine are the six, then Iyx, Izx, Izy; as values they are row-major
        value_order=(0, 3, 4, 6, 1, 5, 7, 8, 2),
        as_sym3=_sym3_of_nine,
        as_six=lambda I: np.stack([I[0], I[4], I[8], 0.5 * (I[1] + I[3]), 0.5 * (I[2] + I[6]), 0.5 * (I[5] + I[7])]),
        flip_products=_flip9,
        # stays nine numbers, so that an asymmetry remains visible (status not_symmetric)
        shifted=lambda I, d: ("full9", I + np.stack([d.xx, d.xy, d.xz, d.xy, d.yy, d.yz, d.xz, d.yz, d.zz])),
    )
)
