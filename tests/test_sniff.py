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
