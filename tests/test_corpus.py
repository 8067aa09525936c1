"""The bad-input corpus (tests/corpus/files, made by tests/corpus/make_corpus.py): every file gets a
clear one-line error with the right exit code, or per-row statuses with every row kept in order.

The command runs in-process here (cli.main, as the console script calls it), so that 50 files
take a second; tests/test_cli.py runs the real process for the same kinds of error.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest
from helpers import mp_solve, rel_err, run_inprocess

FILES = Path(__file__).resolve().parent / "corpus" / "files"

ERRORS = {  # file: (exit code, words the one-line message must hold)
    "empty.csv": (3, "the file is empty"),
    "whitespace_only.csv": (3, "the first line is blank"),
    "binary_garbage.csv": (3, "not a text file"),
    "png_not_csv.csv": (3, "not a text file"),
    "json_not_csv.csv": (3, "is it a CSV header"),
    "missing_Hz.csv": (3, "missing column Hz"),
    "missing_inertia.csv": (3, "missing the inertia"),
    "partial_inertia.csv": (3, "not Ixz, Iyz"),
    "duplicate_column.csv": (3, "'Hx' appears more than once"),
    "two_inertia_forms.csv": (3, "more than one form"),
    "partial_r.csv": (3, "has rx, ry but not rz"),
    "partial_quaternion.csv": (3, "has qw, qx but not qy, qz"),
    "spaces_in_header.csv": (3, "spaces around ' Hy'"),
    "has_output_columns.csv": (3, "already has output column wx"),
    "comments_only.csv": (3, "holds only comment lines (starting with #)"),
    "bad_units_row.csv": (3, "column 'Iyz' of the units row under the header: pint does not understand the unit"),
    "wrong_units_row.csv": (3, "column 'Iyz' of the units row under the header: 'm/s' is not a unit of inertia"),
    "text_in_numeric.csv": (3, "column 'Hy' must be numeric but holds 'two' in data row 2"),
    "mixed_types.csv": (3, "column 'Izz' must be numeric but holds 'four kg' in data row 2"),
    "number_with_unit.csv": (3, "holds '1 kg*m^2/s' in data row 1"),
    "thousands_separator.csv": (3, "holds '1,234.5' in data row 1"),
    "ragged_short_row.csv": (3, "data row 2 has 8 values, but the header names 9 columns"),
    "ragged_long_row.csv": (3, "data row 2 has 10 values, but the header names 9 columns"),
    "latin1_text.csv": (3, "line 2 is not UTF-8"),
    "empty.parquet": (3, "the file is empty"),
    "truncated.parquet": (3, "not a readable Parquet file"),
    "corrupt_footer.parquet": (3, "not a readable Parquet file"),
    "csv_named_parquet.parquet": (3, "is CSV text, not Parquet: rename it"),
    "list_wrong_length.parquet": (3, "'I' holds 4 values per row"),
    "list_ragged.parquet": (3, "'H' holds 2 values in row 2, but H needs 3 (Hx, Hy, Hz)"),
    # H a struct {x, y, z} is read as Hx, Hy, Hz (issue 26), but a CSV cannot hold the struct itself
    "struct_column.parquet": (3, "column 'H' is struct<x: double, y: double, z: double>, which CSV cannot hold"),
    "list_of_lists.parquet": (3, "must be a list of numbers"),
    "string_column.parquet": (3, "column 'Hx' has type string"),
    "bool_column.parquet": (3, "column 'Hx' has type bool"),
    "duplicate_column.parquet": (3, "'Hx' appears more than once"),
    "truncated.arrow": (3, "record batch 1 (from data row 1) cannot be read"),
    "empty.arrow": (3, "the file is empty"),
    "parquet_named_arrow.arrow": (3, "is a Parquet file, not Arrow IPC"),
    "bad_line.jsonl": (3, "line 2 is not valid JSON"),
    "json_array.jsonl": (3, "is one JSON array, not JSON lines"),
    "not_objects.ndjson": (3, "line 1 is a JSON list, not an object"),
}

#: The factor to SI of the inertia a file's units row gives (1 g·cm² = 1e-7 kg·m², exactly by definition)
I_TO_SI = {"units_row.csv": 1e-7}

STATUSES = {  # file: the status of each row, in order
    "header_only.csv": [],
    "zero_rows.parquet": [],
    "utf8_bom.csv": ["ok"],
    "crlf.csv": ["ok", "ok"],
    "quoted_numbers.csv": ["ok"],
    "blank_lines.csv": ["ok", "ok"],
    # dialects: sniffed delimiter, decimal comma, comment lines, a row of units under the header
    "semicolon_delimiter.csv": ["ok"],
    "tab_delimiter.csv": ["ok"],
    "bar_delimiter.csv": ["ok"],
    "decimal_comma.csv": ["ok"],
    "excel_semicolon.csv": ["ok"],
    "comment_lines.csv": ["ok"],
    "units_row.csv": ["ok"],
    "nan_and_blank.csv": ["ok", "invalid_input", "invalid_input"],
    "infinities.csv": ["invalid_input", "invalid_input", "ok"],
    "nulls.parquet": ["ok", "invalid_input", "ok"],
    # H = 1e308 stays finite through I⁻¹ (ok); H = 1e308 over I = 1e-10 cannot (overflow); a
    # tensor of 1.7e308 is still solved, to a subnormal-free ω of ~1e-308 (ok)
    "near_max.csv": ["ok", "overflow", "ok"],
    # H of 1e-310 gives ω of ~7e-311, still 1e-14 accurate (ok); I of 2e-310 gives ω of 5e309 (overflow)
    "subnormal.csv": ["ok", "overflow"],
    "asymmetric_nine.csv": ["not_symmetric", "ok"],
    "negative_moments.csv": ["not_positive_definite", "not_positive_definite", "ok"],
    "not_physical.csv": ["not_physical", "ok"],
    "singular.csv": ["singular", "singular", "ok"],
}


def run(*args: str, capsys) -> tuple[int, str, str]:
    return run_inprocess(*args, capsys=capsys)


def test_corpus_is_big_and_fully_covered():
    files = {p.name for p in FILES.iterdir()}
    assert len(files) >= 40
    assert files == set(ERRORS) | set(STATUSES)  # a new file needs an expected outcome


@pytest.mark.parametrize("name", sorted(ERRORS))
def test_convert_corpus_bad_file_is_one_clear_line(name, tmp_path, capsys):
    code, needle = ERRORS[name]
    out = tmp_path / "out.csv"
    got, stdout, err = run("convert", str(FILES / name), str(out), capsys=capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert got == code, err
    assert len(lines) == 1 and lines[0].startswith("hconv: error: ") and "Traceback" not in err, err
    assert name in lines[0] and needle in lines[0], lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []  # nothing written, no temporary left


@pytest.mark.parametrize("name", sorted(STATUSES))
def test_convert_corpus_file_gives_per_row_statuses(name, tmp_path, capsys):
    out = tmp_path / "out.csv"
    code, _, err = run("convert", str(FILES / name), str(out), "-q", capsys=capsys)
    assert code == 0 and err == "", err
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    if rows and rows[0]["status"] == "":  # the input's row of units, under the header as it was
        assert rows[0]["wx"] == "rad/s" and name == "units_row.csv"
        rows = rows[1:]
    assert [r["status"] for r in rows] == STATUSES[name]
    for r in rows:  # every ok row's ω against a 50-digit solve of the same numbers
        if r["status"] == "ok":
            I = np.array(
                [
                    [float(r["Ixx"]), float(r["Ixy"]), float(r["Ixz"])],
                    [float(r.get("Iyx") or r["Ixy"]), float(r["Iyy"]), float(r["Iyz"])],
                    [float(r.get("Izx") or r["Ixz"]), float(r.get("Izy") or r["Iyz"]), float(r["Izz"])],
                ]
            )
            H = np.array([float(r["Hx"]), float(r["Hy"]), float(r["Hz"])])
            want = mp_solve(I[None] * I_TO_SI.get(name, 1.0), H[None])  # 50 digits: no range trouble at 1e308
            w = np.array([[float(r["wx"]), float(r["wy"]), float(r["wz"])]])
            assert rel_err(w, want)[0] < 1e-12, (name, r)


@pytest.mark.parametrize("case", ["same_as_input", "missing_directory", "is_a_directory", "unwritable_directory"])
def test_convert_bad_output_path_is_one_clear_line(case, tmp_path, capsys, monkeypatch):
    src = tmp_path / "in.csv"
    src.write_text((FILES / "crlf.csv").read_text())
    dst = {
        "same_as_input": src,
        "missing_directory": tmp_path / "nope" / "out.csv",
        "is_a_directory": tmp_path / "dir.csv",
        "unwritable_directory": tmp_path / "out.csv",
    }[case]
    if case == "is_a_directory":  # a directory as OUT takes the input's name: a directory by that name there
        (dst / "in.csv").mkdir(parents=True)
    if case == "unwritable_directory":  # root ignores directory permissions, so refuse like the OS would
        import tempfile

        def refuse(*a, **k):
            raise PermissionError(13, "Permission denied")

        monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code, _, err = run("convert", str(src), str(dst), "--force" if case == "same_as_input" else "-q", capsys=capsys)
    needle = {
        "same_as_input": "is the input file",
        "missing_directory": "does not exist",
        "is_a_directory": "is a directory",
        "unwritable_directory": "cannot write in",
    }[case]
    assert code == 4 and len(err.strip().splitlines()) == 1 and needle in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["in.csv"] + (["dir.csv"] if case == "is_a_directory" else [])
    )
