"""What converts a dataset's planned files: this process, one file after another, or a Dask cluster
(:mod:`hconv.tables.cluster`, imported only when a run asks for one). :func:`hconv.tables.dataset.convert_dataset`
is handed the runner and never imports the cluster module, which itself imports the dataset's pieces."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from hconv.errors import HconvError
from hconv.tables.manifest import FileRecord
from hconv.tables.onefile import convert_one
from hconv.tables.planning import Plan, Task

if TYPE_CHECKING:
    from hconv.tables.cluster import Session


def in_process(
    plan: Plan, keep: Callable[[FileRecord], None], *, strict: bool, threads: int | None
) -> Iterator[tuple[Task, HconvError | None]]:
    """Convert the plan's files one after another in this process: (task, its error or None) for
    each, its record handed to ``keep`` as its output is committed."""
    for task in plan.todo:
        try:
            convert_one(task, plan.src.place, plan.dst, plan.job, strict=strict, threads=threads, done=keep)
        except HconvError as exc:
            yield task, exc
        else:
            yield task, None


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
