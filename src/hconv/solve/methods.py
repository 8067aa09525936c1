"""The conversion methods, each a small vectorised function registered with its metadata.

Every method maps tensors ``I`` (:class:`~hconv.kernels.inertia.Sym3` of ``(N,)`` columns, kg·m²),
momenta ``H`` of shape ``(3, N)`` [kg·m²/s] and, where it needs one, the offset ``r`` of shape
``(3, N)`` [m] to ``(w, flags)``: ``w`` of shape ``(3, N)`` in the method's unit, and a dict of
boolean ``(N,)`` masks for the statuses that only the method itself can see. (Vectors are held
component-major so that every component is one contiguous column.)
All arrays share one dtype, which sets the working precision.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hconv.kernels import frames, linsolve
from hconv.kernels.inertia import Sym3, pinv_moments, principal_frame
from hconv.registry import Registry
from hconv.solve.status import ILL_CONDITIONED_TOL, R_AXIS_RTOL, REPEATED_RTOL, singular_rtol

Kernel = Callable[[Sym3, np.ndarray, np.ndarray | None], "tuple[np.ndarray, dict[str, np.ndarray]]"]

RAD_S = "rad/s"
M2_S = "m^2/s"  # what the seed document's algebra yields: (m² / kg·m²) · kg·m²/s


@dataclass(frozen=True)
class Method:
    """A registered method and what a user needs to know before trusting it."""

    name: str
    kernel: Kernel
    unit: str
    exact: bool  #: True when the method computes I⁻¹H (up to rounding)
    needs_r: bool
    summary: str
    cost: str
    fails: str
    #: statuses for which no answer of this method exists: its ω is NaN on those rows
    nan_on: frozenset = frozenset({"invalid_input", "not_symmetric", "singular"})
    #: exact family only: worst relative error ≈ K·cond(I)·eps, K per precision {64: K, 32: K},
    #: set to about twice the worst K measured over 100k random rows; K = 0 means the error does
    #: not grow with cond before I is singular.
    error_k: dict | None = None
    #: exact family only: the answer is refined with a double-double residual to within one
    #: rounding of I⁻¹H (the compiled engine's ``refined``)
    refines: bool = False
    #: the compiled engine (hconv.solve.engines, hconv.solve.compiled) computes this method
    #: itself; every other method is the numpy engine's alone
    row_engine: bool = False
    #: the method reads only the diagonal I_ii of the tensor as given: its error grows with the
    #: products of inertia (``hconv compare`` lists its worst rows against them)
    ignores_products: bool = False

    def __post_init__(self) -> None:
        # the compiled engine and the refinement compute I⁻¹H: only an exact method can have them
        if (self.refines or self.row_engine) and not self.exact:
            raise ValueError(f"method {self.name!r}: refines and row_engine need exact=True")

    def cond_limit(self, precision: int) -> float:
        """The largest cond(I) at which this method's error stays within ILL_CONDITIONED_TOL."""
        k = (self.error_k or {}).get(precision)
        if not k:
            return float("inf")
        eps = float(np.finfo(np.float64 if precision == 64 else np.float32).eps)
        return ILL_CONDITIONED_TOL / (k * eps)


METHODS: Registry[Method] = Registry("method")


def register(
    name: str,
    *,
    unit: str,
    exact: bool,
    summary: str,
    cost: str,
    fails: str,
    needs_r: bool = False,
    nan_on: set | None = None,
    error_k: dict | None = None,
    refines: bool = False,
    row_engine: bool = False,
    ignores_products: bool = False,
) -> Callable[[Kernel], Kernel]:
    def deco(kernel: Kernel) -> Kernel:
        kw: dict = {
            "error_k": error_k,
            "refines": refines,
            "row_engine": row_engine,
            "ignores_products": ignores_products,
        }
        if nan_on is not None:
            kw["nan_on"] = frozenset(nan_on)
        METHODS.add(name, Method(name, kernel, unit, exact, needs_r, summary, cost, fails, **kw))
        return kernel

    return deco


def get(method: str | Method) -> Method:
    """The method called ``method`` (a Method is its own answer); UsageError (a ValueError)
    naming the choices otherwise. Entry points call this once and pass the Method down."""
    if isinstance(method, Method):
        return method
    return METHODS.get_checked(method)


@register(
    "exact",
    unit=RAD_S,
    exact=True,
    summary="ω = I⁻¹H by LDLᵀ unrolled over column arrays",
    cost="~30 flops/row; the fastest LAPACK-accurate solver",
    fails="singular I (ω = NaN); error grows as cond(I)·eps, like LAPACK's",
    error_k={64: 1.0, 32: 2.5},
    row_engine=True,
)
def _exact(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    fac = linsolve.ldlt_factor(I)
    w = linsolve.ldlt_solve(fac, H)
    # LDLᵀ without pivoting is only stable for positive definite I; the rest go to LU.
    other = ~fac.positive()
    if other.any():
        w[:, other] = linsolve.lapack_solve(I.take(other), H[:, other])
    return w, {}


@register(
    "refined",
    unit=RAD_S,
    exact=True,
    summary="ω = I⁻¹H within one rounding: exact's answer refined with a double-double residual",
    cost="exact + refinement steps of ~170 flops/row, as many as the block needs: "
    "1 to cond ~1e8, 2 to ~1e10, 3 at 1e12 (6 at most)",
    fails="singular I (ω = NaN); in float64 the error stays at rounding up to the singular "
    "threshold; in float32 the rounding of the inputs themselves limits it",
    error_k={64: 0.0, 32: 2.5},
    refines=True,
    row_engine=True,
)
def _refined(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    return linsolve.solve_refined(I, H), {}


@register(
    "lapack",
    unit=RAD_S,
    exact=True,
    summary="ω = I⁻¹H by numpy.linalg.solve on the (N,3,3) stack",
    cost="LU with pivoting per row; the reference most users write",
    fails="singular I (ω = NaN); error grows as cond(I)·eps",
    error_k={64: 1.0, 32: 1.5},
)
def _lapack(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    return linsolve.lapack_solve(I, H), {}


@register(
    "cholesky",
    unit=RAD_S,
    exact=True,
    summary="ω = I⁻¹H by Cholesky LLᵀ unrolled over column arrays",
    cost="~35 flops + 3 square roots per row",
    fails="I not positive definite or singular (ω = NaN); error grows as cond(I)·eps",
    nan_on={"invalid_input", "not_symmetric", "singular", "not_positive_definite"},
    error_k={64: 1.2, 32: 2.5},
)
def _cholesky(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        l11 = np.sqrt(I.xx)
        l21, l31 = I.xy / l11, I.xz / l11
        l22 = np.sqrt(I.yy - l21 * l21)
        l32 = (I.yz - l31 * l21) / l22
        l33 = np.sqrt(I.zz - l31 * l31 - l32 * l32)
        y1 = H[0] / l11
        y2 = (H[1] - l21 * y1) / l22
        y3 = (H[2] - l31 * y1 - l32 * y2) / l33
        x3 = y3 / l33
        x2 = (y2 - l32 * x3) / l22
        x1 = (y1 - l21 * x2 - l31 * x3) / l11
    w = np.stack([x1, x2, x3])
    return w, {"not_positive_definite": ~np.isfinite(l33) | (l33 == 0)}


@register(
    "eigen",
    unit=RAD_S,
    exact=True,
    summary="ω = R·diag(1/S)·Rᵀ·H through the principal axes (numpy.linalg.eigh)",
    cost="a 3×3 eigendecomposition per row; slowest of the exact family",
    fails="zero principal moments (rod, point mass): pseudo-inverse answer, status singular; "
    "error grows as cond(I)·eps, but is about 6 times LDLᵀ's at the same cond (worst K measured 2.8 against 0.43)",
    nan_on={"invalid_input", "not_symmetric"},
    error_k={64: 6.0, 32: 3.0},
)
def _eigen(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    S, R = principal_frame(I)
    inv, zero = pinv_moments(S, singular_rtol(S.dtype) * np.max(np.abs(S), axis=0))
    return frames.to_world(R, inv * frames.to_body(R, H)), {"singular": np.asarray(zero.any(axis=0))}


@register(
    "diagonal",
    unit=RAD_S,
    exact=False,
    summary="ω_i = H_i / I_ii: the shortcut that ignores the products of inertia",
    cost="3 divisions per row",
    fails="exact only when I is diagonal in the given axes; I_ii = 0 gives NaN",
    nan_on={"invalid_input", "not_symmetric"},
    ignores_products=True,
)
def _diagonal(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    with np.errstate(divide="ignore", invalid="ignore"):
        w = H / np.stack([I.xx, I.yy, I.zz])
    return w, {}


def _offset(r: np.ndarray | None) -> np.ndarray:
    """The offset r of a method registered with needs_r (convert refuses to call it without)."""
    if r is None:
        raise ValueError("the document methods need the offset r")
    return r


def _seed_formula(moments: np.ndarray, H: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The seed's per-axis formula ω_i = (r_j² + r_k²) / I_i · H_i, all ``(3, N)``; result in m²/s.

    The seed writes the factor as |r - (r·x̂)x̂|² = |r|² - r_i²; the sum of the other two squares is
    the same number without the cancellation.
    """
    sq = r * r
    perp = np.stack([sq[1] + sq[2], sq[0] + sq[2], sq[0] + sq[1]])
    with np.errstate(divide="ignore", invalid="ignore"):
        w = perp / moments * H
    on_axis = np.any(perp <= R_AXIS_RTOL * (sq[0] + sq[1] + sq[2]), axis=0)
    return w, on_axis


@register(
    "document",
    unit=M2_S,
    exact=False,
    needs_r=True,
    summary="the seed's Version 1: ω_i = (|r|² - r_i²) / I_ii · H_i in the given axes",
    cost="~12 flops per row",
    fails="not I⁻¹H and not in rad/s; r on an axis forces a component to 0 (status r_on_axis)",
    nan_on={"invalid_input", "not_symmetric"},
    ignores_products=True,
)
def _document(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    w, on_axis = _seed_formula(np.stack([I.xx, I.yy, I.zz]), H, _offset(r))
    return w, {"r_on_axis": on_axis}


@register(
    "document-principal",
    unit=M2_S,
    exact=False,
    needs_r=True,
    summary="the seed's Version 2: Version 1 in I's principal frame, then rotated back",
    cost="a 3×3 eigendecomposition per row",
    fails="not I⁻¹H and not in rad/s; repeated moments make the answer depend on an arbitrary "
    "choice of axes (status frame_ambiguous); r on a principal axis (status r_on_axis)",
    nan_on={"invalid_input", "not_symmetric"},
)
def _document_principal(I: Sym3, H: np.ndarray, r: np.ndarray | None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    S, R = principal_frame(I)
    w_p, on_axis = _seed_formula(S, frames.to_body(R, H), frames.to_body(R, _offset(r)))
    gap = np.minimum(S[1] - S[0], S[2] - S[1])
    repeated = gap <= REPEATED_RTOL * np.max(np.abs(S), axis=0)
    return frames.to_world(R, w_p), {"frame_ambiguous": repeated, "r_on_axis": on_axis}


def listing() -> list[dict]:
    """Every method as ``hconv methods --json`` prints it. A cond limit is None (JSON's null,
    which has no Infinity) where it is "up to the singular threshold"."""

    def limit(m: Method, p: int) -> float | None:
        return m.cond_limit(p) if m.exact and math.isfinite(m.cond_limit(p)) else None

    return [
        {
            "name": m.name,
            "unit": m.unit,
            "exact": m.exact,
            "needs_r": m.needs_r,
            "cond_limit_float64": limit(m, 64),
            "cond_limit_float32": limit(m, 32),
            "summary": m.summary,
            "cost": m.cost,
            "fails": m.fails,
        }
        for m in METHODS.values()
    ]
