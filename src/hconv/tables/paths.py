"""``convert_path``: a file or a dataset, by what the paths are, as ``hconv convert`` decides.

The rule is :func:`hconv.tables.dataset.is_dataset`'s: a directory, a glob or a URI is a dataset
(:func:`hconv.tables.dataset.convert_dataset`), anything else one file or stdin
(:func:`hconv.tables.pipeline.convert_file`). The options only a dataset has are refused for
one file, rather than silently ignored.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from hconv import errors
from hconv.errors import UsageError, option
from hconv.solve import options
from hconv.tables import dataset, pipeline
from hconv.tables.job import Job


def convert_path(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    job: Job | None = None,
    method: str | None = None,
    precision: int | None = None,
    diagnostics: bool | None = None,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    strict: bool = False,
    threads: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    log: Callable[[str], None] | None = None,
    endpoint_url: str | None = None,
    cluster: object = None,
    workers: int | None = None,
    cluster_timeout: float | None = None,
    task_rows: int | None = None,
    prefix: str | None = None,
) -> pipeline.Tally | dataset.DatasetResult:
    """Convert ``src`` into ``dst`` as ``hconv convert SRC DST`` does: a dataset (a directory, a
    glob or a URI: :func:`~hconv.tables.dataset.is_dataset`) file by file, returning its
    :class:`~hconv.tables.dataset.DatasetResult`; otherwise one file ("-" for stdin or stdout),
    returning its :class:`~hconv.tables.pipeline.Tally`.

    The keywords are those two functions', with the run configuration ``job`` or ``method``,
    ``precision``, ``diagnostics`` and ``prefix`` (not both: :func:`hconv.solve.options.configure`).
    ``log``, ``endpoint_url``, ``cluster``, ``workers``, ``cluster_timeout`` and ``task_rows``
    are a dataset's; ``endpoint_url`` and the cluster's are refused for one file.
    """
    job = options.configure(
        Job, "convert_path", job, method=method, precision=precision, diagnostics=diagnostics, prefix=prefix
    )
    src, dst = os.fspath(src), os.fspath(dst)
    common: dict[str, Any] = dict(
        job=job, src_format=src_format, dst_format=dst_format, force=force, strict=strict, threads=threads
    )
    on_cluster = cluster is not None or workers is not None or task_rows is not None or cluster_timeout is not None
    if dataset.is_dataset(src, dst):
        return dataset.convert_dataset(
            src,
            dst,
            **common,
            endpoint_url=endpoint_url,
            progress=progress,
            log=log,
            cluster=cluster,
            workers=workers,
            cluster_timeout=10.0 if cluster_timeout is None else cluster_timeout,
            task_rows=task_rows,
        )
    if endpoint_url is not None:
        where = "IN and OUT" if errors.on_command_line() else f"{src} and {dst}"
        raise UsageError(f"{option('endpoint_url')} is for s3:// URIs; {where} are local")
    if on_cluster:
        given = [option(name) for name, value in (("cluster", cluster), ("workers", workers),
                 ("cluster_timeout", cluster_timeout), ("task_rows", task_rows)) if value is not None]  # fmt: skip
        raise UsageError(
            f"{' and '.join(given)} {'is' if len(given) == 1 else 'are'} for a dataset's files on a cluster; "
            f"{src} is one file, converted here (give its directory, or a glob, to use {option('cluster')})"
        )
    return pipeline.convert_file(src, dst, progress=progress, **common)
