"""Atomic output (hconv.tables.output): what it refuses to write over, links, stdout, and a full
disk named as the output's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.csv  # noqa: F401 - pa.csv
import pyarrow.parquet as pq
import pytest
from helpers import run_inprocess, run_on_terminal

ROOT = Path(__file__).resolve().parents[1]
SCENE_CSV = ROOT / "examples" / "data" / "scene.csv"


def test_output_force_refuses_a_path_that_is_not_a_regular_file(tmp_path, capsys, monkeypatch):
    """Before: --force renamed a file over a FIFO (as root, over /dev/full), exit 0."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    os.mkfifo("ff.csv")
    code, _, err = run_inprocess("convert", "in.csv", "ff.csv", "--force", capsys=capsys)
    assert (code, err) == (
        4,
        "hconv: error: ff.csv: is not a regular file (a named pipe (FIFO)); hconv writes OUT by renaming a "
        "finished file into place; give a file path, or - to write to stdout\n",
    )
    assert Path("ff.csv").is_fifo()


def test_output_force_through_a_symlink_writes_its_target_and_keeps_the_link(tmp_path, capsys, monkeypatch):
    """Before: the link itself was replaced by a file, its target left as it was."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    Path("real").mkdir()
    Path("real/out.csv").write_text("old\n")
    os.symlink("real/out.csv", "link.csv")
    code, _, err = run_inprocess("convert", "in.csv", "link.csv", "-q", capsys=capsys)
    assert (code, err) == (4, "hconv: error: link.csv: already exists; pass --force to overwrite it\n")
    code, _, err = run_inprocess("convert", "in.csv", "link.csv", "--force", "-q", capsys=capsys)
    assert (code, err) == (0, "")
    assert os.readlink("link.csv") == "real/out.csv"
    assert Path("real/out.csv").read_text().startswith(SCENE_CSV.read_text().split(",", 1)[0])
    assert [p.name for p in Path("real").iterdir()] == ["out.csv"]  # the temporary went beside the target


def test_output_parquet_to_stdout_on_a_terminal_is_refused(tmp_path):
    """Before: `hconv convert in.csv - --to parquet` wrote binary Parquet onto the terminal."""
    code, shown = run_on_terminal("convert", str(SCENE_CSV), "-", "--to", "parquet", "-q", cwd=tmp_path)
    assert (code, shown) == (2, "hconv: error: Parquet is binary: redirect stdout (> out.parquet) or use --to csv\n")


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_output_full_disk_names_the_output(fmt, tmp_path, capsys, monkeypatch):
    """A full disk while writing: the message names OUT, as every output error does (it said
    ``output: Error writing bytes to file. Detail: [errno 28] ...``)."""
    import errno

    from hconv.tables import csvwrite, parquetio

    writer = csvwrite.CsvWriter if fmt == "csv" else parquetio.ParquetWriter

    def full(self, table):
        raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")

    monkeypatch.setattr(writer, "write", full)
    pq.write_table(pa.table({"Hx": [1.0], "Hy": [2.0], "Hz": [3.0], "I": [2.0]}), tmp_path / "in.parquet")
    out = tmp_path / f"out.{fmt}"
    code, _, err = run_inprocess("convert", str(tmp_path / "in.parquet"), str(out), "-q", capsys=capsys)
    assert (
        code == 4
        and err == f"hconv: error: {out}: could not be written (No space left on device); nothing was written\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.parquet"]


def test_output_to_stdout_on_a_full_disk_names_stdout(tmp_path):
    (tmp_path / "in.csv").write_text("Hx,Hy,Hz,I\n1,2,3,2\n")
    with open("/dev/full", "wb") as full:
        proc = subprocess.run(
            [sys.executable, "-m", "hconv", "convert", "in.csv", "-", "--to", "csv", "-q"],
            stdout=full, stderr=subprocess.PIPE, cwd=tmp_path, timeout=120,
        )  # fmt: skip
    err = proc.stderr.decode()
    assert (
        proc.returncode == 4
        and err == "hconv: error: stdout: could not be written (No space left on device); nothing was written\n"
    )


@pytest.mark.parametrize("through", ["file link", "folder link", "hard link"])
def test_output_that_is_the_input_through_a_link_is_refused_and_the_input_kept(through, tmp_path, capsys):
    """OUT names the input by another path: refused as the input, even with --force, never the
    input replaced by its own conversion."""
    src = tmp_path / "a.parquet"
    code, _, err = run_inprocess("generate", str(src), "--rows", "5", capsys=capsys)
    before = src.read_bytes()
    if through == "file link":
        out = tmp_path / "link_to_a.parquet"
        out.symlink_to("a.parquet")
    elif through == "folder link":
        (tmp_path / "here").symlink_to(".")
        out = tmp_path / "here" / "a.parquet"
    else:
        out = tmp_path / "also_a.parquet"
        os.link(src, out)
    code, _, err = run_inprocess("convert", str(src), str(out), "--force", capsys=capsys)
    assert code == 4 and err == f"hconv: error: {out}: is the input file; write the output to another path\n"
    assert src.read_bytes() == before


def test_output_stdout_redirected_onto_the_input_is_refused(tmp_path):
    """``hconv convert a.csv - >> a.csv`` appended the output to its own input (exit 0). A real
    process: what is under test is the descriptor the shell hands it."""
    src = tmp_path / "a.csv"
    src.write_bytes(SCENE_CSV.read_bytes())
    before = src.read_bytes()
    with open(src, "ab") as out:
        proc = subprocess.run(
            [sys.executable, "-m", "hconv", "convert", str(src), "-", "--to", "csv"],
            stdout=out,
            stderr=subprocess.PIPE,
            timeout=300,
        )
    assert proc.returncode == 4 and src.read_bytes() == before
    assert proc.stderr.decode() == (
        "hconv: error: stdout: is the input file (redirected onto it); write the output to another path\n"
    )


def test_output_in_a_path_through_a_file_says_it_is_not_a_directory(tmp_path, capsys, monkeypatch):
    """It said "(Not a directory); check its permissions": not a permissions problem."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.csv").write_bytes(SCENE_CSV.read_bytes())
    code, _, err = run_inprocess("convert", "a.csv", "a.csv/o.parquet", capsys=capsys)
    assert (code, err) == (4, "hconv: error: a.csv/o.parquet: 'a.csv' is not a directory; give a path in a directory\n")


@pytest.mark.parametrize(
    "out, folder",
    [("nonexist_dir/", "nonexist_dir"), ("nonexist_dir/sub/", "nonexist_dir/sub"), ("nodir/o.csv", "nodir")],
)
def test_output_in_a_missing_directory_says_to_make_it(out, folder, tmp_path, capsys, monkeypatch):
    """Before: OUT nonexist_dir/ said to pass --to FORMAT, and with --to it was 'could not be
    written (Not a directory)'; the directory is missing, and the fix is to make it."""
    monkeypatch.chdir(tmp_path)
    Path("s.csv").write_bytes(SCENE_CSV.read_bytes())
    for extra in ((), ("--to", "csv")):
        code, _, err = run_inprocess("convert", "s.csv", out, *extra, capsys=capsys)
        assert (code, err) == (
            4,
            f"hconv: error: {out}: the directory {folder!r} does not exist; create it first (mkdir -p {folder})\n",
        )
    assert sorted(os.listdir()) == ["s.csv"]
    # the advice works
    os.makedirs(folder)
    code, _, err = run_inprocess("convert", "s.csv", out, "-q", capsys=capsys)
    assert code == 0, err


def test_output_ending_in_slash_on_a_file_says_it_is_not_a_directory(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("s.csv").write_bytes(SCENE_CSV.read_bytes())
    code, _, err = run_inprocess("convert", "s.csv", "s.csv/", capsys=capsys)
    assert (code, err) == (4, "hconv: error: s.csv/: 's.csv' is not a directory; give a path in a directory\n")


_COUNT_ROWS = """
import os, sys


class _Count:
    def find_spec(self, fullname, path=None, target=None):
        if fullname != "hconv.tables.pipeline":
            return None
        sys.meta_path.remove(self)
        import importlib.util

        spec = importlib.util.find_spec(fullname)
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            fn = module.convert_batch

            def counted(table, *args, **kwargs):
                out = fn(table, *args, **kwargs)
                with open(os.environ["HCONV_TEST_COUNT"], "a") as f:
                    f.write(f"{table.num_rows}\\n")
                return out

            module.convert_batch = counted

        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, _Count())
"""


def test_output_into_a_pipe_stops_when_its_reader_goes_away(tmp_path):
    """Before: `hconv convert big - --to csv | head -1` converted the whole file into a spool,
    then found the reader gone. Now rows stream into the pipe, and the reader closing it stops
    the run at its next write: exit 0, nothing on stderr, and only the batches already in
    flight converted. The bound is the pipeline's, not a time: one batch being written, two
    queued for the writer (BackgroundWriter's depth), threads + 1 converting ahead
    (ordered_map), the one in hand; 20 batches leave room, of 400."""
    import pyarrow.ipc as ipc

    batch_rows, batches = 500, 400
    n = batch_rows * batches
    t = pa.table({"id": pa.array(range(n)), "Hx": pa.array([2.0] * n), "Hy": pa.array([4.0] * n),
                  "Hz": pa.array([6.0] * n), "I": pa.array([2.0] * n)})  # fmt: skip
    src = tmp_path / "big.arrow"
    with ipc.new_file(str(src), t.schema) as w:  # batches of 500 rows, each more than a pipe holds as CSV
        for b in t.to_batches(max_chunksize=batch_rows):
            w.write_batch(b)
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(_COUNT_ROWS)
    count = tmp_path / "converted"
    env = dict(os.environ, HCONV_TEST_COUNT=str(count))
    env["PYTHONPATH"] = os.pathsep.join([str(hook), env.get("PYTHONPATH", "")])
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", str(src), "-", "--to", "csv", "--threads", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    assert proc.stdout is not None and proc.stderr is not None
    header = proc.stdout.readline()
    proc.stdout.close()  # as `head -1` does
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == 0, err
    assert header.startswith(b"id,Hx,Hy,Hz,I,wx,wy,wz")
    assert err == b""  # quietly: no error, and no summary claiming rows that no one read
    converted = sum(int(k) for k in count.read_text().split())
    assert 0 < converted <= 20 * batch_rows < n


def test_output_into_a_pipe_streams_every_row(tmp_path):
    """A reader that stays gets every row, in order, as from a file."""
    proc = subprocess.run(
        [sys.executable, "-m", "hconv", "convert", str(SCENE_CSV), "-", "--to", "csv", "-q"],
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    code = subprocess.run(
        [sys.executable, "-m", "hconv", "convert", str(SCENE_CSV), str(tmp_path / "out.csv"), "-q"], timeout=300
    ).returncode
    assert code == 0
    assert proc.stdout == (tmp_path / "out.csv").read_bytes()


@pytest.mark.parametrize(
    "args, name",
    [((), "s.csv"), (("--to", "parquet"), "s.parquet"), (("--to", "arrow"), "s.arrow"), (("--to", "csv"), "s.csv")],
)
def test_output_existing_directory_gets_the_input_name(args, name, tmp_path, capsys, monkeypatch):
    """Before: `hconv convert s.csv outdir` said to pass --to csv, which then failed 'is a directory'."""
    monkeypatch.chdir(tmp_path)
    Path("s.csv").write_bytes(SCENE_CSV.read_bytes())
    Path("outdir").mkdir()
    code, _, err = run_inprocess("convert", "s.csv", "outdir", "-q", *args, capsys=capsys)
    assert code == 0, err
    assert os.listdir("outdir") == [name]
    code, _, err = run_inprocess("convert", "s.csv", "outdir", "-q", *args, capsys=capsys)
    assert code == 4 and err == f"hconv: error: outdir/{name}: already exists; pass --force to overwrite it\n"
    code, _, err = run_inprocess("convert", "s.csv", "outdir", "-q", "--force", *args, capsys=capsys)
    assert code == 0, err


def test_output_existing_directory_for_stdin_is_refused(tmp_path):
    from hconv.errors import UsageError
    from hconv.tables.output import into_directory

    with pytest.raises(UsageError, match=r"is a directory, and stdin has no name to give the output; give OUT"):
        into_directory("-", str(tmp_path), "csv", None)


def test_output_force_refuses_an_input_a_glob_made_into_out(tmp_path, capsys, monkeypatch):
    """Before: `hconv convert two/*.csv --force`, two/a.csv two/b.csv to the command, replaced
    b.csv (an input) by a.csv's output, exit 0."""
    monkeypatch.chdir(tmp_path)
    Path("two").mkdir()
    Path("two/a.csv").write_bytes(SCENE_CSV.read_bytes())
    Path("two/b.csv").write_bytes(SCENE_CSV.read_bytes())
    code, _, err = run_inprocess("convert", "two/a.csv", "two/b.csv", "--force", "-q", capsys=capsys)
    assert (code, err) == (
        4,
        "hconv: error: two/b.csv: looks like an input (it has H and I columns, not hconv's output "
        "columns), so --force does not overwrite it (an unquoted glob?); quote the glob, or remove or "
        "rename the file\n",
    )
    assert Path("two/b.csv").read_bytes() == SCENE_CSV.read_bytes()
    assert sorted(p.name for p in Path("two").iterdir()) == ["a.csv", "b.csv"]


@pytest.mark.parametrize("fmt", ["csv", "parquet", "arrow"])
@pytest.mark.parametrize("before", [(), ("--prefix", "out_")])
def test_output_force_overwrites_hconvs_own_output(fmt, before, tmp_path, capsys, monkeypatch):
    """--force still replaces an earlier output of hconv, whatever its format or --prefix, and an
    input-like OUT in Parquet or Arrow is refused as one in CSV is."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    out = f"out.{fmt}"
    assert run_inprocess("convert", "in.csv", out, *before, "-q", capsys=capsys)[:2] == (0, "")
    for again in [(), ("--prefix", "out_")]:
        code, _, err = run_inprocess("convert", "in.csv", out, "--force", *again, "-q", capsys=capsys)
        assert (code, err) == (0, "")
    # an input in that format (written without hconv's columns): refused
    if fmt == "csv":
        Path(out).write_bytes(SCENE_CSV.read_bytes())
    else:
        table = pa.csv.read_csv(SCENE_CSV)
        if fmt == "parquet":
            pq.write_table(table, out)
        else:
            with pa.ipc.new_file(out, table.schema) as w:
                w.write_table(table)
    before_bytes = Path(out).read_bytes()
    code, _, err = run_inprocess("convert", "in.csv", out, "--force", "-q", capsys=capsys)
    assert code == 4 and f"{out}: looks like an input" in err and err.count("\n") == 1
    assert Path(out).read_bytes() == before_bytes


def test_output_force_refuses_an_input_with_a_status_of_its_own_or_hconvs_metadata(tmp_path, capsys, monkeypatch):
    """Before (second trial): an input with its own `status` (the reason for --prefix), or a
    Parquet table of hconv's whose ω columns were dropped (its metadata kept), counted as
    hconv's output, and `--force --prefix out_` replaced it, exit 0."""
    monkeypatch.chdir(tmp_path)
    own = "Hx,Hy,Hz,I,status\n1,2,3,2,landed\n"
    Path("a.csv").write_text(own)
    Path("b.csv").write_text(own)
    code, _, err = run_inprocess("convert", "a.csv", "b.csv", "--force", "--prefix", "out_", "-q", capsys=capsys)
    assert code == 4 and "b.csv: looks like an input" in err
    assert Path("b.csv").read_text() == own
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    assert run_inprocess("convert", "in.csv", "done.parquet", "-q", capsys=capsys)[0] == 0
    done = pq.read_table("done.parquet")
    stripped = done.drop_columns(
        [c for c in done.column_names if c in ("wx", "wy", "wz", "residual", "cond", "status")]
    )
    assert any(k.startswith(b"hconv.") for k in stripped.schema.metadata)  # pyarrow kept it
    pq.write_table(stripped, "c.parquet")
    kept = Path("c.parquet").read_bytes()
    code, _, err = run_inprocess("convert", "in.csv", "c.parquet", "--force", "-q", capsys=capsys)
    assert code == 4 and "c.parquet: looks like an input" in err
    assert Path("c.parquet").read_bytes() == kept


@pytest.mark.parametrize("force", [(), ("--force",)])
def test_output_missing_input_is_the_inputs_error_whatever_out_is(force, tmp_path, capsys, monkeypatch):
    """Before: with OUT there, a missing IN exited 4, "nosuch.csv: No such file or directory;
    nothing was written" (the output's check of IN and OUT being one file); without OUT, 3."""
    monkeypatch.chdir(tmp_path)
    Path("o.csv").write_text("kept\n")
    code, _, err = run_inprocess("convert", "nosuch.csv", "o.csv", *force, capsys=capsys)
    assert (code, err) == (3, "hconv: error: nosuch.csv: does not exist; check the path\n")
    assert Path("o.csv").read_text() == "kept\n"


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_output_in_a_folder_that_takes_no_files_says_so(tmp_path, capsys, monkeypatch):
    """Before: "cannot write in '/proc' (No such file or directory); check its permissions"."""
    monkeypatch.chdir(tmp_path)
    Path("q.csv").write_bytes(SCENE_CSV.read_bytes())
    code, _, err = run_inprocess("convert", "q.csv", "/proc/x.csv", "-q", capsys=capsys)
    assert (code, err) == (
        4,
        "hconv: error: /proc/x.csv: cannot create a file in '/proc': it takes no new files (a pseudo file "
        "system, as /proc and /sys are); write OUT in another directory\n",
    )
