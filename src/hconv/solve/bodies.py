"""Scenes as they come: body states in any inertia form, frame and reference point, to ω.

:func:`solve` takes the column sets that :meth:`hconv.tables.layout.Layout.read` returns (SI units,
component-major ``(k, N)`` arrays) and the :class:`Conventions` of the scene. It

1. negates the products of inertia if they were given as positive integrals (``products``);
2. re-expresses H (and r, v) in the body frame when an orientation q is given and H is in the
   world frame (``frame``); with q, the tensor is in the body frame (see :mod:`hconv.tables.layout`);
3. moves the reference point (``about``): ``pivot`` shifts I from the centre of mass to the pivot;
   ``free`` takes the centre of mass's orbital momentum out of H (see :mod:`hconv.kernels.frames`);
4. solves with :func:`hconv.solve.convert.convert` on the cheapest form the inertia allows: a scalar or
   principal moments go straight to the division ``H_i / I_i``; a tensor is built only for a
   pivot shift, and otherwise the six or nine numbers go to the chosen method;
5. re-expresses ω (and a dropped axis) in ``omega_frame`` (default: the frame of H);
6. with a mass column, flags rows whose inertia no solid of that mass could have (``unit_suspect``).

The residual is measured in the frame and about the point where the tensor is solved, so it does
not include the (few-ulp) rounding of the rotations.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hconv.solve import convert as core
from hconv.kernels import frames
from hconv.solve import methods
from hconv.solve import status
from hconv.solve import units
from hconv.kernels.inertia import Sym3

FRAMES = ("world", "body")
ABOUT = ("same", "pivot", "free")
PRODUCTS = ("tensor", "positive")
#: Rounding a vector through a rotation costs about this many cond(I)·eps in ω.
ROTATION_K = 2.0
#: Row-major positions of the off-diagonal entries of a 9-number tensor.
_OFF9 = (1, 2, 3, 5, 6, 7)


@dataclass(frozen=True)
class Conventions:
    """How the scene stores its bodies. Defaults: hconv's own conventions (see the README)."""

    frame: str = "world"  #: the frame of H, r and v: world or body (body needs no q)
    omega_frame: Optional[str] = None  #: the frame of ω; None: the frame of H
    about: str = "same"  #: same (I and H about one point), pivot or free
    products: str = "tensor"  #: tensor (Ixy = -∫xy dm) or positive (Pxy = +∫xy dm)
    degenerate: str = "error"  #: error, pinv or lock
    degenerate_rtol: Optional[float] = None  #: a moment <= this × trace counts as zero

    def check(self, method: str) -> None:
        """ValueError naming the option, for a choice that is not allowed or not usable."""
        for opt, value, allowed in (("frame", self.frame, FRAMES), ("omega_frame", self.omega_frame or self.frame, FRAMES),
                                    ("about", self.about, ABOUT), ("products", self.products, PRODUCTS),
                                    ("degenerate", self.degenerate, core.DEGENERATE_MODES)):
            if value not in allowed:
                raise ValueError(f"{opt} must be one of {', '.join(allowed)}, got {value!r}")
        if self.degenerate != "error" and not methods.get(method).exact:
            raise ValueError(f"--degenerate {self.degenerate} applies to the exact methods, not to {method!r}")

    def needs(self, method: str) -> dict:
        """The column sets, besides H and I, that this run cannot do without, each with the reason."""
        need = {}
        if methods.get(method).needs_r:
            need["r"] = f"method {method!r} needs the offset r"
        if self.about == "pivot":
            need.setdefault("r", "--about pivot needs r, the centre of mass relative to the pivot")
            need["m"] = "--about pivot needs the mass m"
        if self.about == "free":
            need.setdefault("r", "--about free needs r, the centre of mass relative to the origin of H")
            need["m"] = "--about free needs the mass m"
            need["v"] = "--about free needs v, the velocity of the centre of mass"
        if (self.omega_frame or self.frame) != self.frame:
            need["q"] = "ω in another frame than H needs the orientation q"
        return need


def inertia_array(form: str, I: np.ndarray) -> np.ndarray:
    """``I`` of shape ``(k, N)`` in ``form`` as core.convert takes it: ``(N, 3)`` diagonal moments
    (scalar and principal), ``(N, 6)`` or ``(N, 3, 3)``. No copy where a view will do."""
    if form == "scalar":
        return np.repeat(I, 3, axis=0).T
    if form in ("principal", "sym6"):
        return I.T
    if form == "full9":
        return np.moveaxis(I.reshape(3, 3, -1), -1, 0)
    raise ValueError(f"unknown inertia form {form!r}")


def _flip_products(form: str, I: np.ndarray) -> np.ndarray:
    if form == "sym6":
        return np.concatenate([I[:3], -I[3:]])
    if form == "full9":
        I = I.copy()
        I[list(_OFF9)] *= -1
    return I  # scalar and principal forms have no products


def _trace(form: str, I: np.ndarray) -> np.ndarray:
    """|trace(I)| ``(N,)`` in any form: Σ|λ| for a positive semi-definite tensor, which is all the
    unit check needs (rows that are not are flagged not_positive_definite, which takes precedence)."""
    if form == "scalar":
        return np.abs(3.0 * I[0])
    if form == "principal":
        return np.abs(I[0] + I[1] + I[2])
    if form == "full9":
        return np.abs(I[0] + I[4] + I[8])
    return np.abs(I[0] + I[1] + I[2])


def _pivot(form: str, I: np.ndarray, m: np.ndarray, r: np.ndarray) -> tuple[str, np.ndarray]:
    """The inertia about the pivot, as sym6 (or full9, to keep an asymmetry visible)."""
    n = I.shape[1]
    zero = np.zeros(n)
    d = frames.shift_to_pivot(Sym3(zero, zero, zero, zero, zero, zero), m, r)
    if form in ("scalar", "principal"):
        diag = np.repeat(I, 3, axis=0) if form == "scalar" else I
        return "sym6", np.stack([diag[0] + d.xx, diag[1] + d.yy, diag[2] + d.zz, d.xy, d.xz, d.yz])
    if form == "sym6":
        return "sym6", I + np.stack(list(d))
    full = np.stack([d.xx, d.xy, d.xz, d.xy, d.yy, d.yz, d.xz, d.yz, d.zz])
    return "full9", I + full


def solve(sets: dict, form: str, method: str = "exact", precision: int = 64, conv: Conventions = Conventions(),
          diagnostics: bool = True) -> core.Result:
    """ω for every row of ``sets`` (see the module docstring); a stacked :class:`core.Result`.

    ``sets``: ``H`` ``(3, N)`` [kg·m²/s], ``I`` ``(k, N)`` in ``form`` [kg·m²] and, where given,
    ``q`` ``(4, N)`` (w, x, y, z), ``r`` ``(3, N)`` [m], ``m`` ``(1, N)`` [kg], ``v`` ``(3, N)`` [m/s].
    """
    conv.check(method)
    with np.errstate(all="ignore"):  # extreme rows get statuses, never warnings
        return _solve(sets, form, method, precision, conv, diagnostics)


def _solve(sets, form, method, precision, conv, diagnostics) -> core.Result:
    H, I = sets["H"], sets["I"]
    q, r, v = sets.get("q"), sets.get("r"), sets.get("v")
    m = sets["m"][0] if "m" in sets else None
    n = H.shape[1]
    for name in conv.needs(method):
        if name not in sets:
            raise ValueError(f"this conversion needs the set {name!r}")
    bad = np.zeros(n, dtype=bool)  # rows with no usable orientation or mass
    if conv.products == "positive":
        I = _flip_products(form, I)
    R = None
    if q is not None:
        R, bad_q = frames.quaternion_matrix(q)
        bad |= bad_q
    rotate_in = R is not None and conv.frame == "world"
    if rotate_in:
        H = frames.to_body(R, H)
        r = None if r is None else frames.to_body(R, r)
        v = None if v is None else frames.to_body(R, v)
    I_com, form_com = I, form
    if conv.about != "same":
        bad |= ~(np.isfinite(m) & (m >= 0))
        if conv.about == "pivot":
            form, I = _pivot(form, I, m, r)
        else:
            H = frames.momentum_about_com(H, m, r, v)
    if bad.any():
        H = np.where(bad, np.nan, H)  # status invalid_input, through core
    res = core.convert(H.T, inertia_array(form, I), None if r is None else r.T, method=method, precision=precision,
                       diagnostics=diagnostics, degenerate=conv.degenerate, degenerate_rtol=conv.degenerate_rtol,
                       extra_k=ROTATION_K if rotate_in else 0.0)
    w, axis, code = res.w, res.null_axis, res.status_code
    if R is not None and (conv.omega_frame or conv.frame) == "world":
        w = frames.to_world(R, w.T.astype(np.float64)).T.astype(w.dtype)
        if axis is not None:
            axis = frames.to_world(R, axis.T).T
    if m is not None:
        # Without --about, I may be about a distant pivot: only "too dense" is certain then.
        slip = units.implausible(_trace(form_com, I_com), m, both_sides=conv.about != "same")
        code = status.merge(code, slip, "unit_suspect")
    return dataclasses.replace(res, w=w, null_axis=axis, status_code=code)
