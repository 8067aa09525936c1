"""``convert``: H and I (and r) to ω with a chosen method, plus per-row diagnostics.

Shapes: ``H`` is ``(N, 3)`` [kg·m²/s]; ``I`` is ``(N, 6)`` as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz),
``(N, 3, 3)`` or ``(N, 3)`` principal/diagonal moments [kg·m²]; ``r`` is ``(N, 3)`` [m]. One body
may be given as ``H`` of shape ``(3,)`` with ``I`` of shape ``(6,)``, ``(3, 3)`` or ``(3,)``; its
result comes back unstacked. Conventions are those of :mod:`hconv.inertia`.

Diagnostics per row:

* ``residual`` = ‖ω - I⁻¹H‖ / ‖I⁻¹H‖, against a reference computed from the float64 inputs: LDLᵀ
  refined with a residual in double the precision, correctly rounded to cond ≈ 1e13 (tested
  against mpmath and exact rational solves). For the ``refined`` method, whose own answer comes
  from that algorithm, the reference runs all refinement steps instead of stopping adaptively.
  For the document methods it compares their number (in m²/s) with I⁻¹H (in rad/s).
* ``cond``: the 2-norm condition number of I, |moment|max / |moment|min.
* ``status``: see :mod:`hconv.status`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from hconv import linsolve, methods, status
from hconv.inertia import Sym3, max_abs, sym_from_array
from hconv.spectrum import eigenvalues

#: Rows per kernel block: small enough that a block's temporaries stay in cache.
BLOCK_ROWS = 16384
DTYPES = {64: np.float64, 32: np.float32}


@dataclass(frozen=True)
class Result:
    """ω and its diagnostics. Arrays are stacked ``(N, ...)`` or, for one body, unstacked."""

    w: np.ndarray  #: (N, 3) or (3,), in ``unit``
    residual: Optional[np.ndarray]  #: (N,) or scalar; None when diagnostics were off
    cond: np.ndarray  #: (N,) or scalar
    status_code: np.ndarray  #: (N,) uint8, or scalar; names in hconv.status.STATUSES
    unit: str  #: unit of w: "rad/s" or "m^2/s"
    method: str

    @property
    def status(self):
        """Status names, shape ``(N,)``, or one name for one body."""
        s = status.names(np.asarray(self.status_code))
        return str(s) if s.ndim == 0 else s

    def counts(self) -> dict[str, int]:
        """Rows per status, in precedence order."""
        return status.counts(np.atleast_1d(self.status_code))


def _as_float(name: str, a) -> np.ndarray:
    try:
        return np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric: {exc}") from None


def convert(H, I, r=None, *, method: str = "exact", precision: int = 64,
            diagnostics: bool = True) -> Result:
    """Convert angular momentum to angular velocity with ``method``; see the module docstring.

    ``precision`` (64 or 32) sets the dtype the method computes in; diagnostics are always
    computed in float64 from the inputs as given. ``diagnostics=False`` skips the residual
    (the costliest diagnostic); cond and status are always computed.
    """
    m = methods.get(method)
    if precision not in DTYPES:
        raise ValueError(f"precision must be 64 or 32, got {precision!r}")
    H = _as_float("H", H)
    I = _as_float("I", I)
    single = H.ndim == 1
    if single:
        H, I = H[None], I[None]
        r = None if r is None else _as_float("r", r)[None]
    if H.ndim != 2 or H.shape[1] != 3:
        raise ValueError(f"Expected H to have shape (3,) or (N, 3), got {H.shape}")
    n = H.shape[0]
    if I.shape[0] != n:
        raise ValueError(f"I holds {I.shape[0]} tensors but H holds {n} vectors")
    if r is not None:
        r = _as_float("r", r)
        if r.shape != (n, 3):
            raise ValueError(f"Expected r to have shape {(3,) if single else (n, 3)}, got {r.shape[1:] if single else r.shape}")
    elif m.needs_r:
        raise ValueError(f"method {method!r} needs the offset r [m]; pass r=...")
    Isym, asym = sym_from_array(I)

    dtype = DTYPES[precision]
    w = np.empty((n, 3), dtype=dtype)
    cond = np.empty(n)
    code = np.empty(n, dtype=np.uint8)
    residual = np.empty(n) if diagnostics else None
    for lo in range(0, n, BLOCK_ROWS):
        sl = slice(lo, min(n, lo + BLOCK_ROWS))
        _convert_block(
            m, dtype, Isym.take(sl), asym[sl], H[sl], None if r is None else r[sl],
            w[sl], cond[sl], code[sl], None if residual is None else residual[sl],
        )
    if single:
        return Result(w[0], None if residual is None else residual[0], cond[0], code[0], m.unit, m.name)
    return Result(w, residual, cond, code, m.unit, m.name)


def _convert_block(m, dtype, I: Sym3, asym, H, r, w_out, cond_out, code_out, res_out) -> None:
    """One block of rows; writes into the ``*_out`` views."""
    n = H.shape[0]
    H = np.ascontiguousarray(H.T)  # (3, n): the kernels' component-major layout
    r_used = np.ascontiguousarray(r.T) if m.needs_r else None
    columns = [*I, *H] + ([] if r_used is None else list(r_used))
    limit = np.finfo(dtype).max  # a finite float64 beyond float32's range is no usable input there
    with np.errstate(invalid="ignore"):
        invalid = ~(max_abs(columns) <= limit)  # NaN compares false, so NaN rows are invalid too
    if invalid.any():
        # Stand-ins keep the kernels quiet; these rows' outputs are replaced below.
        keep = ~invalid
        I = Sym3(*(np.where(keep, c, d) for c, d in zip(I, (1.0, 1.0, 1.0, 0.0, 0.0, 0.0))))
        H = np.where(keep, H, 0.0)
        if r_used is not None:
            r_used = np.where(keep, r_used, 1.0)

    lam = eigenvalues(I)  # (3, n), ascending
    big = np.maximum(np.abs(lam[0]), np.abs(lam[2]))
    small = np.minimum(np.minimum(np.abs(lam[0]), np.abs(lam[1])), np.abs(lam[2]))
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(small > 0, big / np.where(small > 0, small, 1.0), np.inf)
    flags = {
        "invalid_input": invalid,
        "not_symmetric": asym & ~invalid,
        "singular": small <= status.singular_rtol(dtype) * big,
        "not_positive_definite": lam[0] < 0,
        "not_physical": lam[2] - lam[1] - lam[0] > status.TRIANGLE_RTOL * (np.abs(lam[0]) + np.abs(lam[1]) + np.abs(lam[2])),
        "ill_conditioned": cond > m.cond_limit(8 * np.dtype(dtype).itemsize),
    }

    w, own = m.kernel(I.astype(dtype), H.astype(dtype), None if r_used is None else r_used.astype(dtype))
    for name, mask in own.items():
        flags[name] = flags[name] | mask if name in flags else mask
    no_answer = np.zeros(n, dtype=bool)
    for s in m.nan_on:
        if s in flags:
            no_answer |= flags[s]
    # A finite row that still gives a non-finite ω must never pass as ok.
    lost = ~(np.isfinite(w[0]) & np.isfinite(w[1]) & np.isfinite(w[2])) & ~no_answer
    flags["overflow"] = lost & ~invalid
    w[:, no_answer | lost] = np.nan

    w_out[:] = w.T
    cond[invalid] = np.nan
    cond_out[:] = cond
    code_out[:] = status.combine(n, flags)
    if res_out is not None:
        res_out[:] = np.nan
        ok = ~(invalid | flags["not_symmetric"] | flags["singular"])
        if ok.any():
            # For `refined` itself the same algorithm stopping adaptively would compare it with
            # itself; the reference then runs every step, so the residual shows an early stop.
            steps = linsolve.MAX_REFINE_STEPS if m.name == "refined" else None
            ref = linsolve.solve_refined(I.take(ok), H[:, ok], steps=steps)
            d = w[:, ok].astype(np.float64) - ref
            num = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            den = np.sqrt(ref[0] * ref[0] + ref[1] * ref[1] + ref[2] * ref[2])
            with np.errstate(divide="ignore", invalid="ignore"):
                # H = 0 gives I⁻¹H = 0: an answer of 0 is exact, anything else infinitely off.
                res_out[ok] = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.where(num == 0, 0.0, np.inf))
