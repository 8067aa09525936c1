"""Worker processes converting a dataset's small files (hconv.tables.processes): real processes,
real files. The dataset-level behaviours (outputs, Ctrl-C, kill -9) are in test_datasets.py."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from hconv.tables import processes
from hconv.tables.job import Job
from hconv.tables.manifest import FileRecord
from hconv.tables.planning import plan_dataset
from hconv.tools.scene import make_scene


class _Dies:
    """Unpickled in a worker, ends it at once with exit code 3, as a crash would."""

    input = SimpleNamespace(rel="crash.parquet")

    def __reduce__(self):
        return (os._exit, (3,))


def _plan(tmp_path: Path, files: int):
    (tmp_path / "data").mkdir()
    for k in range(files):
        pq.write_table(pa.table(make_scene(30, seed=k)), tmp_path / "data" / f"part-{k}.parquet")
    return plan_dataset(str(tmp_path / "data"), str(tmp_path / "out"), job=Job())


def _workers(plan, count: int = 1) -> processes.Workers:
    return processes.Workers(count, plan.src.place, plan.dst, plan.job, strict=False, cli=False)


def test_send_receive_round_trip_and_end_of_stream():
    stream = io.BytesIO()
    processes.send(stream, {"a": [1, 2.5]})
    processes.send(stream, "second")
    stream.seek(0)
    assert processes.receive(stream) == {"a": [1, 2.5]} and processes.receive(stream) == "second"
    with pytest.raises(EOFError):
        processes.receive(stream)
    one = io.BytesIO()
    processes.send(one, list(range(100)))
    data = one.getvalue()
    for cut in (3, len(data) - 3):  # cut inside a length or a message: its writer died
        with pytest.raises(EOFError):
            processes.receive(io.BytesIO(data[:cut]))


def test_workers_convert_files_as_this_process_does(tmp_path):
    plan = _plan(tmp_path, 5)
    with _workers(plan, 2) as pool:
        got = [pool.submit(plan.todo[:3]), pool.submit(plan.todo[3:])]
        results = got[0].result() + got[1].result()
    assert not any(slot.died for slot in pool._slots)  # each ended at its stdin's end, exit code 0
    assert all(isinstance(r, FileRecord) for r in results)
    assert [r.output for r in results] == [t.output for t in plan.todo]
    for task in plan.todo:
        table = pq.read_table(tmp_path / "out" / task.output)
        assert table.num_rows == 30 and "wx" in table.column_names


def test_workers_worker_that_dies_fails_its_files_alone_and_the_next_start_another(tmp_path):
    plan = _plan(tmp_path, 3)
    with _workers(plan) as pool:
        first = pool.submit(plan.todo[:1]).result()
        died = pool.submit([plan.todo[1], _Dies()]).result()
        after = pool.submit(plan.todo[2:]).result()
    assert isinstance(first[0], FileRecord) and isinstance(after[0], FileRecord)
    assert [str(e) for e in died] == [
        f"{rel}: not converted: the process converting it failed (exit code 3; its error is above); "
        "run the same command again to retry it, or with --threads 1 to convert in this process"
        for rel in ("part-1.parquet", "crash.parquet")
    ]
    assert not (tmp_path / "out" / "part-1.parquet").exists()


class _Killed:
    """Unpickled in a worker, has it killed by SIGKILL, as the out-of-memory killer does."""

    input = SimpleNamespace(rel="huge.parquet")

    def __reduce__(self):
        return (os.system, ("kill -9 $PPID",))


@pytest.mark.skipif(sys.platform == "win32", reason="a POSIX shell's kill")
def test_workers_worker_killed_names_the_signal_and_what_to_do(tmp_path):
    plan = _plan(tmp_path, 1)
    with _workers(plan) as pool:
        (died,) = pool.submit([_Killed()]).result()
        assert isinstance(pool.submit(plan.todo).result()[0], FileRecord)
    assert str(died) == (
        "huge.parquet: not converted: the process converting it was killed (signal 9, as the system does "
        "when memory runs out); run the same command again to retry it, with fewer --threads if memory is short"
    )


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
def test_workers_ignore_ctrl_c_and_sigterm_from_their_start(tmp_path):
    """The parent stops a run and waits for the files under way: a terminal's Ctrl-C, which
    reaches every process of the group, must not cut a worker's file short, nor, while its
    interpreter starts, print a traceback: the worker starts with both blocked (inherited from
    the thread that starts it) and then ignores them."""
    plan = _plan(tmp_path, 1)
    with _workers(plan) as pool:
        assert pool.submit([]).result() == []  # the worker has started
        (pid,) = [slot._process.pid for slot in pool._slots]
        status = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
    for field in ("SigIgn", "SigBlk"):
        mask = int(status[field], 16)
        assert mask >> (signal.SIGINT - 1) & 1 and mask >> (signal.SIGTERM - 1) & 1, field
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])  # this thread still takes them


def test_workers_start_whatever_the_current_folder_holds(tmp_path, monkeypatch):
    """A ``signal.py`` or ``types.py`` in the current folder, which ``python -c`` would import
    in place of the standard module while the worker starts, changes nothing."""
    plan = _plan(tmp_path, 2)
    shadow = tmp_path / "shadow"
    shadow.mkdir()
    for name in ("signal", "types", "struct", "pickle"):
        (shadow / f"{name}.py").write_text("raise SystemExit(7)\n")
    monkeypatch.chdir(shadow)
    with _workers(plan) as pool:
        results = pool.submit(plan.todo).result()
    assert all(isinstance(r, FileRecord) for r in results), results


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_workers_end_when_their_parent_is_killed(tmp_path):
    """A parent killed outright takes its workers along, even one busy for long: none may go on
    writing into OUT while the next run does."""
    _plan(tmp_path, 1)
    script = f"""
import sys, time
sys.path[:0] = {sys.path!r}
from hconv.tables import processes
from hconv.tables.job import Job
from hconv.tables.planning import plan_dataset
plan = plan_dataset({str(tmp_path / "data")!r}, {str(tmp_path / "out")!r}, job=Job())
pool = processes.Workers(1, plan.src.place, plan.dst, plan.job, strict=False, cli=False)
pool.submit([])
while pool._slots[0]._process is None:
    time.sleep(0.01)
pool.submit([time_sleep_for_a_minute])
print(pool._slots[0]._process.pid, flush=True)
time.sleep(600)
""".replace("time_sleep_for_a_minute", "__import__('test_processes')._Sleeps()")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]))
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, env=env)
    pid = int(parent.stdout.readline())
    for _ in range(1000):  # until the worker is inside its minute, past reading its stdin
        if "nanosleep" in Path(f"/proc/{pid}/wchan").read_text():
            break
        time.sleep(0.01)
    else:
        raise AssertionError("the worker never began its minute")
    parent.kill()
    parent.communicate()
    for _ in range(500):
        if not Path(f"/proc/{pid}").exists() or " Z " in Path(f"/proc/{pid}/stat").read_text()[:40]:
            break
        time.sleep(0.01)
    else:
        os.kill(pid, signal.SIGKILL)
        raise AssertionError("the worker outlived its parent")


class _Sleeps:
    """Unpickled in a worker, keeps it busy for a minute."""

    def __reduce__(self):
        return (time.sleep, (60,))


def test_available_only_where_sys_executable_is_a_python(monkeypatch, tmp_path):
    assert processes.available()  # the interpreter running the tests
    blender = tmp_path / "blender"
    blender.write_text("#!/bin/sh\n")
    blender.chmod(0o755)
    for embedded in (str(blender), ""):  # an application embedding Python; none to tell
        monkeypatch.setattr(sys, "executable", embedded)
        assert not processes.available()
