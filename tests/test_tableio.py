"""Tables in and out: the temporary files hconv makes (stdin's spool, the output's atomic
temporary) and what it says about an input it cannot read."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import terminal_signals

ROOT = Path(__file__).resolve().parents[1]
SCENE_CSV = ROOT / "examples" / "data" / "scene.csv"


def _hconv(*args: str, tmpdir: Path, **kw) -> subprocess.Popen:
    """The real command, with its own temporary directory so that what it leaves there is seen."""
    env = dict(os.environ, TMPDIR=str(tmpdir), COLUMNS="200")
    return subprocess.Popen(
        [sys.executable, "-m", "hconv", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=terminal_signals,
        **kw,
    )


def _wait_for(found, what: str, proc: subprocess.Popen, seconds: float = 60) -> None:
    deadline = time.time() + seconds
    while time.time() < deadline and not found():
        assert proc.poll() is None, f"hconv ended before {what}: {proc.stderr.read().decode() if proc.stderr else ''}"
        time.sleep(0.02)
    assert found(), f"no {what} after {seconds} s"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_open_input_interrupted_while_spooling_stdin_leaves_no_spool(sig, tmp_path):
    """`(cat scene.csv; sleep 5) | hconv convert - out.csv --from csv`, then Ctrl-C or SIGTERM:
    the spool of stdin is removed, as after a finished run."""
    spools = tmp_path / "tmp"
    spools.mkdir()
    out = tmp_path / "out.csv"
    proc = _hconv("convert", "-", str(out), "--from", "csv", "-q", tmpdir=spools, stdin=subprocess.PIPE)
    assert proc.stdin is not None and proc.stderr is not None
    proc.stdin.write(SCENE_CSV.read_bytes())
    proc.stdin.flush()  # and the pipe stays open: hconv is still reading it
    _wait_for(lambda: any(spools.iterdir()), "spool of stdin", proc)
    time.sleep(0.2)
    proc.send_signal(sig)
    code = proc.wait(timeout=60)
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
        tableio._spool(_FailingStream(error=OSError(errno.EIO, "Input/output error")), "stdin")
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
        tableio._spool(_FailingStream(b"Hx,Hy,Hz,I\n1,2,3,4\n"), "stdin")
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
    if left == "output":  # a conversion slow enough to be caught at work: the interpreted engine
        _scene_parquet(tmp_path / "big.parquet", 500)
        args = ["convert", str(tmp_path / "big.parquet"), str(out), "--engine", "python", "--threads", "1"]
        proc = _hconv(*args, tmpdir=spools)
        where = tmp_path
    elif left == "stdin":  # still reading a pipe that stays open
        proc = _hconv("convert", "-", str(out), "--from", "csv", tmpdir=spools, stdin=subprocess.PIPE)
        proc.stdin.write(SCENE_CSV.read_bytes())  # type: ignore[union-attr]
        proc.stdin.flush()  # type: ignore[union-attr]
        where = spools
    else:  # done, and writing to a stdout that nobody reads
        proc = _hconv("convert", str(SCENE_CSV), "-", "--to", "csv", tmpdir=spools)
        where = spools
    temporaries = lambda: [p for p in where.iterdir() if p.name.endswith(".hconv-tmp")]  # noqa: E731
    _wait_for(temporaries, "temporary file", proc)
    time.sleep(0.3)
    proc.kill()
    proc.wait(timeout=60)  # reaped: a zombie still holds its pid
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


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="start times come from Linux's /proc")
def test_remove_stale_temporaries_leaves_live_and_unknown_makers_alone(tmp_path, capsys):
    from hconv.tables import tableio

    pid, start, tag = tableio._maker().split("-")
    other_tag = f"{(int(tag, 16) + 1) % (1 << 32):08x}"
    names = {
        f".out.parquet.{pid}-{start}-{tag}-abcd1234.hconv-tmp": "live",  # this process: running
        f"hconv-stdout-{pid}-{start}-{tag}-abcd1234.hconv-tmp": "live",
        f".out.csv.{pid}-{int(start) + 1}-{tag}-abcd1234.hconv-tmp": "stale",  # its pid, another start: reused
        f".out.csv.1-1-{other_tag}-abcd1234.hconv-tmp": "other host",  # pid 1 there means nothing here
        ".out.csv.abcd1234.hconv-tmp": "old name",  # an earlier hconv's: no maker to check
        "notes.txt": "not hconv's",
    }
    for name in names:
        (tmp_path / name).write_text("x")
    removed = tableio.remove_stale_temporaries(str(tmp_path))
    stale = [n for n, why in names.items() if why == "stale"]
    assert removed == [str(tmp_path / n) for n in stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(n for n in names if n not in stale)
    assert capsys.readouterr().err == (
        f"hconv: removed stale temporary file {tmp_path / stale[0]} left by a run that was killed (pid {pid})\n"
    )
