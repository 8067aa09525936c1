"""What converts a dataset's planned files: this process (:func:`in_process`: small files side by
side on a pool of threads, a large one on its own batch threads), or a Dask cluster
(:mod:`hconv.tables.cluster`, imported only when a run asks for one). :func:`hconv.tables.dataset.convert_dataset`
is handed the runner and never imports the cluster module, which itself imports the dataset's pieces.

A runner hands each converted file's record to a :class:`hconv.tables.manifest.GroupCommit`,
which keeps it (for the manifest) once the output is durable, on the calling thread."""

from __future__ import annotations

import contextlib
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING

from hconv import errors, interrupts
from hconv.errors import HconvError
from hconv.solve.engines import available_cores
from hconv.tables import processes
from hconv.tables.manifest import FileRecord, GroupCommit
from hconv.tables.onefile import SMALL_FILE_BYTES, convert_one
from hconv.tables.pipeline import main_thread_signals
from hconv.tables.planning import Plan, Task

if TYPE_CHECKING:
    from hconv.tables.cluster import Session


#: A run converts its small files on worker processes (:mod:`hconv.tables.processes`) when it
#: has at least this many (with fewer, starting the processes, an interpreter and hconv's
#: imports each, costs as much as they save: docs/scaling.md), both its input and output are
#: local, it may use two cores or more, and this interpreter can start them
#: (:func:`hconv.tables.processes.available`).
PROCESS_FILES = 300
#: Small files handed to a worker process at a time: enough to make the exchange's cost small
#: against theirs, few enough that a stopped run waits for little.
CHUNK_FILES = 8
#: Chunks handed out per worker process ahead of those this thread has settled: enough to keep
#: the workers busy while it rewrites the manifest of a group (tenths of a second for thousands
#: of files); those not started are cancelled, at no cost, when the run stops.
WORKER_CHUNKS_AHEAD = 8


def in_process(
    plan: Plan, commit: GroupCommit, *, strict: bool, threads: int | None
) -> Iterator[tuple[Task, HconvError | None]]:
    """Convert the plan's files in this process: (task, its error or None) for each, in the plan's
    order, its record handed to ``commit`` once its output is in place.

    Small files (:data:`SMALL_FILE_BYTES`) convert side by side on ``threads`` workers (default:
    one per core), started once for the run: worker processes when there are
    :data:`PROCESS_FILES` or more, each given :data:`CHUNK_FILES` at a time (at most
    :data:`WORKER_CHUNKS_AHEAD` per worker handed out), else threads (at most twice as many files
    handed out as there are threads). A large file waits for those before it,
    then converts on this thread with its batch threads. Leaving early (Ctrl-C, or the caller
    closing this generator) cancels the files not started, waits for those under way and hands
    over the records of those that were committed meanwhile, so that no output is in place and
    unrecorded."""
    size = threads or available_cores()
    src, dst, job = plan.src.place, plan.dst, plan.job
    small = sum(task.input.size < SMALL_FILE_BYTES for task in plan.todo)
    if size > 1 and small >= PROCESS_FILES and src.local and dst.local and processes.available():
        pool: processes.Workers | ThreadPoolExecutor = processes.Workers(
            size, src, dst, job, strict=strict, cli=errors.on_command_line()
        )
        chunk, ahead = CHUNK_FILES, WORKER_CHUNKS_AHEAD * size
    else:
        pool = ThreadPoolExecutor(size, thread_name_prefix="hconv-file", initializer=main_thread_signals)
        chunk, ahead = 1, 2 * size
    window: deque[tuple[list[Task], Future]] = deque()
    local = dst.local

    def settle() -> Iterator[tuple[Task, HconvError | None]]:
        tasks, future = window[0]
        outcomes = future.result()
        with interrupts.held():  # recorded and out of the window together
            window.popleft()
            for task, outcome in zip(tasks, outcomes):
                if isinstance(outcome, FileRecord):
                    commit.add(outcome, dst.path(task.output) if local else None)
            interrupts.point("file")
        for task, outcome in zip(tasks, outcomes):
            yield task, None if isinstance(outcome, FileRecord) else outcome

    with pool:
        try:
            interrupts.point("files")  # before any file starts
            pending: list[Task] = []
            for task in [*plan.todo, None]:
                if task is not None and task.input.size < SMALL_FILE_BYTES:
                    pending.append(task)
                    if len(pending) < chunk:
                        continue
                if pending:
                    if isinstance(pool, processes.Workers):
                        future = pool.submit(pending)
                    else:
                        future = pool.submit(processes.convert_files, pending, src, dst, job, strict=strict)
                    window.append((pending, future))
                    pending = []
                    if len(window) > ahead:
                        yield from settle()
                if task is None or task.input.size < SMALL_FILE_BYTES:
                    continue
                while window:
                    yield from settle()
                commit.close()  # a large file takes long: the files before it are listed first
                try:
                    convert_one(
                        task,
                        src,
                        dst,
                        job,
                        strict=strict,
                        threads=threads,
                        done=lambda record: commit.add(record, None),  # flushed on its own
                    )
                except HconvError as exc:
                    yield task, exc
                else:
                    yield task, None
            while window:
                yield from settle()
        finally:
            _drain(window, commit, plan)


def _drain(window: deque[tuple[list[Task], Future]], commit: GroupCommit, plan: Plan) -> None:
    """The run stops early: cancel the files not started, wait for those under way, and hand over
    the records of those committed."""
    for _, future in window:
        future.cancel()
    for tasks, future in window:
        if future.cancelled():
            continue
        with contextlib.suppress(BaseException):  # their errors are not reported: the run is stopping
            for task, outcome in zip(tasks, future.result()):
                if isinstance(outcome, FileRecord):
                    commit.add(outcome, plan.dst.path(task.output) if plan.dst.local else None)
    window.clear()


def check_cluster(cluster: object, workers: object, timeout: object) -> None:
    """UsageError unless the cluster options make sense and Dask is installed, when a run asks for
    a cluster (``cluster`` or ``workers`` given); before anything is written."""
    if cluster is not None or workers is not None:
        from hconv.tables import cluster as dask_cluster  # dask, only when asked for

        dask_cluster.check(cluster, workers, timeout)


def on_cluster(
    cluster: object, workers: int | None, timeout: float, threads: int | None
) -> contextlib.AbstractContextManager[Session]:
    """The Dask cluster ``cluster`` connected (its workers' hconv checked), as a
    :class:`hconv.tables.cluster.Session` that runs a plan's files as :func:`in_process` does."""
    from hconv.tables import cluster as dask_cluster

    return dask_cluster.connect(cluster, workers, timeout, threads)
