"""What a bench run leaves when killed outright (hconv.tools.leftovers): its temporary folders,
removed by a later run once their maker is gone, and its children, which die with it."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from hconv.tools import leftovers

ROOT = Path(__file__).resolve().parents[1]


_LEFT_BY_KILL = """
from hconv.tools import leftovers
folder = leftovers.temporary_folder()
open(folder.name + "/in.parquet", "wb").close()
print(folder.name, flush=True)  # only now: the test kills this process once it reads the name
input()
"""


def test_remove_stale_folders_removes_killed_runs_keeps_live_ones(tmp_path, monkeypatch):
    """A bench run killed outright leaves its folder; the next run's start removes it, but never
    the folder of a run still going, nor a folder it cannot tell is a bench run's."""
    env = dict(os.environ, TMPDIR=str(tmp_path))
    with subprocess.Popen(
        [sys.executable, "-c", _LEFT_BY_KILL], stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env, text=True
    ) as killed:
        left = killed.stdout.readline().strip()
        killed.send_signal(signal.SIGKILL)
    assert killed.wait(timeout=60) == -signal.SIGKILL and os.path.isfile(os.path.join(left, "in.parquet"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    live, other = leftovers.temporary_folder(), tmp_path / "hconv-bench-datasets-x"
    other.mkdir()
    said: list[str] = []
    with live:
        assert leftovers.remove_stale_folders(said.append) == [left]
        assert not os.path.exists(left) and os.path.isdir(live.name) and other.is_dir()
        assert said == [f"removed {left}, left by a bench run that was killed"]


_SCRIPT_LEFT_BY_KILL = """
import sys, tempfile
from hconv.tools import leftovers
folder = tempfile.mkdtemp(prefix=leftovers.folder_prefix("datasets-"), dir=sys.argv[1])
print(folder, flush=True)
input()
"""


def test_remove_stale_folders_of_a_benchmark_script_in_its_own_directory(tmp_path):
    """benchmarks/datasets.py and cluster.py name their folders with folder_prefix, in --dir or
    the temporary directory: one left by a script killed outright is removed there too (before,
    their own names were never matched)."""
    with subprocess.Popen(
        [sys.executable, "-c", _SCRIPT_LEFT_BY_KILL, str(tmp_path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    ) as killed:
        left = killed.stdout.readline().strip()
        killed.send_signal(signal.SIGKILL)
    killed.wait(timeout=60)
    assert os.path.dirname(left) == str(tmp_path) and os.path.isdir(left)
    assert leftovers.remove_stale_folders(where=str(tmp_path)) == [left] and not os.path.exists(left)
    for script in ("datasets.py", "cluster.py"):  # the scripts do name theirs so, and clean first
        text = (ROOT / "benchmarks" / script).read_text()
        assert "leftovers.folder_prefix(" in text and "leftovers.remove_stale_folders(print, a.dir)" in text


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's")
def test_child_dies_when_the_bench_is_killed():
    """A bench killed outright must not leave its children running: its cold-start child went on
    compiling for seconds and wrote into a folder the next run had removed (a newcomer trial)."""
    code = (
        "import sys\n"
        "from hconv.tools import leftovers\n"
        "leftovers.child([sys.executable, '-c', 'import os, time; print(os.getpid(), flush=True); time.sleep(3600)'])\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    ended = os.pidfd_open(child)  # readable once the child has ended: an event to wait on, not a poll
    try:
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        # The kernel sends the parent-death signal as the parent ends; the wait's limit only
        # stops a test whose child lives on, and no load makes a dying process take 10 minutes.
        if not select.select([ended], [], [], 600)[0]:
            os.kill(child, signal.SIGKILL)
            raise AssertionError("the child outlived the killed bench")
    finally:
        os.close(ended)
