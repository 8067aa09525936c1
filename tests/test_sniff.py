"""Telling the format of a path (hconv.tables.sniff): the name, --from and --to, and what
contradicts them."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from helpers import run_inprocess

ROOT = Path(__file__).resolve().parents[1]
SCENE_CSV = ROOT / "examples" / "data" / "scene.csv"


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["in.csv", "out.csv", "--to", "parquet"],
            "out.csv: the name says CSV but --to parquet says Parquet; name it out.parquet, or drop --to",
        ),
        (
            ["in.csv", "out.parquet", "--from", "parquet"],
            "in.csv: the name says CSV but --from parquet says Parquet; name it in.parquet, or drop --from",
        ),
        (
            ["generate", "g.pq", "--rows", "5", "--to", "csv"],
            "g.pq: the name says Parquet but --to csv says CSV; name it g.csv, or drop --to",
        ),
    ],
)
def test_format_of_extension_contradicting_from_or_to_is_refused(args, message, tmp_path, capsys, monkeypatch):
    """Before: `hconv convert in.csv out.csv --to parquet` wrote Parquet into out.csv, exit 0."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    command = [] if args[0] == "generate" else ["convert"]
    code, _, err = run_inprocess(*command, *args, capsys=capsys)
    assert (code, err) == (2, f"hconv: error: {message}\n")
    assert not Path(args[1]).exists() or args[1] == "in.csv"


def test_format_of_extension_contradicting_from_or_to_python_names_the_keyword(tmp_path):
    from hconv.errors import UsageError
    from hconv.tables.pipeline import convert_file

    (tmp_path / "in.csv").write_bytes(SCENE_CSV.read_bytes())
    with pytest.raises(
        UsageError, match=r"the name says CSV but dst_format='parquet' says Parquet; .* or drop dst_format$"
    ):
        convert_file(str(tmp_path / "in.csv"), str(tmp_path / "out.csv"), dst_format="parquet")


@pytest.mark.parametrize(
    "args, message",
    [
        (["", "o.csv"], "the input path is empty (''); give a file path, or - for stdin"),
        (["", "o.csv", "--from", "csv"], "the input path is empty (''); give a file path, or - for stdin"),
        ([str(SCENE_CSV), "", "--to", "csv"], "the output path is empty (''); give a file path, or - for stdout"),
    ],
)
def test_format_of_empty_path_says_it_is_empty(args, message, tmp_path, capsys, monkeypatch):
    """Before: 'hconv: error: : does not exist' (an unset shell variable as IN)."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_inprocess("convert", *args, capsys=capsys)
    assert (code, err) == (2, f"hconv: error: {message}\n")


# --- a CSV's dialect ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, delimiter",
    [
        ("Hx,Hy,Hz\n1,2,3\n", ","),
        ("Hx;Hy;Hz\n1,5;2;3\n", ";"),  # decimal commas do not make it comma-separated
        ("Hx\tHy\tHz\n1\t2\t3\n", "\t"),
        ("Hx|Hy|Hz\n1|2|3\n", "|"),
        ('label;Hx;Hy\n"a;b";1;2\n', ";"),  # a quoted delimiter is a value's
        ("Hx,Hy;Hz,Ixx\n1,2;3,4\n", ","),  # more columns under ',' than under ';'
        ("Hx,Hy|note\n1,2|a\n", ","),  # a tie, settled by the header naming hconv's columns under ','
        ("Hx\n1\n", ","),  # one column: nothing to sniff
    ],
)
def test_sniff_delimiter_picks_the_most_columns_that_every_row_has(text, delimiter):
    from hconv.tables import sets
    from hconv.tables.sniff import sniff_delimiter

    assert sniff_delimiter(text.split("\n"), "in.csv", frozenset(sets.all_names())) == delimiter


def test_sniff_delimiter_tie_between_two_is_one_line_naming_the_option():
    from hconv.errors import UsageError
    from hconv.tables.sniff import sniff_delimiter

    with pytest.raises(UsageError, match=r"in.csv: cannot tell the delimiter: ',' and ';' both split every line"):
        sniff_delimiter(["a,b;c", "1,2;3"], "in.csv")


@pytest.mark.parametrize(
    "values, mark",
    [
        ({"Hx": ["1,5", "2"], "Hy": ["-0,25e3"]}, ","),
        ({"Hx": ["1.5", "2"], "Hy": ["3"]}, "."),
        ({"Hx": ["1", "2"]}, "."),  # whole numbers say nothing: the point
        ({"Hx": [",5"]}, ","),
    ],
)
def test_sniff_decimal_comma_only_where_no_value_has_a_point(values, mark):
    from hconv.tables.sniff import sniff_decimal

    assert sniff_decimal(values, "in.csv") == mark


@pytest.mark.parametrize("suffix", [".tsv", ".tab", ".TSV"])
def test_open_input_tsv_is_read_with_tabs(suffix, tmp_path):
    """Before: a .tsv was "cannot tell the format"; with --from csv, refused as "separated by tabs"."""
    from hconv.tables.job import Job
    from hconv.tables.sniff import format_of
    from hconv.tables.tableio import open_input

    src = tmp_path / f"log{suffix}"
    # a comma in a value, and a header that would split at the comma too: the name says tab
    src.write_text("Hx\tHy\tHz\tI1\tI2\tI3\tnote,more\n1\t2\t3\t1\t2\t4\ta,b\n")
    assert format_of(str(src), None, "src_format") == "csv"
    with open_input(str(src), "csv", Job()) as inp:
        table = next(inp.batches)
        assert inp.dialect.delimiter == "\t" and inp.schema.names[-1] == "note,more"
        assert table.column("note,more").to_pylist() == ["a,b"] and table.column("I3").to_pylist() == [4.0]


def test_open_input_comment_lines_before_the_header_are_skipped(tmp_path):
    """Before: "# exported ..." was the header, and the error "the header names 1 columns"."""
    from hconv.tables.job import Job
    from hconv.tables.tableio import open_input

    src = tmp_path / "log.csv"
    src.write_text('# exported by "logger", v2\n#\nHx,Hy,Hz,I1,I2,I3\n1,2,3,1,2,4\n')
    with open_input(str(src), "csv", Job()) as inp:
        assert inp.dialect.comment_lines == 2 and inp.schema.names[:3] == ["Hx", "Hy", "Hz"]
        assert next(inp.batches).num_rows == 1


def test_dialect_describe_says_only_what_is_not_plain_csv():
    from hconv.tables.sniff import Dialect

    assert Dialect().describe() == ""
    assert Dialect(delimiter=";", decimal=",").describe() == "read as CSV: ';' separated, decimal ','"
    assert Dialect(delimiter="\t", comment_lines=1, units_row=True).describe() == (
        "read as CSV: tab separated, decimal '.', 1 comment line skipped, units from the row under the header"
    )


def _feather(path: Path) -> Path:
    import pyarrow.feather as feather
    import pyarrow.parquet as pq

    feather.write_feather(pq.read_table(ROOT / "examples" / "data" / "scene.parquet"), path)
    return path


@pytest.mark.parametrize(
    "name, args, message",
    [
        # Before: "cannot tell the format … name it .csv or .parquet" for every one of these
        (
            "in.dat",
            [],
            "in.dat: cannot tell its format from its name; pass --from FORMAT, one of csv, parquet, arrow or jsonl",
        ),
        (
            "in.orc",
            [],
            "in.orc: its name says ORC (.orc), which hconv does not read; hconv reads CSV, Parquet, "
            "Arrow IPC (Feather) or JSON lines",
        ),
        (
            "in.json",
            [],
            "in.json: hconv reads JSON lines, not JSON: for one object per line, pass --from jsonl; for one array "
            "of objects, first: jq -c '.[]' in.json > in.jsonl",
        ),
        # Before: pyarrow's "Parquet magic bytes not found in footer"
        (
            "in.feather",
            ["--from", "parquet"],
            "in.feather: is an Arrow IPC (Feather) file, as its name says, not Parquet; drop --from parquet",
        ),  # fmt: skip
        (
            "in.bin",
            ["--from", "parquet"],
            "in.bin: is an Arrow IPC (Feather) file, not Parquet; to read it as "
            "that, name it .arrow or pass --from arrow",
        ),  # fmt: skip
    ],
)
def test_format_of_names_the_formats_hconv_reads(name, args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _feather(tmp_path / name)
    code, _, err = run_inprocess("convert", name, "out.csv", *args, capsys=capsys)
    assert code in (2, 3) and len(err.strip().splitlines()) == 1, err
    assert message in err


@pytest.mark.parametrize(
    "name, what",
    [
        ("book.xlsx", "an Excel workbook"),
        ("book.xls", "an Excel workbook"),
        ("book.ods", "an OpenDocument spreadsheet"),
    ],
)
def test_format_of_spreadsheet_by_its_name_says_to_save_it_as_csv(name, what, tmp_path, capsys, monkeypatch):
    """Before: a workbook named .xlsx got the list of formats hconv reads, while the same file
    named .csv was told to be saved as CSV UTF-8 from the spreadsheet: now both get that advice."""
    import zipfile

    monkeypatch.chdir(tmp_path)
    if name.endswith(".xls"):  # Excel 97-2003: an OLE2 compound file
        Path(name).write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + b"\x00" * 504)
    else:
        with zipfile.ZipFile(name, "w") as z:
            if name.endswith(".ods"):
                z.writestr("mimetype", "application/vnd.oasis.opendocument.spreadsheet")
            else:
                z.writestr("[Content_Types].xml", "<Types/>")
                z.writestr("xl/workbook.xml", "<workbook/>")
    code, _, err = run_inprocess("convert", name, "out.csv", capsys=capsys)
    suffix = name[name.index(".") :]
    save_as = "open it in the spreadsheet and save the sheet as 'CSV UTF-8 (comma delimited)'"
    assert (code, err) == (2, f"hconv: error: {name}: is {what} ({suffix}), which hconv does not read; {save_as}\n")
    code, _, err = run_inprocess("convert", name, "out.csv", "--from", "csv", capsys=capsys)
    assert code == 3 and save_as in err  # its bytes read as CSV: the same advice
    assert sorted(os.listdir()) == [name]


def test_format_of_json_lines_out_is_refused_naming_what_hconv_writes(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_inprocess("convert", str(SCENE_CSV), "out.jsonl", capsys=capsys)
    assert (code, err) == (
        2,
        "hconv: error: out.jsonl: hconv reads JSON lines but does not write it: pass --to arrow (or csv, parquet), "
        "and name OUT for it\n",
    )
