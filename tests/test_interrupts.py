"""Ctrl-C and SIGTERM at every moment of a real ``hconv convert``: the run either exits 0 with OUT
complete and correct, or exits 130 with one line and no OUT (a dataset: the files it finished,
listed in a manifest that says complete: false) and no temporary file; never death by the
signal, never a traceback.

The moments are the run's named points (:func:`hconv.interrupts.point`): the run announces each
and waits, and the test sends the signal while it waits there ("at"), or just after letting it go
on ("after", landing somewhere before the next point). No sleeps, no timing: a loaded machine
only makes it slower. Each try is a fork of a process that has imported hconv as the console
script does (a fresh interpreter per try would cost most of the test's time in imports); the
child then runs the command's own ``main()`` and ends as the command does, through the
interpreter's shutdown, where a late signal used to kill it.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import random
import select
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import terminal_signals

from hconv.errors import INTERRUPTED, INTERRUPTED_STREAMED
from hconv.tables.manifest import MANIFEST
from hconv.tables.pipeline import convert_file
from hconv.tools.scene import make_scene

#: The fork server: imports hconv as the hconv command does, then runs each try in a child,
#: several at once; says ``pid ID PID`` when try ID starts and ``exit PID CODE`` when it ends.
SERVER = r"""
import json, os, sys, threading
sys.argv = ["hconv"]  # the command: hconv installs its start-up handlers (hconv.interrupts)
os.environ["HCONV_TEST_POINTS"] = "3:4"
from hconv import cli, report  # and what convert imports when it runs, once here rather than per try
from hconv.tables import dataset, pipeline
lock, kids = threading.Lock(), threading.Semaphore(0)
def say(text):
    with lock:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
def reap():
    while True:
        kids.acquire()
        pid, status = os.wait()
        say(f"exit {pid} {os.waitstatus_to_exitcode(status)}")
threading.Thread(target=reap, daemon=True).start()
for line in sys.stdin:
    job = json.loads(line)
    pid = os.fork()
    if pid == 0:
        ann = os.open(job["ann"], os.O_WRONLY)
        go = os.open(job["go"], os.O_RDONLY)
        os.dup2(ann, 3)
        os.dup2(go, 4)
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
        os.dup2(os.open(job["out"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 1)
        os.dup2(os.open(job["err"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 2)
        os.chdir(job["cwd"])
        os.environ["TMPDIR"] = job["tmp"]
        sys.argv = ["hconv", *job["args"]]
        cli.main()  # raises SystemExit: the interpreter ends as the command's does
    kids.release()
    say(f"pid {job['id']} {pid}")
"""

#: Tries per command: the last points of the run (its very end) every time, the others seeded.
TRIES = 8
SEED = 2024
#: Tries run at once: a try spends most of its time in the interpreter's shutdown.
AT_ONCE = 4


class Server:
    def __init__(self, where: Path):
        self.where = where
        self.proc = subprocess.Popen(
            [sys.executable, "-c", SERVER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            preexec_fn=terminal_signals,  # as from a terminal: Ctrl-C at its default
        )
        self.n = 0
        self.lock = threading.Lock()
        self.boxes: dict[tuple[str, int], queue.Queue] = {}
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _box(self, key: tuple[str, int]) -> queue.Queue:
        with self.lock:
            return self.boxes.setdefault(key, queue.Queue())

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            kind, key, value = line.decode().split()
            self._box((kind, int(key))).put(int(value))

    def run(self, args: list[str], cwd: Path, at: int | None, sig: int, mode: str) -> tuple[int, str, list[str]]:
        """Run ``hconv ARGS`` in ``cwd``, sending ``sig`` at its point number ``at`` (None:
        never); returns (exit code, stderr, the points it passed)."""
        with self.lock:
            self.n += 1
            n = self.n
        base = self.where / f"try{n}"
        ann, go = f"{base}.ann", f"{base}.go"
        os.mkfifo(ann)
        os.mkfifo(go)
        tmp = self.where / f"tmp{n}"
        tmp.mkdir()
        job = {"id": n, "ann": ann, "go": go, "out": f"{base}.out", "err": f"{base}.err", "cwd": str(cwd)}
        job.update(tmp=str(tmp), args=args)
        assert self.proc.stdin is not None
        with self.lock:
            self.proc.stdin.write((json.dumps(job) + "\n").encode())
            self.proc.stdin.flush()
        pid = self._box(("pid", n)).get(timeout=120)
        points: list[str] = []
        with open(ann, "rb") as said, open(go, "wb", buffering=0) as answer:
            for line in said:  # ends when the child has exited
                points.append(line.decode().strip())
                if len(points) - 1 == at and mode == "at":
                    os.kill(pid, sig)
                with contextlib.suppress(BrokenPipeError):  # it ended at the signal, before reading it
                    answer.write(b".")
                if len(points) - 1 == at and mode == "after":
                    os.kill(pid, sig)
        code = self._box(("exit", pid)).get(timeout=120)
        assert list(tmp.iterdir()) == [], "a temporary file was left in TMPDIR"
        return code, Path(f"{base}.err").read_text(), points

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def _no_temporaries(root: Path) -> list[str]:
    return [str(p) for p in root.rglob("*") if p.name.endswith(".hconv-tmp")]


def _moments(points: int, rng: random.Random) -> list[tuple[int, int, str]]:
    """(point, signal, mode) for each try: the run's last four points (its very end) with both
    signals, then seeded points across the whole run."""
    ends = [(points - 1 - k, (signal.SIGINT, signal.SIGTERM)[k % 2], ("at", "after")[k // 2 % 2]) for k in range(4)]
    rest = [
        (rng.randrange(points), rng.choice((signal.SIGINT, signal.SIGTERM)), rng.choice(("at", "after")))
        for _ in range(TRIES - len(ends))
    ]
    return ends + rest


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("server"))
    yield s
    s.close()


def _sweep(
    server: Server, tmp_path: Path, make: Callable[[Path], None], args: list[str], seed: int, check: Callable[..., None]
) -> tuple[list[str], set[tuple[str, int]]]:
    """Run ``hconv ARGS`` once to its end (its points), then once per seeded moment, interrupted
    there, :data:`AT_ONCE` at a time, each in its own copy of the inputs (``make(folder)``);
    ``check(work, code, err, where)`` after each try. Returns the points and the (point, exit
    code) of every try."""
    work = tmp_path / "first"
    make(work)
    code, err, points = server.run(args, work, None, 0, "at")
    assert code == 0 and err == "", err

    def one(k: int, moment: tuple[int, int, str]) -> tuple[str, int]:
        at, sig, mode = moment
        work = tmp_path / f"work{k}"
        make(work)
        code, err, _ = server.run(args, work, at, sig, mode)
        where = (points[at], signal.Signals(sig).name, mode, code, err)
        assert code in (0, 130), where  # never a signal's death (negative), never another failure
        check(work, code, err, where)
        assert _no_temporaries(work) == [], where
        return points[at], code

    moments = _moments(len(points), random.Random(seed))
    with ThreadPoolExecutor(AT_ONCE) as pool:
        outcomes = set(pool.map(one, range(len(moments)), moments))
    return points, outcomes


def _file(work: Path) -> None:
    work.mkdir(parents=True)
    pq.write_table(pa.table(make_scene(50, seed=1)), work / "in.parquet")


def test_interrupt_convert_file_at_any_moment_exits_0_complete_or_130_with_no_output(server, tmp_path):
    ref = tmp_path / "ref"
    _file(ref)
    convert_file(str(ref / "in.parquet"), str(ref / "out.parquet"))
    reference = (ref / "out.parquet").read_bytes()

    def check(work: Path, code: int, err: str, where: tuple) -> None:
        out = work / "out.parquet"
        if code == 0:
            assert err == "" and out.read_bytes() == reference, where
            out.unlink()
        else:
            assert err == f"hconv: error: {INTERRUPTED}\n", where
            assert not out.exists(), where

    points, outcomes = _sweep(server, tmp_path, _file, ["convert", "in.parquet", "out.parquet", "-q"], SEED, check)
    assert {"start", "batch", "commit", "committed", "returned", "exit", "shutdown"} <= set(points), points
    # the sweep reached both outcomes, and the end of the run never gave 130
    assert {c for _, c in outcomes} == {0, 130}
    assert all(c == 0 for p, c in outcomes if p in ("committed", "returned", "exit", "shutdown")), outcomes


#: Six files, converted on one thread (--threads 1): the pool takes three ahead of the main thread,
#: whose points ("file" as each is recorded) then fall while files remain to be converted.
PARTS = [f"day={k}/part.parquet" for k in range(6)]


def _dataset(work: Path) -> None:
    for k, rel in enumerate(PARTS):
        (work / "data" / rel).parent.mkdir(parents=True)
        pq.write_table(pa.table(make_scene(30, seed=k)), work / "data" / rel)


def test_interrupt_convert_dataset_at_any_moment_exits_0_complete_or_130_keeping_finished_files(server, tmp_path):
    ref = tmp_path / "ref"
    _dataset(ref)
    reference = {}
    for rel in PARTS:
        convert_file(str(ref / "data" / rel), str(ref / "one.parquet"), force=True)
        reference[rel] = (ref / "one.parquet").read_bytes()

    def check(work: Path, code: int, err: str, where: tuple) -> None:
        out = work / "out"
        if code == 0:
            assert err == "", where
            assert json.loads((out / MANIFEST).read_text())["complete"] is True, where
        else:
            assert len(err.splitlines()) == 1 and err.startswith("hconv: error: interrupted"), where
        if out.exists():
            m = json.loads((out / MANIFEST).read_text())
            listed = sorted(f["output"] for f in m["files"])
            assert m["complete"] is (code == 0) and (code == 130 or listed == PARTS), where
            present = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
            assert present == sorted([*listed, MANIFEST]), where  # no file it does not list
            assert all((out / rel).read_bytes() == reference[rel] for rel in listed), where
            if code == 130:
                assert err.endswith("run the same command again to convert the rest\n"), where
            shutil.rmtree(out)
        else:  # interrupted before the first file was done: OUT, made by the run, is removed
            assert code == 130 and err == f"hconv: error: {INTERRUPTED}\n", where

    args = ["convert", "data", "out", "-q", "--threads", "1"]
    points, outcomes = _sweep(server, tmp_path, _dataset, args, SEED + 1, check)
    assert points.count("file") == 6 and {"manifest", "settled", "returned", "exit", "shutdown"} <= set(points)
    assert {c for _, c in outcomes} == {0, 130}
    assert all(c == 0 for p, c in outcomes if p in ("settled", "returned", "exit", "shutdown")), outcomes


def test_interrupt_convert_dataset_after_its_last_file_waits_for_the_manifest_and_exits_0(server, tmp_path):
    """Every file done, an interrupt before the last manifest is written (the last group's commit,
    a cluster's shutdown) waits for it, then finds the run settled: exit 0, OUT complete. Before,
    it exited 130 with OUT complete and no word of what was kept."""
    args = ["convert", "data", "out", "-q", "--threads", "1"]
    _dataset(tmp_path / "first")
    code, err, points = server.run(args, tmp_path / "first", None, 0, "at")
    assert code == 0 and "files done" in points, (code, err, points)
    _dataset(tmp_path / "work")
    for sig in (signal.SIGINT, signal.SIGTERM):
        shutil.rmtree(tmp_path / "work" / "out", ignore_errors=True)
        code, err, _ = server.run(args, tmp_path / "work", points.index("files done"), sig, "at")
        assert code == 0 and err == "", (signal.Signals(sig).name, code, err)
        m = json.loads((tmp_path / "work" / "out" / MANIFEST).read_text())
        assert m["complete"] is True and sorted(f["output"] for f in m["files"]) == PARTS


def test_interrupt_convert_dataset_before_its_first_file_leaves_no_out(server, tmp_path):
    """Interrupted before any file is done, a dataset run removes the OUT it made (and its
    manifest, which claimed the paths): there is nothing to keep."""
    _dataset(tmp_path)
    for sig, point in ((signal.SIGINT, 0), (signal.SIGTERM, 1)):  # at its start, at its first batch
        code, err, points = server.run(["convert", "data", "out", "-q"], tmp_path, point, sig, "at")
        assert points[0] == "start" and "file" not in points, points
        assert code == 130 and err == f"hconv: error: {INTERRUPTED}\n", err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]


def test_interrupt_as_a_usage_error_ends_is_ignored(server, tmp_path):
    """A usage error (before the command's own code runs) decided its exit code: an interrupt at
    its end, or in the interpreter's shutdown, leaves it 2 with its one line."""
    for at, sig in ((0, signal.SIGINT), (1, signal.SIGTERM)):  # "exit", then "shutdown"
        code, err, points = server.run(["convert", "in.parquet"], tmp_path, at, sig, "at")
        assert points == ["exit", "shutdown"] and code == 2, (points, code, err)
        assert err.startswith("hconv: error: Missing argument 'OUT'") and len(err.splitlines()) == 1, err


def test_interrupt_a_real_hconv_process_as_it_ends_exits_0_with_out(tmp_path):
    """The same handshake with the command as a user starts it (``python -m hconv``, a fresh
    interpreter): Ctrl-C while the interpreter shuts down, after OUT is in place, is ignored."""
    _file(tmp_path / "work")
    ann_r, ann_w = os.pipe()
    go_r, go_w = os.pipe()
    env = dict(os.environ, HCONV_TEST_POINTS=f"{ann_w}:{go_r}")
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "in.parquet", "out.parquet", "-q"],
        cwd=tmp_path / "work",
        env=env,
        pass_fds=(ann_w, go_r),
        stderr=subprocess.PIPE,
        preexec_fn=terminal_signals,
    )
    os.close(ann_w)
    os.close(go_r)
    points = []
    with os.fdopen(ann_r, "rb") as said, os.fdopen(go_w, "wb", buffering=0) as answer:
        for line in said:
            points.append(line.decode().strip())
            if points[-1] == "shutdown":
                proc.send_signal(signal.SIGINT)
            with contextlib.suppress(BrokenPipeError):
                answer.write(b".")
    _, err = proc.communicate(timeout=120)
    assert points[-1] == "shutdown" and proc.returncode == 0 and err == b"", (points, proc.returncode, err)
    assert pq.read_table(tmp_path / "work" / "out.parquet").num_rows == 50


def test_interrupt_convert_into_a_pipe_after_rows_went_out_says_the_output_is_incomplete(tmp_path):
    """CSV into a pipe goes out batch by batch: Ctrl-C after rows reached the pipe exits 130
    saying its reader got part of the output (not that nothing was written)."""
    work = tmp_path / "work"
    work.mkdir()
    pq.write_table(pa.table(make_scene(100_000, seed=1)), work / "in.parquet", row_group_size=25_000)
    ann_r, ann_w = os.pipe()
    go_r, go_w = os.pipe()
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "in.parquet", "-", "--to", "csv", "-q"],
        cwd=work,
        env=dict(os.environ, HCONV_TEST_POINTS=f"{ann_w}:{go_r}"),
        pass_fds=(ann_w, go_r),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=terminal_signals,
    )
    os.close(ann_w)
    os.close(go_r)
    got, batches = b"", 0
    rest = threading.Thread(target=proc.stdout.read, daemon=True)
    with os.fdopen(ann_r, "rb") as said, os.fdopen(go_w, "wb", buffering=0) as answer:
        for line in said:
            batches += line.strip() == b"batch"
            if batches == 2 and not got and select.select([proc.stdout], [], [], 60)[0]:
                got = os.read(proc.stdout.fileno(), 1 << 16)  # the first batch's rows, in the pipe
                proc.send_signal(signal.SIGINT)
                rest.start()  # the pipe's reader goes on reading, as a real one would
            with contextlib.suppress(BrokenPipeError):
                answer.write(b".")
    proc.wait(timeout=120)
    err = proc.stderr.read()
    assert got.startswith(b"id,") and proc.returncode == 130, (got[:80], proc.returncode, err)
    assert err.decode() == f"hconv: error: {INTERRUPTED_STREAMED}\n"
