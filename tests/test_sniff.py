"""Telling the format of a path (hconv.tables.sniff): the name, --from and --to, and what
contradicts them."""

from __future__ import annotations

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
            "cannot tell the format of 'in.dat' from its extension; hconv reads CSV (.csv), Parquet (.parquet, .pq), "
            "Arrow IPC (Feather) (.arrow, .feather, .ipc) or JSON lines (.jsonl, .ndjson): pass --from FORMAT "
            "(csv, parquet, arrow or jsonl) if it is one of them",
        ),
        (
            "in.orc",
            [],
            "in.orc: its name says ORC (.orc), which hconv does not read; hconv reads CSV (.csv), Parquet "
            "(.parquet, .pq), Arrow IPC (Feather) (.arrow, .feather, .ipc) or JSON lines (.jsonl, .ndjson)",
        ),
        ("in.json", [], "if it holds one JSON object per line, pass --from jsonl"),
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


def test_format_of_json_lines_out_is_refused_naming_what_hconv_writes(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_inprocess("convert", str(SCENE_CSV), "out.jsonl", capsys=capsys)
    assert (code, err) == (
        2,
        "hconv: error: out.jsonl: hconv reads JSON lines but does not write it; it writes CSV (.csv), Parquet "
        "(.parquet, .pq) or Arrow IPC (Feather) (.arrow, .feather, .ipc): pass --to arrow (or csv, parquet), and "
        "name OUT for it\n",
    )
