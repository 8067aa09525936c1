"""Units in and out: any unit pint understands, SI without pint, and the unit-slip status."""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import mp_solve, physical_bodies, rel_err, run_hconv, six, vec, w_of

import hconv
from hconv.errors import UsageError
from hconv.solve import units
from hconv.tables.job import Job

SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]


def test_factor_known_conversions():
    # Independent arithmetic: 1 g·cm² = 1e-3 kg · 1e-4 m²; 1 lb = 0.45359237 kg, 1 ft = 0.3048 m.
    assert units.factor("I", "g*cm**2") == pytest.approx(1e-7, rel=1e-15)
    assert units.factor("I", "lb*ft**2") == pytest.approx(0.45359237 * 0.3048**2, rel=1e-15)
    assert units.factor("H", "g*mm**2/s") == pytest.approx(1e-9, rel=1e-15)
    assert units.factor("I", "kg·m²") == 1.0 and units.factor("H", "N*m*s") == 1.0
    assert units.omega_factor("deg/s") == pytest.approx(180 / math.pi, rel=1e-15)
    assert units.omega_factor("rpm") == pytest.approx(60 / (2 * math.pi), rel=1e-15)


@pytest.mark.parametrize(
    "bad, needle",
    [
        ("g*cm", "not a unit of inertia"),
        ("furlongs_per_blob", "does not understand"),
        ("degC*m**2", "offset|not a unit"),
    ],
)
def test_factor_bad_unit_is_a_usage_error(bad, needle):
    with pytest.raises(UsageError, match=needle):
        units.factor("I", bad, "--unit I")


def test_convert_gram_centimetre_inputs_give_the_same_omega(rng):
    I = physical_bodies(rng, 40)
    H = rng.normal(size=(40, 3))
    want = mp_solve(I, H)
    si = pa.table({**vec("H", H), **dict(zip(SIX, six(I).T))})
    cgs = pa.table({**vec("H", H * 1e7), **dict(zip(SIX, six(I).T * 1e7))})
    job = Job(unit_options=(("I", "g*cm**2"), ("H", "g*cm**2/s")))
    got = hconv.convert_table(cgs, job=job)
    assert rel_err(w_of(got), want).max() < 1e-14
    assert rel_err(w_of(hconv.convert_table(si)), want).max() < 1e-14
    assert got.schema.field("Ixy").metadata[b"unit"] == b"g*cm**2"  # the unit it was read in


def test_convert_parquet_unit_metadata_is_read(tmp_path, rng):
    I = physical_bodies(rng, 20)
    H = rng.normal(size=(20, 3))
    fields = [pa.field(c, pa.float64(), metadata={"unit": "g*cm**2/s"}) for c in ("Hx", "Hy", "Hz")]
    fields += [pa.field(c, pa.float64(), metadata={"unit": "g*cm**2"}) for c in SIX]
    t = pa.Table.from_arrays([pa.array(x) for x in np.concatenate([H.T, six(I).T]) * 1e7], schema=pa.schema(fields))
    pq.write_table(t, tmp_path / "cgs.parquet")
    proc = run_hconv(
        "convert", str(tmp_path / "cgs.parquet"), str(tmp_path / "out.parquet"), "--omega-unit", "deg/s", "-q"
    )
    assert proc.returncode == 0, proc.stderr.decode()
    out = pq.read_table(tmp_path / "out.parquet")
    assert out.schema.field("wx").metadata[b"unit"] == b"deg/s"
    assert rel_err(w_of(out), np.degrees(mp_solve(I, H))).max() < 1e-14


def test_convert_unit_option_beats_metadata_and_names_bad_keys():
    t = pa.table({"Hx": [1.0], "Hy": [0.0], "Hz": [0.0], "I": [2.0]})
    got = hconv.convert_table(t, job=Job(unit_options=(("Hx", "kg*cm**2/s"),)))
    assert w_of(got)[0, 0] == pytest.approx(0.5e-4, rel=1e-15)
    with pytest.raises(UsageError, match="'Lx' is not a column hconv reads"):
        hconv.convert_table(t, job=Job(unit_options=(("Lx", "kg"),)))


def test_status_unit_suspect_catches_gram_centimetre_slip():
    # A 1 m water cube (1000 kg, moments 1000·2/12): plausible. Its g·cm² numbers read as kg·m²,
    # or its mass given in grams, are not.
    ok_I = 1000 * 2 / 12
    t = pa.table(
        {
            "Hx": [1.0] * 4,
            "Hy": [0.0] * 4,
            "Hz": [0.0] * 4,
            "I": [ok_I, ok_I * 1e7, ok_I, ok_I * 1e-7],
            "m": [1000.0, 1000.0, 1e6, 1000.0],
        }
    )
    got = hconv.convert_table(t).column("status").to_pylist()
    # row 2 (I 1e7 too big) could be inertia about a far pivot, so without --about only the
    # "too dense" rows are certain; about the centre of mass every slip is caught.
    assert got == ["ok", "ok", "unit_suspect", "unit_suspect"]
    t2 = (
        t.append_column("rx", pa.array([0.0] * 4))
        .append_column("ry", pa.array([0.0] * 4))
        .append_column("rz", pa.array([0.0] * 4))
    )
    from hconv.solve.options import Conventions

    got = hconv.convert_table(t2, job=Job(conventions=Conventions(about="pivot"))).column("status").to_pylist()
    assert got == ["ok", "unit_suspect", "unit_suspect", "unit_suspect"]


def test_one_units_and_omega_unit():
    proc = run_hconv(
        "one",
        "--H",
        "1e7,0,0",
        "--I",
        "2e7",
        "--unit",
        "H=g*cm**2/s",
        "--unit",
        "I=g*cm**2",
        "--omega-unit",
        "deg/s",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr.decode()
    import json

    out = json.loads(proc.stdout)
    assert out["unit"] == "deg/s" and out["w"][0] == pytest.approx(math.degrees(0.5), rel=1e-15)


def test_convert_omega_unit_refused_for_document_methods():
    proc = run_hconv(
        "one", "--H", "1,0,0", "--I", "2,2,2", "--r", "1,1,0", "--method", "document", "--omega-unit", "deg/s"
    )
    assert proc.returncode == 2 and b"m^2/s" in proc.stderr
