"""Analytic rigid bodies and random scenes of them, with the ω that produced their H.

Principal moments are textbook formulas about the centre of mass [kg·m²], for mass m [kg] and
sizes [m]. A scene row holds a body turned by a random rotation R: I = R·diag(moments)·Rᵀ (tensor
entries, products negative-∫ convention of :mod:`hconv.kernels.inertia`), a random ω [rad/s], H = I·ω
[kg·m²/s] and a random offset r [m]. The known ω differs from the exact I⁻¹H of the stored,
rounded H by about cond(I)·eps.

Each body's shape is drawn so that its condition number cond(I) = I_max / I_min is log-uniform
between 1 and ``cond_max`` (as far as the kind allows: a sphere is always 1, a disk at most 2,
a rod at least 100).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike

from hconv.errors import UsageError, option
from hconv.kernels.frames import quaternion_matrix
from hconv.solve.options import check_choice

KINDS = ("box", "cylinder", "rod", "sphere", "ellipsoid")
SCENES = ("mix",) + KINDS


def box_moments(m: ArrayLike, a: ArrayLike, b: ArrayLike, c: ArrayLike) -> np.ndarray:
    """Solid box with edges a, b, c along x, y, z; shape ``(..., 3)``."""
    m, a, b, c = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, a, b, c)))
    return np.stack([m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)], axis=-1) / 12.0


def cylinder_moments(m: ArrayLike, radius: ArrayLike, length: ArrayLike) -> np.ndarray:
    """Solid cylinder with its axis along z; shape ``(..., 3)``."""
    m, R, L = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, radius, length)))
    side = m * (3.0 * R * R + L * L) / 12.0
    return np.stack([side, side, 0.5 * m * R * R], axis=-1)


def sphere_moments(m: ArrayLike, radius: ArrayLike) -> np.ndarray:
    """Solid sphere; shape ``(..., 3)``."""
    m, R = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, radius)))
    i = 0.4 * m * R * R
    return np.stack([i, i, i], axis=-1)


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random rotation matrices, shape ``(n, 3, 3)``: isotropic normal 4-vectors
    are uniform in direction, so their quaternions' rotations are uniform."""
    R, _ = quaternion_matrix(rng.normal(size=(n, 4)).T)
    return np.moveaxis(R, -1, 0)


def rotate_tensors(R: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """``R·diag(moments)·Rᵀ`` for ``(n, 3, 3)`` and ``(n, 3)``; symmetric ``(n, 3, 3)``."""
    I = np.einsum("nij,nj,nkj->nik", R, moments, R)
    return 0.5 * (I + np.swapaxes(I, 1, 2))  # exactly symmetric despite rounding


def ellipsoid_moments(m: ArrayLike, a: ArrayLike, b: ArrayLike, c: ArrayLike) -> np.ndarray:
    """Solid ellipsoid with semi-axes a, b, c along x, y, z; shape ``(..., 3)``."""
    m, a, b, c = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (m, a, b, c)))
    return np.stack([m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)], axis=-1) / 5.0


def _shapes(rng: np.random.Generator, kind: np.ndarray, m: np.ndarray, cond_max: float) -> np.ndarray:
    """Principal moments ``(n, 3)`` for bodies of the given kinds, each with a drawn target cond κ."""
    n = kind.shape[0]
    kappa = np.power(10.0, rng.random(n) * np.log10(max(cond_max, 1.0)))
    w = np.asarray(rng.uniform(0.05, 1.0, n))  # the body's cross-section size [m]
    u = np.asarray(rng.uniform(0.5, 1.0, n))  # aspect of the cross-section
    moments = np.empty((n, 3))
    # box / ellipsoid: cross-section a × b (a ≥ b), length L along z with cond = (a² + L²)/(a² + b²)
    a, b = w, w * u
    L = np.sqrt(np.maximum(kappa * (a * a + b * b) - a * a, 0.0))
    sel = kind == "box"
    moments[sel] = box_moments(m[sel], a[sel], b[sel], L[sel])
    sel = kind == "ellipsoid"
    moments[sel] = ellipsoid_moments(m[sel], a[sel], b[sel], L[sel])  # semi-axes: same relation
    # cylinder: cond = (3R² + L²) / (6R²) → L² = 3R²(2κ − 1); a rod is a cylinder with κ ≥ 100
    R = w / 2
    for k, floor in (("cylinder", 1.0), ("rod", 100.0)):
        sel = kind == k
        kk = np.maximum(kappa[sel], floor)
        moments[sel] = cylinder_moments(m[sel], R[sel], np.sqrt(3 * R[sel] ** 2 * (2 * kk - 1)))
    sel = kind == "sphere"
    moments[sel] = sphere_moments(m[sel], R[sel])
    return moments


def check_scene(scene: str, cond_max: float) -> None:
    """UsageError (a ValueError) for a scene kind or cond_max that cannot be drawn."""
    check_choice("scene", scene, tuple(SCENES))
    if not (cond_max >= 1 and np.isfinite(cond_max)):  # inf draws singular bodies, written as nan
        raise UsageError(f"{option('cond_max')} must be a finite number, at least 1, got {cond_max}")


def make_scene(
    n: int,
    seed: int = 0,
    scene: str = "mix",
    cond_max: float = 1e3,
    *,
    first_id: int = 1,
    rng: np.random.Generator | None = None,
) -> dict[str, np.ndarray]:
    """A scene of ``n`` bodies as named columns: the input contract plus ``id``, ``body``, ``mass``
    and the known ``w_true_x, w_true_y, w_true_z`` [rad/s]."""
    check_scene(scene, cond_max)
    rng = rng if rng is not None else np.random.default_rng(seed)
    kind = rng.choice(np.asarray(KINDS), size=n) if scene == "mix" else np.full(n, scene)
    m = rng.uniform(0.1, 20.0, n)
    moments = _shapes(rng, kind, m, cond_max)
    R = random_rotations(rng, n)
    I = rotate_tensors(R, moments)
    w = rng.normal(0.0, 2.0, (n, 3))
    H = np.einsum("nij,nj->ni", I, w)
    r = rng.uniform(-1.0, 1.0, (n, 3))
    cols = {"id": np.arange(first_id, first_id + n), "body": kind.astype(str), "m": m}
    cols.update({f"H{a}": H[:, k] for k, a in enumerate("xyz")})
    for name, (i, j) in zip(
        ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"), ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
    ):
        cols[name] = I[:, i, j]
    cols.update({f"r{a}": r[:, k] for k, a in enumerate("xyz")})
    cols.update({f"w_true_{a}": w[:, k] for k, a in enumerate("xyz")})
    return cols


def iter_scene(
    n: int, seed: int = 0, scene: str = "mix", cond_max: float = 1e3, chunk: int = 1 << 18
) -> Iterator[dict[str, np.ndarray]]:
    """:func:`make_scene` in chunks of ``chunk`` rows, for bounded memory. The rows depend on the
    seed and the chunk size; the same call always gives the same rows."""
    rng = np.random.default_rng(seed)
    for lo in range(0, n, chunk):
        yield make_scene(min(chunk, n - lo), scene=scene, cond_max=cond_max, first_id=lo + 1, rng=rng)
