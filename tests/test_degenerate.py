"""Degenerate bodies: zero or near-zero principal moments (thin rods, point masses)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from helpers import axis_angle, rel_err, rodrigues, vec, w_of

import hconv
from hconv.solve.options import Conventions
from hconv.tables.job import Job

SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]


def rods(rng, n, axial):
    """Rods of moments (axial, 1, 1) turned at random; tensors (n, 6), axes (n, 3), rotations."""
    u, th = axis_angle(rng, n)
    R = rodrigues(u, th)
    I = R @ (np.array([axial, 1.0, 1.0])[None, :, None] * np.swapaxes(R, 1, 2))
    return np.stack([I[:, 0, 0], I[:, 1, 1], I[:, 2, 2], I[:, 0, 1], I[:, 0, 2], I[:, 1, 2]], axis=1), R[:, :, 0]


@pytest.mark.parametrize("mode", ["pinv", "lock"])
def test_convert_pinv_on_thin_rods_drops_the_axis(rng, mode):
    I, axis = rods(rng, 60, 0.0)
    H = rng.normal(size=(60, 3))
    t = pa.table({**vec("H", H), **dict(zip(SIX, I.T))})
    got = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate=mode)))
    assert set(got.column("status").to_pylist()) == {"degenerate"}
    # no rotation about the rod; across it, ω = H⊥ / 1
    H_perp = H - np.sum(H * axis, axis=1, keepdims=True) * axis
    assert rel_err(w_of(got), H_perp).max() < 1e-12
    null = np.column_stack([got.column(c).to_numpy() for c in ("null_x", "null_y", "null_z")])
    assert np.abs(np.abs(np.sum(null * axis, axis=1)) - 1).max() < 1e-12  # the rod's axis, either sign
    assert set(got.column("null_dim").to_pylist()) == {1}


def test_convert_degenerate_error_is_singular_without_answer(rng):
    I, _ = rods(rng, 10, 0.0)
    t = pa.table({**vec("H", rng.normal(size=(10, 3))), **dict(zip(SIX, I.T))})
    got = hconv.convert_table(t)
    assert set(got.column("status").to_pylist()) == {"singular"}
    assert np.isnan(w_of(got)).all()
    assert "null_x" not in got.column_names


def test_convert_point_mass_pinv_gives_zero_and_no_single_axis():
    t = pa.table({"Hx": [1.0], "Hy": [2.0], "Hz": [3.0], "I1": [0.0], "I2": [0.0], "I3": [0.0]})
    got = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate="pinv")))
    assert got.column("status").to_pylist() == ["degenerate"]
    assert w_of(got).tolist() == [[0.0, 0.0, 0.0]]
    assert got.column("null_dim").to_pylist() == [3] and np.isnan(got.column("null_x").to_numpy()).all()


@pytest.mark.parametrize("scale", [1e-100, 1.0, 1e100])
def test_convert_degenerate_threshold_is_relative_to_the_trace(rng, scale):
    # Axial moment 1e-8 of the transverse: dropped with rtol 1e-6, kept with rtol 1e-10, at any scale.
    I, axis = rods(rng, 20, 1e-8)
    H = rng.normal(size=(20, 3))
    t = pa.table({**vec("H", H * scale), **dict(zip(SIX, I.T * scale))})
    loose = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate="pinv", degenerate_rtol=1e-6)))
    tight = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate="pinv", degenerate_rtol=1e-10)))
    assert set(loose.column("status").to_pylist()) == {"degenerate"}
    assert "degenerate" not in set(tight.column("status").to_pylist())
    strict = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate_rtol=1e-6)))
    assert set(strict.column("status").to_pylist()) == {"singular"}


def test_convert_negative_moment_beyond_threshold_stays_not_positive_definite():
    t = pa.table({"Hx": [1.0], "Hy": [1.0], "Hz": [1.0], "I1": [-0.5], "I2": [0.0], "I3": [1.0]})
    got = hconv.convert_table(t, job=Job(conventions=Conventions(degenerate="pinv")))
    assert got.column("status").to_pylist() == ["not_positive_definite"]


def test_summary_counts_degenerate_rows(tmp_path, capsys):
    import pyarrow.parquet as pq
    from helpers import hconv_inprocess

    pq.write_table(
        pa.table(
            {"Hx": [1.0, 1.0], "Hy": [0.0, 1.0], "Hz": [0.0, 0.0], "I1": [0.0, 1.0], "I2": [1.0] * 2, "I3": [1.0] * 2}
        ),
        tmp_path / "rod.parquet",
    )
    proc = hconv_inprocess(
        "convert", str(tmp_path / "rod.parquet"), str(tmp_path / "out.parquet"), "--degenerate", "pinv", capsys=capsys
    )
    assert proc.returncode == 0, proc.stderr.decode()
    # in a pipe the summary is tab-separated text
    rows = dict(ln.split("\t") for ln in proc.stderr.decode().splitlines() if ln.count("\t") == 1)
    assert rows == {"status": "rows", "ok": "1", "degenerate": "1", "total": "2"}
