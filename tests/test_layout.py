"""Column plans: a pure function of (schema, job), an immutable layout, and list columns whose
length one batch fixes for the whole file."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import hconv_inprocess

from hconv.errors import InputError, UsageError
from hconv.tables import layout, pipeline
from hconv.tables.job import Job


def _list_table(H_rows, I_rows) -> pa.Table:
    return pa.table({"H": pa.array(H_rows, pa.list_(pa.float64())), "I": pa.array(I_rows, pa.list_(pa.float64()))})


def test_plan_is_pure_and_its_layout_immutable():
    schema = pa.schema([(c, pa.float64()) for c in ("Hx", "Hy", "Hz", "I1", "I2", "I3")])
    job = Job()
    a, b = layout.plan(schema, job, "x.csv"), layout.plan(schema, job, "x.csv")
    assert a == b and a.form == "principal" and job == Job()
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.form = "sym6"


def test_resolve_fixes_list_lengths_in_a_new_layout():
    t = _list_table([[1.0, 2.0, 3.0]], [[1.0, 2.0, 3.0, 0.0, 0.0, 0.0]])
    plan = layout.plan(t.schema, Job(), "t")
    assert plan.form is None and plan.groups["I"].size is None
    resolved = plan.resolve(t)
    assert resolved.form == "sym6" and resolved.groups["I"].size == 6 and resolved.groups["H"].size == 3
    assert plan.form is None and plan.groups["I"].size is None  # the original is untouched
    sets, form = resolved.read(t)
    assert form == "sym6" and sets["I"].shape == (6, 1)


def test_read_list_column_null_in_every_row_gives_invalid_input_rows():
    import hconv

    t = _list_table([[1.0, 2.0, 3.0], [1.0, 0.0, 0.0]], [None, None])
    got = hconv.convert_table(t)
    assert got.column("status").to_pylist() == ["invalid_input", "invalid_input"]


def _two_row_groups(path, second_H):
    writer = pq.ParquetWriter(path, _list_table([[1.0, 2.0, 3.0]], [[1.0, 2.0, 3.0]]).schema)
    writer.write_table(_list_table([[1.0, 2.0, 3.0]] * 5, [[1.0, 2.0, 3.0]] * 5))
    writer.write_table(_list_table([second_H] * 5, [[1.0, 2.0, 3.0]] * 5))
    writer.close()


def test_parquet_list_length_is_fixed_by_the_first_batch(tmp_path, monkeypatch):
    monkeypatch.setattr("hconv.tables.parquetio.PARQUET_BATCH_ROWS", 5)  # one batch per row group
    _two_row_groups(tmp_path / "bad.parquet", [1.0, 2.0])
    with pytest.raises(InputError, match=r"list column 'H' holds 2 values in row 6, but H needs 3 \(Hx, Hy, Hz\)"):
        pipeline.convert_file(str(tmp_path / "bad.parquet"), str(tmp_path / "out.parquet"), threads=2)
    assert not (tmp_path / "out.parquet").exists()
    _two_row_groups(tmp_path / "good.parquet", [0.0, 1.0, 0.0])
    pipeline.convert_file(str(tmp_path / "good.parquet"), str(tmp_path / "out.parquet"), threads=2)
    w = np.column_stack([pq.read_table(tmp_path / "out.parquet").column(c).to_numpy() for c in ("wx", "wy", "wz")])
    np.testing.assert_array_equal(w, [[1.0, 1.0, 1.0]] * 5 + [[0.0, 0.5, 0.0]] * 5)


SIZES = "3 (principal), 6 (Ixx,Iyy,Izz,Ixy,Ixz,Iyz) or 9 (row-major)"


@pytest.mark.parametrize(
    "H_rows, I_rows, message",
    [
        # one row: there are no "others"; H needs 3 by its definition
        ([[1.0, 2.0]], [[2.0, 2.0, 2.0]], "'H' holds 2 values in row 1, but H needs 3 (Hx, Hy, Hz)"),
        ([[1.0, 2.0, 3.0, 4.0]] * 3, [[2.0, 2.0, 2.0]] * 3, "'H' holds 4 values in row 1, but H needs 3"),
        ([[]], [[2.0, 2.0, 2.0]], "'H' holds an empty list in row 1, but H needs 3"),
        ([[1.0, 2.0, 3.0]] * 2 + [[1.0, 2.0]], [[2.0, 2.0, 2.0]] * 3, "'H' holds 2 values in row 3, but H needs 3"),
        # I's size is what the rows hold, so a disagreement names both rows
        (
            [[1.0, 2.0, 3.0]] * 2,
            [[1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]],
            "'I' holds 6 values in row 2, but 4 in row 1",
        ),
        ([[1.0, 2.0, 3.0]] * 3, [None, [2.0, 2.0, 2.0], []], "'I' holds an empty list in row 3, but 3 in row 2"),
        ([[1.0, 2.0, 3.0]], [[]], f"'I' holds empty lists; an inertia list holds {SIZES}"),
    ],
)
def test_read_list_column_of_the_wrong_length_names_the_row_and_what_is_needed(H_rows, I_rows, message):
    t = pa.table({"H": pa.array(H_rows, pa.list_(pa.float64())), "I": pa.array(I_rows, pa.list_(pa.float64()))})
    with pytest.raises(InputError) as err:
        layout.plan(t.schema, Job(), "in.parquet").read(t)
    assert str(err.value).startswith(f"in.parquet: list column {message}"), str(err.value)
    assert "in others" not in str(err.value)


def test_read_list_column_null_row_is_invalid_input_not_an_error():
    import hconv

    t = _list_table([[1.0, 2.0, 3.0], None], [[1.0, 2.0, 3.0]] * 2)
    assert hconv.convert_table(t).column("status").to_pylist() == ["ok", "invalid_input"]


def test_parquet_inertia_list_length_change_in_a_later_batch_names_its_row(tmp_path, monkeypatch):
    monkeypatch.setattr("hconv.tables.parquetio.PARQUET_BATCH_ROWS", 5)
    writer = pq.ParquetWriter(tmp_path / "in.parquet", _list_table([[1.0, 2.0, 3.0]], [[1.0, 2.0, 3.0]]).schema)
    writer.write_table(_list_table([[1.0, 2.0, 3.0]] * 5, [[1.0, 2.0, 3.0, 0.0, 0.0, 0.0]] * 5))
    writer.write_table(_list_table([[1.0, 2.0, 3.0]] * 5, [[1.0, 2.0, 3.0]] * 5))
    writer.close()
    with pytest.raises(
        InputError,
        match="'I' holds 3 values in row 6, but 6 in the rows before it; every row must hold the same number, "
        + re.escape(SIZES),
    ):
        pipeline.convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "out.parquet"), threads=2)


@pytest.mark.parametrize("name", ["w_unit", "wx", "status", "null_dim"])
def test_plan_refuses_an_input_column_named_as_an_output(name, tmp_path):
    """Every name hconv writes, w_unit too (a CSV's unit column), is refused in the input by name;
    before, a w_unit column gave an output with two w_unit columns that hconv could not read back."""
    schema = pa.schema([(c, pa.float64()) for c in ("Hx", "Hy", "Hz", "I")] + [(name, pa.string())])
    with pytest.raises(InputError, match=f"already has output column {name}; rename or drop it"):
        layout.plan(schema, Job(), "in.csv")
    src = tmp_path / "in.csv"
    src.write_text(f"Hx,Hy,Hz,I,{name}\n1,2,3,2,x\n")
    with pytest.raises(InputError, match=name):
        pipeline.convert_file(str(src), str(tmp_path / "out.csv"))
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize(
    "columns, mapping, needle",
    [
        # hconv's Hy is read from column Hx, so its Hx has no column: say that, not "missing Hx"
        (("Hx", "Hy", "Hz", "I1", "I2", "I3"), {"Hy": "Hx"}, "column 'Hx' is read as Hy: mapping={'Hy': 'Hx'}"),
        (("Hx", "Hy", "Hz", "I1", "I2", "I3"), {"I3": "I1"}, "column 'I1' is read as I3: mapping={'I3': 'I1'}"),
    ],
)
def test_plan_map_taking_a_name_s_own_column_says_so(columns, mapping, needle):
    schema = pa.schema([(c, pa.float64()) for c in columns])
    with pytest.raises(InputError) as info:
        layout.plan(schema, Job(mapping=mapping), "x.csv")
    msg = str(info.value)
    assert needle in msg and "give" in msg and "a column too" in msg


def test_plan_map_clash_is_spelled_as_the_command_line_does(tmp_path, capsys):
    src = tmp_path / "in.csv"
    src.write_text("Hx,Hy,Hz,I1,I2,I3\n1,2,3,4,5,6\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--map", "Hy=Hx", capsys=capsys)
    err = proc.stderr.decode().strip()
    assert proc.returncode == 3 and len(err.splitlines()) == 1
    assert "column 'Hx' is read as Hy: --map Hy=Hx); give Hx a column too, e.g. --map Hx=COLUMN" in err


def test_read_integer_column_beyond_2_53_rounds_to_float64_as_csv_does(tmp_path):
    """Before: 'internal error: ArrowInvalid: Integer value 9007199254740993 not in range'."""
    import hconv

    big = 9007199254740993  # 2^53 + 1: not a float64
    cols = {"Hx": [big], "Hy": [0], "Hz": [0], "I1": [big], "I2": [big], "I3": [big]}
    from_ints = hconv.convert_table(pa.table({k: pa.array(v, pa.int64()) for k, v in cols.items()}))
    pq.write_table(pa.table({k: pa.array(v, pa.int64()) for k, v in cols.items()}), tmp_path / "in.parquet")
    (tmp_path / "in.csv").write_text(",".join(cols) + "\n" + ",".join(str(v[0]) for v in cols.values()) + "\n")
    pipeline.convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "p.parquet"))
    pipeline.convert_file(str(tmp_path / "in.csv"), str(tmp_path / "c.parquet"))
    got = [pq.read_table(tmp_path / f"{n}.parquet").column("wx").to_pylist() for n in "pc"]
    assert got[0] == got[1] == from_ints.column("wx").to_pylist() == [1.0]


def test_plan_quat_order_with_named_quaternion_columns_is_refused():
    names = ("Hx", "Hy", "Hz", "I1", "I2", "I3", "qw", "qx", "qy", "qz")
    schema = pa.schema([(c, pa.float64()) for c in names])
    with pytest.raises(UsageError, match=r"quat_order='xyzw' orders a list column q, but this input names"):
        layout.plan(schema, Job(quat_order="xyzw"), "x.csv")
    assert layout.plan(schema, Job(), "x.csv").groups["q"].columns == ("qw", "qx", "qy", "qz")


def _spark_schema(fields: list, units: dict) -> pa.Schema:
    """A schema as pyarrow reads a Parquet file Spark wrote: bare fields, and Spark's own schema,
    field metadata included, in the file's metadata."""
    spark = {"type": "struct", "fields": [{"name": n, "metadata": {"unit": u}} for n, u in units.items()]}
    return pa.schema(fields, metadata={layout.SPARK_SCHEMA_KEY: json.dumps(spark).encode()})


def test_stored_units_reads_field_metadata_then_sparks_schema_in_column_order():
    fields = [
        pa.field("Ixx", pa.float64()),
        pa.field("Hx", pa.float64(), metadata={"unit": "g*cm**2/s"}),
        pa.field("id", pa.int64()),
    ]
    assert layout.stored_units(pa.schema(fields)) == {"Hx": "g*cm**2/s"}
    # Spark's unit where the field has none; the field's own where it has one
    spark = _spark_schema(fields, {"Hx": "kg*m**2/s", "Ixx": "g*cm**2"})
    assert list(layout.stored_units(spark).items()) == [("Ixx", "g*cm**2"), ("Hx", "g*cm**2/s")]


def test_stored_units_of_file_metadata_that_is_not_sparks_schema_is_none():
    for junk in (b"not json", b"[1, 2]", b'{"fields": [{"metadata": {"unit": "m"}}]}', b'{"fields": 3}'):
        schema = pa.schema([pa.field("Hx", pa.float64())], metadata={layout.SPARK_SCHEMA_KEY: junk})
        assert layout.stored_units(schema) == {}


def test_plan_reads_sparks_units_as_field_metadata():
    names = ("Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
    schema = _spark_schema([pa.field(c, pa.float64()) for c in names], {"Ixx": "g*cm**2"})
    got = layout.plan(schema, Job(), "spark.parquet").groups["I"]
    assert got.units[0] == "g*cm**2" and got.factors[0] == pytest.approx(1e-7)
    assert got.factors[1:] == (1.0,) * 5


def test_plan_field_units_stand_in_for_dropped_metadata_after_unit_options_and_the_fields_own():
    names = ("Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
    fields = [pa.field(c, pa.float64(), metadata={"unit": "kg*m**2"} if c == "Iyy" else None) for c in names]
    dropped = {"Ixx": "g*cm**2", "Iyy": "g*cm**2", "Izz": "g*cm**2", "id": "1", "elsewhere": "m"}
    job = Job(field_units=dropped, unit_options={"Izz": "kg*m**2"})
    I = layout.plan(pa.schema(fields), job, "engine").groups["I"]
    # Ixx from field_units; Iyy's own metadata and Izz's --unit win; columns not read are left alone
    assert I.units[:3] == ("g*cm**2", "kg*m**2", "kg*m**2")
    assert I.factors[:3] == pytest.approx((1e-7, 1.0, 1.0))


def test_plan_field_units_refuses_a_unit_of_the_wrong_kind_naming_the_keyword():
    names = ("Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
    with pytest.raises(UsageError, match=re.escape("field_units={'Ixx': 'm/s'}")):
        layout.plan(pa.schema([(c, pa.float64()) for c in names]), Job(field_units={"Ixx": "m/s"}), "engine")


def test_plan_missing_vector_set_suggests_the_map_that_reads_look_alike_columns(tmp_path, capsys):
    src = tmp_path / "in.csv"
    src.write_text("Lx,Ly,Lz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz\n1,2,3,1,2,4,0,0,0\n")
    out = tmp_path / "o.csv"
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    err = proc.stderr.decode().strip()
    assert proc.returncode == 3 and len(err.splitlines()) == 1
    suggested = re.search(r"give (--map \S+)$", err)
    assert suggested, err
    assert "Ixx" not in suggested.group(1)  # the inertia's own columns are read by their names
    # the suggestion is a command that works: ω of the diagonal body is H / I per axis
    proc = hconv_inprocess("convert", str(src), str(out), *suggested.group(1).split(), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    row = out.read_text().splitlines()[1].split(",")
    header = out.read_text().splitlines()[0].split(",")
    w = [float(row[header.index(c)]) for c in ("wx", "wy", "wz")]
    assert w == [1.0, 1.0, 0.75]


def test_plan_missing_vector_set_without_look_alikes_suggests_nothing():
    schema = pa.schema([(c, pa.float64()) for c in ("Ax", "By", "Cz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")])
    with pytest.raises(InputError) as info:
        layout.plan(schema, Job(), "x.csv")
    assert str(info.value) == "x.csv: missing columns Hx, Hy, Hz (or a list column H)"
