"""A dataset's small files converted on worker processes of this run (:class:`Workers`), used by
:func:`hconv.tables.runners.in_process` when a run has many of them. A small file's conversion
is mostly Python that holds the GIL (its reading, planning, tallying, the writer's set-up), so
threads in one process convert many small files hardly faster than one thread does; each
process has its own interpreter (docs/scaling.md has the figures).

How a worker runs
-----------------
A worker is ``python -I -c`` (:data:`_BOOT`), not a multiprocessing child: that would import
the caller's main script again in the child, which a script without a ``__main__`` guard cannot
survive. Isolated (``-I``), so that a ``signal.py`` or ``types.py`` in the current folder cannot
stand in for the standard module while it starts. It talks over its stdin and a copy of its
stdout, one pickled message at a time, each after its length (stray prints of the worker go to
stderr): first the parent's ``sys.path``, so that it imports the same hconv, then the run's
setup, then lists of files to convert, each answered by a list of their records or errors. It
ends when its stdin closes.

What a worker does not do
-------------------------
It commits each output (renamed into place) but does not flush it: its records go to the
parent's :class:`hconv.tables.manifest.GroupCommit`, which makes the outputs durable by group
before the manifest lists them, as for files converted on threads. It ignores Ctrl-C and
SIGTERM from its start (they are blocked in the thread that starts it, and a child inherits the
mask): the parent stops the run, waits for the files under way, and keeps their records. It
dies with its parent (Linux's ``PR_SET_PDEATHSIG``), so that a run killed outright leaves no
worker converting behind the next run; its temporary files carry the run's tag, and the parent
removes those of a worker that died (:func:`hconv.tables.temporaries.remove_run_temporaries`).
A worker that dies fails the files it was converting, each with its own error, and the next
files start a new one."""

from __future__ import annotations

import contextlib
import os
import pickle
import queue
import struct
import subprocess
import sys
import threading
from concurrent.futures import Future
from typing import IO, Any

from hconv.errors import HconvError, OutputError
from hconv.tables import temporaries
from hconv.tables.job import Job
from hconv.tables.manifest import FileRecord
from hconv.tables.onefile import convert_one
from hconv.tables.pipeline import main_thread_signals
from hconv.tables.planning import Task
from hconv.tables.storage import Place

#: What a worker process runs: signals ignored and the parent's death followed first, before
#: anything slower; then the parent's sys.path, then :func:`serve`.
_BOOT = """\
import os, pickle, signal, struct, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
parent = int(sys.argv[1])
if sys.platform.startswith("linux"):
    import ctypes
    ctypes.CDLL(None).prctl(1, 9)  # PR_SET_PDEATHSIG, SIGKILL
    if os.getppid() != parent:  # the parent died before that took effect
        os._exit(1)
replies = os.fdopen(os.dup(1), "wb")
os.dup2(2, 1)
(n,) = struct.unpack("<Q", sys.stdin.buffer.read(8))
sys.path[:] = pickle.loads(sys.stdin.buffer.read(n))
from hconv.tables.processes import serve
serve(sys.stdin.buffer, replies)
"""

_LENGTH = struct.Struct("<Q")


def available() -> bool:
    """Whether this interpreter can start workers: ``sys.executable`` is a Python to run with
    ``-c``. In an application that embeds Python (Blender, uWSGI) it is the application's own
    program, or empty, and the run converts on threads instead."""
    name = os.path.basename(sys.executable or "").lower()
    return name.startswith(("python", "pypy")) and os.access(sys.executable, os.X_OK)


def send(stream: IO[bytes], message: object) -> None:
    """``message`` pickled onto ``stream`` after its length."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_LENGTH.pack(len(data)) + data)
    stream.flush()


def receive(stream: IO[bytes]) -> Any:
    """The next message on ``stream``; EOFError once the other end has closed it."""
    head = stream.read(_LENGTH.size)
    if len(head) < _LENGTH.size:
        raise EOFError
    (n,) = _LENGTH.unpack(head)
    data = stream.read(n)
    if len(data) < n:
        raise EOFError
    return pickle.loads(data)


def serve(requests: IO[bytes], replies: IO[bytes]) -> None:
    """A worker's loop: the setup (src, dst, job, strict, command-line spelling, run tag), then
    lists of files converted, each answered with their records or errors, until ``requests``
    closes."""
    from hconv import errors
    from hconv.kernels import allocator

    allocator.tune()  # as the hconv command's (hconv.kernels.allocator)
    src, dst, job, strict, cli, run = receive(requests)
    with errors.command_line() if cli else contextlib.nullcontext(), temporaries.sweeping_once():
        while True:
            try:
                tasks = receive(requests)
            except EOFError:
                return
            send(replies, convert_files(tasks, src, dst, job, strict=strict, run=run))


def convert_files(
    tasks: list[Task], src: Place, dst: Place, job: Job, *, strict: bool, run: str | None = None
) -> list[FileRecord | HconvError]:
    """Small files converted whole, one after another on this thread, each committed but not
    flushed (its group will be): each one's record, or its error."""
    done: list[FileRecord | HconvError] = []
    for task in tasks:
        try:
            done.append(convert_one(task, src, dst, job, strict=strict, threads=1, run=run, flush=False, whole=True))
        except HconvError as exc:
            done.append(exc)
    return done


class _Worker:
    """One worker process, started when first needed and again after it dies."""

    def __init__(self, setup: tuple) -> None:
        self._setup = setup
        self._process: subprocess.Popen[bytes] | None = None
        self.died = False  #: a worker of this slot ended before its stdin closed

    def _start(self) -> subprocess.Popen[bytes]:
        process = subprocess.Popen(
            [sys.executable, "-I", "-c", _BOOT, str(os.getpid())], stdin=subprocess.PIPE, stdout=subprocess.PIPE
        )
        assert process.stdin is not None
        send(process.stdin, list(sys.path))
        send(process.stdin, self._setup)
        return process

    def convert(self, tasks: list[Task]) -> list[FileRecord | HconvError]:
        """The files' records or errors, from this slot's worker process."""
        try:
            if self._process is None:
                self._process = self._start()
            assert self._process.stdin is not None and self._process.stdout is not None
            send(self._process.stdin, tasks)
            return list(receive(self._process.stdout))
        except (EOFError, OSError, pickle.UnpicklingError):
            why = _death(self._end(kill=True))
            self.died = True
            return [OutputError(f"{task.input.rel}: not converted: {why}") for task in tasks]

    def _end(self, kill: bool = False) -> int | None:
        """Close the worker (it ends at the end of its stdin); its return code (-N: killed by
        signal N), None if there was none."""
        process, self._process = self._process, None
        if process is None:
            return None
        with contextlib.suppress(OSError):
            assert process.stdin is not None
            process.stdin.close()
        try:
            code = process.wait(timeout=0.5 if kill else 30)
        except subprocess.TimeoutExpired:
            process.kill()
            code = process.wait()
        assert process.stdout is not None
        process.stdout.close()
        return code

    def close(self) -> None:
        if self._end() not in (0, None):
            self.died = True


def _death(code: int | None) -> str:
    """What a file's error says of the worker process that died converting it, from its return
    code, with what to do."""
    retry = "run the same command again to retry it"
    if code is None:
        return f"no process could be started to convert it; {retry} with --threads 1 to convert in this process"
    if -code == 9:
        return (
            "the process converting it was killed (signal 9, as the system does when memory runs out); "
            f"{retry}, with fewer --threads if memory is short"
        )
    if code < 0:
        return f"the process converting it was killed (signal {-code}); {retry}"
    return (
        f"the process converting it failed (exit code {code}; its error is above); {retry}, "
        "or with --threads 1 to convert in this process"
    )


class Workers:
    """``count`` worker processes converting lists of small files handed to :meth:`submit`, one
    list at a time each, in a thread of this process per worker that waits on it. Use as a
    context manager: leaving it waits for the lists under way, cancels those not started, ends
    the workers, and removes the temporary files of any that died."""

    def __init__(self, count: int, src: Place, dst: Place, job: Job, *, strict: bool, cli: bool) -> None:
        self._run = temporaries.new_run_tag()
        self._dst = dst
        self._slots = [_Worker((src, dst, job, strict, cli, self._run)) for _ in range(count)]
        self._queue: queue.SimpleQueue[tuple[list[Task], Future] | None] = queue.SimpleQueue()
        self._threads = [
            threading.Thread(target=self._feed, args=(slot,), name="hconv-worker", daemon=True) for slot in self._slots
        ]
        for thread in self._threads:
            thread.start()

    def submit(self, tasks: list[Task]) -> Future:
        """A future of the files' records or errors, in their order."""
        future: Future = Future()
        self._queue.put((tasks, future))
        return future

    def _feed(self, slot: _Worker) -> None:
        # The slot's worker is started, restarted and ended on this thread alone: Linux sends
        # PR_SET_PDEATHSIG when the thread that started a process ends, not its process. Its
        # Ctrl-C and SIGTERM are blocked, so that the kernel gives them to the main thread, and
        # a worker inherits the mask: one cannot land while its interpreter starts, before
        # _BOOT ignores them (it printed a traceback then).
        main_thread_signals()
        try:
            while (item := self._queue.get()) is not None:
                tasks, future = item
                if future.set_running_or_notify_cancel():
                    try:
                        future.set_result(slot.convert(tasks))
                    except BaseException as exc:  # its waiter raises it; it must not wait forever
                        future.set_exception(exc)
        finally:
            slot.close()

    def __enter__(self) -> Workers:
        return self

    def __exit__(self, *exc: object) -> None:
        with contextlib.suppress(queue.Empty):  # not started: cancelled
            while (item := self._queue.get_nowait()) is not None:
                item[1].cancel()
        for _ in self._threads:
            self._queue.put(None)
        for thread in self._threads:
            thread.join()
        if any(slot.died for slot in self._slots) and self._dst.local:
            temporaries.remove_run_temporaries(self._dst.root, self._run, recursive=True)
