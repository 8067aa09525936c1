"""`hconv bench` on a small run: every method and precision measured, targets computed, chart drawn."""

from __future__ import annotations

import functools
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from helpers import hconv_inprocess

import hconv
from hconv.tools import bench

ROOT = Path(__file__).resolve().parents[1]


def test_bench_command_small_run_writes_tables_json_and_chart(tmp_path, capsys, monkeypatch):
    """In this process, without a time limit: the bench starts its own processes (cold starts, a
    compile, the command's start-up), which take minutes on a loaded machine. Each is measured
    once, not three or ten times (cold starts, start-ups): every figure is still there."""
    once = bench.rounds
    monkeypatch.setattr(bench, "rounds", lambda jobs, repeats: once(jobs, 1))
    monkeypatch.setattr(bench, "cold_start", functools.partial(bench.cold_start, repeats=1))
    chart, data = tmp_path / "sva.png", tmp_path / "bench.json"
    args = ["bench", "--rows", "10000", "--repeats", "1", "--out", str(chart), "--json", str(data)]
    proc = hconv_inprocess(*args, capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    res = json.loads(data.read_text())
    keys = {f"{m}/{p}" for m in hconv.METHODS for p in (64, 32)}
    assert set(res["kernel"]) == keys and set(res["convert"]) == keys and set(res["accuracy"]) == keys
    assert all(v > 0 for v in res["kernel"].values())
    # accuracy is measured, not assumed: refined is correctly rounded, document far off
    assert res["accuracy"]["refined/64"]["10000"][1] <= 2.3e-16
    assert res["accuracy"]["document/64"]["10000"][0] > 0.1
    names = [t[0] for t in res["targets"]]
    assert "exact kernel / lapack kernel" in names and "convert exact / I/O roofline" in names
    for _name, value, required, met in res["targets"]:
        assert met is None or met == (value >= required)
    out = proc.stdout.decode()
    assert "targets" in out and "document-principal" in out
    # what users call comes first: hconv.convert against numpy.linalg.solve at 1, 100 and 10k rows
    assert list(res["user"])[:3] == ["1", "100", "10000"] and out.index("what users call") < out.index("kernel")
    for times in res["user"].values():
        assert times["numpy.linalg.solve"] > 0
        calls = [v for k, v in times.items() if k != "numpy.linalg.solve"]
        assert calls and all(set(by) >= {"auto", "numpy"} and min(by.values()) > 0 for by in calls)
    assert res["user"]["1"]["(N,3,3)"].keys() >= {"auto", "numpy", "python"}
    assert "solve / convert (N,3,3), one body, engine auto" in names
    assert "solve / convert (N,3,3), N = 2,000,000, engine auto" not in names  # not measured at 20k rows
    # a fresh process's first call, by engine
    assert res["cold"]["numpy"]["first_call_s"] > 0
    assert "pyarrow read+append+write time / hconv convert time" in names


def test_bench_rejects_other_chart_formats(tmp_path, capsys):
    proc = hconv_inprocess("bench", "--rows", "1000", "--out", str(tmp_path / "x.gif"), capsys=capsys)
    assert proc.returncode == 2 and ".png or .svg" in proc.stderr.decode()


def test_bench_rejects_rows_below_one_as_usage_error(capsys):
    for value in ("0", "-1"):
        proc = hconv_inprocess("bench", "--rows", value, "--no-chart", capsys=capsys)
        err = proc.stderr.decode()
        assert (
            proc.returncode == 2 and "--rows" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
        )


_LEFT_BY_KILL = """
from hconv.tools import bench
folder = bench.temporary_folder()
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
    live, other = bench.temporary_folder(), tmp_path / "hconv-bench-datasets-x"
    other.mkdir()
    said: list[str] = []
    with live:
        assert bench.remove_stale_folders(said.append) == [left]
        assert not os.path.exists(left) and os.path.isdir(live.name) and other.is_dir()
        assert said == [f"removed {left}, left by a bench run that was killed"]


_SCRIPT_LEFT_BY_KILL = """
import sys, tempfile
from hconv.tools import bench
folder = tempfile.mkdtemp(prefix=bench.folder_prefix("datasets-"), dir=sys.argv[1])
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
    assert bench.remove_stale_folders(where=str(tmp_path)) == [left] and not os.path.exists(left)
    for script in ("datasets.py", "cluster.py"):  # the scripts do name theirs so, and clean first
        text = (ROOT / "benchmarks" / script).read_text()
        assert "bench.folder_prefix(" in text and "bench.remove_stale_folders(print, a.dir)" in text


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's")
def test_child_dies_when_the_bench_is_killed():
    """A bench killed outright must not leave its children running: its cold-start child went on
    compiling for seconds and wrote into a folder the next run had removed (a newcomer trial)."""
    code = (
        "import sys\n"
        "from hconv.tools import bench\n"
        "bench._child([sys.executable, '-c', 'import os, time; print(os.getpid(), flush=True); time.sleep(3600)'])\n"
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
