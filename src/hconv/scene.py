"""Analytic rigid bodies and random scenes of them, with the ω that produced their H.

Principal moments are textbook formulas about the centre of mass [kg·m²], for mass m [kg] and
sizes [m]. A scene row holds a body turned by a random rotation R: I = R·diag(moments)·Rᵀ (tensor
entries, products negative-∫ convention of :mod:`hconv.inertia`), a random ω [rad/s], H = I·ω
[kg·m²/s] and a random offset r [m]. The known ω differs from the exact I⁻¹H of the stored,
rounded H by about cond(I)·eps.
"""
from __future__ import annotations

import numpy as np

KINDS = ("box", "cylinder", "rod", "sphere")


def box_moments(m, a, b, c) -> np.ndarray:
    """Solid box with edges a, b, c along x, y, z; shape ``(..., 3)``."""
    m, a, b, c = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, a, b, c)))
    return np.stack([m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)], axis=-1) / 12.0


def cylinder_moments(m, radius, length) -> np.ndarray:
    """Solid cylinder with its axis along z; shape ``(..., 3)``."""
    m, R, L = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, radius, length)))
    side = m * (3.0 * R * R + L * L) / 12.0
    return np.stack([side, side, 0.5 * m * R * R], axis=-1)


def sphere_moments(m, radius) -> np.ndarray:
    """Solid sphere; shape ``(..., 3)``."""
    m, R = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, radius)))
    i = 0.4 * m * R * R
    return np.stack([i, i, i], axis=-1)


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random rotation matrices, shape ``(n, 3, 3)`` (from unit quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def rotate_tensors(R: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """``R·diag(moments)·Rᵀ`` for ``(n, 3, 3)`` and ``(n, 3)``; symmetric ``(n, 3, 3)``."""
    I = np.einsum("nij,nj,nkj->nik", R, moments, R)
    return 0.5 * (I + np.swapaxes(I, 1, 2))  # exactly symmetric despite rounding


def make_scene(n: int, seed: int = 0, kinds=KINDS) -> dict[str, np.ndarray]:
    """A scene of ``n`` bodies as named columns (the input contract plus ``id``, ``body``, ``mass``
    and the known ``w_true_x, w_true_y, w_true_z``)."""
    rng = np.random.default_rng(seed)
    kind = rng.choice(np.asarray(kinds), size=n)
    m = rng.uniform(0.1, 20.0, n)
    size = rng.uniform(0.05, 2.0, (n, 3))
    moments = np.empty((n, 3))
    for k, fn in (
        ("box", lambda s, mm: box_moments(mm, s[:, 0], s[:, 1], s[:, 2])),
        ("cylinder", lambda s, mm: cylinder_moments(mm, 0.5 * s[:, 0], s[:, 1])),
        # a rod: a slender cylinder, radius 1% of its length (a finite, physical rod)
        ("rod", lambda s, mm: cylinder_moments(mm, 0.01 * s[:, 1], s[:, 1])),
        ("sphere", lambda s, mm: sphere_moments(mm, 0.5 * s[:, 0])),
    ):
        sel = kind == k
        if sel.any():
            moments[sel] = fn(size[sel], m[sel])
    R = random_rotations(rng, n)
    I = rotate_tensors(R, moments)
    w = rng.normal(0.0, 2.0, (n, 3))
    H = np.einsum("nij,nj->ni", I, w)
    r = rng.uniform(-1.0, 1.0, (n, 3))
    cols = {"id": np.arange(1, n + 1), "body": kind.astype(str), "mass": m}
    cols.update({f"H{a}": H[:, k] for k, a in enumerate("xyz")})
    for name, (i, j) in zip(("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"), ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
        cols[name] = I[:, i, j]
    cols.update({f"r{a}": r[:, k] for k, a in enumerate("xyz")})
    cols.update({f"w_true_{a}": w[:, k] for k, a in enumerate("xyz")})
    return cols
