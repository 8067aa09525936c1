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

Vectors are component-major, shape ``(3, N)``; a rotation is a ``(3, 3, N)`` array, so that every
entry is one contiguous column.
"""

from __future__ import annotations

import numpy as np

from hconv.kernels.inertia import Sym3


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


def momentum_about_com(H_P: np.ndarray, m: np.ndarray, r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A free body's angular momentum about its centre of mass, ``H_C = H_P - r × (m·v)``.

    ``H_P``: ``(3, N)`` about the origin P [kg·m²/s]; ``m`` ``(N,)`` [kg]; ``r`` ``(3, N)`` =
    p_C - p_P [m]; ``v`` ``(3, N)``, the velocity of C [m/s]; all in one frame.
    """
    return H_P - cross(r, m * v)
