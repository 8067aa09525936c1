"""convert_table, the Arrow edge of the library: its own options against a whole Job; output_schema,
the schema it returns, known before converting; and hconv's Parquet settings, public."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import need, w_of

import hconv
from hconv.errors import InputError, UsageError
from hconv.tables import parquetio
from hconv.tables.pipeline import convert_file

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "data"


def _table() -> pa.Table:
    return pa.table({"Hx": [1.0], "Hy": [2.0], "Hz": [3.0], "Ixx": [2.0], "Iyy": [3.0], "Izz": [4.0],
                     "Ixy": [0.1], "Ixz": [0.0], "Iyz": [0.2]})  # fmt: skip


@pytest.mark.parametrize("beside", [{"method": "refined"}, {"precision": 32}, {"diagnostics": False}])
def test_convert_table_refuses_options_beside_a_job(beside):
    name = next(iter(beside))
    with pytest.raises(UsageError, match=f"convert_table: {name} given beside job=; put them in the Job"):
        hconv.convert_table(_table(), job=hconv.Job(), **beside)


def test_convert_table_options_alone_and_job_alone_are_honoured():
    plain = hconv.convert_table(_table())
    assert "residual" in plain.column_names
    assert "residual" not in hconv.convert_table(_table(), diagnostics=False).column_names
    assert "residual" not in hconv.convert_table(_table(), job=hconv.Job(diagnostics=False)).column_names
    doc = hconv.convert_table(_table().append_column("rx", pa.array([0.1])).append_column("ry", pa.array([0.2]))
                              .append_column("rz", pa.array([0.3])), method="document")  # fmt: skip
    assert doc.schema.field("wx").metadata[b"unit"] == b"m^2/s"


# ---- output_schema: convert_table's schema from the input's schema alone ----

N = 5


def _columns(names: str, rng: np.random.Generator) -> dict:
    """Float64 columns named in ``names`` (space-separated), physical enough to convert."""
    out = {}
    for name in names.split():
        if name in ("Ixx", "Iyy", "Izz", "I1", "I2", "I3", "I", "m"):
            out[name] = rng.uniform(2.0, 3.0, N)
        elif name in ("Iyx", "Izx", "Izy"):
            continue  # the transposes of Ixy, Ixz, Iyz, added below
        else:
            out[name] = rng.uniform(-0.2, 0.2, N)
    for tr, of in (("Iyx", "Ixy"), ("Izx", "Ixz"), ("Izy", "Iyz")):
        if tr in names.split():
            out[tr] = out[of]
    return out


SYM6 = "Hx Hy Hz Ixx Iyy Izz Ixy Ixz Iyz"
FULL9 = SYM6 + " Iyx Izx Izy"
PRINCIPAL_Q = "Hx Hy Hz I1 I2 I3 qw qx qy qz"
LAYOUTS = {
    "sym6": SYM6,
    "full9": FULL9,
    "principal+q": PRINCIPAL_Q,
    "isotropic": "Hx Hy Hz I",
    "principal+q+r+m+v": PRINCIPAL_Q + " rx ry rz m vx vy vz",
    "sym6+r+m+v": SYM6 + " rx ry rz m vx vy vz",
}
JOBS = {
    **{f"method={m}": hconv.Job(method=m) for m in hconv.METHODS},
    "precision=32": hconv.Job(precision=32),
    "diagnostics=False": hconv.Job(diagnostics=False),
    "omega_unit=deg/s": hconv.Job(omega_unit="deg/s"),
    "omega_unit=rpm, precision=32": hconv.Job(omega_unit="rpm", precision=32),
    "about=free": hconv.Job(conventions=hconv.Conventions(about="free")),
    "about=pivot": hconv.Job(conventions=hconv.Conventions(about="pivot")),
    "degenerate=pinv": hconv.Job(conventions=hconv.Conventions(degenerate="pinv")),
    "degenerate=lock, body frame": hconv.Job(conventions=hconv.Conventions(degenerate="lock", frame="body")),
    "units": hconv.Job(unit_options={"I": "g*cm**2", "Hx": "g*cm**2/s"}),
    "units, m in grams": hconv.Job(unit_options={"I": "g*cm**2", "m": "g"}),
}


def _assert_same_schema(got: pa.Schema, want: pa.Schema) -> None:
    assert got.equals(want, check_metadata=True), f"{got}\n!=\n{want}"
    assert got.metadata == want.metadata
    assert [(f.name, f.type, f.metadata) for f in got] == [(f.name, f.type, f.metadata) for f in want]


@pytest.mark.parametrize("job", JOBS.values(), ids=JOBS.keys())
@pytest.mark.parametrize("names", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_output_schema_is_convert_tables_schema_for_every_layout_and_job(names, job, rng):
    table = pa.table(_columns(names, rng))
    try:
        want = hconv.convert_table(table, job=job).schema
    except hconv.errors.HconvError as exc:  # a job this layout cannot serve: refused alike
        with pytest.raises(type(exc), match=re.escape(str(exc))):
            hconv.output_schema(table.schema, job=job, source="table")
        return
    _assert_same_schema(hconv.output_schema(table.schema, job=job), want)


def _with_passthrough(table: pa.Table) -> pa.Table:
    """``table`` between ids, labels, times, flags and a struct, with field and schema metadata."""
    n = table.num_rows
    front = {
        "id": pa.array(range(n), pa.int64()),
        "label": pa.array([f"b{k}" for k in range(n)]).dictionary_encode(),
        "t": pa.array(range(n), pa.timestamp("ms", tz="UTC")),
    }
    back = {
        "ok": pa.array([k % 2 == 0 for k in range(n)]),
        "pose": pa.array([{"x": 1.0, "name": "a"}] * n),
        "zip": pa.array(["02134"] * n),
    }
    out = pa.table({**front, **dict(zip(table.column_names, table.columns)), **back})
    out = out.set_column(0, pa.field("id", pa.int64(), metadata={"description": "body id"}), out.column("id"))
    return out.replace_schema_metadata({b"source": b"a test", b"pandas": b"{}"})


def test_output_schema_keeps_passthrough_columns_and_metadata_in_order(rng):
    table = _with_passthrough(pa.table(_columns(SYM6 + " rx ry rz", rng)))
    want = hconv.convert_table(table, method="document").schema
    got = hconv.output_schema(table.schema, method="document")
    _assert_same_schema(got, want)
    assert got.names[:3] == ["id", "label", "t"] and got.names[-9:-6] == ["ok", "pose", "zip"]
    assert got.names[-6:] == ["wx", "wy", "wz", "residual", "cond", "status"]
    assert got.field("wx").metadata == {b"unit": b"m^2/s", b"method": b"document"}
    assert got.field("status").type == pa.dictionary(pa.int8(), pa.string())
    assert got.metadata[b"source"] == b"a test" and got.metadata[b"hconv.method"] == b"document"


LIST_TABLES = {
    "H, I list(6)": lambda rng: pa.table(
        {"H": pa.array(rng.normal(size=(N, 3)).tolist()), "I": pa.array([[2.0, 3.0, 4.0, 0.1, 0.0, 0.2]] * N)}
    ),
    "I fixed_size_list(9), q list": lambda rng: pa.table(
        {
            "Hx": rng.normal(size=N),
            "Hy": rng.normal(size=N),
            "Hz": rng.normal(size=N),
            "I": pa.array([[2.0, 0.1, 0.0, 0.1, 3.0, 0.2, 0.0, 0.2, 4.0]] * N, pa.list_(pa.float64(), 9)),
            "q": pa.array([[1.0, 0.0, 0.0, 0.0]] * N),
        }
    ),
    "I list(3) float32, r list, large_list H": lambda rng: pa.table(
        {
            "H": pa.array(rng.normal(size=(N, 3)).tolist(), pa.large_list(pa.float64())),
            "I": pa.array([[2.0, 3.0, 4.0]] * N, pa.list_(pa.float32())),
            "r": pa.array([[0.1, 0.2, 0.3]] * N),
        }
    ),
}


@pytest.mark.parametrize("make", LIST_TABLES.values(), ids=LIST_TABLES.keys())
@pytest.mark.parametrize("method", ["exact", "document"])
def test_output_schema_is_convert_tables_schema_for_list_columns(make, method, rng):
    table = _with_passthrough(make(rng))
    if method == "document" and "r" not in table.column_names:
        table = table.append_column("r", pa.array([[0.1, 0.2, 0.3]] * N))
    _assert_same_schema(
        hconv.output_schema(table.schema, method=method), hconv.convert_table(table, method=method).schema
    )


def test_output_schema_carries_the_units_read_from_field_metadata_and_mapping(rng):
    cols = _columns(SYM6, rng)
    cols["Lx"] = cols.pop("Hx")
    table = pa.table(cols)
    i = table.schema.get_field_index("Ixx")
    table = table.set_column(
        i, pa.field("Ixx", pa.float32(), metadata={"unit": "g*cm**2"}), table.column(i).cast(pa.float32())
    )
    job = hconv.Job(mapping={"Hx": "Lx"}, unit_options={"H": "g*cm**2/s"}, omega_unit="deg/s")
    got = hconv.output_schema(table.schema, job=job)
    _assert_same_schema(got, hconv.convert_table(table, job=job).schema)
    assert got.field("Lx").metadata == {b"unit": b"g*cm**2/s"}
    assert got.field("Ixx").metadata == {b"unit": b"g*cm**2"} and got.field("Ixx").type == pa.float32()
    assert got.field("wz").metadata[b"unit"] == b"deg/s"


@pytest.mark.parametrize("name", ["scene.csv", "engine-bodies.csv", "cad-export.csv", "pendulums.csv"])
def test_output_schema_is_convert_tables_schema_for_csv_typed_tables(name):
    table = pacsv.read_csv(EXAMPLES / name)
    _assert_same_schema(hconv.output_schema(table.schema), hconv.convert_table(table).schema)
    text = pacsv.read_csv(EXAMPLES / name, convert_options=pacsv.ConvertOptions(
        column_types={c: pa.string() for c in ("id", "body", "part", "w_true_x")}))  # fmt: skip
    job = hconv.Job(unit_options={"m": "g"}) if name == "cad-export.csv" else hconv.Job()
    _assert_same_schema(hconv.output_schema(text.schema, job=job), hconv.convert_table(text, job=job).schema)


def test_output_schema_of_a_record_batch_and_of_no_rows_is_the_same(rng):
    table = _with_passthrough(pa.table(_columns(PRINCIPAL_Q, rng)))
    want = hconv.output_schema(table.schema, precision=32, diagnostics=False)
    for data in (table.to_batches()[0], table.schema.empty_table()):
        _assert_same_schema(want, hconv.convert_table(data, precision=32, diagnostics=False).schema)


def test_output_schema_refuses_what_convert_table_refuses(rng):
    table = pa.table(_columns(SYM6, rng))
    with pytest.raises(UsageError, match="output_schema takes a pyarrow Schema, got Table; pass its .schema"):
        hconv.output_schema(table)
    with pytest.raises(UsageError, match="output_schema: method given beside job=; put them in the Job"):
        hconv.output_schema(table.schema, method="refined", job=hconv.Job())
    with pytest.raises(InputError, match="schema: missing column.* rx, ry, rz"):
        hconv.output_schema(table.schema, method="document")
    taken = table.append_column("status", pa.array(["x"] * N))
    with pytest.raises(InputError, match="in.parquet: already has output column status"):
        hconv.output_schema(taken.schema, source="in.parquet")


# ---- hconv's Parquet settings, public: one owner for hconv's writer and the recipes ----


def _chunk_settings(path) -> list:
    """(column, compression, dictionary page) of each column chunk of the file's first row group."""
    rg = pq.ParquetFile(path).metadata.row_group(0)
    return [(rg.column(k).path_in_schema, rg.column(k).compression, rg.column(k).has_dictionary_page)
            for k in range(rg.num_columns)]  # fmt: skip


def test_parquet_write_options_are_what_hconvs_own_writer_writes(tmp_path):
    src = EXAMPLES / "scene.parquet"
    convert_file(str(src), str(tmp_path / "hconv.parquet"))
    out = pq.read_table(tmp_path / "hconv.parquet")
    options = hconv.parquet_write_options(out.schema)
    assert options["compression"]["wx"] == "none" and "status" in options["use_dictionary"]
    pq.write_table(out, tmp_path / "public.parquet", **options)
    assert _chunk_settings(tmp_path / "hconv.parquet") == _chunk_settings(tmp_path / "public.parquet")
    floats = {f.name for f in out.schema if pa.types.is_floating(f.type)}
    for name, compression, dictionary in _chunk_settings(tmp_path / "hconv.parquet"):
        assert (compression, dictionary) == (("UNCOMPRESSED", False) if name in floats else ("SNAPPY", True)), name


def test_hconvs_writer_takes_its_settings_from_parquet_write_options(tmp_path, monkeypatch):
    asked = []

    def gzip_everything(schema: pa.Schema) -> dict:
        asked.append(schema)
        return {"compression": "gzip", "use_dictionary": False}

    monkeypatch.setattr(parquetio, "parquet_write_options", gzip_everything)
    convert_file(str(EXAMPLES / "scene.parquet"), str(tmp_path / "out.parquet"))
    assert len(asked) == 1 and asked[0].names[-3:] == ["residual", "cond", "status"]
    assert {(c, d) for _, c, d in _chunk_settings(tmp_path / "out.parquet")} == {("GZIP", False)}


def _with_unit(table: pa.Table, column: str, unit: str) -> pa.Table:
    k = table.schema.get_field_index(column)
    return table.cast(table.schema.set(k, table.schema.field(k).with_metadata({"unit": unit})))


def test_units_of_a_schema_is_every_stored_unit_in_column_order():
    schema = _with_unit(_with_unit(_table(), "Iyy", "g*cm**2"), "Hx", "g*cm**2/s").schema
    assert list(hconv.units_of(schema).items()) == [("Hx", "g*cm**2/s"), ("Iyy", "g*cm**2")]
    out = hconv.output_schema(schema)
    assert hconv.units_of(out)["wx"] == "rad/s" and hconv.units_of(out)["Ixx"] == "kg*m**2"


def test_units_of_files_reads_every_footer_of_a_file_directory_or_glob(tmp_path):
    (tmp_path / "d=1").mkdir()
    pq.write_table(_with_unit(_table(), "Ixx", "g*cm**2"), tmp_path / "d=1" / "a.parquet")
    pq.write_table(_with_unit(_table(), "Hx", "g*cm**2/s"), tmp_path / "b.parquet")
    (tmp_path / "_SUCCESS").write_text("")  # an engine's marker, and a CSV, have no footer to read
    (tmp_path / "c.csv").write_text("Hx\n1\n")
    both = {"Hx": "g*cm**2/s", "Ixx": "g*cm**2"}
    assert hconv.units_of(tmp_path) == hconv.units_of(str(tmp_path / "**" / "*.parquet")) == both
    assert hconv.units_of(tmp_path / "b.parquet") == {"Hx": "g*cm**2/s"}


def test_units_of_files_refuses_a_column_stored_in_two_units_naming_both_files(tmp_path):
    pq.write_table(_with_unit(_table(), "Ixx", "g*cm**2"), tmp_path / "a.parquet")
    pq.write_table(_with_unit(_table(), "Ixx", "kg*m**2"), tmp_path / "b.parquet")
    want = f"{tmp_path}/b.parquet: column 'Ixx' is in kg*m**2, but in g*cm**2 in {tmp_path}/a.parquet; convert"
    with pytest.raises(InputError, match=re.escape(want)):
        hconv.units_of(tmp_path)


def test_units_of_refuses_what_it_cannot_read(tmp_path):
    with pytest.raises(UsageError, match="units_of takes a pyarrow Schema or the path of Parquet files, got Table"):
        hconv.units_of(_table())
    with pytest.raises(InputError, match="does not exist; check the path"):
        hconv.units_of(tmp_path / "none")
    (tmp_path / "bad.parquet").write_bytes(b"not parquet")
    with pytest.raises(InputError, match=re.escape(f"{tmp_path}/bad.parquet: cannot read its Parquet footer (")):
        hconv.units_of(tmp_path)


def test_convert_table_with_units_of_gives_what_the_dropped_metadata_gave(tmp_path):
    stored = _with_unit(_table(), "Ixx", "g*cm**2")
    pq.write_table(stored, tmp_path / "a.parquet")
    bare = pa.table(stored.columns, names=stored.column_names)  # what an engine that drops metadata hands on
    job = hconv.Job(field_units=hconv.units_of(tmp_path))
    assert hconv.convert_table(bare, job=job).equals(hconv.convert_table(stored))
    assert not hconv.convert_table(bare).equals(hconv.convert_table(stored))


def test_convert_table_prefix_names_every_appended_column_and_output_schema_agrees(rng):
    H, I = rng.normal(size=(4, 3)), np.abs(rng.normal(size=(4, 3))) + 1
    data = pa.table({"Hx": H[:, 0], "Hy": H[:, 1], "Hz": H[:, 2], "I1": I[:, 0], "I2": I[:, 1], "I3": I[:, 2],
                     "status": ["a", "b", "c", "d"], "wx": np.zeros(4)})  # fmt: skip
    with pytest.raises(InputError, match=r"or pass prefix='out_' for hconv's new ones$"):
        hconv.convert_table(data)
    got = hconv.convert_table(data, prefix="o.")
    appended = ["o.wx", "o.wy", "o.wz", "o.residual", "o.cond", "o.status"]
    assert got.column_names == data.column_names + appended
    assert got.column("status").equals(data.column("status")) and got.column("wx").equals(data.column("wx"))
    np.testing.assert_array_equal(np.stack([got.column(c).to_numpy() for c in appended[:3]], 1), H / I)
    assert got.schema == hconv.output_schema(data.schema, prefix="o.")
    assert got.schema.metadata[b"hconv.prefix"] == b"o."
    assert hconv.convert_table(data, job=hconv.Job(prefix="o.")).equals(got)
    # a table hconv wrote with a prefix, converted again with another: the record is the new run's
    again = hconv.convert_table(got, prefix="p_")
    assert again.schema.metadata[b"hconv.prefix"] == b"p_"
    assert b"hconv.prefix" not in hconv.convert_table(got.drop_columns(["status", "wx"] + appended)).schema.metadata


def test_convert_table_reads_struct_columns_and_output_schema_agrees(rng):
    H = rng.normal(size=(6, 3))
    six = np.array([2.0, 3.0, 4.0, 0.1, -0.2, 0.3])
    h = pa.StructArray.from_arrays([pa.array(H[:, k]) for k in range(3)], names=["x", "y", "z"])
    inertia = pa.StructArray.from_arrays(
        [pa.array(np.full(6, v)) for v in six], names=["xx", "yy", "zz", "xy", "xz", "yz"]
    )
    data = pa.table({"H": h, "I": inertia})
    got = hconv.convert_table(data)
    assert got.schema == hconv.output_schema(data.schema)
    assert got.column_names[:2] == ["H", "I"] and got.column("H").equals(data.column("H"))
    xx, yy, zz, xy, xz, yz = six
    M = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    w = np.stack([got.column(c).to_numpy() for c in ("wx", "wy", "wz")], 1)
    np.testing.assert_allclose(w, np.linalg.solve(M, H.T).T, rtol=1e-14)


def _scene() -> pa.Table:
    return pq.read_table(EXAMPLES / "scene.parquet")


@pytest.mark.parametrize("kind", ["pandas", "pandas-indexed", "polars", "duckdb", "reader", "batch"])
def test_convert_table_takes_tables_that_speak_arrow_and_gives_back_their_kind(kind):
    """Before: 'convert_table takes a pyarrow Table or RecordBatch, got DataFrame'."""
    t = _scene()
    ref = hconv.convert_table(t)
    if kind.startswith("pandas"):
        pd = need("pandas")
        frame = t.to_pandas()
        if kind == "pandas-indexed":
            frame.index = pd.Index([f"r{k}" for k in range(len(frame))], name="row")
        got = hconv.convert_table(frame)
        assert isinstance(got, pd.DataFrame)
        assert list(got.index) == list(frame.index)  # the frame's index kept
        w = got[["wx", "wy", "wz"]].to_numpy()
        assert list(got["status"].astype(str)) == ref.column("status").to_pylist()
    elif kind == "polars":
        pl = need("polars")
        got = hconv.convert_table(pl.from_arrow(t))
        assert isinstance(got, pl.DataFrame)
        w = got.select(["wx", "wy", "wz"]).to_numpy()
        assert got["status"].cast(pl.String).to_list() == ref.column("status").to_pylist()
    elif kind == "duckdb":
        duckdb = need("duckdb")
        con = duckdb.connect()
        con.register("scene", t)
        got = hconv.convert_table(con.sql("select * from scene"))
        assert isinstance(got, pa.Table)
        w = w_of(got)
    else:
        data = pa.RecordBatchReader.from_batches(t.schema, t.to_batches()) if kind == "reader" else t.to_batches()[0]
        got = hconv.convert_table(data)
        assert isinstance(got, pa.Table)
        w = w_of(got)
        ref = hconv.convert_table(pa.Table.from_batches([data])) if kind == "batch" else ref
    assert np.array_equal(w, w_of(ref), equal_nan=True)  # the same bits as from the pyarrow Table


@pytest.mark.parametrize(
    "make, says",
    [
        (lambda: need("polars").LazyFrame({"Hx": [1.0]}), r"got LazyFrame \(call \.collect\(\) first\)"),
        (lambda: need("polars").Series("Hx", [1.0]), r"polars.Series gives Arrow data that is not one"),
        (lambda: [1, 2], r"got list; or any table that speaks Arrow"),
    ],
)
def test_convert_table_refuses_what_is_not_a_table_in_one_line(make, says):
    with pytest.raises(UsageError, match=says) as info:
        hconv.convert_table(make())
    assert "\n" not in str(info.value)
