"""``hconv convert IN OUT --cluster ...``: a dataset's files converted on Dask. The tests start a
real scheduler and two workers as processes (one set for the module), run the real command in a
subprocess, and compare every output with the one-process ``hconv convert`` of the same dataset,
bit for bit; one test kills a worker mid-file, one interrupts the driver. They skip without Dask
(``pip install -e '.[dask]'``)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import S3_ENV, free_port, hconv_inprocess, need, run_hconv, run_inprocess, terminal_signals

import hconv
from hconv.errors import UsageError
from hconv.tables import temporaries
from hconv.tables.manifest import MANIFEST
from hconv.tools.scene import make_scene

distributed = need("distributed")

SRC = str(Path(__file__).resolve().parents[1] / "src")


def _write_dataset(root: Path, files: int, rows: int) -> None:
    """``files`` Parquet files in two hive partitions, a CSV, and files a dataset leaves out."""
    table = pa.table(make_scene(files * rows, seed=3, cond_max=1e6))
    for k in range(files):
        path = root / f"day={k % 2}" / f"part-{k:03d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table.slice(k * rows, rows), path)
    pacsv.write_csv(table.slice(0, rows), root / "day=0" / "extra.csv")
    (root / "_SUCCESS").write_bytes(b"")


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def _same_as_one_process(out: Path, data: Path, tmp: Path) -> dict:
    """Assert that every output in ``out`` is the one-process run's, bit for bit, and that no
    temporary file is left; returns the manifest. The one-process run is the library call that
    ``hconv convert DATA REF`` makes, in this process: the command's own run of a dataset is
    tests/test_datasets.py's, and a process started for each reference cost its start-up again."""
    ref = tmp / f"ref-{os.urandom(3).hex()}"
    assert hconv.convert_dataset(data, ref).complete
    got, want = _files(out), _files(ref)
    assert [p for p in got if p.endswith(temporaries.TEMP_SUFFIX)] == []
    assert set(got) == set(want)
    for rel in want:
        if rel != MANIFEST:
            assert got[rel] == want[rel], rel
    m = json.loads(got[MANIFEST])
    assert m["complete"] is True and m["failed"] == [] and m["pending"] == []
    # what the outputs hold; the input's time and ETag are where it was read from, seconds vary
    same = ("input", "output", "output_size", "rows", "statuses", "worst_residual", "worst_row", "engines")
    for a, b in zip(m["files"], json.loads(want[MANIFEST])["files"]):
        assert {k: a[k] for k in same} == {k: b[k] for k in same}
    return m


def _start_worker(address: str, tmp: Path, name: str) -> subprocess.Popen:
    """A Dask worker process (no nanny: a SIGKILL ends it for good), one task at a time, with the
    worktree's hconv and the S3 server's credentials."""
    env = dict(os.environ, PYTHONPATH=SRC, **S3_ENV)
    log = open(tmp / f"{name}.log", "wb")  # noqa: SIM115 - the process writes it until the fixture ends
    return subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-nanny"]
        + ["--no-dashboard", "--name", name, "--local-directory", str(tmp / name)],
        stdout=log,
        stderr=log,
        env=env,
    )


def _driver(scheduler: str, cwd: Path, *more: str) -> subprocess.Popen:
    """``hconv convert data out --cluster SCHEDULER`` started in ``cwd``, seeing Ctrl-C as from a
    terminal; one batch thread per task, so that a file takes long enough to be caught mid-way."""
    return subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "data", "out", "--cluster", scheduler, "--threads", "1", *more],
        cwd=cwd,
        stderr=subprocess.PIPE,
        preexec_fn=terminal_signals,
    )


def _kill_while_writing(victim: subprocess.Popen, driver: subprocess.Popen, out: Path, pattern: str) -> None:
    """Kill ``victim`` once a temporary file it writes (its name holds its pid) matching
    ``pattern`` appears in ``out``, while ``driver`` runs."""
    mark, deadline, killed = f".{victim.pid}-", time.time() + 60, False
    while not killed and driver.poll() is None and time.time() < deadline:
        killed = any(mark in p.name for p in out.rglob(pattern)) if out.exists() else False
        time.sleep(0.005)
    assert killed, "the victim wrote nothing while the run lasted"
    victim.kill()


def _wait_for_workers(address: str, n: int) -> None:
    with distributed.Client(address, timeout=20, set_as_default=False) as client:
        client.wait_for_workers(n, timeout=30)


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """The address of a Dask scheduler with two workers, each its own process, for this module."""
    tmp = tmp_path_factory.mktemp("dask")
    address = f"tcp://127.0.0.1:{free_port()}"
    log = open(tmp / "scheduler.log", "wb")  # noqa: SIM115
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1"]
            + ["--port", address.rsplit(":", 1)[1], "--no-dashboard"],
            stdout=log,
            stderr=log,
            env=dict(os.environ, PYTHONPATH=SRC),
        )
    ]
    try:
        procs += [_start_worker(address, tmp, f"w{k}") for k in range(2)]
        _wait_for_workers(address, 2)
        yield address
    finally:
        _stop(procs[::-1])


def test_convert_cluster_tcp_is_bit_for_bit_the_one_process_run(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_dataset(data, files=5, rows=2000)
    proc = run_hconv("convert", "data", "out", "--cluster", scheduler, cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    m = _same_as_one_process(tmp_path / "out", data, tmp_path)
    assert m["inputs"] == 6 and m["hconv"] == hconv.__version__
    assert f"converted on the Dask scheduler at {scheduler}, 2 workers" in err
    assert "# files: 6 converted, 0 already up to date; out/_hconv_manifest.json says the dataset is complete" in err
    again = run_hconv("convert", "data", "out", "--cluster", scheduler, cwd=tmp_path)
    assert again.returncode == 0 and "all 6 files already converted and up to date" in again.stderr.decode()
    assert "converted on" not in again.stderr.decode()  # nothing to convert: no cluster is asked


def test_convert_cluster_failing_file_is_named_and_the_others_finish(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_dataset(data, files=3, rows=500)
    (data / "day=1" / "broken.parquet").write_bytes(b"not parquet at all")
    proc = run_hconv("convert", "data", "out", "--cluster", scheduler, cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 3, err
    assert "hconv: error: data/day=1/broken.parquet: " in err and "Traceback" not in err
    m = json.loads((tmp_path / "out" / MANIFEST).read_text())
    assert m["complete"] is False and [f["input"] for f in m["failed"]] == ["day=1/broken.parquet"]
    assert len(m["files"]) == 4
    assert not [p for p in (tmp_path / "out").rglob("*") if p.name.endswith(temporaries.TEMP_SUFFIX)]


def test_convert_cluster_worker_killed_midfile_loses_nothing_and_leaves_no_temporary(scheduler, tmp_path):
    victim = _start_worker(scheduler, tmp_path, "victim")
    try:
        _wait_for_workers(scheduler, 3)
        data = tmp_path / "data"
        _write_dataset(data, files=6, rows=50_000)
        out = tmp_path / "out"
        driver = _driver(scheduler, tmp_path)
        _kill_while_writing(victim, driver, out, "*" + temporaries.TEMP_SUFFIX)  # while it writes an output
        _, err = driver.communicate(timeout=120)
        assert driver.returncode == 0, err.decode()
    finally:
        _stop([victim])
    m = _same_as_one_process(out, data, tmp_path)
    assert m["inputs"] == 7
    # the summary does not claim the workers it started with: one died (it said "3 workers")
    assert "3 workers (1 lost during the run; their files were converted again)" in err.decode()


def _write_large(root: Path, rows: int, group: int) -> None:
    """One Parquet file of ``rows`` rows in row groups of ``group`` (not a multiple of hconv's
    batch, so that a part starts inside a row group), beside a small file."""
    table = pa.table(make_scene(rows, seed=5, cond_max=1e6))
    (root / "day=0").mkdir(parents=True)
    pq.write_table(table, root / "day=0" / "big.parquet", row_group_size=group)
    pq.write_table(table.slice(0, 1000), root / "day=0" / "small.parquet")


def _tasks(client, run) -> list[tuple[str, str]]:
    """(key, worker) of every task that ``run()`` ran on ``client``'s cluster."""
    with distributed.get_task_stream(client=client) as stream:
        run()
    return [(t["key"], t["worker"]) for t in stream.data]


def test_convert_cluster_split_file_is_bit_for_bit_the_one_process_run(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_large(data, rows=200_000, group=50_000)
    with distributed.Client(scheduler, set_as_default=False) as client:
        ran = _tasks(client, lambda: hconv.convert_dataset(data, tmp_path / "out", cluster=client, task_rows=65536))
    parts = [(k, w) for k, w in ran if "-part-" in k]
    assert len(parts) == 3  # 65536 rows, 65536, and the 68928 left (its short tail joined)
    assert len({w for _, w in parts}) == 2  # both workers converted parts
    m = _same_as_one_process(tmp_path / "out", data, tmp_path)  # its record too: rows, statuses, worst row
    assert "parts_run" not in m  # named only while parts may exist, for a killed driver's next run
    assert [f["rows"] for f in m["files"]] == [200_000, 1000]


def test_convert_cluster_task_rows_leaves_files_whole(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_large(data, rows=140_000, group=50_000)
    with distributed.Client(scheduler, set_as_default=False) as client:
        for k, rows in enumerate([0, 140_000]):  # off; and a file not above the threshold
            out = tmp_path / f"out{k}"
            ran = _tasks(client, lambda: hconv.convert_dataset(data, out, cluster=client, task_rows=rows))  # noqa: B023
            assert len(ran) == 2 and not [key for key, _ in ran if "-part-" in key]
            _same_as_one_process(out, data, tmp_path)


def test_convert_cluster_summary_says_how_many_files_were_split(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_large(data, rows=140_000, group=50_000)
    (data / "day=1").mkdir()
    shutil.copy(data / "day=0" / "big.parquet", data / "day=1" / "big.parquet")
    proc = run_hconv("convert", "data", "out", "--cluster", scheduler, "--task-rows", "65536", cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    # each big file: 65536 rows and the 74464 left; the small one whole
    assert "\n# split 2 files into 4 parts (--task-rows 65536)\n" in err
    # no file above the threshold: nothing split, nothing said
    proc = run_hconv("convert", "data", "whole", "--cluster", scheduler, "--task-rows", "140000", cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    assert "converted on the Dask scheduler" in err and "# split" not in err


def test_convert_cluster_worker_killed_during_parts_loses_nothing(scheduler, tmp_path):
    victim = _start_worker(scheduler, tmp_path, "victim")
    try:
        _wait_for_workers(scheduler, 3)
        data = tmp_path / "data"
        _write_large(data, rows=600_000, group=60_000)
        out = tmp_path / "out"
        driver = _driver(scheduler, tmp_path, "--task-rows", "65536")
        _kill_while_writing(victim, driver, out, "*.part-*" + temporaries.TEMP_SUFFIX)  # while it writes a part
        _, err = driver.communicate(timeout=120)
        assert driver.returncode == 0, err.decode()
    finally:
        _stop([victim])
    _same_as_one_process(out, data, tmp_path)  # no part or temporary file is left either
    assert "3 workers (1 lost during the run; their files were converted again)" in err.decode()


def test_convert_cluster_s3_in_and_out_through_a_scheduler(scheduler, s3, tmp_path):
    import pyarrow.fs as pafs

    url, fs, bucket = s3
    data = tmp_path / "data"
    _write_dataset(data, files=3, rows=1000)
    # and one file split in two parts, their part objects in conv/ and removed
    pq.write_table(pa.table(make_scene(100_000, seed=6)), data / "day=1" / "big.parquet", row_group_size=50_000)
    pafs.copy_files(str(data), f"{bucket}/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs)
    args = (f"s3://{bucket}/raw/", f"s3://{bucket}/conv/", "--endpoint-url", url, "--cluster", scheduler)
    args += ("--task-rows", "65536")
    proc = run_hconv("convert", *args, cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    assert f"s3://{bucket}/conv/{MANIFEST} says the dataset is complete" in err
    out = tmp_path / "out"
    for info in fs.get_file_info(pafs.FileSelector(f"{bucket}/conv", recursive=True)):
        if info.type == pafs.FileType.File:
            (out / info.path.split("/conv/", 1)[1]).parent.mkdir(parents=True, exist_ok=True)
            (out / info.path.split("/conv/", 1)[1]).write_bytes(fs.open_input_stream(info.path).read())
    m = _same_as_one_process(out, data, tmp_path)
    assert m["source"] == f"s3://{bucket}/raw"


def test_convert_cluster_interrupt_writes_the_manifest_and_leaves_no_temporary(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_dataset(data, files=8, rows=40_000)
    out = tmp_path / "out"
    driver = _driver(scheduler, tmp_path)
    deadline = time.time() + 60
    while not (out.exists() and any(out.rglob("*.parquet"))) and time.time() < deadline:
        time.sleep(0.005)
    driver.send_signal(signal.SIGINT)
    _, err = driver.communicate(timeout=60)
    lines = err.decode().strip().splitlines()
    assert driver.returncode == 130, err.decode()
    assert lines[-1].startswith("hconv: error: interrupted; ") and "Traceback" not in err.decode()
    m = json.loads((out / MANIFEST).read_text())
    assert m["complete"] is False and 1 <= len(m["files"]) < 9
    listed = {f["output"] for f in m["files"]}
    time.sleep(1.5)  # a task the driver lost track of would still be writing
    written = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()} - {MANIFEST}
    assert written == listed  # every output there is listed; no temporary file
    proc = run_hconv("convert", "data", "out", "--cluster", scheduler, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr.decode()
    _same_as_one_process(out, data, tmp_path)


def test_convert_cluster_local_starts_its_workers_and_leaves_no_scratch_space(tmp_path):
    data = tmp_path / "data"
    _write_dataset(data, files=2, rows=500)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    proc = run_hconv("convert", "data", "out", "--cluster", "local", "--workers", "2", cwd=tmp_path, env=env)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    assert "converted on a local Dask cluster, 2 workers" in err
    assert "Warning" not in err
    assert list(tmp.iterdir()) == []  # Dask's dask-scratch-space stayed there after every run
    _same_as_one_process(tmp_path / "out", data, tmp_path)


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ("--cluster", "dask.example.com:8786"),
            "--cluster must be local or a Dask scheduler's address such as tcp://HOST:8786, "
            "got 'dask.example.com:8786'",
        ),
        (("--workers", "2"), "--workers sets how many workers --cluster local starts; add that"),
        (("--cluster", "local", "--workers", "0"), "--workers must be a whole number, 1 or more, got 0"),
        (
            ("--cluster", "tcp://127.0.0.1:9", "--workers", "2"),
            "--workers is for --cluster local; a running scheduler has the workers started for it "
            "(dask worker ADDRESS starts one more)",
        ),
        (
            ("--cluster", "local", "--cluster-timeout", "0"),
            "--cluster-timeout must be a number of seconds above 0, got 0.0",
        ),
        (
            ("--cluster", "local", "--task-rows", "5"),
            "--task-rows must be 0 (one task per file) or a whole number of rows, 65536 or more, got 5",
        ),
        (("--task-rows", "100000"), "--task-rows sets how --cluster splits large files; add that"),
    ],
)
def test_convert_cluster_bad_options_fail_in_one_line(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _write_dataset(tmp_path / "data", files=1, rows=10)
    code, _, err = run_inprocess("convert", "data", "out", *args, capsys=capsys)
    assert (code, err) == (2, f"hconv: error: {message}\n")
    assert not (tmp_path / "out").exists()


def test_convert_cluster_without_dask_names_the_extra(tmp_path, capsys, monkeypatch):
    from hconv.tables import cluster

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cluster, "dask_installed", lambda: False)
    _write_dataset(tmp_path / "data", files=1, rows=10)
    code, _, err = run_inprocess("convert", "data", "out", "--cluster", "local", capsys=capsys)
    assert (code, err) == (
        2,
        "hconv: error: --cluster needs Dask: pip install 'dask[distributed]' "
        "(hconv's dask extra: pip install '.[dask]' in its clone)\n",
    )


def _imported_as_a_cluster_run_imports() -> None:
    """What a --cluster run imports, imported before a test times one: the time measured is then
    the run's own (for the timeout to bound), not an import that a loaded machine slows down."""
    need("distributed")
    import dask  # noqa: F401

    from hconv.tables import cluster, dataset  # noqa: F401


def test_convert_cluster_unreachable_scheduler_names_it_within_the_timeout(tmp_path, capsys, monkeypatch):
    _write_dataset(tmp_path / "data", files=1, rows=10)
    monkeypatch.chdir(tmp_path)
    _imported_as_a_cluster_run_imports()
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    t0 = time.perf_counter()
    proc = hconv_inprocess("convert", "data", "out", "--cluster", address, "--cluster-timeout", "1", capsys=capsys)
    seconds = time.perf_counter() - t0
    err = proc.stderr.decode().splitlines()
    assert proc.returncode == 2 and err[-1] == (
        f"hconv: error: --cluster {address}: nothing listens there (connection refused); start a scheduler "
        "there (dask scheduler) or give the address of one"
    )
    assert seconds < 8
    assert not (tmp_path / "out").exists()


def test_convert_cluster_address_of_a_server_that_is_not_dask_fails_within_the_timeout(tmp_path, capsys, monkeypatch):
    """A server that waits for a request (an HTTP server: the dashboard's port 8787, a proxy):
    Dask's client waited for ever there, whatever --cluster-timeout said, and Ctrl-C did not stop it."""
    _write_dataset(tmp_path / "data", files=1, rows=10)
    monkeypatch.chdir(tmp_path)
    _imported_as_a_cluster_run_imports()
    with socket.socket() as server:  # accepts connections, never sends a byte
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        t0 = time.perf_counter()
        proc = hconv_inprocess("convert", "data", "out", "--cluster", address, "--cluster-timeout", "1", capsys=capsys)
        seconds = time.perf_counter() - t0
    err = proc.stderr.decode().splitlines()
    assert proc.returncode == 2 and err[-1].startswith(
        f"hconv: error: --cluster {address}: a server there accepted the connection but said nothing"
    ), err
    assert "Traceback" not in proc.stderr.decode() and "8786" in err[-1] and seconds < 8
    assert not (tmp_path / "out").exists()


class _FakeClient:
    """What check_workers asks of a client: the workers, and each one's answer to a function."""

    def __init__(self, answers: dict):
        self.answers = answers

    def wait_for_workers(self, n: int, timeout: float) -> None:
        pass

    def run(self, fn, on_error: str) -> dict:
        return self.answers


def test_check_workers_refuses_workers_of_another_hconv():
    from hconv.tables import cluster

    session = cluster.Session(_FakeClient({"tcp://10.0.0.2:4000": "0.0.1"}), "the Dask scheduler at tcp://x:1", None)
    with pytest.raises(UsageError) as info:
        session.check_workers(1.0)
    assert str(info.value) == (
        "the Dask scheduler at tcp://x:1: worker tcp://10.0.0.2:4000 runs hconv 0.0.1 "
        f"(this is hconv {hconv.__version__}); install hconv {hconv.__version__} with its dask extra on every worker"
    )
    session = cluster.Session(_FakeClient({"tcp://w:1": ModuleNotFoundError("No module named 'hconv'")}), "s", None)
    with pytest.raises(UsageError, match=r"worker tcp://w:1 cannot run hconv \(No module named 'hconv'\)"):
        session.check_workers(1.0)
    session = cluster.Session(_FakeClient({"tcp://w:1": hconv.__version__}), "s", None)
    session.check_workers(1.0)
    assert session.describe() == "s, 1 worker"


def test_convert_dataset_on_a_client_leaves_it_open(scheduler, tmp_path):
    data = tmp_path / "data"
    _write_dataset(data, files=2, rows=300)
    with distributed.Client(scheduler, set_as_default=False) as client:
        result = hconv.convert_dataset(data, tmp_path / "out", cluster=client)
        assert result.ran_on == f"the Dask scheduler at {scheduler}, 2 workers" and result.complete
        assert client.status == "running"  # the caller's client: used, not closed
    _same_as_one_process(tmp_path / "out", data, tmp_path)


def _task(rel: str, size: int):
    from hconv.tables.planning import Task
    from hconv.tables.storage import Listed

    return Task(Listed(rel, size, None), rel, "parquet", "parquet", False)


def test_batches_pack_small_files_in_order_and_leave_a_large_one_alone():
    """Small files go to a task together until it carries the limit's bytes; a file of the limit
    or more is a task alone (it may be split into parts); the order is the plan's."""
    from hconv.tables import cluster

    sizes = [30, 30, 30, 100, 10, 50, 50, 5]
    tasks = [_task(f"f{k}", s) for k, s in enumerate(sizes)]
    groups = [[t.input.rel for t in g] for g in cluster._batches(tasks, 60)]
    assert groups == [["f0", "f1"], ["f2"], ["f3"], ["f4", "f5"], ["f6", "f7"]]
    assert [t for g in cluster._batches(tasks, 60) for t in g] == tasks


def test_batch_bytes_gives_each_worker_several_tasks_up_to_task_bytes():
    from hconv.tables import cluster

    small = [_task(f"f{k}", 1000) for k in range(4000)]  # 4 MB in all
    assert cluster.batch_bytes(small, 2) == 4_000_000 // (2 * cluster.TASKS_PER_WORKER)
    assert cluster.batch_bytes([_task("big", 10 * cluster.TASK_BYTES)] * 100, 2) == cluster.TASK_BYTES
