"""`hconv generate`: physically valid bodies, the requested cond spread, a known ω that is right."""

from __future__ import annotations

import numpy as np
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import EPS, hconv_inprocess, rel_err, run_hconv

import hconv
from hconv.tools.scene import KINDS, make_scene


def _arrays(cols):
    H = np.column_stack([cols[f"H{a}"] for a in "xyz"])
    I = np.column_stack([cols[c] for c in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")])
    w = np.column_stack([cols[f"w_true_{a}"] for a in "xyz"])
    return H, I, w


@pytest.mark.parametrize("scene", ("mix",) + KINDS)
def test_generate_bodies_are_physical_with_requested_cond(scene):
    cols = make_scene(3000, seed=4, scene=scene, cond_max=1e4)
    H, I, w_true = _arrays(cols)
    res = hconv.convert(H, I)
    assert (res.status == "ok").all()  # positive definite, triangle inequality, well inside range
    lam = np.linalg.eigvalsh(
        np.stack([[I[:, 0], I[:, 3], I[:, 4]], [I[:, 3], I[:, 1], I[:, 5]], [I[:, 4], I[:, 5], I[:, 2]]]).transpose(
            2, 0, 1
        )
    )
    cond = lam[:, 2] / lam[:, 0]
    assert cond.max() <= 1e4 * (1 + 1e-9)
    if scene == "sphere":
        np.testing.assert_allclose(cond, 1.0, rtol=1e-12)
    if scene == "rod":
        assert cond.min() >= 100 * (1 - 1e-9)
    if scene in ("box", "ellipsoid"):  # log-uniform: about half above √cond_max
        assert 0.4 < np.mean(cond > 100) < 0.6
    # the known ω is I⁻¹H up to the rounding of the stored H
    assert (rel_err(res.w, w_true) <= 4 * res.cond * EPS).all()


def test_generate_command_parquet_and_csv_agree(tmp_path, capsys):
    for ext in ("parquet", "csv"):
        proc = hconv_inprocess("generate", str(tmp_path / f"s.{ext}"), "--rows", "1000", "--seed", "9", capsys=capsys)
        assert proc.returncode == 0, proc.stderr.decode()
    a, b = pq.read_table(tmp_path / "s.parquet"), pacsv.read_csv(tmp_path / "s.csv")
    assert a.num_rows == 1000 and a.column_names == b.column_names
    for c in ("Hx", "Ixy", "rz", "w_true_y"):
        np.testing.assert_array_equal(a.column(c).to_numpy(), b.column(c).to_numpy())


def test_generate_same_seed_same_rows_other_seed_other_rows(tmp_path, capsys):
    for name, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        assert (
            hconv_inprocess(
                "generate", str(tmp_path / f"{name}.parquet"), "-n", "500", "--seed", seed, capsys=capsys
            ).returncode
            == 0
        )
    a, b, c = (pq.read_table(tmp_path / f"{k}.parquet") for k in "abc")
    assert a.equals(b) and not a.equals(c)


def test_generate_bad_arguments(tmp_path, capsys):
    proc = hconv_inprocess("generate", str(tmp_path / "x.csv"), "--rows", "5", "--scene", "blob", capsys=capsys)
    assert proc.returncode == 2 and "--scene must be one of mix, box," in proc.stderr.decode()
    proc = hconv_inprocess("generate", str(tmp_path / "x.csv"), "--rows", "5", "--cond-max", "0.5", capsys=capsys)
    assert proc.returncode == 2 and "--cond-max must be a finite number, at least 1" in proc.stderr.decode()
    (tmp_path / "y.csv").write_text("keep\n")
    proc = hconv_inprocess("generate", str(tmp_path / "y.csv"), "--rows", "5", capsys=capsys)
    assert proc.returncode == 4 and (tmp_path / "y.csv").read_text() == "keep\n"


def test_generate_to_stdout_feeds_convert(tmp_path):
    gen = run_hconv("generate", "-", "--rows", "50", "--to", "csv")
    conv = run_hconv("convert", "-", "-", "--from", "csv", "--to", "csv", "-q", input=gen.stdout)
    lines = conv.stdout.decode().splitlines()
    assert len(lines) == 51 and lines[0].endswith("status,w_unit")


@pytest.mark.parametrize("value", ["inf", "nan", "-inf"])
def test_generate_cond_max_not_finite_is_refused(value, tmp_path):
    """Before: --cond-max inf exited 0 writing nan and inf rows."""
    from hconv.errors import UsageError
    from hconv.tools.generate import generate_file

    with pytest.raises(UsageError, match=rf"^cond_max must be a finite number, at least 1, got {value}$"):
        generate_file(str(tmp_path / "x.csv"), 20, cond_max=float(value))
    assert not (tmp_path / "x.csv").exists()


def test_generate_unknown_scene_names_the_option(tmp_path, capsys):
    """Before: "unknown scene 'blob'", naming neither --scene nor scene=."""
    from helpers import run_inprocess

    from hconv.errors import UsageError
    from hconv.tools.generate import generate_file

    code, _, err = run_inprocess("generate", str(tmp_path / "x.csv"), "--rows", "5", "--scene", "blob", capsys=capsys)
    assert (code, err) == (
        2,
        "hconv: error: --scene must be one of mix, box, cylinder, rod, sphere, ellipsoid, got 'blob'\n",
    )
    with pytest.raises(UsageError, match=r"^scene must be one of mix, box, .*, got 'blob'$"):
        generate_file(str(tmp_path / "x.csv"), 5, scene="blob")


@pytest.mark.parametrize("flag", ["-q", "--quiet"])
def test_generate_quiet_prints_no_summary_and_writes_the_same_rows(flag, tmp_path, capsys):
    """Before: `hconv generate ... -q` was 'No such option: -q', though convert takes it."""
    loud = hconv_inprocess("generate", str(tmp_path / "a.csv"), "-n", "5", "--seed", "3", capsys=capsys)
    assert loud.returncode == 0 and loud.stderr.startswith(b"hconv generate: 5 rows to ")
    quiet = hconv_inprocess("generate", str(tmp_path / "b.csv"), "-n", "5", "--seed", "3", flag, capsys=capsys)
    assert (quiet.returncode, quiet.stderr, quiet.stdout) == (0, b"", b"")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
