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
