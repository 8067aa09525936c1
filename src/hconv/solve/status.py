"""Per-row statuses: why a row's answer cannot be trusted, and the tolerances that decide it.

A status describes the input and the numerics, never a method's approximation error (that is
what the ``residual`` column measures). Where several apply, the earliest in :data:`STATUSES`
wins. Codes are small integers so that a status column costs one byte per row.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import DTypeLike

#: Status names in order of precedence; the code of a status is its index.
STATUSES: tuple[str, ...] = (
    "ok",
    "invalid_input",  # NaN or Inf in a value used, a value beyond float32 in --precision 32, or mass <= 0 with I != 0
    "not_symmetric",  # a 3×3 tensor whose Iij and Iji differ by more than SYMMETRY_RTOL·max|I|
    "singular",  # smallest |moment| <= SINGULAR_RTOL_EPS·eps·largest |moment|
    "overflow",  # finite input, but ω is beyond the working precision's range
    "not_positive_definite",  # a negative principal moment (beyond the degenerate threshold)
    "degenerate",  # --degenerate pinv|lock: a (near-)zero principal moment was dropped or locked
    "not_physical",  # principal moments break the triangle inequality I1 <= I2 + I3
    "unit_suspect",  # with a mass column: no solid of that mass has that inertia (a unit slip?)
    "ill_conditioned",  # exact family: cond(I) so large that the error could exceed ILL_CONDITIONED_TOL
    "inaccurate",  # exact family: the measured residual exceeds ILL_CONDITIONED_TOL anyway (subnormals on the way)
    # --about free: H_P - r × m·v cancels so many digits that cond(I)·ε_C plus the solve's own
    # K·cond(I)·eps could exceed ILL_CONDITIONED_TOL (ε_C: hconv.kernels.frames.momentum_about_com).
    # After the codes the row engine sets (rows.py): numba's cache keys on rows.py alone, and
    # compiled code holds those codes as constants, so they must not move.
    "cancellation",
    "frame_ambiguous",  # document-principal on repeated principal moments
    "r_on_axis",  # document methods: r (nearly) on an axis, so a component is forced to zero
)
CODE = {name: code for code, name in enumerate(STATUSES)}

SYMMETRY_RTOL = 1e-12
#: A tensor is singular when cond(I) >= 1 / (SINGULAR_RTOL_EPS · eps) of the working precision:
#: about 1.1e15 in float64 and 2.1e6 in float32. Beyond that no digit of I⁻¹H is reliable.
SINGULAR_RTOL_EPS = 4.0
#: A row is ill_conditioned when its method's error bound K·cond(I)·eps could exceed this, and
#: cancellation when that bound plus a free body's cond(I)·ε_C could.
ILL_CONDITIONED_TOL = 1e-6
#: Principal moments closer than this fraction of the largest count as repeated.
REPEATED_RTOL = 1e-9
#: The triangle inequality may be broken by this fraction of the trace before a row is flagged,
#: so that exact boundary bodies (thin plates, rods) are not flagged for rounding.
TRIANGLE_RTOL = 1e-9
#: r lies on axis i when r_j² + r_k² <= R_AXIS_RTOL · |r|² (or r = 0).
R_AXIS_RTOL = 1e-9


def singular_rtol(dtype: DTypeLike) -> float:
    """The ratio |moment|min / |moment|max at or below which I counts as singular in ``dtype``."""
    return SINGULAR_RTOL_EPS * float(np.finfo(dtype).eps)


#: unit_suspect: the density of the uniform cube with the body's mass and radius of gyration
#: must lie in this band [kg/m³]. Real bodies, from a kite to a tungsten ball, lie within
#: 1e-2…3e4; a kg·m² ↔ g·cm² slip moves the figure by about 3e10, a kg ↔ g mass slip by 3e7.
UNIT_DENSITY_BAND = (1e-4, 1e6)


def merge(code: np.ndarray, mask: np.ndarray, name: str) -> np.ndarray:
    """``code`` with status ``name`` set on ``mask`` rows, unless they hold a status that takes
    precedence over it; a new array."""
    c = CODE[name]
    return np.where(mask & ((code == 0) | (code > c)), np.uint8(c), code).astype(np.uint8)


def combine(n: int, flags: dict[str, np.ndarray]) -> np.ndarray:
    """Status codes of shape ``(N,)`` (uint8) from boolean masks keyed by status name."""
    code = np.zeros(n, dtype=np.uint8)
    for name in reversed(STATUSES[1:]):  # lowest precedence first, so the highest is written last
        mask = flags.get(name)
        if mask is not None:
            code[mask] = CODE[name]
    return code


def names(codes: np.ndarray) -> np.ndarray:
    """Status names for an array of codes, same shape, dtype str."""
    return np.asarray(STATUSES)[codes]


def counts(codes: np.ndarray) -> dict[str, int]:
    """How many rows carry each status, for the statuses that occur, in precedence order."""
    c = np.bincount(np.asarray(codes, dtype=np.int64).ravel(), minlength=len(STATUSES))
    return {STATUSES[k]: int(c[k]) for k in range(len(STATUSES)) if c[k]}
