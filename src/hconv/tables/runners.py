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

from hconv import interrupts
from hconv.errors import HconvError
from hconv.solve.engines import available_cores
from hconv.tables.manifest import FileRecord, GroupCommit
from hconv.tables.onefile import SMALL_FILE_BYTES, convert_one
from hconv.tables.pipeline import main_thread_signals
from hconv.tables.planning import Plan, Task

if TYPE_CHECKING:
    from hconv.tables.cluster import Session


def in_process(
    plan: Plan, commit: GroupCommit, *, strict: bool, threads: int | None
) -> Iterator[tuple[Task, HconvError | None]]:
    """Convert the plan's files in this process: (task, its error or None) for each, in the plan's
    order, its record handed to ``commit`` once its output is in place.

    Small files (:data:`SMALL_FILE_BYTES`) convert on a pool of ``threads`` threads (default: one
    per core), started once for the run, at most twice as many files under way as threads; a
    large file waits for those before it, then converts on this thread with its batch threads.
    Leaving early (Ctrl-C, or the caller closing this generator) cancels the files not started,
    waits for those under way (one small file each) and hands over the records of those that
    were committed meanwhile, so that no output is in place and unrecorded."""
    size = threads or available_cores()
    window: deque[tuple[Task, Future]] = deque()
    local = plan.dst.local

    def settle() -> tuple[Task, HconvError | None]:
        task, future = window[0]
        try:
            record = future.result()
        except HconvError as exc:
            window.popleft()
            return task, exc
        with interrupts.held():  # recorded and out of the window together
            window.popleft()
            commit.add(record, plan.dst.path(task.output) if local else None)
            interrupts.point("file")
        return task, None

    with ThreadPoolExecutor(size, thread_name_prefix="hconv-file", initializer=main_thread_signals) as pool:
        try:
            interrupts.point("files")  # before any file starts
            for task in plan.todo:
                if task.input.size < SMALL_FILE_BYTES:
                    window.append((task, pool.submit(_small, task, plan, strict)))
                    if len(window) > 2 * size:
                        yield settle()
                    continue
                while window:
                    yield settle()
                commit.close()  # a large file takes long: the files before it are listed first
                try:
                    convert_one(
                        task,
                        plan.src.place,
                        plan.dst,
                        plan.job,
                        strict=strict,
                        threads=threads,
                        done=lambda record: commit.add(record, None),  # flushed on its own
                    )
                except HconvError as exc:
                    yield task, exc
                else:
                    yield task, None
            while window:
                yield settle()
        finally:
            _drain(window, commit, plan)


def _small(task: Task, plan: Plan, strict: bool) -> FileRecord:
    """One small file, on a pool thread: converted whole, not flushed (its group will be)."""
    return convert_one(task, plan.src.place, plan.dst, plan.job, strict=strict, threads=1, flush=False, whole=True)


def _drain(window: deque[tuple[Task, Future]], commit: GroupCommit, plan: Plan) -> None:
    """The run stops early: cancel the files not started, wait for those under way, and hand over
    the records of those committed."""
    for _, future in window:
        future.cancel()
    for task, future in window:
        if future.cancelled():
            continue
        with contextlib.suppress(BaseException):  # its error is not reported: the run is stopping
            record = future.result()
            commit.add(record, plan.dst.path(task.output) if plan.dst.local else None)
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
