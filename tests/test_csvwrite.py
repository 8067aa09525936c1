"""CSV out (hconv.tables.csvwrite)."""

from __future__ import annotations

import csv
import io


def test_csv_writer_csv_to_csv_text_columns_come_out_byte_for_byte(tmp_path):
    """Before: one value needing quotes made every text value of its batch quoted (1 -> "1",
    02134 -> "02134"), though docs/input.md promises them back exactly as they went in."""
    from hconv.tables.pipeline import convert_file

    rows = ['1,02134,plain text,"a,b",,"say ""hi""",007', '2,00501,x y,z,,"line\nbreak",1e3']
    text = "id,zip,label,note,empty,quote,code,Hx,Hy,Hz,I1,I2,I3\n" + "".join(r + ",1,2,3,1,2,4\n" for r in rows)
    (tmp_path / "in.csv").write_text(text)
    convert_file(str(tmp_path / "in.csv"), str(tmp_path / "out.csv"))
    out = (tmp_path / "out.csv").read_text()
    assert out.startswith("id,zip,label,note,empty,quote,code,Hx,")
    body = out.split("\n", 1)[1]
    assert body.startswith(rows[0] + ",1,2,3,1,2,4,")
    assert "\n" + rows[1] + ",1,2,3,1,2,4," in body


def test_csv_writer_tsv_quotes_tabs_not_commas(tmp_path):
    import pyarrow as pa

    from hconv.tables.csvwrite import CsvWriter

    t = pa.table({"a": ["x,y", "p\tq", 'say "hi"'], "b": [1.5, 2.0, 0.1]})
    w = CsvWriter(str(tmp_path / "out.tsv"), t.schema, "\t")
    w.write(t)
    w.close()
    assert (tmp_path / "out.tsv").read_text() == 'a\tb\nx,y\t1.5\n"p\tq"\t2\n"say ""hi"""\t0.1\n'


def test_csv_writer_slices_write_the_bytes_of_the_whole_table(tmp_path, monkeypatch):
    """A table whose text holds a stand-in byte has its rows joined a slice at a time: the bytes
    are those of the whole table joined at once (a column's nulls beside empty strings are decided
    on the whole table, though a slice may hold only one of them), and every value comes back as
    it was."""
    import numpy as np
    import pyarrow as pa

    from hconv.tables import csvwrite

    n = 3 * csvwrite._QUOTED_ROWS
    rng = np.random.default_rng(1)
    words = np.array(["", "a", "b,c", 'say "hi"', "x\ny", "007", "bell\x01"], dtype=object)
    text = words[rng.integers(0, len(words), n)]
    text[: n // 2][text[: n // 2] == ""] = None  # nulls in the first half only, empty strings in the second
    t = pa.table({"t": pa.array(text, pa.string()), "x": rng.normal(size=n), "d": pa.array(["p"] * n)})
    written = {}
    for rows in (csvwrite._QUOTED_ROWS, 10 * n):
        monkeypatch.setattr(csvwrite, "_QUOTED_ROWS", rows)
        w = csvwrite.CsvWriter(str(tmp_path / f"{rows}.csv"), t.schema)
        w.write(t)
        w.close()
        written[rows] = (tmp_path / f"{rows}.csv").read_bytes()
    assert written[10 * n] == written[csvwrite._QUOTED_ROWS]
    rows = list(csv.reader(io.StringIO(written[10 * n].decode(), newline="")))
    assert [r[0] for r in rows[1:]] == ["" if v is None else v for v in text]  # every value back as it was
    assert b'\n"",' in written[10 * n] and b"\n," in written[10 * n]  # "" an empty string, nothing a null


def test_csv_writer_a_value_pyarrow_refuses_unquoted_takes_its_rows_back(tmp_path, monkeypatch):
    """pyarrow's writer writes a table's rows straight into the file, 1024 at a time, and refuses
    a value that needs quotes only when it gets there: the rows it wrote are taken back, and the
    table written with quotes, as if it had been seen first."""
    import pyarrow as pa

    from hconv.tables import csvwrite

    t = pa.table({"t": ["a"] * 5000 + ["b,c"], "x": [0.5] * 5001})
    expected = "t,x\n" + "a,0.5\n" * 5000 + '"b,c",0.5\n'
    scan = csvwrite._scan
    for seen in (True, False):
        monkeypatch.setattr(csvwrite, "_scan", lambda t, d, seen=seen, scan=scan: scan(t, d) if seen else ({}, False))
        w = csvwrite.CsvWriter(str(tmp_path / "out.csv"), t.schema)
        w.write(t.slice(0, 10))
        w.write(t)
        w.close()
        assert (tmp_path / "out.csv").read_text() == "t,x\n" + "a,0.5\n" * 10 + expected[4:]


def _written(tmp_path, t, delimiter: str = ",", name: str = "out.csv") -> bytes:
    from hconv.tables.csvwrite import CsvWriter

    w = CsvWriter(str(tmp_path / name), t.schema, delimiter)
    w.write(t)
    w.close()
    return (tmp_path / name).read_bytes()


def test_csv_writer_quoted_values_are_the_bytes_of_rows_joined_one_by_one(tmp_path):
    """Values that need quotes go through pyarrow's writer quoted already, with stand-in bytes put
    back after: the bytes are those of the rows joined value by value (the writer's other path,
    :func:`_csv_rows`), for every kind of column and both delimiters, one value in 100 or every
    value needing quotes, and Python's csv module reads every value back."""
    import datetime

    import numpy as np
    import pyarrow as pa

    from hconv.tables import csvwrite

    rng = np.random.default_rng(7)
    n = 3000
    for delimiter in (",", "\t"):
        for every in (100, 1):
            words = np.array([f"id-{k}" for k in range(n)], dtype=object)
            tricky = ["a,b", 'say "hi"', "x\ny", "cr\r\nlf", "tab\there", "", "ünï, ok", '"']
            at = np.arange(0, n, every)
            words[at] = [tricky[k % len(tricky)] for k in range(len(at))]
            words[rng.integers(0, n, 50)] = None  # nulls beside empty texts: those are quoted
            t = pa.table(
                {
                    "text": pa.array(words, pa.string()),
                    "x": pa.array(np.where(rng.random(n) < 0.1, np.nan, rng.normal(size=n) * 1e5)),
                    "k": pa.array(rng.integers(-(10**12), 10**12, n)),
                    "ok": pa.array(rng.random(n) < 0.5),
                    "label": pa.array(["p,q" if k % 7 == 0 else "p" for k in range(n)]).dictionary_encode(),
                    "when": pa.array([datetime.datetime(2026, 1, 1) + datetime.timedelta(seconds=k) for k in range(n)]),
                    "big": pa.array(words, pa.large_string()),
                }
            )
            out = _written(tmp_path, t, delimiter)
            header, body = out.split(b"\n", 1)
            joined = csvwrite._csv_rows(
                pa.Table.from_arrays(
                    [t[c].cast(pa.string()) if c == "label" else t[c] for c in t.column_names], names=t.column_names
                ),
                delimiter,
                frozenset(k for k, c in enumerate(t.columns) if c.null_count),
            )
            assert body == joined.to_pybytes()
            rows = list(csv.reader(io.StringIO(out.decode(), newline=""), delimiter=delimiter))
            assert [r[0] for r in rows[1:]] == ["" if v is None else v for v in words]


def test_csv_writer_text_holding_a_stand_in_byte_comes_back_as_it_was(tmp_path):
    """A text that holds one of the stand-in bytes itself is written by joining the rows, so that
    putting the stand-ins back does not change it."""
    import pyarrow as pa

    t = pa.table({"a": ["x\x01y", "b,c", 'q"\x02'], "b": [1.5, 2.0, 0.1]})
    assert _written(tmp_path, t) == b'a,b\nx\x01y,1.5\n"b,c",2\n"q""\x02",0.1\n'


def test_csv_writer_quoted_rows_longer_than_the_buffer_grow_it(tmp_path, monkeypatch):
    """The buffer quoted rows are formatted in is sized from the table's bytes; booleans take 1 bit
    there and up to 6 bytes as text: the buffer grows, and every row is written once."""
    import pyarrow as pa

    from hconv.tables import csvwrite

    sizes = []
    allocate = pa.allocate_buffer
    monkeypatch.setattr(pa, "allocate_buffer", lambda size: sizes.append(size) or allocate(size))
    n = 100_000
    flags = {f"b{j}": [(k + j) % 3 == 0 for k in range(n)] for j in range(8)}
    t = pa.table(flags | {"t": ['a,"b"' if k % 1000 == 0 else "a" for k in range(n)]})
    out = _written(tmp_path, t).decode()
    assert len(sizes) > 1  # grown
    rows = [",".join("true" if (k + j) % 3 == 0 else "false" for j in range(8)) for k in range(n)]
    text = ['"a,""b"""' if k % 1000 == 0 else "a" for k in range(n)]
    assert out == ",".join(t.column_names) + "\n" + "".join(f"{r},{v}\n" for r, v in zip(rows, text))
    assert n > csvwrite._SLICE_ROWS  # and in two slices


#: 1 g·cm²/s in kg·m²/s: the unit the bodies' H is written in below
G_CM2 = 1e-7


def _bodies_csv(path, units: str | None) -> tuple:
    """A CSV of three bodies with columns hconv passes through (t, mass, temp) and H written in
    g*cm**2/s; ``units``: the row of units under its header, or None for none. Returns its path
    and ω as numpy solves it from the SI values."""
    import numpy as np

    rng = np.random.default_rng(26)
    a = rng.normal(size=(3, 3, 3))
    I_si = 0.1 * a @ a.transpose(0, 2, 1) + 3 * np.eye(3)  # symmetric, positive definite, physical
    H_written = rng.normal(size=(3, 3)) * 1e7
    w_si = np.linalg.solve(I_si, (H_written * G_CM2)[:, :, None])[:, :, 0]
    lines = ["t,mass,temp,Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz"] + ([units] if units is not None else [])
    for k in range(3):
        I6 = [I_si[k, 0, 0], I_si[k, 1, 1], I_si[k, 2, 2], I_si[k, 0, 1], I_si[k, 0, 2], I_si[k, 1, 2]]
        lines.append(",".join([f"{k * 0.5}", f"{3 + k}", f"{20 + k}"] + [repr(float(v)) for v in [*H_written[k], *I6]]))
    path.write_text("\n".join(lines) + "\n")
    return str(path), w_si


UNITS = "s,g,degC,g*cm**2/s,g*cm**2/s,g*cm**2/s,kg*m**2,kg*m**2,kg*m**2,kg*m**2,kg*m**2,kg*m**2"


def _w_read_back(src, tmp_path, prefix: str):
    """ω as hconv reads ``src`` back (into Parquet, with ``prefix`` for its new columns)."""
    import numpy as np
    import pyarrow.parquet as pq

    from hconv.tables.pipeline import convert_file

    convert_file(str(src), str(tmp_path / f"{prefix}back.parquet"), prefix=prefix)
    t = pq.read_table(tmp_path / f"{prefix}back.parquet")
    return np.column_stack([t.column(prefix + c).to_numpy() for c in ("wx", "wy", "wz")])


def test_convert_file_parquet_into_csv_writes_a_units_row_that_reads_back(tmp_path):
    """Before (issue 26): Parquet into CSV wrote no row of units, so H stored in g*cm**2/s (the
    Parquet's field metadata) was written as bare numbers and read back as kg*m**2/s: ω 1e7 too
    large. Now the output's row of units says what each column's field metadata said."""
    import numpy as np

    from hconv.tables.pipeline import convert_file

    src, w_si = _bodies_csv(tmp_path / "u2.csv", UNITS)
    convert_file(src, str(tmp_path / "u2.parquet"))
    convert_file(str(tmp_path / "u2.parquet"), str(tmp_path / "u2p.csv"), prefix="a_")
    rows = list(csv.reader(io.StringIO((tmp_path / "u2p.csv").read_text())))
    units = dict(zip(rows[0], rows[1], strict=True))
    assert [units[c] for c in ("t", "mass", "temp", "Hx", "Ixx", "wx", "a_wx", "a_residual", "a_status")] == [
        "s", "g", "degC", "g*cm**2/s", "kg*m**2", "rad/s", "rad/s", "1", ""
    ]  # fmt: skip
    assert [r[0] for r in rows[2:]] == ["0", "0.5", "1"]  # every row, in order, after it (t is float64)
    np.testing.assert_allclose(_w_read_back(tmp_path / "u2p.csv", tmp_path, "b_"), w_si, rtol=1e-12)


def test_convert_file_parquet_without_units_into_csv_writes_no_units_row(tmp_path):
    """An input that carries no unit anywhere gives CSV without a row of units, as before."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from hconv.tables.pipeline import convert_file

    pq.write_table(pa.table({"id": [1], "Hx": [1.0], "Hy": [2.0], "Hz": [3.0], "I": [2.0]}), tmp_path / "in.parquet")
    convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "out.csv"))
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert lines[1:] == ["1,1,2,3,2,0.5,1,1.5,0,1,ok,rad/s"]


def test_convert_unit_option_over_a_units_row_writes_the_unit_read_in(tmp_path, capsys):
    """Before (issue 26): --unit beat the row of units, but the output's row still named the old
    unit under Hx..Hz, so hconv read its own output back in another unit than it had converted
    it in. Now the row names the unit each column was read in; the others' texts stay as written."""
    import numpy as np
    from helpers import hconv_inprocess

    src, w_si = _bodies_csv(tmp_path / "u2.csv", UNITS)
    out = tmp_path / "u2o.csv"
    proc = hconv_inprocess("convert", src, str(out), "--unit", "H=kg*m**2/s", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.reader(io.StringIO(out.read_text())))
    assert rows[1] == UNITS.replace("g*cm**2/s", "kg*m**2/s").split(",") + ["rad/s"] * 3 + ["1", "1", "", ""]
    w_given = w_si / G_CM2  # H's numbers taken as kg*m**2/s, as the user said
    w_out = np.array([[float(r[rows[0].index(c)]) for c in ("wx", "wy", "wz")] for r in rows[2:]])
    np.testing.assert_allclose(w_out, w_given, rtol=1e-12)
    np.testing.assert_allclose(_w_read_back(out, tmp_path, "b_"), w_given, rtol=1e-12)


def test_convert_unit_option_over_a_header_unit_writes_a_units_row(tmp_path, capsys):
    """Before: --unit beat the unit in a column's header, but the output kept that header and had
    nothing else to say the numbers were read in another unit, so reading it back gave another ω.
    Now a row of units names the unit each column hconv read was read in; an input that says no
    unit anywhere gets none, with --unit or without, as before."""
    import numpy as np
    from helpers import hconv_inprocess

    src, w_si = _bodies_csv(tmp_path / "plain.csv", None)
    text = (tmp_path / "plain.csv").read_text()
    (tmp_path / "named.csv").write_text(text.replace("Hx,Hy,Hz", "Hx [g*cm^2/s],Hy [g*cm^2/s],Hz [g*cm^2/s]", 1))
    out = tmp_path / "out.csv"
    proc = hconv_inprocess("convert", str(tmp_path / "named.csv"), str(out), "--unit", "Hz=kg*m**2/s", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    units = ",,,g*cm^2/s,g*cm^2/s,kg*m**2/s" + ",kg*m**2" * 6 + ",rad/s" * 3 + ",1,1,,"
    assert out.read_text().splitlines()[1] == units
    # Hz's numbers taken as kg*m**2/s, as the user said: H's SI values are (1e-7 Hx, 1e-7 Hy, Hz)
    a = np.loadtxt(src, delimiter=",", skiprows=1)
    H = a[:, 3:6] * np.array([G_CM2, G_CM2, 1.0])
    I_si = np.array([[[r[6], r[9], r[10]], [r[9], r[7], r[11]], [r[10], r[11], r[8]]] for r in a])
    w_given = np.linalg.solve(I_si, H[:, :, None])[:, :, 0]
    np.testing.assert_allclose(_w_read_back(out, tmp_path, "b_"), w_given, rtol=1e-12)
    proc = hconv_inprocess("convert", src, str(out), "--force", "--unit", "H=g*cm**2/s", capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().splitlines()[1].startswith("0.0,3,20,")  # the first body's row: no units row


def test_csv_writer_pieces_on_threads_write_the_bytes_of_one_thread(tmp_path, monkeypatch):
    """A table cut into pieces formatted on threads and written in order: the bytes of one
    thread's writing, with the pieces' edges on quoted values, nulls beside empty texts and
    plain rows (a piece with no null of a column that has some quotes its empty texts all the
    same), with a row of units, into a .tsv, for tables smaller than a piece and larger than
    a slice, one after another (the buffers used again, and grown), and a value needing quotes
    that the scan missed, in a middle piece (its slice's rows written joined)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from hconv.tables import csvwrite

    rng = np.random.default_rng(3)
    n = 1000
    words = np.array([f"w{k}" for k in range(n)], dtype=object)
    words[rng.integers(0, n, 120)] = "a,b"
    words[rng.integers(0, n, 60)] = 'say "hi"\tthere'
    words[rng.integers(0, n, 60)] = ""
    words[rng.integers(0, n, 60)] = None
    t = pa.table(
        {
            "text": pa.array(words, pa.string()),
            "x": pa.array(np.where(rng.random(n) < 0.1, np.nan, rng.normal(size=n))),
            "plain": pa.array([f"p{k}" for k in range(n)]),
        }
    )
    blocks = [t.slice(0, 5), t.slice(5, 600), t.slice(605, 20), t.slice(625)]
    rows_formatted: dict[int, list[int]] = {1: [], 3: []}
    write_csv = pacsv.write_csv
    monkeypatch.setattr(pacsv, "write_csv", lambda d, *a: rows_formatted[cores].append(d.num_rows) or write_csv(d, *a))
    monkeypatch.setattr(csvwrite, "_PIECE_ROWS", 7)
    monkeypatch.setattr(csvwrite, "_SLICE_ROWS", 50)
    monkeypatch.setattr(csvwrite, "_PIECES_PER_THREAD", 4)
    for name, delimiter in (("out.csv", ","), ("out.tsv", "\t")):
        written = {}
        for cores in (1, 3):  # noqa: B007 - the patched writer records by it
            monkeypatch.setattr(csvwrite, "available_cores", lambda cores=cores: cores)
            w = csvwrite.CsvWriter(str(tmp_path / name), t.schema, delimiter, units={"x": "m", "text": "-"})
            for b in blocks:
                w.write(b)
            w.close()
            written[cores] = (tmp_path / name).read_bytes()
        assert written[3] == written[1]
        rows = list(csv.reader(io.StringIO(written[3].decode(), newline=""), delimiter=delimiter))
        assert rows[1] == ["-", "m", ""]
        assert [r[0] for r in rows[2:]] == ["" if v is None else v for v in words]
    # on 3 cores, slices of 150 rows, up to 12 pieces of 7 rows at least: 5 rows straight into the
    # file; 600 as 4 slices of 11 pieces of 13 rows and one of 7; 20 as 2 of 10; 375 as 2 slices as
    # those of the 600, and 75 rows in 9 pieces of 8 and one of 3
    slice_150 = [13] * 11 + [7]
    assert sorted(rows_formatted[3]) == sorted(2 * ([5] + 4 * slice_150 + [10, 10] + 2 * slice_150 + [8] * 9 + [3]))
    # the scan sees nothing: pyarrow refuses a value in a middle piece, and its slice is joined
    scan = csvwrite._scan
    monkeypatch.setattr(csvwrite, "_scan", lambda t, d: ({}, False) if t.num_rows == 150 else scan(t, d))
    plain = pa.table({"t": [f"v{k}" for k in range(150)], "x": [0.5] * 150})
    hidden = plain.set_column(0, "t", pa.array([f"v{k}" if k != 70 else "v,70" for k in range(150)]))
    written = {}
    for cores in (1, 3):
        monkeypatch.setattr(csvwrite, "available_cores", lambda cores=cores: cores)
        w = csvwrite.CsvWriter(str(tmp_path / "hidden.csv"), plain.schema)
        w.write(plain.slice(0, 20))
        w.write(hidden)
        w.close()
        written[cores] = (tmp_path / "hidden.csv").read_text()
    assert written[3] == written[1]
    values = [f"v{k}" if k != 70 else '"v,70"' for k in range(150)]
    assert written[3] == "t,x\n" + "".join(f"v{k},0.5\n" for k in range(20)) + "".join(f"{v},0.5\n" for v in values)


def test_csv_writer_pieces_do_not_wait_for_a_pool_busy_with_another_writer(tmp_path, monkeypatch):
    """The pool is shared by every writer of the process (a dataset's files): a writer whose pool
    threads are all busy formats its pieces on its own thread and returns, rather than waiting
    for the pool to take its queued share. The pool's one thread is held until the writer has
    returned (bounded only for a writer that would wait, which then fails)."""
    import threading

    import pyarrow as pa

    from hconv.tables import csvwrite

    monkeypatch.setattr(csvwrite, "available_cores", lambda: 2)
    from hconv.solve.engines import SharedPool

    # a pool of one thread, not one an earlier test left larger
    monkeypatch.setattr(csvwrite, "_shared_pool", SharedPool("hconv-csv"))
    pool = csvwrite._shared_pool(1)
    held, release = threading.Event(), threading.Event()
    blocker = pool.submit(lambda: held.set() or release.wait(30))
    held.wait()
    n = 4 * csvwrite._PIECE_ROWS
    out = _written(tmp_path, pa.table({"t": [f"v{k}" for k in range(n)]}))
    returned_while_held = not blocker.done()
    release.set()
    pool.shutdown()
    assert returned_while_held
    assert out == b"t\n" + b"".join(b"v%d\n" % k for k in range(n))
