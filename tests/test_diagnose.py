"""`hconv diagnose` recovers a planted convention; `hconv compare` measures the shortcuts.

Each convention is planted with independent numpy code (numpy.linalg.solve on the tensor that
convention builds), never with hconv's own hypothesis functions.
"""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import axis_angle, physical_bodies, quats, rodrigues, run_hconv, six, vec

from hconv.tools import diagnose
from hconv.tools.stats import Summary

SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]
N = 120


def scene(rng):
    I = physical_bodies(rng, N)  # body-frame tensors with products
    u, th = axis_angle(rng, N)
    R = rodrigues(u, th)
    return dict(
        I=I, R=R, q=quats(u, th), H=rng.normal(size=(N, 3)), r=rng.normal(size=(N, 3)), m=rng.uniform(0.5, 3, N)
    )


def solve(T, H):
    return np.linalg.solve(T, H[..., None])[..., 0]


def world(R, T):
    return R @ T @ np.swapaxes(R, 1, 2)


def from_six(v, order):
    """The tensor an engine builds from hconv's six numbers read in ``order``."""
    T = np.zeros((len(v), 3, 3))
    idx = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
    for k, e in enumerate(order):
        i, j = idx[e]
        T[:, i, j] = T[:, j, i] = v[:, k]
    return T


def plant(s, name):
    I, R, H, r, m = s["I"], s["R"], s["H"], s["r"], s["m"]
    Rt = np.swapaxes(R, 1, 2)
    rb = np.einsum("nji,nj->ni", R, r)  # r in the body frame
    Hb = np.einsum("nji,nj->ni", R, H)
    if name == "exact":
        return solve(world(R, I), H)
    if name == "transposed-rotation":
        return solve(world(Rt, I), H)
    if name == "ignored-rotation":
        return solve(I, H)
    if name == "flipped-products":
        return solve(world(R, 2 * I * np.eye(3) - I), H)
    if name == "ordering-urdf":
        return solve(world(R, from_six(six(I), ("xx", "xy", "xz", "yy", "yz", "zz"))), H)
    if name == "ordering-sympy":
        return solve(world(R, from_six(six(I), ("xx", "yy", "zz", "xy", "yz", "xz"))), H)
    if name == "pivot":
        shift = m[:, None, None] * (np.sum(r * r, axis=1)[:, None, None] * np.eye(3) - np.einsum("ni,nj->nij", r, r))
        return solve(world(R, I) + shift, H)
    if name == "diagonal":
        return np.einsum("nij,nj->ni", R, Hb / np.diagonal(I, axis1=1, axis2=2))
    if name == "document":
        perp = np.sum(rb * rb, axis=1, keepdims=True) - rb * rb
        return np.einsum("nij,nj->ni", R, perp / np.diagonal(I, axis1=1, axis2=2) * Hb)
    if name == "document-principal":
        S, P = np.linalg.eigh(I)
        rp, Hp = np.einsum("nji,nj->ni", P, rb), np.einsum("nji,nj->ni", P, Hb)
        perp = np.sum(rp * rp, axis=1, keepdims=True) - rp * rp
        return np.einsum("nij,nj->ni", R @ P, perp / S * Hp)
    raise KeyError(name)


def scene_table(s, w_obs) -> pa.Table:
    return pa.table(
        {
            **vec("H", s["H"]),
            **dict(zip(SIX, six(s["I"]).T)),
            **vec("q", s["q"], "wxyz"),
            **vec("r", s["r"]),
            "m": s["m"],
            **{f"w{c}_obs": w_obs[:, k] for k, c in enumerate("xyz")},
        }
    )


@pytest.mark.parametrize("name", diagnose.NAMES)
def test_diagnose_names_the_planted_convention_first(rng, tmp_path, name):
    s = scene(rng)
    # an engine in float32: its ω carries float32 rounding, well inside the default tolerance
    w_obs = plant(s, name).astype(np.float32).astype(np.float64)
    pq.write_table(scene_table(s, w_obs), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    top = d.ranking()[0]
    assert top.hypothesis == name
    assert top.residual.share_within == 1.0
    second = d.ranking()[1]
    assert second.residual.share_within < 0.5  # the planted one is clearly apart


def test_diagnose_json_from_the_command_line(rng, tmp_path):
    s = scene(rng)
    pq.write_table(scene_table(s, plant(s, "transposed-rotation")), tmp_path / "obs.parquet")
    proc = run_hconv("diagnose", str(tmp_path / "obs.parquet"), "--json")
    assert proc.returncode == 0, proc.stderr.decode()
    ranking = json.loads(proc.stdout)
    assert ranking[0]["hypothesis"] == "transposed-rotation" and ranking[0]["share_explained"] == 1.0
    assert set(ranking[0]) >= {"hypothesis", "median_residual", "share_explained"}
    assert ranking[0]["median_residual"] < 1e-12
    assert {r["hypothesis"] for r in ranking} == set(diagnose.NAMES)


def test_diagnose_reports_rows_nothing_explains(rng, tmp_path):
    s = scene(rng)
    w = plant(s, "exact")
    w[:7] *= 1.5  # rows a wrong engine made up
    pq.write_table(scene_table(s, w), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    assert d.ranking()[0].hypothesis == "exact"
    assert d.unexplained == 7 and [e[0] for e in d.examples] == list(range(7))
    proc = run_hconv("diagnose", str(tmp_path / "obs.parquet"))
    assert proc.returncode == 0 and b"7 rows no hypothesis explains" in proc.stdout


def test_diagnose_without_observed_omega_names_the_columns(tmp_path):
    pq.write_table(pa.table({"Hx": [1.0], "Hy": [0.0], "Hz": [0.0], "I": [1.0]}), tmp_path / "x.parquet")
    proc = run_hconv("diagnose", str(tmp_path / "x.parquet"))
    assert proc.returncode == 3 and b"wx_obs, wy_obs, wz_obs" in proc.stderr


def test_summary_median_within_half_a_bin(rng):
    values = 10.0 ** rng.uniform(-12, 2, 10001)
    s = Summary(1e-6)
    for k in range(0, 10001, 999):
        s.add(values[k : k + 999], k)
    assert abs(s.median / np.median(values) - 1) < 0.012
    assert s.maximum == values.max() and s.max_row == int(np.argmax(values))
    assert s.within == int((values <= 1e-6).sum())


def test_compare_writes_per_row_figures_and_finds_shortcut_failures(rng, tmp_path):
    s = scene(rng)
    t = pa.table({**vec("H", s["H"]), **dict(zip(SIX, six(world(s["R"], s["I"])).T)), **vec("r", s["r"])})
    pq.write_table(t, tmp_path / "in.parquet")
    proc = run_hconv("compare", str(tmp_path / "in.parquet"), str(tmp_path / "cmp.parquet"))
    assert proc.returncode == 0, proc.stderr.decode()
    out = pq.read_table(tmp_path / "cmp.parquet")
    assert out.num_rows == N and out.column_names[:12] == t.column_names
    np.testing.assert_array_equal(out.column("diff_exact").to_numpy(), 0.0)
    assert out.column("diff_lapack").to_numpy().max() < 1e-12
    # the diagonal shortcut's error grows with the off-diagonal ratio
    off, diff = out.column("offdiag").to_numpy(), out.column("diff_diagonal").to_numpy()
    assert np.median(diff[off > 0.3]) > 4 * np.median(diff[off < 0.1])
    assert b"rows where diagonal is furthest off" in proc.stdout
