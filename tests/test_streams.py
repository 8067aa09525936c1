"""The command's standard streams (hconv.streams): closed or full, stdout fails the run naming
it (exit 4), stderr never changes the exit code. Real processes: what is under test is the file
descriptors a shell hands the command (``>&-``, ``2>&-``, ``> /dev/full``)."""

from __future__ import annotations

import errno
import os
import subprocess
import sys

import pytest

from hconv import streams

EXAMPLE = os.path.join(os.path.dirname(__file__), "..", "examples", "data", "scene.parquet")


def _run(args: list[str], close: int | None = None, **kw) -> subprocess.CompletedProcess:
    """``python -m hconv ARGS`` with file descriptor ``close`` closed as it starts."""
    return subprocess.run(
        [sys.executable, "-m", "hconv", *args],
        preexec_fn=None if close is None else (lambda: os.close(close)),
        timeout=300,
        **kw,
    )


def test_standard_streams_closed_stdout_is_exit_4_naming_it():
    proc = _run(["one", "--H", "1,2,3", "--I", "1,1,1"], close=1, stderr=subprocess.PIPE)
    assert proc.returncode == 4
    assert proc.stderr.decode() == "hconv: error: stdout: it was closed when hconv started; nothing was written\n"


def test_standard_streams_full_stdout_is_exit_4_naming_it():
    with open("/dev/full", "w") as full:
        proc = _run(["methods"], stdout=full, stderr=subprocess.PIPE)
    assert proc.returncode == 4
    assert proc.stderr.decode() == "hconv: error: stdout: No space left on device; nothing was written\n"


@pytest.mark.parametrize("stderr", ["closed", "full"])
def test_standard_streams_stderr_closed_or_full_leaves_the_exit_code_to_the_run(tmp_path, stderr):
    """Before: exit 1 (an internal error), after OUT was written in full."""
    out, bad = tmp_path / "o.csv", tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    with open("/dev/full", "w") as full:
        kw = {"close": 2} if stderr == "closed" else {"stderr": full}
        ok = _run(["convert", EXAMPLE, str(out)], **kw)
        failed = _run(["convert", str(bad), str(tmp_path / "o2.csv")], **kw)
    assert ok.returncode == 0 and len(out.read_text().splitlines()) == 401
    assert failed.returncode == 3 and not (tmp_path / "o2.csv").exists()


def test_standard_streams_named_write_failure_keeps_errno_and_broken_pipe():
    class Failing:
        def __init__(self, exc):
            self.exc = exc

        def write(self, text):
            raise self.exc

        flush = write

    named = streams._Named(Failing(OSError(errno.ENOSPC, "No space left on device")), "stdout")
    with pytest.raises(OSError) as info:
        named.write("x")
    assert (info.value.errno, info.value.filename) == (errno.ENOSPC, "stdout")
    with pytest.raises(BrokenPipeError):  # the reader's choice, which the command takes quietly
        streams._Named(Failing(BrokenPipeError(errno.EPIPE, "Broken pipe")), "stdout").write("x")
    assert streams._Forgiving(Failing(OSError(errno.ENOSPC, "full"))).write("abc") == 3
