"""Write the bad-input corpus: files a user might really feed hconv, each wrong in one way.

    python tests/corpus/make_corpus.py

The expected outcome of each file (a one-line error with its exit code, or per-row statuses) is
in tests/test_corpus.py. The files are committed; this script documents how each was made.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

HERE = Path(__file__).resolve().parent / "files"
HEAD = "Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz"
ROW = "1,2,3,2,3,4,-0.5,0,0"


def text(name: str, content: str | bytes) -> None:
    data = content.encode() if isinstance(content, str) else content
    (HERE / name).write_bytes(data)


def table(**cols) -> pa.Table:
    return pa.table(cols)


def good(n=3) -> dict:
    return {
        "Hx": [1.0] * n,
        "Hy": [2.0] * n,
        "Hz": [3.0] * n,
        "Ixx": [2.0] * n,
        "Iyy": [3.0] * n,
        "Izz": [4.0] * n,
        "Ixy": [-0.5] * n,
        "Ixz": [0.0] * n,
        "Iyz": [0.0] * n,
    }


def main() -> None:
    HERE.mkdir(exist_ok=True)
    # --- CSV: the file as a whole ---
    text("empty.csv", "")
    text("header_only.csv", HEAD + "\n")
    text("whitespace_only.csv", "   \n\t\n")
    text("binary_garbage.csv", bytes(np.random.default_rng(1).integers(0, 256, 400, dtype=np.uint8)))
    text("json_not_csv.csv", '{"Hx": 1, "Hy": 2, "Hz": 3}\n')
    text("png_not_csv.csv", b"\x89PNG\r\n\x1a\n" + bytes(range(64)))
    # --- CSV: the header ---
    text("missing_Hz.csv", "Hx,Hy,Ixx,Iyy,Izz,Ixy,Ixz,Iyz\n1,2,2,3,4,-0.5,0,0\n")
    text("missing_inertia.csv", "Hx,Hy,Hz\n1,2,3\n")
    text("partial_inertia.csv", "Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy\n1,2,3,2,3,4,0\n")
    text("duplicate_column.csv", HEAD + ",Hx\n" + ROW + ",1\n")
    text("two_inertia_forms.csv", HEAD + ",I1,I2,I3\n" + ROW + ",1,1,1\n")
    text("partial_r.csv", HEAD + ",rx,ry\n" + ROW + ",1,1\n")
    text("partial_quaternion.csv", HEAD + ",qw,qx\n" + ROW + ",1,0\n")
    text("spaces_in_header.csv", HEAD.replace(",", ", ") + "\n" + ROW + "\n")
    text("has_output_columns.csv", HEAD + ",wx\n" + ROW + ",1\n")
    text("semicolon_delimiter.csv", HEAD.replace(",", ";") + "\n" + ROW.replace(",", ";") + "\n")
    text("tab_delimiter.csv", HEAD.replace(",", "\t") + "\n" + ROW.replace(",", "\t") + "\n")
    text("decimal_comma.csv", HEAD.replace(",", ";") + "\n1,5;2;3;2;3;4;-0,5;0;0\n")
    # as Excel saves "CSV (semicolon)" in much of Europe: a byte-order mark, CRLF, decimal commas
    text("excel_semicolon.csv", ("\ufeff" + HEAD.replace(",", ";") + "\r\n1,5;2;3;2;3;4;-0,5;0;0\r\n").encode())
    text("bar_delimiter.csv", HEAD.replace(",", "|") + "\n" + ROW.replace(",", "|") + "\n")
    text("comment_lines.csv", "# exported by a logger\n# H in kg*m^2/s\n" + HEAD + "\n" + ROW + "\n")
    text("comments_only.csv", "# nothing but a comment\n")
    text("units_row.csv", HEAD + "\n" + ",".join(["kg*m^2/s"] * 3 + ["g*cm^2"] * 6) + "\n1,2,3,2e7,3e7,4e7,-5e6,0,0\n")
    text("bad_units_row.csv", HEAD + "\n" + ",".join(["kg*m^2/s"] * 3 + ["g*cm^2"] * 5 + ["kgm2"]) + "\n" + ROW + "\n")
    text("wrong_units_row.csv", HEAD + "\n" + ",".join(["kg*m^2/s"] * 3 + ["g*cm^2"] * 5 + ["m/s"]) + "\n" + ROW + "\n")
    # --- CSV: encodings and line endings that should just work ---
    text("utf8_bom.csv", b"\xef\xbb\xbf" + (HEAD + "\n" + ROW + "\n").encode())
    text("crlf.csv", (HEAD + "\r\n" + ROW + "\r\n" + ROW + "\r\n").encode())
    text("quoted_numbers.csv", HEAD + '\n"1","2","3","2","3","4","-0.5","0","0"\n')
    text("blank_lines.csv", HEAD + "\n" + ROW + "\n\n" + ROW + "\n\n")
    # --- CSV: the values ---
    text("text_in_numeric.csv", HEAD + "\n" + ROW + "\n1,two,3,2,3,4,-0.5,0,0\n")
    text("mixed_types.csv", HEAD + "\n" + ROW + "\n" + ROW.replace("2,3,4", "2,3,four kg") + "\n")
    text("number_with_unit.csv", HEAD + "\n" + ROW.replace("1,2,3", "1 kg*m^2/s,2,3") + "\n")
    text("thousands_separator.csv", HEAD + '\n"1,234.5",2,3,2,3,4,-0.5,0,0\n')
    text("ragged_short_row.csv", HEAD + "\n" + ROW + "\n1,2,3,2,3,4,-0.5,0\n")
    text("ragged_long_row.csv", HEAD + "\n" + ROW + "\n" + ROW + ",9\n")
    text("latin1_text.csv", (HEAD + ",name\n" + ROW + ",caf").encode() + b"\xe9\n")
    text("nan_and_blank.csv", HEAD + "\n" + ROW + "\nnan,2,3,2,3,4,-0.5,0,0\n1,,3,2,3,4,-0.5,0,0\n")
    text("infinities.csv", HEAD + "\ninf,2,3,2,3,4,-0.5,0,0\n1,2,3,-inf,3,4,-0.5,0,0\n" + ROW + "\n")
    text("subnormal.csv", HEAD + "\n1e-310,2e-310,3e-310,2,3,4,-0.5,0,0\n1,2,3,2e-310,3e-310,4e-310,0,0,0\n")
    text(
        "near_max.csv",
        HEAD + "\n1e308,1e308,1e308,2,3,4,-0.5,0,0\n1e308,2,3,1e-10,1e-10,1e-10,0,0,0\n"
        "1,2,3,1.7e308,1.7e308,1.7e308,0,0,0\n",
    )
    text("asymmetric_nine.csv", HEAD + ",Iyx,Izx,Izy\n" + ROW + ",-0.7,0,0\n" + ROW + ",-0.5,0,0\n")
    text("negative_moments.csv", HEAD + "\n1,2,3,-2,3,4,0,0,0\n1,2,3,-2,-3,-4,0,0,0\n" + ROW + "\n")
    text("not_physical.csv", HEAD + "\n1,2,3,1,1,5,0,0,0\n" + ROW + "\n")
    text("singular.csv", HEAD + "\n1,2,3,0,0,0,0,0,0\n1,2,3,1,1,0,0,0,0\n" + ROW + "\n")
    # --- Parquet ---
    pq.write_table(table(**good()), HERE / "good.parquet")
    raw = (HERE / "good.parquet").read_bytes()
    text("empty.parquet", b"")
    text("truncated.parquet", raw[: len(raw) // 2])
    text("corrupt_footer.parquet", raw[:-12] + b"\x00" * 8 + raw[-4:])
    text("csv_named_parquet.parquet", HEAD + "\n" + ROW + "\n")
    os.remove(HERE / "good.parquet")
    pq.write_table(
        pa.table({"H": pa.array([[1.0, 2.0, 3.0]]), "I": pa.array([[1.0, 2.0, 3.0, 4.0]])}),
        HERE / "list_wrong_length.parquet",
    )
    pq.write_table(
        pa.table({"H": pa.array([[1.0, 2.0, 3.0], [1.0, 2.0]]), "I": pa.array([[1.0, 2.0, 3.0]] * 2)}),
        HERE / "list_ragged.parquet",
    )
    pq.write_table(
        pa.table({"H": pa.array([{"x": 1.0, "y": 2.0, "z": 3.0}]), "I": pa.array([2.0])}),
        HERE / "struct_column.parquet",
    )
    pq.write_table(
        pa.table({"H": pa.array([[[1.0], [2.0], [3.0]]]), "I": pa.array([2.0])}), HERE / "list_of_lists.parquet"
    )
    pq.write_table(pa.table({**good(1), "Hx": pa.array(["1"])}), HERE / "string_column.parquet")
    pq.write_table(pa.table({**good(1), "Hx": pa.array([True])}), HERE / "bool_column.parquet")
    pq.write_table(pa.table({**good(3), "Hy": pa.array([2.0, None, 2.0])}), HERE / "nulls.parquet")
    pq.write_table(
        pa.Table.from_arrays([pa.array([1.0])] * 10, names=HEAD.split(",") + ["Hx"]), HERE / "duplicate_column.parquet"
    )
    pq.write_table(pa.table({k: pa.array([], pa.float64()) for k in good(0)}), HERE / "zero_rows.parquet")
    other_formats()


def other_formats() -> None:
    """Arrow IPC and JSON lines, each wrong in one way."""
    import pyarrow.ipc as ipc

    sink = pa.BufferOutputStream()
    with ipc.new_stream(sink, pa.table(good(100)).schema) as w:
        w.write_table(pa.table(good(100)))
    whole = sink.getvalue().to_pybytes()
    text("truncated.arrow", whole[: len(whole) - 200])  # cut inside the record batch
    text("empty.arrow", b"")
    buf = pa.BufferOutputStream()
    pq.write_table(pa.table(good(1)), buf)
    text("parquet_named_arrow.arrow", buf.getvalue().to_pybytes())
    line = '{"Hx": 1, "Hy": 2, "Hz": 3, "Ixx": 2, "Iyy": 3, "Izz": 4, "Ixy": -0.5, "Ixz": 0, "Iyz": 0}'
    text("bad_line.jsonl", line + "\n" + line[:40] + "\n" + line + "\n")
    text("json_array.jsonl", "[" + line + ", " + line + "]\n")
    text("not_objects.ndjson", "[1, 2, 3]\n")


if __name__ == "__main__":
    main()
