"""JSON lines in (hconv.tables.jsonio): files written by pandas, polars and DuckDB read as the
Parquet they came from; numbers whose type changes between blocks; bad lines named by number."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import hconv_inprocess, need, w_of

import hconv
from hconv.tables import jsonio
from hconv.tables.pipeline import convert_file

SCENE = Path(__file__).resolve().parents[1] / "examples" / "data" / "scene.parquet"


@pytest.mark.parametrize("writer", ["pandas", "polars", "duckdb"])
def test_open_jsonl_reads_as_the_parquet_it_came_from(writer, tmp_path):
    t = pq.read_table(SCENE)
    src = tmp_path / "scene.jsonl"
    if writer == "pandas":
        need("pandas")
        t.to_pandas().to_json(src, orient="records", lines=True, double_precision=15)
    elif writer == "polars":
        need("polars").from_arrow(t).write_ndjson(src)
    else:
        duckdb = need("duckdb")
        con = duckdb.connect()
        con.register("scene", t)
        con.sql(f"copy (select * from scene) to '{src}' (format json)")
    convert_file(str(src), str(tmp_path / "out.parquet"))
    got = pq.read_table(tmp_path / "out.parquet")
    assert got.column("id").to_pylist() == t.column("id").to_pylist()  # every row, in order
    # the reference: the same lines parsed by Python's json module (pandas writes 15 digits)
    rows = [json.loads(line) for line in src.read_text().splitlines() if line.strip()]
    ref = hconv.convert_table(pa.Table.from_pylist(rows))
    assert np.array_equal(w_of(got), w_of(ref), equal_nan=True)


def test_open_jsonl_integers_then_fractions_in_a_later_block(tmp_path, monkeypatch):
    """pyarrow types a column from the first block: Hx = 1 there and 1.5 later failed."""
    monkeypatch.setattr(jsonio, "JSON_BLOCK_BYTES", 1 << 10)
    rows = [{"id": k, "Hx": 2, "Hy": 0, "Hz": 0, "I": 2} for k in range(200)] + [
        {"id": 200, "Hx": 3.0, "Hy": 0.5, "Hz": 0, "I": 2}
    ]
    src = tmp_path / "log.ndjson"
    src.write_text("".join(json.dumps(r) + "\n" for r in rows))
    convert_file(str(src), str(tmp_path / "out.parquet"))
    got = pq.read_table(tmp_path / "out.parquet")
    assert got.num_rows == 201 and got.column("id").to_pylist() == list(range(201))
    assert got.schema.field("id").type == "int64"  # a column hconv does not read keeps its type
    assert w_of(got)[0].tolist() == [1.0, 0.0, 0.0] and w_of(got)[-1].tolist() == [1.5, 0.25, 0.0]


def test_open_jsonl_bad_line_is_quoted_short(tmp_path, capsys):
    """The bad line is quoted as CSV's values are (:func:`hconv.errors.quoted`), its end kept too."""
    src = tmp_path / "bad.jsonl"
    src.write_text('{"Hx": 1' + "x" * 5000 + "}\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and err.count("\n") == 1
    assert """: '{"Hx": 1""" + "x" * 18 + "…" + "x" * 12 + "}'; JSON lines" in err


@pytest.mark.parametrize(
    "text, says",
    [
        ('{"Hx":1,"Hy":0,"Hz":0,"I":1}\n{"Hx":1,"Hy":0,\n', r": line 2 is not valid JSON \(Expecting"),
        ('{"Hx":1,"Hy":0,"Hz":0,"I":1}\n\n[1, 2]\n', r": line 3 is a JSON list, not an object"),
        ('[{"Hx":1,"Hy":0,"Hz":0,"I":1}]\n', r": is one JSON array, not JSON lines .*jq -c"),
        ("", r": the file is empty"),
        (
            '{"Hx":1,"Hy":0,"Hz":0,"I":1}\n{"Hx":"a","Hy":0,"Hz":0,"I":1}\n',
            r": line 2: column 'Hx' holds text where line 1 holds a number; hconv reads it as numbers",
        ),
        (
            '{"Hx":1,"Hy":0,"Hz":0,"I":1,"tag":1}\n\n{"Hx":1,"Hy":0,"Hz":0,"I":1,"tag":"b"}\n',
            r": line 3: column 'tag' holds text where line 1 holds a number; .* jq -c 'del\(\.\[\"tag\"\]\)'",
        ),
    ],
)
def test_open_jsonl_bad_line_is_exit_3_naming_it(text, says, tmp_path, capsys):
    src = tmp_path / "bad.jsonl"
    src.write_text(text)
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"hconv: error: {src}")
    assert __import__("re").search(says, err), err
    assert not (tmp_path / "out.csv").exists()


def test_open_jsonl_key_first_seen_in_a_later_block_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(jsonio, "JSON_BLOCK_BYTES", 1 << 10)
    lines = ['{"Hx":1,"Hy":0,"Hz":0,"I":1}'] * 100 + ['{"Hx":1,"Hy":0,"Hz":0,"I":1,"note":"x"}']
    src = tmp_path / "late.jsonl"
    src.write_text("\n".join(lines) + "\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and f"{src}: line 101 has the key 'note'" in err, err


def test_open_jsonl_type_change_in_a_later_block_is_named_by_line(tmp_path, monkeypatch, capsys):
    """pyarrow counts rows from 0 within a block; the message names the file's line."""
    monkeypatch.setattr(jsonio, "JSON_BLOCK_BYTES", 1 << 10)
    lines = ['{"Hx":1,"Hy":0,"Hz":0,"I":1,"tag":7}'] * 100 + ['{"Hx":1,"Hy":0,"Hz":0,"I":1,"tag":"x"}']
    src = tmp_path / "late.jsonl"
    src.write_text("\n".join(lines) + "\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and len(err.strip().splitlines()) == 1, err
    assert f"{src}: line 101: column 'tag' holds text where line 1 holds a number" in err, err
    assert not (tmp_path / "out.csv").exists()
