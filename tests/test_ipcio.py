"""Arrow IPC in and out (hconv.tables.ipcio): files and streams written by pyarrow, Feather,
polars and DuckDB read as the Parquet they came from; damaged files named; hconv's own Arrow
output read back by polars and pandas (DuckDB reads Arrow IPC files only through an extension it
downloads)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.feather as feather
import pyarrow.ipc as ipc
import pyarrow.parquet as pq
import pytest
from helpers import hconv_inprocess, need, w_of

from hconv.errors import InputError
from hconv.tables import ipcio
from hconv.tables.pipeline import convert_file

SCENE = Path(__file__).resolve().parents[1] / "examples" / "data" / "scene.parquet"


def _reference(tmp_path) -> pa.Table:
    convert_file(str(SCENE), str(tmp_path / "ref.parquet"))
    return pq.read_table(tmp_path / "ref.parquet")


def _write(kind: str, path: Path, t: pa.Table) -> None:
    if kind == "feather-lz4":
        feather.write_feather(t, path)  # Feather v2, lz4-compressed by default
    elif kind == "file-small-batches":
        with ipc.new_file(path, t.schema) as w:
            for b in t.to_batches(max_chunksize=37):
                w.write_batch(b)
    elif kind == "stream":
        with ipc.new_stream(path, t.schema) as w:
            w.write_table(t)
    elif kind == "polars":
        need("polars").from_arrow(t).write_ipc(path)
    elif kind == "duckdb":
        duckdb = need("duckdb")
        con = duckdb.connect()
        con.register("scene", t)
        with ipc.new_file(path, t.schema) as w:
            w.write_table(con.sql("select * from scene").to_arrow_table().cast(t.schema))


@pytest.mark.parametrize("kind", ["feather-lz4", "file-small-batches", "stream", "polars", "duckdb"])
def test_open_ipc_reads_as_the_parquet_it_came_from(kind, tmp_path):
    t = pq.read_table(SCENE)
    src = tmp_path / "scene.arrow"
    _write(kind, src, t)
    convert_file(str(src), str(tmp_path / "out.parquet"))
    got, ref = pq.read_table(tmp_path / "out.parquet"), _reference(tmp_path)
    assert got.num_rows == t.num_rows == 400
    assert np.array_equal(w_of(got), w_of(ref), equal_nan=True)  # bit for bit
    assert got.column("status").to_pylist() == ref.column("status").to_pylist()
    assert got.column("id").to_pylist() == t.column("id").to_pylist()  # every row, in order


def test_open_ipc_cuts_one_huge_batch(tmp_path, monkeypatch):
    monkeypatch.setattr(ipcio, "IPC_BATCH_ROWS", 64)
    t = pq.read_table(SCENE)
    feather.write_feather(t, tmp_path / "s.feather", chunksize=1000)  # one batch of 400 rows
    with ipcio.open_ipc(str(tmp_path / "s.feather"), "s.feather", __import__("hconv").Job()) as inp:
        sizes = [b.num_rows for b in inp.batches]
        assert inp.total == 400
    assert sizes == [64] * 6 + [16]


@pytest.mark.parametrize(
    "kind, cut, says",
    [
        # the file format's footer lost: named as truncated, not as "not an Arrow file"
        ("file-small-batches", 3000, "the Arrow IPC file is truncated: it starts with ARROW1 but does not end with it"),
        ("feather-lz4", -8, "the Arrow IPC file is truncated: it starts with ARROW1 but does not end with it"),
        ("stream", 30000, "record batch 1 (from data row 1) cannot be read"),
        ("stream", 100, "completely written"),
    ],
)
def test_open_ipc_truncated_is_exit_3_naming_the_file(kind, cut, says, tmp_path, capsys):
    t = pq.read_table(SCENE)
    whole = tmp_path / "whole.arrow"
    _write(kind, whole, t)
    bad = tmp_path / "bad.arrow"
    bad.write_bytes(whole.read_bytes()[:cut])
    proc = hconv_inprocess("convert", str(bad), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"hconv: error: {bad}: ") and "Traceback" not in err
    assert says in err, err
    assert not (tmp_path / "out.csv").exists()


def test_open_ipc_stream_cut_in_a_later_batch_names_its_first_row(tmp_path, capsys):
    """Batches of 37 rows, the stream cut inside the third: its first data row is 2 * 37 + 1,
    counted from 1 as a Parquet row group's rows are."""
    t = pq.read_table(SCENE)
    sink = pa.BufferOutputStream()
    ends = []  # the stream's length after each batch
    with ipc.new_stream(sink, t.schema) as w:
        for b in t.to_batches(max_chunksize=37):
            w.write_batch(b)
            ends.append(sink.tell())
    bad = tmp_path / "bad.arrow"
    bad.write_bytes(sink.getvalue().to_pybytes()[: (ends[1] + ends[2]) // 2])
    proc = hconv_inprocess("convert", str(bad), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and f"{bad}: record batch 3 (from data row 75) cannot be read" in err, err
    assert not (tmp_path / "out.csv").exists()


def test_open_ipc_parquet_named_arrow_says_what_it_is(tmp_path):
    src = tmp_path / "s.arrow"
    src.write_bytes(SCENE.read_bytes())
    with pytest.raises(InputError, match=r"s.arrow: is a Parquet file, not Arrow IPC \(Feather\); .*s.parquet"):
        ipcio.open_ipc(str(src), str(src), __import__("hconv").Job())


@pytest.mark.parametrize("reader", ["pyarrow", "polars", "pandas"])
def test_write_arrow_file_is_read_back_by_other_libraries(reader, tmp_path, capsys):
    out = tmp_path / "out.arrow"
    proc = hconv_inprocess("convert", str(SCENE), str(out), "-q", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:6] == b"ARROW1"  # the file format, for a file
    ref = _reference(tmp_path)
    if reader == "pyarrow":
        got = feather.read_table(out)
        assert got.schema.field("wx").metadata[b"unit"] == b"rad/s"
        assert got.column("status").to_pylist() == ref.column("status").to_pylist()
    elif reader == "polars":
        got = need("polars").read_ipc(out).to_arrow()
    else:
        got = pa.table(need("pandas").read_feather(out)[["wx", "wy", "wz"]])
    assert np.array_equal(w_of(got), w_of(ref), equal_nan=True)


def test_write_arrow_to_stdout_is_a_stream(tmp_path, monkeypatch):
    import io
    import sys

    class Stdout:  # not a terminal, not a pipe: the stream is copied whole on success
        buffer = io.BytesIO()

        def isatty(self):
            return False

        def fileno(self):
            raise io.UnsupportedOperation("fileno")

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", Stdout())
    convert_file(str(SCENE), "-", dst_format="arrow")
    got = ipc.open_stream(pa.BufferReader(Stdout.buffer.getvalue())).read_all()
    assert np.array_equal(w_of(got), w_of(_reference(tmp_path)), equal_nan=True)
