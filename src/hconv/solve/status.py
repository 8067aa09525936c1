"""Per-row statuses: why a row's answer cannot be trusted, and the tolerances that decide it.

A status describes the input and the numerics, never a method's approximation error (that is
what the ``residual`` column measures). Each status has two separate things, each stated once
here: its code (:data:`CODE`), the small integer that every output holds for it (one byte per
row), and its place in :data:`PRECEDENCE`, which decides the status of a row where several
apply. A new status takes the next free code and its place in the order; no code ever moves.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import DTypeLike

#: Every status and its code, pinned: a code is what Result.status_code, the compiled engine
#: (hconv.solve.compiled hands it the codes it sets) and users' stored outputs hold, so it is
#: never renumbered. docs/input.md lists the same numbers.
CODE: dict[str, int] = {
    "ok": 0,
    # NaN or Inf in a value used, a value beyond float32 in --precision 32, or mass <= 0 with I != 0
    "invalid_input": 1,
    "not_symmetric": 2,  # a 3×3 tensor whose Iij and Iji differ by more than SYMMETRY_RTOL·max|I|
    "singular": 3,  # smallest |moment| <= SINGULAR_RTOL_EPS·eps·largest |moment|
    "overflow": 4,  # finite input, but ω is beyond the working precision's range
    "not_positive_definite": 5,  # a negative principal moment (beyond the degenerate threshold)
    "degenerate": 6,  # --degenerate pinv|lock: a (near-)zero principal moment was dropped or locked
    "not_physical": 7,  # principal moments break the triangle inequality I1 <= I2 + I3
    "unit_suspect": 8,  # with a mass column: no solid of that mass has that inertia (a unit slip?)
    "ill_conditioned": 9,  # exact family: cond(I) so large that the error could exceed ILL_CONDITIONED_TOL
    "inaccurate": 10,  # exact family: the measured residual exceeds ILL_CONDITIONED_TOL anyway (subnormals on the way)
    # --about free: H_P - r × m·v cancels so many digits that cond(I)·ε_C plus the solve's own
    # K·cond(I)·eps could exceed ILL_CONDITIONED_TOL (ε_C: hconv.kernels.frames.momentum_about_com).
    "cancellation": 11,
    "frame_ambiguous": 12,  # document-principal on repeated principal moments
    "r_on_axis": 13,  # document methods: r (nearly) on an axis, so a component is forced to zero
}
#: Status names by code: ``STATUSES[code]`` is the name (codes run 0, 1, 2, ... without a gap,
#: so that a code indexes this tuple, and Arrow's dictionary of the status column is this tuple).
STATUSES: tuple[str, ...] = tuple(sorted(CODE, key=CODE.__getitem__))
#: Where several statuses apply to a row, the earliest here wins; ``ok`` is what no other holds.
#: The compiled engine sets ok, singular, not_physical, ill_conditioned and inaccurate, and relies
#: on inaccurate coming after the other three (tests/test_compiled.py checks).
PRECEDENCE: tuple[str, ...] = (
    "invalid_input",
    "not_symmetric",
    "singular",
    "overflow",
    "not_positive_definite",
    "degenerate",
    "not_physical",
    "unit_suspect",
    "ill_conditioned",
    "inaccurate",
    "cancellation",
    "frame_ambiguous",
    "r_on_axis",
)

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
#: With precision 32 the numbers are float32's: a tensor computed in float32 is symmetric, and a
#: body on the triangle inequality's boundary lies on it, only to float32's roundings (a float32
#: R·D·Rᵀ differs from its transpose by a few eps). So both tolerances are at least this many
#: eps of the working precision (symmetry_rtol, triangle_rtol): 7.6e-6 in float32, and below
#: both in float64, where they stand as stated.
ROUNDING_RTOL_EPS = 64.0


def symmetry_rtol(dtype: DTypeLike) -> float:
    """|Iij − Iji| / max|I| above which nine numbers in ``dtype`` are ``not_symmetric``."""
    return max(SYMMETRY_RTOL, ROUNDING_RTOL_EPS * float(np.finfo(dtype).eps))


def triangle_rtol(dtype: DTypeLike) -> float:
    """The fraction of the trace by which moments in ``dtype`` may break the triangle
    inequality before a row is ``not_physical``."""
    return max(TRIANGLE_RTOL, ROUNDING_RTOL_EPS * float(np.finfo(dtype).eps))


def singular_rtol(dtype: DTypeLike) -> float:
    """The ratio |moment|min / |moment|max at or below which I counts as singular in ``dtype``."""
    return SINGULAR_RTOL_EPS * float(np.finfo(dtype).eps)


#: unit_suspect: the density of the uniform cube with the body's mass and radius of gyration
#: must lie in this band [kg/m³]. Real bodies, from a kite to a tungsten ball, lie within
#: 1e-2…3e4; a kg·m² ↔ g·cm² slip moves the figure by about 3e10, a kg ↔ g mass slip by 3e7.
UNIT_DENSITY_BAND = (1e-4, 1e6)


@functools.cache
def _ranks(order: tuple[str, ...]) -> np.ndarray:
    """Each code's place in ``order`` (lower wins), indexed by code; ok after every other status."""
    return np.array([order.index(name) if name != "ok" else len(order) for name in STATUSES], dtype=np.uint8)


def merge(code: np.ndarray, mask: np.ndarray, name: str) -> np.ndarray:
    """``code`` with status ``name`` set on ``mask`` rows, unless they hold a status that takes
    precedence over it; a new array."""
    c, rank = CODE[name], _ranks(PRECEDENCE)
    return np.where(mask & (rank[code] > rank[c]), np.uint8(c), code).astype(np.uint8)


def combine(n: int, flags: dict[str, np.ndarray]) -> np.ndarray:
    """Status codes of shape ``(N,)`` (uint8) from boolean masks keyed by status name."""
    code = np.full(n, CODE["ok"], dtype=np.uint8)
    for name in reversed(PRECEDENCE):  # lowest precedence first, so the highest is written last
        mask = flags.get(name)
        if mask is not None:
            code[mask] = CODE[name]
    return code


def names(codes: np.ndarray) -> np.ndarray:
    """Status names for an array of codes, same shape, dtype str."""
    return np.asarray(STATUSES)[codes]


def counts(codes: np.ndarray) -> dict[str, int]:
    """How many rows carry each status, for the statuses that occur: ok, then in precedence order."""
    c = np.bincount(np.asarray(codes, dtype=np.int64).ravel(), minlength=len(STATUSES))
    return {name: int(c[CODE[name]]) for name in ("ok", *PRECEDENCE) if c[CODE[name]]}
