"""Opening an input (hconv.tables.tableio and its readers): stdin's spool, the temporary file a
killed run leaves, and what hconv says about an input it cannot read."""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import StopAt, run_hconv, run_inprocess, terminal_signals

import hconv
import hconv.errors
from hconv.tables.job import Job
from hconv.tables.tableio import open_input

ROOT = Path(__file__).resolve().parents[1]
SCENE_CSV = ROOT / "examples" / "data" / "scene.csv"


def _hconv(*args: str, tmpdir: Path, stop: StopAt | None = None, **kw) -> subprocess.Popen:
    """The real command, with its own temporary directory so that what it leaves there is seen;
    ``stop``: a point where it waits for the test (helpers.StopAt)."""
    env = dict(os.environ, TMPDIR=str(tmpdir), COLUMNS="200")
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=stop.env(env) if stop else env,
        preexec_fn=terminal_signals,
        pass_fds=stop.fds if stop else (),
        **kw,
    )
    if stop:
        stop.started()
    return proc


def _wait_for(found, what: str, proc: subprocess.Popen) -> None:
    """Until ``found()``: a file hconv makes while it runs and keeps while it waits (on a pipe, or
    at a StopAt), so no deadline; a run that ends first fails the test."""
    while not found():
        assert proc.poll() is None, f"hconv ended before {what}: {proc.stderr.read().decode() if proc.stderr else ''}"
        time.sleep(0.02)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_open_input_interrupted_while_spooling_stdin_leaves_no_spool(sig, tmp_path):
    """`(cat scene.csv; sleep 5) | hconv convert - out.csv --from csv`, then Ctrl-C or SIGTERM:
    the spool of stdin is removed, as after a finished run."""
    spools = tmp_path / "tmp"
    spools.mkdir()
    out = tmp_path / "out.csv"
    # Stopped as it reads its first chunk, the spool made (helpers.StopAt). Sent as soon as the
    # spool was seen, a SIGINT once left the child reading the open pipe for ever (issue 25).
    stop = StopAt(tmp_path / "hook", "hconv.tables.tableio:_read_chunk")
    proc = _hconv("convert", "-", str(out), "--from", "csv", "-q", tmpdir=spools, stop=stop, stdin=subprocess.PIPE)
    assert proc.stdin is not None and proc.stderr is not None
    proc.stdin.write(SCENE_CSV.read_bytes()[:4096])  # within the pipe's buffer: hconv waits at the stop
    proc.stdin.flush()  # and the pipe stays open: hconv is still reading it
    assert stop.reached(), proc.stderr.read().decode()
    assert any(spools.iterdir())  # the spool of stdin, to be removed
    proc.send_signal(sig)
    stop.release()
    code = proc.wait()
    err = proc.stderr.read().decode()
    proc.stdin.close()
    assert code == 130, err
    assert err.startswith("hconv: error: interrupted") and len(err.strip().splitlines()) == 1, err
    assert list(spools.iterdir()) == [] and not out.exists()


class _FailingStream:
    def __init__(self, data: bytes = b"", error: OSError | None = None):
        self.data, self.error = data, error

    def read(self, n: int) -> bytes:
        if self.error:
            raise self.error
        chunk, self.data = self.data[:n], self.data[n:]
        return chunk


def test_spool_read_error_or_full_temporary_directory_is_one_line_and_no_spool(tmp_path, monkeypatch):
    import errno
    import tempfile

    from hconv.errors import InputError, OutputError
    from hconv.tables import tableio

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with pytest.raises(InputError, match=r"^stdin: cannot read it \(Input/output error\)$"):
        tableio.spool(_FailingStream(error=OSError(errno.EIO, "Input/output error")), "stdin")
    assert list(tmp_path.iterdir()) == []

    real = os.fdopen

    class Full:
        def __init__(self, f):
            self.f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, chunk):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fdopen", lambda fd, mode: Full(real(fd, mode)))
    with pytest.raises(OutputError, match="No space left on device.*set TMPDIR to a directory with room"):
        tableio.spool(_FailingStream(b"Hx,Hy,Hz,I\n1,2,3,4\n"), "stdin")
    assert list(tmp_path.iterdir()) == []


def _scene_parquet(path: Path, copies: int) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    scene = pq.read_table(ROOT / "examples" / "data" / "scene.parquet")
    pq.write_table(pa.concat_tables([scene] * copies), path)


@pytest.mark.parametrize("left", ["output", "stdin", "stdout"])
def test_output_removes_the_temporary_file_of_a_killed_run_and_says_so(left, tmp_path):
    """`kill -9` leaves a temporary file behind: beside OUT while converting, or stdin's or
    stdout's spool in the temporary directory. The next run that writes there removes it."""
    spools = tmp_path / "tmp"
    spools.mkdir()
    out = tmp_path / "out.parquet"
    if left == "output":  # caught at work: stopped as it writes its first batch (helpers.StopAt)
        _scene_parquet(tmp_path / "big.parquet", 500)
        args = ["convert", str(tmp_path / "big.parquet"), str(out), "--engine", "numpy", "--threads", "1"]
        stop = StopAt(tmp_path.parent / f"{tmp_path.name}-hook", "hconv.tables.output:Output.write")
        proc = _hconv(*args, tmpdir=spools, stop=stop)
        assert stop.reached(), proc.communicate()[1].decode()
        where = tmp_path
    elif left == "stdin":  # still reading a pipe that stays open
        proc = _hconv("convert", "-", str(out), "--from", "csv", tmpdir=spools, stdin=subprocess.PIPE)
        proc.stdin.write(SCENE_CSV.read_bytes())  # type: ignore[union-attr]
        proc.stdin.flush()  # type: ignore[union-attr]
        where = spools
    else:  # done, and writing to a stdout that nobody reads (--strict: all or nothing, so spooled)
        proc = _hconv("convert", str(SCENE_CSV), "-", "--to", "csv", "--strict", tmpdir=spools)
        where = spools
    temporaries = lambda: [p for p in where.iterdir() if p.name.endswith(".hconv-tmp")]  # noqa: E731
    _wait_for(temporaries, "temporary file", proc)
    proc.kill()
    proc.wait()  # reaped: a zombie still holds its pid
    if left == "output":
        stop.release()
    for f in (proc.stdin, proc.stdout, proc.stderr):
        if f:
            f.close()
    (stale,) = temporaries()
    assert f".{proc.pid}-" in stale.name or f"-{proc.pid}-" in stale.name

    again = subprocess.run(
        [sys.executable, "-m", "hconv", "convert", "-", str(out), "--from", "csv", "-q"],
        input=SCENE_CSV.read_bytes(),
        capture_output=True,
        env=dict(os.environ, TMPDIR=str(spools)),
        timeout=120,
    )
    err = again.stderr.decode()
    assert again.returncode == 0, err
    assert err == f"hconv: removed stale temporary file {stale} left by a run that was killed (pid {proc.pid})\n"
    assert not stale.exists() and out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".hconv-tmp")] == []
    assert list(spools.iterdir()) == []


def _as(kind: str, text: bytes) -> bytes:
    """``text`` as the files people hand hconv by mistake."""
    import bz2
    import gzip
    import lzma
    import zipfile

    if kind in ("zip", "xlsx"):
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as z:
            if kind == "xlsx":
                z.writestr("[Content_Types].xml", "<Types/>")
            z.writestr("in.csv", text)
        return buf.getvalue()
    packers = {"gzip": gzip.compress, "bzip2": bz2.compress, "xz": lzma.compress}
    if kind in packers:
        return packers[kind](text)
    if kind == "zstd":  # the standard library has no zstd: its frame magic, then the bytes
        return b"\x28\xb5\x2f\xfd" + text
    if kind == "xls":
        return b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + b"\x00" * 504
    return text.decode().encode(kind)  # an encoding


KINDS = ("gzip", "bzip2", "xz", "zstd", "zip", "xlsx", "xls", "utf-16", "utf-16-le", "utf-16-be", "utf-32")
SAVE_AS = "open it in the spreadsheet and save the sheet as 'CSV UTF-8 (comma delimited)'"


@pytest.mark.parametrize(
    "kind, message",
    [
        (
            "gzip",
            "is gzip-compressed; hconv reads uncompressed CSV, so decompress it first: gzip -dc in.csv > in-plain.csv",
        ),
        (
            "bzip2",
            "is bzip2-compressed; hconv reads uncompressed CSV, so decompress it first: "
            "bzip2 -dc in.csv > in-plain.csv",
        ),
        ("xz", "is xz-compressed; hconv reads uncompressed CSV, so decompress it first: xz -dc in.csv > in-plain.csv"),
        (
            "zstd",
            "is zstd-compressed; hconv reads uncompressed CSV, so decompress it first: zstd -dc in.csv > in-plain.csv",
        ),
        (
            "zip",
            "is a zip archive; hconv reads uncompressed CSV, so decompress it first: unzip -p in.csv > in-plain.csv",
        ),
        ("xlsx", f"is an Excel workbook (.xlsx), not CSV; {SAVE_AS}"),
        ("xls", f"is an Excel 97-2003 workbook (.xls), not CSV; {SAVE_AS}"),
        (
            "utf-16",
            "is UTF-16 text; hconv reads UTF-8, so convert it first: iconv -f UTF-16 -t UTF-8 in.csv > in-utf8.csv",
        ),
        (
            "utf-16-le",
            "is UTF-16LE text; hconv reads UTF-8, so convert it first: iconv -f UTF-16LE -t UTF-8 in.csv > in-utf8.csv",
        ),
        (
            "utf-16-be",
            "is UTF-16BE text; hconv reads UTF-8, so convert it first: iconv -f UTF-16BE -t UTF-8 in.csv > in-utf8.csv",
        ),
        (
            "utf-32",
            "is UTF-32 text; hconv reads UTF-8, so convert it first: iconv -f UTF-32 -t UTF-8 in.csv > in-utf8.csv",
        ),
    ],
    ids=KINDS,
)
def test_open_input_csv_compressed_or_utf16_says_what_it_is_and_how_to_convert(
    kind, message, tmp_path, capsys, monkeypatch
):
    """Before, every one of these was 'in.csv: is not a text file, so not CSV', with no fix."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(_as(kind, SCENE_CSV.read_bytes()))
    code, _, err = run_inprocess("convert", "in.csv", "out.csv", capsys=capsys)
    assert (code, err) == (3, f"hconv: error: in.csv: {message}\n")
    assert sorted(os.listdir()) == ["in.csv"]


def test_open_input_compressed_stdin_says_to_decompress_in_the_pipe(tmp_path):
    got = run_hconv(
        "convert", "-", str(tmp_path / "out.csv"), "--from", "csv", input=_as("gzip", SCENE_CSV.read_bytes())
    )
    assert got.returncode == 3
    assert got.stderr.decode() == (
        "hconv: error: stdin: is gzip-compressed; hconv reads uncompressed CSV, "
        "so decompress it in the pipe, before hconv: ... | gzip -dc | hconv ...\n"
    )


def test_open_input_parquet_compressed_or_csv_says_what_it_is(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("in.parquet").write_bytes(_as("gzip", (ROOT / "examples" / "data" / "scene.parquet").read_bytes()))
    code, _, err = run_inprocess("convert", "in.parquet", "out.parquet", capsys=capsys)
    assert (code, err) == (
        3,
        "hconv: error: in.parquet: is gzip-compressed; hconv reads uncompressed Parquet, "
        "so decompress it first: gzip -dc in.parquet > in-plain.parquet\n",
    )
    Path("in.parquet").write_bytes(SCENE_CSV.read_bytes())
    code, _, err = run_inprocess("convert", "in.parquet", "out.parquet", capsys=capsys)
    assert (code, err) == (3, "hconv: error: in.parquet: is CSV text, not Parquet: rename it in.csv\n")


@pytest.mark.parametrize(
    "args, code, message",
    [
        (
            ["in.csv.gz", "out.csv"],
            3,
            "in.csv.gz: is gzip-compressed; hconv reads uncompressed CSV, so decompress it first: "
            "gzip -dc in.csv.gz > in-plain.csv",
        ),
        (
            ["in.csv", "out.csv.gz"],
            4,
            "out.csv.gz: hconv writes uncompressed CSV; write out.csv and compress it afterwards: gzip out.csv",
        ),
        (
            ["in.csv", "out.parquet.zip"],
            4,
            "out.parquet.zip: hconv writes uncompressed Parquet; write out.parquet and compress it afterwards: "
            "zip out.parquet.zip out.parquet",
        ),
    ],
)
def test_format_of_compressed_name_says_how_to_compress_or_decompress(
    args, code, message, tmp_path, capsys, monkeypatch
):
    """Before: 'cannot tell the format of 'in.csv.gz' from its extension', a usage error."""
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_bytes(SCENE_CSV.read_bytes())
    Path("in.csv.gz").write_bytes(_as("gzip", SCENE_CSV.read_bytes()))
    got, _, err = run_inprocess("convert", *args, capsys=capsys)
    assert (got, err) == (code, f"hconv: error: {message}\n")


README_POINTER = "(hconv convert takes a whole directory: see docs/datasets.md)"


@pytest.mark.parametrize(
    "command, given, message",
    [
        (
            "diagnose",
            "data",
            f"data: is a directory, and this command reads one file; give one of the 2 CSV or Parquet files in "
            f"it, such as data/part-0.parquet {README_POINTER}",
        ),
        (
            "compare",
            "empty.parquet",
            "empty.parquet: is a directory, and this command reads one file; give a CSV or Parquet file "
            + README_POINTER,
        ),
        ("convert", "scene.cvs", "scene.cvs: does not exist (did you mean scene.csv?); check the path"),
        ("convert", "nothing", "nothing: does not exist; check the path"),
        (
            "convert",
            "nowhere/in.csv",
            "nowhere/in.csv: does not exist, nor does the directory 'nowhere'; check the path",
        ),
        ("convert", "link.csv", "link.csv: is a link to 'gone.csv', which does not exist; check the link"),
    ],
)
def test_open_input_directory_or_missing_path_says_so(command, given, message, tmp_path, capsys, monkeypatch):
    """Before: 'cannot tell the format' (exit 2) for a directory or a missing path without an
    extension, and 'is a directory, not a CSV file' with no way on. (hconv convert takes a
    directory as a dataset: test_datasets.py.)"""
    monkeypatch.chdir(tmp_path)
    Path("data").mkdir()
    Path("data/part-0.parquet").write_bytes(b"")
    Path("data/part-1.parquet").write_bytes(b"")
    Path("empty.parquet").mkdir()
    Path("scene.csv").write_bytes(SCENE_CSV.read_bytes())
    os.symlink("gone.csv", "link.csv")
    code, _, err = run_inprocess(command, given, *(["out.csv"] if command == "convert" else []), capsys=capsys)
    assert (code, err) == (3, f"hconv: error: {message}\n")


def test_open_input_unreadable_file_is_one_line(tmp_path, capsys, monkeypatch):
    import builtins

    src = tmp_path / "in.csv"
    src.write_bytes(SCENE_CSV.read_bytes())
    real = builtins.open

    def refuse(file, *a, **k):  # root reads any file: refuse as the OS refuses anyone else
        if str(file) == str(src):
            raise PermissionError(13, "Permission denied", str(file))
        return real(file, *a, **k)

    monkeypatch.setattr(builtins, "open", refuse)
    code, _, err = run_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert (code, err) == (
        3,
        f"hconv: error: {src}: cannot read it (Permission denied); check the path and its permissions\n",
    )


def test_open_input_named_pipe_is_read_like_stdin(tmp_path):
    """`hconv convert <(gzip -dc in.csv.gz) out.csv --from csv`: a pipe cannot seek, so it is
    spooled as stdin is (before: 'cannot read it (lseek failed)', or a wait for a second writer)."""
    import threading

    spools = tmp_path / "tmp"
    spools.mkdir()
    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    # a daemon: if hconv never opens the pipe, the writer waits in open() and must not keep pytest
    threading.Thread(target=lambda: fifo.write_bytes(SCENE_CSV.read_bytes()), daemon=True).start()
    got = subprocess.run(
        [sys.executable, "-m", "hconv", "convert", str(fifo), str(tmp_path / "out.csv"), "--from", "csv", "-q"],
        capture_output=True,
        env=dict(os.environ, TMPDIR=str(spools)),
        timeout=60,
    )
    assert (got.returncode, got.stderr) == (0, b"")
    assert (tmp_path / "out.csv").read_text().count("\n") == SCENE_CSV.read_text().count("\n")
    assert list(spools.iterdir()) == []  # the spool is gone


def _scene_with(tmp_path, column) -> str:
    import pyarrow.parquet as pq

    t = pq.read_table(ROOT / "examples" / "data" / "scene.parquet")
    pq.write_table(t.append_column("extra", column(t.num_rows)), tmp_path / "in.parquet")
    return str(tmp_path / "in.parquet")


def _nested(kind):
    import pyarrow as pa

    if kind == "struct":
        return lambda n: pa.array([{"a": i} for i in range(n)])
    return lambda n: pa.array([[("k", i)] for i in range(n)], pa.map_(pa.string(), pa.int64()))


@pytest.mark.parametrize("kind, typename", [("struct", "struct<a: int64>"), ("map", "map<string, int64 ('extra')>")])
def test_convert_file_parquet_to_csv_with_a_column_csv_cannot_hold_is_refused(kind, typename, tmp_path):
    """Before: 'internal error: ArrowInvalid: Unsupported Type:struct<…>', exit 1."""
    from hconv.errors import InputError
    from hconv.tables.pipeline import convert_file

    src = _scene_with(tmp_path, _nested(kind))
    with pytest.raises(InputError) as err:
        convert_file(src, str(tmp_path / "out.csv"))
    assert str(err.value) == (
        f"{src}: column 'extra' is {typename}, which CSV cannot hold; write Parquet instead "
        "(OUT named .parquet), or drop the column first"
    )
    assert list(tmp_path.iterdir()) == [tmp_path / "in.parquet"]


def test_convert_file_parquet_to_csv_with_binary_not_utf8_is_refused(tmp_path, capsys):
    """Before: 'internal error: ArrowInvalid: Invalid UTF8 payload', exit 1, and then the message
    named no file. Binary that is text (a byte array without the string annotation) is written as text."""
    import pyarrow as pa

    src = _scene_with(tmp_path, lambda n: pa.array([b"\xff"] * n))
    code, _, err = run_inprocess("convert", src, str(tmp_path / "out.csv"), "-q", capsys=capsys)
    assert (code, err) == (
        3,
        f"hconv: error: {src}: column 'extra' is binary and holds bytes that are not UTF-8 text, which CSV "
        "cannot hold; write Parquet instead (OUT named .parquet), or drop the column first\n",
    )
    assert not (tmp_path / "out.csv").exists()
    src = _scene_with(tmp_path, lambda n: pa.array([b"text"] * n))
    code, _, err = run_inprocess("convert", src, str(tmp_path / "out.csv"), "-q", capsys=capsys)
    assert (code, err) == (0, "")
    assert (tmp_path / "out.csv").read_text().splitlines()[1].split(",")[18] == "text"


@pytest.mark.parametrize(
    "column, text",
    [
        (lambda n: __import__("pyarrow").array(["x"] * n).dictionary_encode(), "x"),
        (lambda n: __import__("pyarrow").array(["x"] * n, __import__("pyarrow").large_string()), "x"),
        (
            lambda n: __import__("pyarrow").array([0] * n, __import__("pyarrow").timestamp("s", tz="Europe/Paris")),
            "1970-01-01 01:00:00.000+0100",
        ),
        (lambda n: __import__("pyarrow").array([__import__("decimal").Decimal("1.50")] * n), "1.50"),
        (lambda n: __import__("pyarrow").nulls(n), ""),
    ],
    ids=["dictionary", "large_string", "timestamp_tz", "decimal", "null"],
)
def test_convert_file_parquet_to_csv_other_column_types_are_written_as_text(column, text, tmp_path):
    from hconv.tables.pipeline import convert_file

    convert_file(_scene_with(tmp_path, column), str(tmp_path / "out.csv"))
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert lines[0].split(",")[18] == "extra" and lines[1].split(",")[18] == text


def test_open_input_compressed_hint_names_a_file_that_does_not_exist_with_its_extension(tmp_path, capsys, monkeypatch):
    """Before: `gzip -dc ok.csv.gz > ok.csv` over an existing ok.csv, and `unzip -p ok.zip > ok`."""
    monkeypatch.chdir(tmp_path)
    Path("ok.csv").write_bytes(SCENE_CSV.read_bytes())
    Path("ok-plain.csv").write_bytes(b"mine\n")
    Path("ok.csv.gz").write_bytes(_as("gzip", SCENE_CSV.read_bytes()))
    code, _, err = run_inprocess("convert", "ok.csv.gz", "out.csv", capsys=capsys)
    assert (code, err) == (
        3,
        "hconv: error: ok.csv.gz: is gzip-compressed; hconv reads uncompressed CSV, so decompress it first: "
        "gzip -dc ok.csv.gz > ok-plain-2.csv\n",
    )
    Path("data.zip").write_bytes(_as("zip", SCENE_CSV.read_bytes()))
    code, _, err = run_inprocess("convert", "data.zip", "out.csv", "--from", "csv", capsys=capsys)
    assert (code, err) == (
        3,
        "hconv: error: data.zip: is a zip archive; hconv reads uncompressed CSV, so decompress it first: "
        "unzip -p data.zip > data.csv\n",
    )


def test_csv_writer_parquet_empty_string_and_null_stay_distinct(tmp_path):
    """Unquoted, both were an empty field; a null stays empty and the empty string is quoted."""
    import pyarrow as pa

    from hconv.tables.pipeline import convert_file

    src = _scene_with(tmp_path, lambda n: pa.array((["", None, "x"] * n)[:n]))
    convert_file(src, str(tmp_path / "out.csv"))
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert [line.split(",")[18] for line in lines[1:4]] == ['""', "", "x"]


def test_open_input_csv_nan_in_a_numeric_column_stays_nan_and_an_empty_field_stays_missing(tmp_path):
    """A file's NaN is a float value: pyarrow's default null markers include its spellings, and
    hconv turned it into a null (an empty field in CSV output, a null in Parquet)."""
    import math

    import pyarrow.parquet as pq

    src = tmp_path / "in.csv"
    src.write_text("Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz\nNaN,2,3,1,2,4,0,0,0\n,2,3,1,2,4,0,0,0\n-nan,NA,3,1,2,4,0,0,0\n")
    assert run_hconv("convert", str(src), str(tmp_path / "o.parquet"), "-q").returncode == 0
    got = pq.read_table(tmp_path / "o.parquet")
    hx, hy = got.column("Hx").to_pylist(), got.column("Hy").to_pylist()
    assert math.isnan(hx[0]) and hx[1] is None and math.isnan(hx[2])
    assert hy == [2.0, 2.0, None]  # NA is a missing value, as pyarrow reads it
    assert got.column("status").to_pylist() == ["invalid_input"] * 3
    assert run_hconv("convert", str(src), str(tmp_path / "o.csv"), "-q").returncode == 0
    first = [line.split(",")[0] for line in (tmp_path / "o.csv").read_text().splitlines()[1:]]
    assert first[0].lower() == "nan" and first[1] == "" and first[2].lower() in ("nan", "-nan")


# --- what pyarrow reads, and what it says when it cannot -------------------------------------


def _scene_csv(path: Path, rows: int, label=lambda k: f"b{k}") -> bytes:
    """A CSV of ``rows`` valid bodies (diagonal inertia), with a text column ``label``."""
    lines = ["Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz,label"]
    lines += [f"{k % 7 + 1},{k % 3},1,2,3,4,0,0,0,{label(k)}" for k in range(rows)]
    data = ("\n".join(lines) + "\n").encode()
    path.write_bytes(data)
    return data


def test_open_input_csv_error_leaves_no_python_read_on_pyarrow_threads(tmp_path, monkeypatch):
    """pyarrow reads a CSV ahead on its own threads. Given a Python file object, those threads
    call into the interpreter; after an error in the first block they were still reading when
    the process exited, and a thread coming back into an exiting interpreter aborts it
    (SIGABRT, 'terminate called without an active exception', 2 runs in 60 of `hconv convert`
    on such a file). So no read of the input may go through Python off the main thread: each is
    recorded here, deterministically, wherever the race would have gone."""
    import threading

    from hconv.tables import csvio, pipeline

    monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", 1 << 18)
    src = tmp_path / "bad.csv"
    data = _scene_csv(src, 20000)
    at = data.index(b",b", 100_000) + 2  # past the 64 KiB hconv checks itself, in pyarrow's first block
    src.write_bytes(data[:at] + b"\xe9\xff" + data[at:])
    off_main = []

    class Seen(io.FileIO):
        def read(self, n: int = -1) -> bytes:
            if threading.current_thread() is not threading.main_thread():
                off_main.append(threading.current_thread().name)
            return super().read(n)

    def seen_open(path, mode="r", *args, **kwargs):
        return Seen(path, "r") if mode == "rb" else open(path, mode, *args, **kwargs)

    monkeypatch.setattr(csvio, "open", seen_open, raising=False)
    with pytest.raises(hconv.errors.InputError, match="bad.csv: column 'label' holds text that is not UTF-8"):
        pipeline.convert_file(str(src), str(tmp_path / "out.parquet"))
    assert not off_main, f"pyarrow's threads read the input through Python: {sorted(set(off_main))}"
    assert not (tmp_path / "out.parquet").exists()


def _scene_parquet(path: Path, groups: int, rows: int = 50, checksums: bool = False) -> pa.Table:
    """A Parquet file of ``groups`` row groups of ``rows`` valid bodies, with a snappy text column."""
    import numpy as np

    n = groups * rows
    table = pa.table(
        {
            "Hx": np.arange(n, dtype=float),
            "Hy": np.ones(n),
            "Hz": np.ones(n),
            "Ixx": np.full(n, 2.0),
            "Iyy": np.full(n, 3.0),
            "Izz": np.full(n, 4.0),
            "Ixy": np.zeros(n),
            "Ixz": np.zeros(n),
            "Iyz": np.zeros(n),
            "label": [f"body {k} of a long enough name" for k in range(n)],
        }
    )
    pq.write_table(
        table, path, row_group_size=rows, compression="snappy", use_dictionary=False, write_page_checksum=checksums
    )
    return table


def _overwrite_chunk(path: Path, group: int, column: str, fill: bytes) -> None:
    """Overwrite the second half of a column chunk's pages in row group ``group`` (0-based) with
    ``fill``, repeated: its page header intact, its data damaged."""
    meta = pq.ParquetFile(path).metadata
    names = [meta.schema.column(k).name for k in range(meta.num_columns)]
    chunk = meta.row_group(group).column(names.index(column))
    start, size = chunk.data_page_offset, chunk.total_compressed_size
    data = bytearray(path.read_bytes())
    data[start + size // 2 : start + size] = (fill * size)[: size - size // 2]
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    ("column", "checksums", "why"),
    [
        ("label", False, "Corrupt snappy compressed data"),  # a compressed page that does not decompress
        ("Hx", True, "CRC checksum verification failed"),  # plain floats: only a checksum tells
    ],
    ids=["snappy", "checksum"],
)
def test_open_input_parquet_damaged_page_names_the_input_and_its_row_group(
    column, checksums, why, tmp_path, capsys, monkeypatch
):
    src = tmp_path / "in.parquet"
    _scene_parquet(src, groups=4, checksums=checksums)
    _overwrite_chunk(src, 2, column, b"\xff\x00\x13")
    monkeypatch.chdir(tmp_path)
    code, _, err = run_inprocess("convert", "in.parquet", "out.parquet", capsys=capsys)
    assert code == 3, err
    assert err.startswith("hconv: error: in.parquet: row group 3 of 4 (data rows 101-150) cannot be read (")
    assert why in err and "the file is damaged" in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.parquet"]


def test_open_input_parquet_whole_damaged_page_names_the_input_and_its_row_group(tmp_path):
    """A small file read into memory at once (``whole``) names a damaged page as one streamed does."""
    src = tmp_path / "in.parquet"
    _scene_parquet(src, groups=4, checksums=True)
    _overwrite_chunk(src, 2, "Hx", b"\xff\x00\x13")
    with (
        open_input(str(src), "parquet", Job(), "in.parquet", whole=True) as inp,
        pytest.raises(hconv.errors.InputError) as err,
    ):
        list(inp.batches)
    assert str(err.value).startswith("in.parquet: row group 3 of 4 (data rows 101-150) cannot be read (")
    assert "CRC checksum verification failed" in str(err.value)


def test_open_input_parquet_whole_reads_the_batches_a_streamed_read_does(tmp_path, monkeypatch):
    """Batches of PARQUET_BATCH_ROWS across row groups, the same whether the file is streamed
    or read into memory at once: a dataset's small file gives its single conversion's output."""
    from hconv.tables import parquetio

    monkeypatch.setattr(parquetio, "PARQUET_BATCH_ROWS", 70)
    src = tmp_path / "in.parquet"
    table = _scene_parquet(src, groups=3)
    got = {}
    for whole in (False, True):
        with open_input(str(src), "parquet", Job(), whole=whole) as inp:
            got[whole] = list(inp.batches)
    assert [b.num_rows for b in got[True]] == [b.num_rows for b in got[False]] == [70, 70, 10]
    assert pa.Table.from_batches(got[True]).equals(table) and pa.Table.from_batches(got[False]).equals(table)


def test_parquet_writer_writes_the_bytes_pyarrow_writes_with_hconvs_options(tmp_path):
    """hconv's writer buffers what pyarrow writes; the file is byte for byte pyarrow's own."""
    from hconv.tables.parquetio import ParquetWriter, parquet_write_options

    table = _scene_parquet(tmp_path / "in.parquet", groups=2)
    writer = ParquetWriter(str(tmp_path / "hconv.parquet"), table.schema)
    writer.write(table.slice(0, 60))
    writer.write(table.slice(60))
    writer.close()
    with pq.ParquetWriter(tmp_path / "pyarrow.parquet", table.schema, **parquet_write_options(table.schema)) as w:
        w.write_table(table.slice(0, 60))
        w.write_table(table.slice(60))
    assert (tmp_path / "hconv.parquet").read_bytes() == (tmp_path / "pyarrow.parquet").read_bytes()


@pytest.mark.parametrize(("fmt", "whole"), [("csv", False), ("parquet", False), ("parquet", True)])
def test_convert_file_input_rewritten_while_read_is_refused(fmt, whole, tmp_path, monkeypatch):
    """A file appended to, cut or rewritten in place while hconv reads it: what was read may mix
    two versions of it, which no later check would see. ``whole``: a dataset's small file, read
    into memory at once, is checked after its last batch as well."""
    from hconv.tables import csvio, parquetio, pipeline

    src = tmp_path / f"in.{fmt}"
    if fmt == "csv":
        monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", 1 << 12)
        _scene_csv(src, 2000)
    else:
        monkeypatch.setattr(parquetio, "PARQUET_BATCH_ROWS", 50)
        _scene_parquet(src, groups=4)
    calls = []

    def progress(done: int, total: int | None) -> None:  # after the first batch: another writer appends
        calls.append(done)
        if len(calls) == 1:
            with open(src, "ab") as f:
                f.write(b"1,2,3,4,5,6,0,0,0,late\n")

    changed = rf"in\.{fmt}: changed while hconv read it \(from \d+ to \d+ bytes"
    with pytest.raises(hconv.errors.InputError, match=changed):
        pipeline.convert_file(str(src), str(tmp_path / "out.parquet"), progress=progress, threads=1, whole=whole)
    assert len(calls) >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"in.{fmt}"]


@pytest.mark.parametrize("change", ["appended", "cut"])
def test_open_input_parquet_whole_changed_during_its_read_is_refused(change, tmp_path, monkeypatch):
    """A small file read into memory at once (``whole``) and appended to or cut while that read
    runs: its size and time are taken before the read, so the change is seen (taken after it,
    an append went unseen and the file's first bytes were converted), and a cut one is named as
    changed, not as a file without a Parquet footer."""
    from hconv.tables import parquetio, pipeline

    src = tmp_path / "in.parquet"
    _scene_parquet(src, groups=2)
    read_whole = parquetio._read_whole

    def racing(fd: int, size: int) -> pa.Buffer:
        if change == "cut":
            os.truncate(src, size // 2)
        data = read_whole(fd, size)
        if change == "appended":
            with open(src, "ab") as f:
                f.write(b"late")
        return data

    monkeypatch.setattr(parquetio, "_read_whole", racing)
    changed = r"^in\.parquet: changed while hconv read it \(from (\d+) to (\d+) bytes"
    with pytest.raises(hconv.errors.InputError, match=changed) as err:
        pipeline.convert_file(str(src), str(tmp_path / "out.parquet"), name="in.parquet", threads=1, whole=True)
    before, after = map(int, re.match(changed, str(err.value)).groups())
    assert after == (before + 4 if change == "appended" else before // 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.parquet"]


def test_open_input_csv_without_a_line_end_says_so_not_that_it_is_empty(tmp_path, capsys, monkeypatch):
    from hconv.tables import csvio

    monkeypatch.chdir(tmp_path)
    big = tmp_path / "one.csv"
    big.write_bytes(b"Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz" + b",1" * ((csvio.CSV_BLOCK_BYTES >> 1) + 10))
    code, _, err = run_inprocess("convert", "one.csv", "out.parquet", capsys=capsys)
    assert (code, err.strip()) == (
        3,
        "hconv: error: one.csv: has no line end in its first 4 MiB; a CSV is a header line and one line per "
        "row, each shorter than that: is it a CSV?",
    )
    # a header written without its newline is a table with no rows, as it is with one
    header = "Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz,note"
    (tmp_path / "header.csv").write_bytes(header.encode())
    code, _, err = run_inprocess("convert", "header.csv", "out.parquet", "-q", capsys=capsys)
    assert code == 0, err
    out = pq.read_table(tmp_path / "out.parquet")
    assert out.num_rows == 0 and ",".join(out.column_names[:10]) == header


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (
            lambda row: row + b"x" * (200 << 10),  # a row longer than pyarrow's block: it cut it there
            "data row 3000 runs on for more than 128 KiB in one value: a quote opened and never closed, or "
            "a line that is not CSV; fix that row",
        ),
        (
            lambda row: b'"' + row,  # the rest of the file (under 128 KiB) is one value
            "data row 3000 has 1 values where the header names 10, one of them running over several lines: "
            "a quote opened and never closed? close it",
        ),
    ],
    ids=["long", "quote"],
)
def test_open_input_csv_row_cut_by_a_block_end_or_an_open_quote_is_named(
    damage, message, tmp_path, capsys, monkeypatch
):
    """pyarrow splits a CSV into blocks; a row it cannot end within one came out as 'a row has 1
    values', naming no row, though the row had all its values."""
    from hconv.tables import csvio

    monkeypatch.setattr(csvio, "CSV_BLOCK_BYTES", 1 << 16)
    monkeypatch.chdir(tmp_path)
    lines = _scene_csv(tmp_path / "in.csv", 3500).split(b"\n")
    lines[3000] = damage(lines[3000])
    (tmp_path / "in.csv").write_bytes(b"\n".join(lines))
    code, _, err = run_inprocess("convert", "in.csv", "out.parquet", capsys=capsys)
    assert (code, err.strip()) == (3, f"hconv: error: in.csv: {message}")


@pytest.mark.parametrize("fmt", ["arrow-stream", "arrow-file", "jsonl"])
def test_open_input_stdin_as_arrow_or_json_lines(fmt, tmp_path, monkeypatch):
    """`… | hconv convert - out --from arrow` (or jsonl): stdin spooled, then read as that format."""
    import io
    import json

    import pyarrow.ipc as ipc

    from hconv.tables import pipeline

    t = pq.read_table(ROOT / "examples" / "data" / "scene.parquet")
    sink = io.BytesIO()
    if fmt == "jsonl":
        sink.write("".join(json.dumps(r) + "\n" for r in t.to_pylist()).encode())
    else:
        with (ipc.new_stream if fmt == "arrow-stream" else ipc.new_file)(sink, t.schema) as w:
            w.write_table(t)

    class Stdin:
        buffer = io.BytesIO(sink.getvalue())

        def isatty(self):
            return False

    monkeypatch.setattr(sys, "stdin", Stdin())
    out = tmp_path / "out.parquet"
    pipeline.convert_file("-", str(out), src_format=fmt.split("-")[0])
    got = pq.read_table(out)
    assert got.column("wx").to_pylist() == hconv.convert_table(t).column("wx").to_pylist()
