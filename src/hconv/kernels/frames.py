"""Orientation, frames and points: quaternions, re-expressing vectors, shifting the reference point.

Conventions (stated once, here):

* A quaternion ``q = (w, x, y, z)`` rotates body-frame vectors into the world frame,
  ``v_W = R(q)·v_B``, as in Jolt and MuJoCo. hconv normalises q; a q of zero length or with a
  NaN/Inf gives no rotation and the row is flagged ``invalid_input`` by the caller.
* ``r`` is the position of the centre of mass C relative to the point P that H is taken about:
  ``r = p_C - p_P`` [m].
* Parallel-axis shift from C to P: ``I_P = I_C + m·(|r|²·E - r·rᵀ)`` [kg·m²], in tensor entries
  (so the products gain ``-m·r_i·r_j``).
* A free body's momentum about P: ``H_P = H_C + r × (m·v_C)``, so ``H_C = H_P - r × (m·v_C)``.

What the point change costs. Far from P (a satellite 7,000 km out at 7.5 km/s), |H_P| and
|r|·m·|v| can exceed |H_C| by 1e13, and the subtraction cancels that many of H_P's digits.
:func:`momentum_about_com` does it with error-free products and sums, so the computation adds one
rounding of H_C and no more; but no arithmetic recovers what the inputs lost when they were
rounded to float64 (each to within u = eps/2 of its value). With i, j, k cyclic, component i is
known to within

    δ_i = eps·(½·|H_P,i| + 3/2·(|r_j|·m·|v_k| + |r_k|·m·|v_j|) + ½·|H_C,i|)

(H_P's rounding; r's, m's and v's, u each in every product; the final rounding of H_C), to
first order in eps, and the function returns ‖δ‖₂ / ‖H_C‖₂. Through ω = I⁻¹·H_C that is a
relative error of at most cond(I)·‖δ‖/‖H_C‖ in ω, which :mod:`hconv.solve.bodies` flags
(``cancellation``). It holds while the products stay out of the subnormal range (below 1e-290,
the error terms round); beyond 1e300 the splits overflow, the plain subtraction is kept and its
own three roundings per product count (3 instead of 3/2).
The parallel-axis shift adds no cancellation: I_C and m·(|r|²E − r·rᵀ) are both positive
semi-definite, so its rounding is a few eps of ‖I_P‖ (bodies' ``PIVOT_K``).

Vectors are component-major, shape ``(3, N)``; a rotation is a ``(3, 3, N)`` array, so that every
entry is one contiguous column.
"""

from __future__ import annotations

import numpy as np

from hconv.kernels.eft import split, two_diff, two_prod_split
from hconv.kernels.inertia import Sym3, max_abs, sum_sq


def quaternion_matrix(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations ``R`` of shape ``(3, 3, N)`` from quaternions ``(4, N)`` in (w, x, y, z) order.

    Returns ``R`` and a mask ``(N,)`` of rows whose q has no direction (zero length, NaN or Inf);
    those rows get the identity, so that later arithmetic stays quiet.
    """
    w, x, y, z = (np.asarray(c, dtype=np.float64) for c in q)
    with np.errstate(over="ignore", invalid="ignore"):
        # Scale by the largest component first, so that the squares neither overflow nor underflow.
        big = np.maximum(np.maximum(np.abs(w), np.abs(x)), np.maximum(np.abs(y), np.abs(z)))
        bad = ~(np.isfinite(big) & (big > 0))
        s = np.where(bad, 1.0, big)
        w, x, y, z = (np.where(bad, d, c / s) for c, d in zip((w, x, y, z), (1.0, 0.0, 0.0, 0.0)))
        k = 2.0 / (w * w + x * x + y * y + z * z)
    R = np.empty((3, 3) + w.shape)
    R[0, 0] = 1 - k * (y * y + z * z)
    R[0, 1] = k * (x * y - w * z)
    R[0, 2] = k * (x * z + w * y)
    R[1, 0] = k * (x * y + w * z)
    R[1, 1] = 1 - k * (x * x + z * z)
    R[1, 2] = k * (y * z - w * x)
    R[2, 0] = k * (x * z - w * y)
    R[2, 1] = k * (y * z + w * x)
    R[2, 2] = 1 - k * (x * x + y * y)
    return R, bad


def to_world(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R·v``: body-frame vectors ``(3, N)`` re-expressed in the world frame."""
    return np.stack([R[i, 0] * v[0] + R[i, 1] * v[1] + R[i, 2] * v[2] for i in range(3)])


def to_body(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Rᵀ·v``: world-frame vectors ``(3, N)`` re-expressed in the body frame."""
    return np.stack([R[0, i] * v[0] + R[1, i] * v[1] + R[2, i] * v[2] for i in range(3)])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for ``(3, N)`` vectors."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def shift_to_pivot(I_C: Sym3, m: np.ndarray, r: np.ndarray) -> Sym3:
    """The parallel-axis shift: inertia about the pivot P from inertia about the centre of mass.

    ``I_C``: N tensors about C [kg·m²]; ``m``: ``(N,)`` [kg]; ``r``: ``(3, N)`` = p_C - p_P [m], in
    the tensor's frame. Returns ``I_P = I_C + m·(|r|²·E - r·rᵀ)``.
    """
    mx, my, mz = m * r[0], m * r[1], m * r[2]
    return Sym3(
        I_C.xx + (my * r[1] + mz * r[2]),
        I_C.yy + (mx * r[0] + mz * r[2]),
        I_C.zz + (mx * r[0] + my * r[1]),
        I_C.xy - mx * r[1],
        I_C.xz - mx * r[2],
        I_C.yz - my * r[2],
    )


#: Rows per block of the compensated subtraction: its ~200 operations per row then stay in cache
#: (2M rows: 0.25 s, against 0.58 s on whole columns; docs/measurements.md).
MOMENTUM_BLOCK_ROWS = 16384


def momentum_about_com(H_P: np.ndarray, m: np.ndarray, r: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A free body's angular momentum about its centre of mass, ``H_C = H_P - r × (m·v)``, and
    how well the inputs determine it: ``ε_C = ‖δ‖₂ / ‖H_C‖₂`` ``(N,)`` (the module docstring's
    bound; 0 where nothing can be lost, inf where H_C cancelled to zero).

    ``H_P``: ``(3, N)`` about the origin P [kg·m²/s]; ``m`` ``(N,)`` [kg]; ``r`` ``(3, N)`` =
    p_C - p_P [m]; ``v`` ``(3, N)``, the velocity of C [m/s]; all in one frame.
    """
    n = H_P.shape[1]
    H_C, eps_C = np.empty_like(H_P), np.empty(n, dtype=H_P.dtype)
    for lo in range(0, n, MOMENTUM_BLOCK_ROWS):
        b = slice(lo, lo + MOMENTUM_BLOCK_ROWS)
        H_C[:, b], eps_C[b] = _momentum_block(H_P[:, b], m[b], r[:, b], v[:, b])
    return H_C, eps_C


def _momentum_block(H_P: np.ndarray, m: np.ndarray, r: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`momentum_about_com` on one block of rows."""
    # Compensated: m·v and r_j·(m·v)_k as exact sums of two floats (Dekker), the cross product's
    # and H_P's differences by TwoSum; the error terms are added once at the end, so that
    # cancelling 13 digits does not also cancel the arithmetic's own roundings into H_C.
    mh, ml = split(m)
    p, e = [], []  # m·v = p + e exactly
    for k in range(3):
        pk, ek = two_prod_split(m, mh, ml, v[k], *split(v[k]))
        p.append(pk)
        e.append(ek)
    r_split = [split(r[k]) for k in range(3)]
    p_split = [split(pk) for pk in p]
    H_C = np.empty_like(H_P)
    plain = np.zeros(H_P.shape[1], dtype=bool)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        s1, t1 = two_prod_split(r[j], *r_split[j], p[k], *p_split[k])
        s2, t2 = two_prod_split(r[k], *r_split[k], p[j], *p_split[j])
        d, f = two_diff(s1, s2)  # d: the plain cross product's component
        lo = f + (t1 - t2) + (r[j] * e[k] - r[k] * e[j])
        g, h = two_diff(H_P[i], d)  # g: the plain subtraction
        fine = np.isfinite(lo) & np.isfinite(h)  # a split beyond 1e300 overflows: keep the plain result
        H_C[i] = np.where(fine, g + (h - lo), g)
        plain |= ~fine
    # δ per component; where the plain result was kept, its three roundings per product count too.
    c = np.where(plain, 3.0, 1.5)
    mv, ar = np.abs(m) * np.abs(v), np.abs(r)
    delta = np.stack(
        [
            0.5 * np.abs(H_P[i])
            + c * (ar[(i + 1) % 3] * mv[(i + 2) % 3] + ar[(i + 2) % 3] * mv[(i + 1) % 3])
            + 0.5 * np.abs(H_C[i])
            for i in range(3)
        ]
    )
    return H_C, float(np.finfo(H_P.dtype).eps) * _norm_ratio(delta, H_C)


def _norm_ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """‖a‖₂ / ‖b‖₂ per row of ``(3, N)`` vectors, each norm taken in units of its largest part
    (safe at any scale); 0 where a = 0, inf where only b = 0."""
    ua, ub = max_abs(a), max_abs(b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        na = np.sqrt(sum_sq(a / np.where(ua > 0, ua, 1.0)))
        nb = np.sqrt(sum_sq(b / np.where(ub > 0, ub, 1.0)))
        ratio = (ua / ub) * (na / nb)
    return np.where(ua == 0, 0.0, ratio)
