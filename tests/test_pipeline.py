"""The machinery under `hconv convert`'s speed: ordered parallel batches and the Parquet writer's
encodings (the allocator settings are in test_allocator.py)."""

from __future__ import annotations

import csv
import io
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from hconv.tables import csvio, csvtypes, pipeline
from hconv.tables.job import Job
from hconv.tools.scene import make_scene


def _slow_square(k: int) -> int:
    time.sleep(0.002 * (k % 5))  # later items often finish first
    return k * k


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_ordered_map_keeps_input_order(threads):
    assert list(pipeline.ordered_map(_slow_square, range(40), threads)) == [k * k for k in range(40)]


def test_ordered_map_uses_several_threads():
    seen = set()
    # The first two items wait for each other: they pass only if two threads run them at once
    # (one thread would wait out the timeout, which only a broken ordered_map reaches).
    together = threading.Barrier(2, timeout=600)

    def record(k):
        seen.add(threading.get_ident())
        if k < 2:
            together.wait()
        return k

    assert list(pipeline.ordered_map(record, range(12), 3)) == list(range(12))
    assert len(seen) >= 2


def test_ordered_map_raises_the_first_error_in_order_and_stops_reading():
    read = []

    def items():
        for k in range(100):
            read.append(k)
            yield k

    def fail_at_5(k):
        if k == 5:
            raise ValueError("row 5")
        return k

    got = []
    with pytest.raises(ValueError, match="row 5"):
        for x in pipeline.ordered_map(fail_at_5, items(), 2):
            got.append(x)
    assert got == [0, 1, 2, 3, 4]
    assert len(read) <= 5 + 2 + 1  # bounded look-ahead: it did not read on to the end


def test_convert_file_same_output_for_any_threads(tmp_path):
    src = tmp_path / "in.parquet"
    pq.write_table(pa.table(make_scene(5000, seed=3, cond_max=1e8)), src)
    outs = []
    for threads in (1, 2, 3):
        dst = tmp_path / f"out{threads}.parquet"
        tally = pipeline.convert_file(str(src), str(dst), threads=threads)
        assert tally.rows == 5000
        outs.append(pq.read_table(dst))
    assert outs[0].equals(outs[1]) and outs[0].equals(outs[2])


def test_convert_file_threads_below_one_is_usage_error(tmp_path):
    from hconv.errors import UsageError

    with pytest.raises(UsageError, match="^threads must be a whole number, 1 or more"):
        pipeline.convert_file("in.parquet", str(tmp_path / "out.parquet"), threads=0)


def test_convert_file_progress_not_callable_is_usage_error_and_writes_nothing(tmp_path):
    """Before, a TypeError after the first batch."""
    from hconv.errors import UsageError

    src = tmp_path / "in.csv"
    src.write_text("Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz\n1,2,3,1,2,4,0,0,0\n")
    with pytest.raises(UsageError, match=r"^progress takes a function or None, got 5 \(int\)"):
        pipeline.convert_file(str(src), str(tmp_path / "out.parquet"), progress=5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


def test_default_threads_is_between_one_and_the_cap():
    assert 1 <= pipeline.default_threads() <= pipeline.MAX_THREADS


def test_parquet_output_floats_plain_labels_compressed(tmp_path):
    src, dst = tmp_path / "in.parquet", tmp_path / "out.parquet"
    cols = make_scene(3000, seed=1)
    pq.write_table(pa.table(cols), src)
    pipeline.convert_file(str(src), str(dst))
    meta = pq.ParquetFile(dst).metadata.row_group(0)
    codec = {meta.column(k).path_in_schema: meta.column(k).compression for k in range(meta.num_columns)}
    assert codec["wx"] == codec["residual"] == codec["Hx"] == "UNCOMPRESSED"
    assert codec["status"] == codec["body"] == "SNAPPY"
    np.testing.assert_array_equal(pq.read_table(dst).column("Hx").to_numpy(), cols["Hx"])  # nothing lost on the way


def test_convert_file_tally_names_the_engine_that_ran(tmp_path):
    """auto converts files on the compiled engine; a run the asked engine does not cover is numpy's, and says so."""
    src, dst = "examples/data/scene.parquet", str(tmp_path / "o.parquet")
    root = Path(__file__).resolve().parents[1]
    auto = pipeline.convert_file(str(root / src), dst, force=True)
    forced = os.environ.get("HCONV_ENGINE", "auto")  # a run of the suite may make every auto numpy
    assert auto.engines == {"compiled" if forced == "auto" else forced: 400}
    named = pipeline.convert_file(str(root / src), dst, force=True, job=Job(engine="compiled"))
    assert named.engines == {"compiled": 400}
    eigen = pipeline.convert_file(str(root / src), dst, force=True, job=Job(method="eigen", engine="compiled"))
    assert eigen.engines == {"numpy": 400}


ROOT = Path(__file__).resolve().parents[1]
SCENE_CSV = ROOT / "examples" / "data" / "scene.csv"
#: pyarrow's null markers less its NaN spellings (hconv keeps NaN a float): the reference read
REFERENCE = pacsv.ConvertOptions(null_values=[v for v in pacsv.ConvertOptions().null_values if "nan" not in v.lower()])


def test_convert_file_csv_to_parquet_types_the_scene_columns(tmp_path):
    dst = tmp_path / "s.parquet"
    pipeline.convert_file(str(SCENE_CSV), str(dst))
    out = pq.read_table(dst)
    assert out.schema.field("id").type == pa.int64() and out.schema.field("body").type == pa.string()
    assert {out.schema.field(f"w_true_{c}").type for c in "xyz"} == {pa.float64()}
    ref = pacsv.read_csv(SCENE_CSV)  # an independent reference: pyarrow's own CSV reader
    for name in ("id", "body", "w_true_x", "w_true_y", "w_true_z"):
        assert out.column(name).equals(ref.column(name)), name
    scene = pq.read_table(ROOT / "examples" / "data" / "scene.parquet")  # the same scene, never text
    assert out.column("id").equals(scene.column("id")) and out.column("w_true_x").equals(scene.column("w_true_x"))


def test_convert_file_csv_to_parquet_keeps_a_column_of_null_markers_as_text(tmp_path):
    """Before: a column s of NA, null and blanks alone became ``s: null`` in Parquet, its text
    gone (kept into CSV, and into Parquet beside any other text)."""
    src, dst = tmp_path / "na.csv", tmp_path / "na.parquet"
    rows = [("NA", ""), ("null", ""), ("", "")]
    src.write_text("Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz,s,b\n" + "".join(f"1,2,3,1,2,3,0,0,0,{s},{b}\n" for s, b in rows))
    pipeline.convert_file(str(src), str(dst))
    out = pq.read_table(dst)
    assert out.schema.field("s").type == pa.string()
    assert out.column("s").to_pylist() == ["NA", "null", ""]
    assert out.schema.field("b").type == pa.null()  # blanks alone: no text to keep


def late_misfits(n: int = 1000) -> str:
    """A CSV whose first blocks say int, but whose later ones hold a float, a zip code, text in
    an empty column and a null marker."""
    lines = ["id,code,zip,note,count,Hx,Hy,Hz,I"]
    for k in range(n):
        code = "3.5" if k == 700 else str(k % 50)
        zipc = "02134" if k == 650 else str(10000 + k)
        note = "hello, world" if k == 800 else ""
        count = "n/a" if k == 500 else str(k)
        lines.append(f'{k},{code},{zipc},"{note}",{count},1,2,3,2')
    return "\n".join(lines) + "\n"


def check_late_misfits(out: pa.Table, src: Path, n: int = 1000) -> None:
    assert out.column("id").to_pylist() == list(range(n))  # every row, in order
    types = {f.name: f.type for f in out.schema}
    assert (types["code"], types["zip"], types["note"], types["count"]) == (
        pa.float64(),
        pa.string(),
        pa.string(),
        pa.int64(),
    )
    ref = pacsv.read_csv(src, convert_options=REFERENCE)
    for name in ("id", "code", "note", "count"):  # the types pyarrow infers from the whole file
        assert out.column(name).equals(ref.column(name)), name
    assert out.column("zip")[650].as_py() == "02134" and out.column("zip")[0].as_py() == "10000"  # pyarrow: 2134
    assert out.column("count")[500].as_py() is None


def test_convert_file_csv_to_parquet_later_block_that_does_not_fit_types_from_whole_file(tmp_path, monkeypatch):
    monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", 512)  # about 25 rows a block: the misfits come late
    src, dst = tmp_path / "in.csv", tmp_path / "out.parquet"
    src.write_text(late_misfits())
    text = pacsv.ConvertOptions(column_types={"code": pa.string()}, include_columns=["code"])
    first = csvtypes.infer(pacsv.read_csv(src, convert_options=text).slice(0, 25), ["code"])
    assert first == {"code": pa.int64()}  # the first block alone does say int
    tally = pipeline.convert_file(str(src), str(dst), threads=2)
    assert tally.rows == 1000
    check_late_misfits(pq.read_table(dst), src)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "out.parquet"]  # no temporary left


def test_convert_file_stdin_csv_to_parquet_types_from_whole_file(tmp_path, monkeypatch):
    monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", 512)
    src, dst = tmp_path / "in.csv", tmp_path / "out.parquet"
    src.write_text(late_misfits())
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(src.read_bytes())))
    pipeline.convert_file("-", str(dst), src_format="csv")
    check_late_misfits(pq.read_table(dst), src)


def test_convert_file_keep_text_keeps_csv_columns_as_text(tmp_path):
    dst = tmp_path / "s.parquet"
    pipeline.convert_file(str(SCENE_CSV), str(dst), job=Job(keep_text=True))
    out = pq.read_table(dst)
    names = ("id", "body", "w_true_x", "w_true_y", "w_true_z")
    assert {out.schema.field(c).type for c in names} == {pa.string()}
    text = pacsv.read_csv(
        SCENE_CSV, convert_options=pacsv.ConvertOptions(column_types=dict.fromkeys(names, pa.string()))
    )
    assert out.select(names).equals(text.select(names))


AWKWARD = [  # id, zip, price, sci, note, blank
    ("0001", "02134", "1.50", "1e3", '"a, b"', ""),
    ("0002", "10001", "2", "-2.5E-3", '"say ""hi"""', ""),
    ("0003", "90210", "NaN", "inf", "ünï ω≈1", ""),
    ("0004", "00501", "", "7", "", ""),
]


def test_convert_file_awkward_csv_exact_in_csv_typed_in_parquet(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text(
        "id,zip,price,sci,note,blank,Hx,Hy,Hz,I\n" + "".join(",".join(r) + ",1,2,3,2\n" for r in AWKWARD),
        encoding="utf-8",
    )
    pipeline.convert_file(str(src), str(tmp_path / "out.csv"))
    got = list(csv.reader(io.StringIO((tmp_path / "out.csv").read_text(encoding="utf-8"))))
    want = list(csv.reader(io.StringIO(src.read_text(encoding="utf-8"))))
    assert [r[:10] for r in got] == want  # CSV to CSV: every field as it went in
    pipeline.convert_file(str(src), str(tmp_path / "out.parquet"))
    out = pq.read_table(tmp_path / "out.parquet")
    types = {f.name: f.type for f in out.schema}
    assert [types[c] for c in ("id", "zip", "price", "sci", "note", "blank")] == [
        pa.string(),  # leading zeros: an identifier, not the number 1
        pa.string(),
        pa.float64(),
        pa.float64(),
        pa.string(),
        pa.null(),
    ]
    assert out.column("id").to_pylist() == [r[0] for r in AWKWARD]
    assert out.column("note").to_pylist() == [w[4] for w in want[1:]]
    price = out.column("price").to_pylist()
    assert price[:2] == [1.5, 2.0] and np.isnan(price[2]) and price[3] is None  # NaN stays NaN, blank is null
    assert out.column("sci").to_pylist() == [1000.0, -0.0025, float("inf"), 7.0]


def test_convert_file_parquet_in_keeps_its_types(tmp_path):
    src = tmp_path / "in.parquet"
    cols = make_scene(50, seed=2)
    t = pa.table(cols).append_column("label", pa.array(["007"] * 50)).append_column("n", pa.array(["1"] * 50))
    pq.write_table(t, src)
    for fmt in ("parquet", "csv"):
        pipeline.convert_file(str(src), str(tmp_path / f"out.{fmt}"))
    out = pq.read_table(tmp_path / "out.parquet")
    assert out.select(["id", "label", "n"]).equals(t.select(["id", "label", "n"]))  # strings stay strings
    back = list(csv.reader(io.StringIO((tmp_path / "out.csv").read_text())))
    assert {(r[back[0].index("label")], r[back[0].index("n")]) for r in back[1:]} == {("007", "1")}


def test_convert_file_errors_name_python_keywords_not_flags(tmp_path):
    from hconv.errors import OutputError, UsageError

    with pytest.raises(UsageError, match=r"pass src_format='csv' or src_format='parquet'$"):
        pipeline.convert_file("-", str(tmp_path / "out.parquet"))
    (tmp_path / "out.parquet").write_bytes(b"")
    with pytest.raises(OutputError, match=r"already exists; pass force=True to overwrite it$"):
        pipeline.convert_file(str(ROOT / "examples" / "data" / "scene.parquet"), str(tmp_path / "out.parquet"))


@pytest.mark.parametrize("bad_rows, verb", [(1, "is"), (2, "are")])
def test_convert_file_strict_names_the_rows_not_ok_in_a_sentence(bad_rows, verb, tmp_path):
    """`--strict` names the rows that are not ok; one row 'is' not ok (it said 'are')."""
    from hconv.errors import StrictError
    from hconv.tables.pipeline import convert_file

    rows = ["1,2,3,2"] + ["1,2,3,-2"] * bad_rows  # a negative moment: no mass distribution has it
    src = tmp_path / "in.csv"
    src.write_text("Hx,Hy,Hz,I\n" + "\n".join(rows) + "\n")
    with pytest.raises(StrictError) as raised:
        convert_file(str(src), str(tmp_path / "out.csv"), strict=True)
    named = ", ".join(f"row {k} (not_positive_definite)" for k in range(2, 2 + bad_rows))
    assert f"{named} {verb} not ok; nothing was written" in str(raised.value)
    assert not (tmp_path / "out.csv").exists()
