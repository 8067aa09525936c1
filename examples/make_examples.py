"""Write the small example files in examples/data that the scene examples of docs/scenes.md use.

    python examples/make_examples.py

Every file is deterministic (fixed seed) and holds bodies whose ω is known, so each example
command can be checked by eye against the `w_true_*` columns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

OUT = Path(__file__).resolve().parent / "data"
RNG = np.random.default_rng(2026_11_22)
SIX = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")


def quaternions(n):
    """Random unit quaternions (w, x, y, z), w >= 0, and their rotation matrices (body → world)."""
    q = RNG.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1, 1)
    w, x, y, z = q.T
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )
    return q, R


def rotation(q):
    """The rotation matrices (body → world) of unit quaternions (w, x, y, z), ``(n, 3, 3)``."""
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


def tumbling(I_B, q, w_B, dt, steps):
    """A free body with no torque, from orientation q and body-frame ω, after ``steps`` RK4 steps
    of Euler's equations I·dω/dt = -ω × I·ω and dq/dt = ½ q ⊗ (0, ω)."""

    def rate(q, w):
        dw = np.linalg.solve(I_B, -np.cross(w, I_B @ w))
        dq = 0.5 * np.concatenate([[-q[1:] @ w], q[0] * w + np.cross(q[1:], w)])
        return dq, dw

    for _ in range(steps):
        k1 = rate(q, w_B)
        k2 = rate(q + dt / 2 * k1[0], w_B + dt / 2 * k1[1])
        k3 = rate(q + dt / 2 * k2[0], w_B + dt / 2 * k2[1])
        k4 = rate(q + dt * k3[0], w_B + dt * k3[1])
        q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        w_B = w_B + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        q /= np.linalg.norm(q)
    return q, w_B


def box(m, a, b, c):
    return np.stack([m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)], -1) / 12


def write_csv(name, cols):
    pacsv.write_csv(pa.table(cols), OUT / name)


def engine_bodies(n=8):
    """Boxes as a physics engine stores them: principal moments, orientation, world-frame H."""
    m = RNG.uniform(1, 20, n).round(2)
    dims = RNG.uniform(0.2, 2.0, (n, 3)).round(2)
    moments = box(m, *dims.T)
    q, R = quaternions(n)
    w_true = RNG.normal(size=(n, 3)).round(3)
    H = np.einsum("nij,nj,nkj,nk->ni", R, moments, R, w_true)  # (R·diag·Rᵀ)·ω
    return m, moments, q, R, w_true, H


def main():
    OUT.mkdir(exist_ok=True)
    m, moments, q, R, w_true, H = engine_bodies()
    # the engine's bodies as stored: id, mass, principal moments, orientation, world-frame H
    bodies = {"id": np.arange(1, len(m) + 1), "m": m}
    bodies.update({f"I{k + 1}": moments[:, k] for k in range(3)})
    bodies.update({f"q{c}": q[:, k] for k, c in enumerate("wxyz")})
    bodies.update({f"H{c}": H[:, k] for k, c in enumerate("xyz")})
    write_csv("engine-bodies.csv", {**bodies, **{f"w_true_{c}": w_true[:, k] for k, c in enumerate("xyz")}})

    # An engine log whose ω came from the transposed rotation (world → body used as body → world),
    # in float32 as engines compute. `hconv diagnose` should name it.
    Rt = np.swapaxes(R, 1, 2)
    I_world_wrong = np.einsum("nij,nj,nkj->nik", Rt, moments, Rt)
    w_obs = np.linalg.solve(I_world_wrong, H[..., None])[..., 0].astype(np.float32)
    write_csv("engine-log.csv", {**bodies, **{f"w{c}_obs": w_obs[:, k] for k, c in enumerate("xyz")}})

    # Pendulums: solid cylinders along x swinging about the centre of one end face. I about the
    # centre of mass; r = centre of mass relative to the pivot; H about the pivot.
    n = 5
    mp, a, L = RNG.uniform(0.5, 3, n).round(2), RNG.uniform(0.01, 0.05, n).round(3), RNG.uniform(0.3, 1.5, n).round(2)
    across = mp * (3 * a * a + L * L) / 12
    about_end = mp * (a * a / 4 + L * L / 3)
    w_true = np.stack([np.zeros(n), np.zeros(n), RNG.uniform(-3, 3, n).round(2)], -1)
    write_csv(
        "pendulums.csv",
        {
            "m": mp,
            "I1": mp * a * a / 2,
            "I2": across,
            "I3": across,
            "rx": L / 2,
            "ry": np.zeros(n),
            "rz": np.zeros(n),
            "Hx": np.zeros(n),
            "Hy": np.zeros(n),
            "Hz": about_end * w_true[:, 2],
            "w_true_x": w_true[:, 0],
            "w_true_y": w_true[:, 1],
            "w_true_z": w_true[:, 2],
        },
    )

    # A CAD export: positive products of inertia (Pxy = +∫xy dm) in g·mm², H in g·mm²/s.
    n = 4
    m2 = RNG.uniform(100, 900, n).round(0)  # grams
    dims = RNG.uniform(20, 120, (n, 3)).round(0)  # millimetres
    q2, R2 = quaternions(n)
    I_gmm = np.einsum("nij,nj,nkj->nik", R2, box(m2, *dims.T), R2)
    w_true = RNG.normal(size=(n, 3)).round(3)
    H_gmm = np.einsum("nij,nj->ni", I_gmm, w_true)
    write_csv(
        "cad-export.csv",
        {
            "part": [f"bracket-{k}" for k in range(1, n + 1)],
            "m": m2,
            "Ixx": I_gmm[:, 0, 0],
            "Iyy": I_gmm[:, 1, 1],
            "Izz": I_gmm[:, 2, 2],
            "Ixy": -I_gmm[:, 0, 1],
            "Ixz": -I_gmm[:, 0, 2],
            "Iyz": -I_gmm[:, 1, 2],
            "Hx": H_gmm[:, 0],
            "Hy": H_gmm[:, 1],
            "Hz": H_gmm[:, 2],
            "w_true_x": w_true[:, 0],
            "w_true_y": w_true[:, 1],
            "w_true_z": w_true[:, 2],
        },
    )

    # Ideal thin rods (axial moment exactly 0) along random axes, as a Parquet file with list columns.
    n = 4
    q3, R3 = quaternions(n)
    mr, Lr = RNG.uniform(0.1, 1, n).round(2), RNG.uniform(0.5, 2, n).round(2)
    moments = np.stack([np.zeros(n), mr * Lr**2 / 12, mr * Lr**2 / 12], -1)
    w_true = RNG.normal(size=(n, 3)).round(3)
    w_true -= np.einsum("ni,ni->n", w_true, R3[:, :, 0])[:, None] * R3[:, :, 0]  # no spin about the rod
    H = np.einsum("nij,nj,nkj,nk->ni", R3, moments, R3, w_true)
    pq.write_table(
        pa.table(
            {
                "H": pa.FixedSizeListArray.from_arrays(pa.array(H.ravel()), 3),
                "I": pa.FixedSizeListArray.from_arrays(pa.array(moments.ravel()), 3),
                "q": pa.FixedSizeListArray.from_arrays(pa.array(q3.ravel()), 4),
                "w_true": pa.FixedSizeListArray.from_arrays(pa.array(w_true.ravel()), 3),
            }
        ),
        OUT / "rods.parquet",
    )

    # A tumbling free body logged as MuJoCo gives it: q = qpos[3:7], the six numbers of its
    # fullinertia (MuJoCo's order is hconv's), H = subtree_angmom (about the centre of mass, in
    # the world frame) and ω = qvel[3:6], which MuJoCo keeps in the body frame, logged as world.
    # `hconv diagnose` should say omega-body-frame; w_true_* is ω in the world frame.
    I_B = np.array([[0.30, 0.03, -0.02], [0.03, 0.22, 0.05], [-0.02, 0.05, 0.12]])
    q, w_B = RNG.normal(size=4), RNG.normal(size=3) * 3
    q /= np.linalg.norm(q)
    t, qs, ws = np.arange(8) * 0.25, [], []
    for _ in t:
        qs.append(q)
        ws.append(w_B)
        q, w_B = tumbling(I_B, q, w_B, 0.0025, 100)
    q, w_B = np.array(qs), np.array(ws)
    R = rotation(q)
    w_W = np.einsum("nij,nj->ni", R, w_B)
    H = np.einsum("nij,jk,nk->ni", R, I_B, w_B)
    six = {c: np.full(len(t), I_B[i, j]) for c, (i, j) in zip(SIX, ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)))}
    write_csv(
        "free-body-log.csv",
        {
            "t": t,
            **{f"q{c}": q[:, k] for k, c in enumerate("wxyz")},
            **six,
            **{f"H{c}": H[:, k] for k, c in enumerate("xyz")},
            **{f"w{c}_obs": w_B[:, k] for k, c in enumerate("xyz")},
            **{f"w_true_{c}": w_W[:, k] for k, c in enumerate("xyz")},
        },
    )


if __name__ == "__main__":
    main()
