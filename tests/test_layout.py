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

import hconv
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


def test_plan_of_a_schema_seen_before_is_kept_but_named_and_unit_metadata_tells_schemas_apart():
    """Plans are kept by schema and Job (a dataset's files share one): the kept plan names the
    file asked about, and a schema that differs only in a field's unit metadata (which pyarrow's
    == and hash leave out) gets its own plan."""
    fields = [(c, pa.float64()) for c in ("Hx", "Hy", "Hz", "I1", "I2", "I3")]
    grams = pa.schema([pa.field(c, t, metadata={"unit": "g*m^2"}) if c == "I1" else (c, t) for c, t in fields])
    si = pa.schema(fields)
    assert grams == si  # pyarrow's equality: what the kept plans must not go by
    first, again, other = layout.plan(si, Job(), "a.parquet"), layout.plan(si, Job(), "b.parquet"), None
    assert (first.source, again.source) == ("a.parquet", "b.parquet") and again.groups is first.groups
    other = layout.plan(grams, Job(), "c.parquet")
    assert other.groups["I"].factors == (1e-3, 1.0, 1.0) and first.groups["I"].factors == (1.0, 1.0, 1.0)
    assert layout.plan(si, Job(method="refined"), "d.parquet").groups is not first.groups


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


def test_plan_missing_vector_set_without_look_alikes_names_the_map_to_give():
    schema = pa.schema([(c, pa.float64()) for c in ("Ax", "By", "Cz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")])
    with pytest.raises(InputError) as info:
        layout.plan(schema, Job(), "x.csv")
    assert str(info.value) == (
        "x.csv: missing columns Hx, Hy, Hz (or a list column H); if another column holds Hx, "
        "give mapping={'Hx': 'COLUMN'}"
    )


def _csv_w(out) -> np.ndarray:
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    rows = [r.split(",") for r in lines[1:]]
    rows = [r for r in rows if r[header.index("wx")] != "rad/s"]  # a row of units is no data
    return np.array([[float(r[header.index(c)]) for c in ("wx", "wy", "wz")] for r in rows])


def test_plan_reads_units_written_in_headers_and_names_in_any_case(tmp_path, capsys):
    """A CSV as a spreadsheet writes it: units in brackets or parentheses after the names, names in
    another case. ω is I⁻¹H in SI: 1 g·cm² is 1e-7 kg·m²."""
    src = tmp_path / "units.csv"
    src.write_text(
        "t,hx [kg*m^2/s],HY [kg*m^2/s],Hz [kg*m^2/s],ixx (g*cm^2),Iyy (g*cm^2),IZZ (g*cm^2),"
        "Ixy (g*cm^2),Ixz (g*cm^2),iyz (g*cm^2)\n"
        "0,1,2,3,1e7,2e7,4e7,0,0,0\n"
    )
    out = tmp_path / "o.csv"
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    np.testing.assert_array_equal(_csv_w(out), [[1.0, 1.0, 0.75]])
    assert out.read_text().splitlines()[0].startswith("t,hx [kg*m^2/s],HY [kg*m^2/s]")  # the input's names, kept
    # --unit wins over the header's
    proc = hconv_inprocess("convert", str(src), str(out), "--force", "--unit", "I=kg*m**2", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    np.testing.assert_allclose(_csv_w(out), [[1e-7, 1e-7, 0.75e-7]], rtol=1e-15)
    # and the output says so under the header, which still names g*cm^2
    assert out.read_text().splitlines()[1].startswith(",kg*m^2/s,kg*m^2/s,kg*m^2/s,kg*m**2,kg*m**2,")


@pytest.mark.parametrize(
    "header, needle",
    [
        ("Hx [blorts],Hy,Hz,I1,I2,I3", "column 'Hx [blorts]' (the unit in its header): pint does not understand"),
        ("Hx [m/s],Hy,Hz,I1,I2,I3", "column 'Hx [m/s]' (the unit in its header): 'm/s' is not a unit of"),
    ],
)
def test_plan_header_unit_pint_cannot_use_names_the_column_and_unit_option(header, needle, tmp_path, capsys):
    src = tmp_path / "bad.csv"
    src.write_text(header + "\n1,2,3,1,1,1\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), capsys=capsys)
    err = proc.stderr.decode().strip()
    assert proc.returncode == 3 and len(err.splitlines()) == 1, err
    assert needle in err and err.endswith("or give its unit with --unit Hx=UNIT, which wins")
    # the fix it names works
    fixed = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--unit", "Hx=kg*m^2/s", capsys=capsys)
    assert fixed.returncode == 0, fixed.stderr.decode()


def test_plan_two_columns_for_one_name_in_different_case_names_both_and_map():
    schema = pa.schema([(c, pa.float64()) for c in ("hx", "HX", "Hy", "Hz", "I1", "I2", "I3")])
    with pytest.raises(InputError) as info:
        layout.plan(schema, Job(), "x.csv")
    assert str(info.value) == "x.csv: columns 'hx' and 'HX' could both be Hx; say which with mapping={'Hx': 'hx'}"
    plan = layout.plan(schema, Job(mapping={"Hx": "HX"}), "x.csv")
    assert plan.groups["H"].columns == ("HX", "Hy", "Hz")


def test_plan_exact_names_win_and_one_letter_names_keep_their_case():
    """A column named exactly as hconv's name is read, never its look-alike in another case; and
    M or V (a Mach number, a voltage) is not taken for the mass or the velocity."""
    schema = pa.schema([(c, pa.float64()) for c in ("Hx", "HX", "Hy", "Hz", "I1", "I2", "I3", "M", "R")])
    plan = layout.plan(schema, Job(), "x.csv")
    assert plan.groups["H"].columns == ("Hx", "Hy", "Hz") and set(plan.groups) == {"H", "I"}


@pytest.mark.parametrize(
    "columns, needle",
    [
        (("Hx", "Hy", "H_z", "I1", "I2", "I3"), "if column 'H_z' holds Hz, give mapping={'Hz': 'H_z'}"),
        (("Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "I_yz"), "give mapping={'Iyz': 'I_yz'}"),
        (("Hx", "Hy", "Hz", "inertia"), "if another column holds I1, give mapping={'I1': 'COLUMN'}"),
        (("Hx", "Hy", "Hz", "I1", "I2", "I3", "rx", "ry"), "if another column holds rz, give mapping={'rz': 'COLUMN'}"),
    ],
)
def test_plan_missing_columns_always_name_the_map(columns, needle):
    schema = pa.schema([(c, pa.float64()) for c in columns])
    with pytest.raises(InputError) as info:
        layout.plan(schema, Job(), "x.csv")
    assert needle in str(info.value) and "\n" not in str(info.value)


def _struct_table(n: int, rng) -> tuple[pa.Table, np.ndarray, np.ndarray]:
    H = rng.normal(size=(n, 3))
    six = np.abs(rng.normal(size=(n, 6))) * [1, 1, 1, 0.1, 0.1, 0.1] + [3, 3, 3, 0, 0, 0]
    h = pa.StructArray.from_arrays([pa.array(H[:, k]) for k in range(3)], names=["x", "y", "z"])
    inertia = pa.StructArray.from_arrays(
        [pa.array(six[:, k]) for k in range(6)], names=["xx", "yy", "zz", "xy", "xz", "yz"]
    )
    return pa.table({"t": np.arange(n), "H": h, "I": inertia}), H, six


def _solve(H: np.ndarray, six: np.ndarray) -> np.ndarray:
    xx, yy, zz, xy, xz, yz = six.T
    M = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], 1)
    return np.array([np.linalg.solve(M[k], H[k]) for k in range(len(H))])


def test_plan_reads_struct_columns_named_like_sets_from_a_parquet_file(tmp_path, rng, capsys):
    """A Parquet file with H a struct {x, y, z} and I a struct {xx, ..., yz}, as pyarrow writes it:
    the structs stand for their sets, and stay structs in the output."""
    data, H, six = _struct_table(40, rng)
    src, out = tmp_path / "s.parquet", tmp_path / "o.parquet"
    pq.write_table(data, src)
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    got = pq.read_table(out)
    assert got.schema.field("H").type == data.schema.field("H").type
    assert got.column("H").equals(data.column("H")) and got.column("I").equals(data.column("I"))
    w = np.stack([got.column(c).to_numpy() for c in ("wx", "wy", "wz")], 1)
    np.testing.assert_allclose(w, _solve(H, six), rtol=1e-13)


def test_plan_map_reads_a_struct_field_by_its_dotted_path(tmp_path, rng, capsys):
    data, H, six = _struct_table(5, rng)
    momentum = pa.StructArray.from_arrays(
        [data.column("H").combine_chunks().field(k) for k in range(3)], ["a", "b", "c"]
    )
    data = data.set_column(1, "L", momentum)
    src = tmp_path / "s.parquet"
    pq.write_table(data, src)
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.parquet"), capsys=capsys)
    err = proc.stderr.decode().strip()
    assert proc.returncode == 3 and "missing columns Hx, Hy, Hz" in err and "--map" in err
    proc = hconv_inprocess(
        "convert", str(src), str(tmp_path / "o.parquet"), "--map", "Hx=L.a,Hy=L.b,Hz=L.c", capsys=capsys
    )
    assert proc.returncode == 0, proc.stderr.decode()
    got = pq.read_table(tmp_path / "o.parquet")
    w = np.stack([got.column(c).to_numpy() for c in ("wx", "wy", "wz")], 1)
    np.testing.assert_allclose(w, _solve(H, six), rtol=1e-13)
    assert got.column("L").equals(data.column("L"))


def test_read_struct_row_that_is_null_is_invalid_input(rng):
    data, _, _ = _struct_table(3, rng)
    h = data.column("H").combine_chunks()
    masked = pa.StructArray.from_arrays(h.flatten(), names=["x", "y", "z"], mask=pa.array([False, True, False]))
    got = hconv.convert_table(data.set_column(1, "H", masked))
    assert got.column("status").to_pylist() == ["ok", "invalid_input", "ok"]
    assert got.column("H").equals(pa.chunked_array([masked]))


def test_plan_input_with_hconv_s_output_names_converts_with_a_prefix(tmp_path, capsys):
    """An input that has a status and a wx column of its own: refused naming --prefix, and with it
    converted, the input's columns kept as they were and hconv's prefixed, w_unit too."""
    src, out = tmp_path / "log.csv", tmp_path / "o.csv"
    src.write_text("Hx,Hy,Hz,I1,I2,I3,status,wx\n1,2,3,2,4,4,armed,9\n2,2,2,2,2,2,idle,8\n")
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    err = proc.stderr.decode().strip()
    assert proc.returncode == 3 and len(err.splitlines()) == 1
    assert err.endswith("already has output columns wx, status; rename or drop them (hconv's own output?), "
                        "or pass --prefix out_ for hconv's new ones")  # fmt: skip
    proc = hconv_inprocess("convert", str(src), str(out), "--prefix", "out_", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    lines = out.read_text().splitlines()
    assert lines[0] == "Hx,Hy,Hz,I1,I2,I3,status,wx,out_wx,out_wy,out_wz,out_residual,out_cond,out_status,out_w_unit"
    assert lines[1].startswith("1,2,3,2,4,4,armed,9,0.5,0.5,0.75,") and lines[1].endswith(",ok,rad/s")
    assert "ok\t2" in proc.stderr.decode()  # the tally counts hconv's status, not the input's
    # converting the output again needs another prefix, and says so
    again = hconv_inprocess("convert", str(out), str(tmp_path / "o2.csv"), "--prefix", "out_", capsys=capsys)
    assert again.returncode == 3 and "or pass another --prefix for hconv's new ones" in (again.stderr.decode())


def test_plan_reads_the_unit_a_struct_field_stores_as_its_metadata():
    unit = {b"unit": b"g*cm**2/s"}
    h = pa.struct([pa.field(a, pa.float64(), metadata=unit) for a in "xyz"])
    schema = pa.schema([("H", h), ("I1", pa.float64()), ("I2", pa.float64()), ("I3", pa.float64())])
    assert layout.stored_units(schema) == {"H.x": "g*cm**2/s", "H.y": "g*cm**2/s", "H.z": "g*cm**2/s"}
    plan = layout.plan(schema, Job(), "s.parquet")
    assert plan.groups["H"].columns == ("H.x", "H.y", "H.z") and plan.groups["H"].factors == pytest.approx([1e-7] * 3)


def test_plan_reads_an_observed_omega_struct_for_diagnose(rng):
    """w_obs {x, y, z}, whose columns (wx_obs...) are not the struct's name and a field's."""
    data, H, six = _struct_table(4, rng)
    w = pa.StructArray.from_arrays([pa.array(rng.normal(size=4)) for _ in range(3)], names=["x", "y", "z"])
    plan = layout.plan(data.append_column("w_obs", w).schema, Job(observed=True), "log.parquet")
    assert plan.groups["w_obs"].columns == ("w_obs.x", "w_obs.y", "w_obs.z")


def test_plan_lowercase_i_suggests_the_isotropic_map_that_works(tmp_path, capsys):
    """Before: a column 'i' got 'if column 'i' holds I1, give --map I1=i', which then failed
    for lacking I2, I3; the isotropic inertia's name is I, and --map I=i reads the file."""
    src = tmp_path / "i.csv"
    src.write_text("Hx,Hy,Hz,i\n1,2,3,2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and len(err.strip().splitlines()) == 1
    assert err.rstrip().endswith("if column 'i' holds I, give --map I=i")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--map", "I=i", "-q", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    import pyarrow.csv as pacsv

    assert pacsv.read_csv(tmp_path / "o.csv").column("wx").to_pylist() == [0.5]  # H / I: 1 / 2


@pytest.mark.parametrize(
    "header, name, column, fixed",
    [
        ("Hx [kg*m^2/s,Hy,Hz,I", "Hx", "Hx [kg*m^2/s", "Hx [kg*m^2/s]"),
        ("Hx,Hy,Hz,Ixx (g*cm^2,Iyy,Izz,Ixy,Ixz,Iyz", "Ixx", "Ixx (g*cm^2", "Ixx (g*cm^2)"),
    ],
)
def test_plan_unclosed_unit_bracket_names_the_column_and_its_fix(header, name, column, fixed, tmp_path, capsys):
    """Before: 'missing column Hx' with no word of the column 'Hx [kg*m^2/s', whose bracket is
    not closed; docs/input.md promises the close column is named."""
    src = tmp_path / "b.csv"
    values = ",".join(["1"] * len(header.split(",")))
    src.write_text(f"{header}\n{values}\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and len(err.strip().splitlines()) == 1
    assert f"column {column!r} is {name} with its unit's bracket not closed: rename it {fixed!r}" in err
    src.write_text(f"{header.replace(column, fixed)}\n{values}\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "-q", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
