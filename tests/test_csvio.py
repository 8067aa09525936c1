"""CSV in and out (hconv.tables.csvio)."""

from __future__ import annotations

import csv
import io

import pytest
from helpers import run_inprocess


def _wheels(tmp_path, text: str, name: str = "in.csv"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_convert_file_units_row_gives_the_columns_units_and_keeps_them_in_parquet(tmp_path):
    """Before: the row of units was read as data, and refused as text in a numeric column."""
    import pyarrow.parquet as pq

    from hconv.tables.pipeline import convert_file

    src = _wheels(
        tmp_path,
        "id,Hx,Hy,Hz,I1,I2,I3\nunit,kg*m^2/s,kg*m^2/s,g*cm^2/s,g*cm^2,g*cm^2,g*cm^2\n7,1,2,3e7,2e7,4e7,6e7\n8,1,1,1e7,1e7,1e7,1e7\n",
    )
    tally = convert_file(src, str(tmp_path / "out.parquet"))
    assert tally.rows == 2 and "units from the row under the header" in tally.read_as
    t = pq.read_table(tmp_path / "out.parquet")
    assert t.column("id").to_pylist() == [7, 8]  # the units row is no data row; the rows keep their order
    assert t.schema.field("I1").metadata == {b"unit": b"g*cm^2"}
    # H = (1, 2, 3) kg·m²/s over I = (2, 4, 6) kg·m² (1 g·cm² = 1e-7 kg·m²), and then all ones
    assert t.column("wx").to_pylist() == [0.5, 1.0] and t.column("wz").to_pylist() == [0.5, 1.0]


def test_convert_file_units_row_comes_out_under_the_header_and_reads_back(tmp_path):
    """Before: CSV into CSV dropped the row of units, so that the output's H and I read back as SI
    (g*cm^2 taken for kg*m^2) and ω's unit was in w_unit only. Now the input's row comes out as
    it was, with ω's unit and 1 for the ratios under hconv's columns, and hconv reads it back."""
    import pyarrow.parquet as pq

    from hconv.tables.pipeline import convert_file

    src = _wheels(
        tmp_path,
        "id,Hx,Hy,Hz,I1,I2,I3\nunit,kg*m^2/s,kg*m^2/s,g*cm^2/s,g*cm^2,g*cm^2,g*cm^2\n7,1,2,3e7,2e7,4e7,6e7\n8,1,1,1e7,1e7,1e7,1e7\n",
    )
    convert_file(src, str(tmp_path / "out.csv"))
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert lines[0] == "id,Hx,Hy,Hz,I1,I2,I3,wx,wy,wz,residual,cond,status,w_unit"
    assert lines[1] == "unit,kg*m^2/s,kg*m^2/s,g*cm^2/s,g*cm^2,g*cm^2,g*cm^2,rad/s,rad/s,rad/s,1,1,,"
    assert [ln.split(",")[0] for ln in lines[2:]] == ["7", "8"]
    tally = convert_file(str(tmp_path / "out.csv"), str(tmp_path / "again.parquet"), prefix="again_")
    assert tally.rows == 2 and "units from the row under the header" in tally.read_as
    t = pq.read_table(tmp_path / "again.parquet")
    # H = (1, 2, 3) kg·m²/s over I = (2, 4, 6) kg·m², then all ones: read back in the same units
    assert t.column("again_wx").to_pylist() == [0.5, 1.0] and t.column("again_wz").to_pylist() == [0.5, 1.0]
    assert t.schema.field("I1").metadata == {b"unit": b"g*cm^2"}
    convert_file(src, str(tmp_path / "out.parquet"))  # into Parquet, the units stay field metadata
    assert pq.read_table(tmp_path / "out.parquet").column("id").to_pylist() == [7, 8]


def test_convert_file_units_row_then_bad_rows_are_named_by_data_row(tmp_path):
    """Rows are counted from the first data row: comment lines and the units row are not rows."""
    import pytest

    from hconv.errors import InputError
    from hconv.tables.pipeline import convert_file

    head = "# a logger\nHx;Hy;Hz;I1;I2;I3\nkg*m^2/s;kg*m^2/s;kg*m^2/s;kg*m^2;kg*m^2;kg*m^2\n1,5;2;3;1;1;1\n"
    src = _wheels(tmp_path, head + "1;two;3;1;1;1\n")
    with pytest.raises(InputError, match=r"column 'Hy' must be numeric but holds 'two' in data row 2"):
        convert_file(src, str(tmp_path / "out.csv"))
    src = _wheels(tmp_path, head + "1;2;3;1;1\n")
    with pytest.raises(InputError, match=r"data row 2 has 5 values, but the header names 6 columns.*semicolon\)"):
        convert_file(src, str(tmp_path / "out.csv"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


def test_convert_file_progress_counts_bytes_of_the_rows_converted(tmp_path, monkeypatch):
    """Before: pyarrow reads up to 16 blocks ahead, so the file's position, the progress, was
    near its end at the first batch (100 % while still converting), and the bar had no size
    until then. Now: the size first, then each batch's end, the file's end last."""
    from hconv.tables import csvio
    from hconv.tables.pipeline import convert_file

    block = 4096
    monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", block)
    lines = ["Hx,Hy,Hz,I1,I2,I3"] + [f"{k},{k + 1},{k + 2},1,2,4" for k in range(3000)]
    src = _wheels(tmp_path, "\n".join(lines) + "\n")
    size = (tmp_path / "in.csv").stat().st_size
    calls = []
    convert_file(src, str(tmp_path / "out.csv"), threads=2, progress=lambda done, total: calls.append((done, total)))
    done = [d for d, _ in calls]
    assert {t for _, t in calls} == {size} and done[0] == 0 and done[-1] == size
    assert all(d < size for d in done[:-1])  # 100 % only once the last row is converted
    assert len(calls) == 1 + -(-size // block)  # the size, then one call per block of the file
    # the k-th batch is the k-th block: it reports k blocks in, never the reader's read-ahead
    assert done[1:-1] == [block * k for k in range(1, len(calls) - 1)]


def test_convert_delimiter_comma_on_a_semicolon_file_names_the_semicolon(tmp_path, capsys):
    """Before: --delimiter , on an Excel-style file ('0,5' values) said a row has more values than
    the header and to quote a value holding a comma; the header is split by ';' instead."""
    from helpers import hconv_inprocess

    src = tmp_path / "excel.csv"
    src.write_text("Hx;Hy;Hz;I\n0,5;2,1;3;2\n4;5;6;2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--delimiter", ",", capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3
    assert len(err.strip().splitlines()) == 1
    assert "separated by semicolons, not commas: pass --delimiter semicolon or drop --delimiter" in err
    assert "quote a value" not in err
    assert not (tmp_path / "o.csv").exists()


def test_convert_decimal_point_on_a_decimal_comma_value_names_decimal_comma(tmp_path, capsys):
    """Before: --decimal . on a decimal-comma file said to fix or blank '0,5'; it is a number,
    read with --decimal , (or without --decimal, which sniffs the comma)."""
    from helpers import hconv_inprocess

    src = tmp_path / "dec.csv"
    src.write_text("Hx;Hy;Hz;I\n1;2;3;2\n0,5;2;3;2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--decimal", ".", capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3
    assert len(err.strip().splitlines()) == 1
    assert "'0,5' in data row 2" in err
    assert "pass --decimal , or drop --decimal" in err
    # the advice works: without --decimal the file is read, 0,5 as 0.5
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "-q", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o.csv").read_text().splitlines()[2].startswith("0.5,")


def test_convert_non_number_keeps_fix_or_blank_advice(tmp_path, capsys):
    """A value that is no number at all, not one with a decimal comma, keeps its advice."""
    from helpers import hconv_inprocess

    src = tmp_path / "bad.csv"
    src.write_text("Hx;Hy;Hz;I\n1;2;3;2\nabc;2;3;2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "o.csv"), "--decimal", ".", capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3
    assert "fix or blank that value" in err and "--decimal ," not in err


def test_convert_file_units_row_gives_every_column_its_unit_in_parquet_and_arrow(tmp_path):
    """Before (issue 26): into Parquet or Arrow, only the columns hconv reads kept the unit the
    row of units gave them; t, mass, temp and a previous run's wx lost theirs (mass and temp
    also when typed as integers). Now each column's field metadata ``unit`` says what the row
    said, and CSV written from that output reads back to the same ω."""
    import numpy as np
    import pyarrow.ipc as ipc
    import pyarrow.parquet as pq

    from hconv.tables.pipeline import convert_file

    rng = np.random.default_rng(3)
    a = rng.normal(size=(2, 3, 3))
    I_si = 0.1 * a @ a.transpose(0, 2, 1) + 3 * np.eye(3)  # symmetric, positive definite, physical
    H_written = rng.normal(size=(2, 3)) * 1e7  # in g*cm**2/s, 1e-7 kg*m**2/s
    w_si = np.linalg.solve(I_si, (H_written * 1e-7)[:, :, None])[:, :, 0]
    lines = ["t,mass,temp,wx,Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz", "s,g,degC,deg/s," + ",".join(["g*cm**2/s"] * 3)]
    lines[1] += ",kg*m**2" * 6
    for k in range(2):
        I6 = [I_si[k, 0, 0], I_si[k, 1, 1], I_si[k, 2, 2], I_si[k, 0, 1], I_si[k, 0, 2], I_si[k, 1, 2]]
        lines.append(f"{k}.5,{3 + k},{20 + k},57.3," + ",".join(repr(float(v)) for v in [*H_written[k], *I6]))
    src = _wheels(tmp_path, "\n".join(lines) + "\n")
    convert_file(src, str(tmp_path / "out.parquet"), prefix="a_")
    convert_file(src, str(tmp_path / "out.arrow"), prefix="a_")
    want = {"t": "s", "mass": "g", "temp": "degC", "wx": "deg/s", "Hx": "g*cm**2/s", "Iyz": "kg*m**2", "a_wx": "rad/s"}
    for schema in (pq.read_schema(tmp_path / "out.parquet"), ipc.open_file(tmp_path / "out.arrow").schema):
        assert str(schema.field("mass").type) == "int64"  # typed, its unit kept
        assert {c: schema.field(c).metadata[b"unit"].decode() for c in want} == want
    convert_file(str(tmp_path / "out.arrow"), str(tmp_path / "back.csv"), prefix="b_")
    rows = [r.split(",") for r in (tmp_path / "back.csv").read_text().splitlines()]
    assert rows[1][:5] == ["s", "g", "degC", "deg/s", "g*cm**2/s"]
    convert_file(str(tmp_path / "back.csv"), str(tmp_path / "again.parquet"), prefix="c_")
    t = pq.read_table(tmp_path / "again.parquet")
    w_back = np.column_stack([t.column(c).to_numpy() for c in ("c_wx", "c_wy", "c_wz")])
    np.testing.assert_allclose(w_back, w_si, rtol=1e-12)
    assert t.schema.field("wx").metadata == {b"unit": b"deg/s"}  # the previous run's ω, still in deg/s


def test_convert_long_bad_value_is_quoted_short(tmp_path, capsys):
    """Before: a value of 5,000 characters was quoted whole in the "must be numeric" line."""
    from helpers import hconv_inprocess

    src = tmp_path / "long.csv"
    value = "9" * 10 + "x" * 4990
    src.write_text(f"Hx,Hy,Hz,I1,I2,I3\n1,2,3,1,1,{value}\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and err.count("\n") == 1
    assert f"column 'I3' must be numeric but holds '{'9' * 10}{'x' * 16}…{'x' * 13}' in data row 1; " in err
    assert len(err) - len(str(src)) < 200


def test_convert_row_against_a_header_of_one_column_says_column(tmp_path, capsys):
    """Before: "the header names 1 columns"."""
    from helpers import hconv_inprocess

    src = tmp_path / "q.csv"
    src.write_text("Hx\n1,2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert proc.returncode == 3
    assert ": data row 1 has 2 values, but the header names 1 column; every row needs" in proc.stderr.decode()


@pytest.mark.parametrize("marker", ["NA", "null", "#N/A", "n/a"])
def test_convert_file_first_row_of_null_markers_is_data_not_units(marker, tmp_path, capsys):
    """Before (second trial): a first data row of NA (null, #N/A, n/a …) was read as a row of
    units, and pint could not read 'NA': exit 3, 'or remove that row if it is data'. It is a row
    with missing values (invalid_input), as the same row further down is."""
    src = tmp_path / "na.csv"
    src.write_text(f"Hx,Hy,Hz,I\n{marker},{marker},{marker},{marker}\n1,2,3,2\n")
    code, out, err = run_inprocess("convert", str(src), "-", "--to", "csv", "-q", capsys=capsys)
    assert code == 0, err
    rows = list(csv.DictReader(io.StringIO(out)))
    assert [r["status"] for r in rows] == ["invalid_input", "ok"]
    assert [float(rows[1][c]) for c in ("wx", "wy", "wz")] == [0.5, 1.0, 1.5]


def test_csv_value_error_of_a_reader_on_one_thread_names_column_value_and_row(tmp_path):
    """pyarrow's reader on one thread (a cluster's part of a file) says "Row #3: " before the
    conversion error; that message came out raw, 'not a readable CSV file (In CSV column #1:
    Row #3: …)', where other runs named the column, the value and its data row (second trial)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from hconv.tables import csvio
    from hconv.tables.sniff import Dialect

    path = tmp_path / "bad.csv"
    path.write_text("Hx,Hy,Hz,I\n1,2,3,2\n1,x,3,2\n")
    opts = pacsv.ConvertOptions(column_types={c: pa.float64() for c in ("Hx", "Hy", "Hz", "I")})
    with pytest.raises(pa.ArrowInvalid, match="Row #3") as raised:
        pacsv.read_csv(path, read_options=pacsv.ReadOptions(use_threads=False), convert_options=opts)
    err = csvio._csv_value_error(str(path), "bad.csv", ["Hx", "Hy", "Hz", "I"], Dialect(), raised.value)
    assert str(err) == (
        "bad.csv: column 'Hy' must be numeric but holds 'x' in data row 2; "
        "fix or blank that value (a blank becomes a row with status invalid_input)"
    )


def test_csv_parse_error_line_break_in_quotes_at_a_block_edge_is_named_with_its_fix(tmp_path):
    """A value in quotes holding a line break where pyarrow's reader splits the file into blocks
    gave pyarrow's 'CSV parser got out of sync with chunker … newlines_in_values', an option no
    hconv user can set (met converting a 300k-row CSV whose label column held line breaks; the
    same file read fine in other sizes, as it depends on where a block ends)."""
    import pyarrow as pa

    from hconv.tables import csvio
    from hconv.tables.sniff import Dialect

    path = tmp_path / "breaks.csv"
    path.write_text('Hx,Hy,Hz,I,label\n1,2,3,2,"arm\nleft"\n')
    exc = pa.ArrowInvalid(
        "CSV parser got out of sync with chunker. This can mean the data file contains cell values spanning "
        "multiple lines; please consider enabling the option 'newlines_in_values'."
    )
    assert str(csvio._csv_parse_error(str(path), "breaks.csv", exc, Dialect())) == (
        "breaks.csv: a value in quotes holds a line break, which hconv does not read in CSV; "
        "remove the line breaks from that column, or convert the file from Parquet"
    )
