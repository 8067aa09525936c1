"""A large Parquet file of a dataset converted in parts by separate tasks of a cluster run: where
to cut it (:func:`split`, on batch boundaries, so that the joined file is the whole conversion's
bytes), converting one part, joining the parts into the output, and removing the parts of a run
whose driver was killed outright."""

from __future__ import annotations

import contextlib
import os
import re
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hconv import interrupts
from hconv.errors import UsageError, option
from hconv.tables import parquetio, storage, temporaries
from hconv.tables.job import Job
from hconv.tables.manifest import FileRecord
from hconv.tables.onefile import commit_output, flushed, local_input, shown_output, stage_output
from hconv.tables.pipeline import Tally, convert_file
from hconv.tables.planning import Plan, Task
from hconv.tables.storage import Place

#: Splitting a large Parquet file into parts converted by separate tasks of a cluster run (see
#: :func:`split`) is off by default: joining the parts costs most of what converting the file
#: once does, so it pays only with many workers and a costly method (docs/scaling.md).
TASK_ROWS = 0


def check_task_rows(task_rows: object) -> None:
    """UsageError unless ``task_rows`` is None (the default), 0 (no splitting) or at least one
    batch (:data:`hconv.tables.parquetio.PARQUET_BATCH_ROWS` rows)."""
    least = parquetio.PARQUET_BATCH_ROWS
    if task_rows is not None and (
        isinstance(task_rows, bool) or not isinstance(task_rows, int) or (task_rows != 0 and task_rows < least)
    ):
        raise UsageError(
            f"{option('task_rows')} must be 0 (one task per file) or a whole number of rows, {least} or more, "
            f"got {task_rows!r}"
        )


@dataclass(frozen=True)
class Part:
    """Rows [start, stop) of a task's Parquet input, converted by one task into a part file that
    :func:`join_parts` joins with the others into the task's output."""

    k: int  #: its place among the file's parts
    start: int
    stop: int
    rel: str  #: the part file, relative to OUT: hidden, run-tagged (temporaries.part_name)


@dataclass
class PartRecord:
    """What converting one part gave: :class:`hconv.tables.manifest.FileRecord`'s counts, rows counted
    from its start."""

    rows: int
    statuses: dict
    worst_residual: float | None
    worst_row: int | None
    engines: dict
    seconds: float
    input_etag: str | None  #: where the store gives one (object storage)


def split(task: Task, src: Place, task_rows: int, run: str) -> list[Part]:
    """The parts of ``task``'s input, or [] to convert it whole: a Parquet file written as
    Parquet, of at least 2 row groups and more than ``task_rows`` rows (0: never), cut into
    ranges of about ``task_rows`` rows.

    Each cut falls on a multiple of :data:`~hconv.tables.parquetio.PARQUET_BATCH_ROWS` rows, where
    the whole file's reading starts a batch: hconv writes one row group per batch, so the parts'
    row groups are the whole conversion's and the joined file is its bytes. A file smaller than
    ``task_rows`` bytes is not opened to count its rows: no hconv input stores a row in less than
    a byte, so it cannot hold more."""
    if not task_rows or task.src_format != "parquet" or task.dst_format != "parquet" or task.input.size < task_rows:
        return []
    where = src.path(task.input.rel)
    try:
        if src.local:
            rows, groups = parquetio.parquet_shape(where)
        else:
            with src.fs.open_input_file(where) as f:
                rows, groups = parquetio.parquet_shape(f)
    except (OSError, ValueError):  # pyarrow's errors are one or the other
        return []  # converted whole: its task names what is wrong with it
    if groups < 2 or rows <= task_rows:
        return []
    batch = parquetio.PARQUET_BATCH_ROWS
    step = max(batch, round(task_rows / batch) * batch)
    cuts = list(range(0, rows, step)) + [rows]
    if rows - cuts[-2] < step // 2 and len(cuts) > 2:  # a short tail joins the part before it
        del cuts[-2]
    folder, name = os.path.split(task.output)
    return [
        Part(k, a, b, os.path.join(folder, temporaries.part_name(name, run, k)).replace(os.sep, "/"))
        for k, (a, b) in enumerate(zip(cuts, cuts[1:]))
    ]


def convert_part(
    task: Task,
    part: Part,
    src: Place,
    dst: Place,
    job: Job,
    *,
    strict: bool = False,
    threads: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    run: str | None = None,
) -> PartRecord:
    """Convert ``part`` of ``task``'s input into its part file in OUT (hidden, run-tagged), as
    :func:`hconv.tables.onefile.convert_one` converts a whole file: through a temporary file, committed whole, so that a
    second run of the same part (its worker died) writes the same part again."""
    t0 = time.perf_counter()
    rel = task.input.rel
    with contextlib.ExitStack() as cleanup:
        # the whole object, for each part: reading only its row groups from the store is not built
        local_in, etag = local_input(src, rel, cleanup, run)
        target = dst.path(part.rel)
        staged = stage_output(dst, part.rel, cleanup, run)
        tally = convert_file(
            local_in,
            staged,
            src_format="parquet",
            dst_format="parquet",
            force=True,
            job=job,
            strict=strict,
            threads=threads,
            progress=progress,
            name=src.name(rel),
            rows=(part.start, part.stop),
            dst_name=shown_output(dst, part.rel, staged),
        )
        with interrupts.held():
            if dst.local:
                os.replace(staged, target)
            else:
                storage.put(staged, dst, part.rel)
    worst = tally.worst_residual
    return PartRecord(
        tally.rows,
        tally.counts(),
        None if np.isnan(worst) else worst,
        tally.worst_row,
        dict(tally.engines),
        time.perf_counter() - t0,
        etag,
    )


def join_parts(
    task: Task, parts: list[Part], records: list[PartRecord], dst: Place, *, run: str | None = None
) -> FileRecord:
    """Join the part files of ``task`` into its output, committed as :func:`hconv.tables.onefile.convert_one` commits
    one, then remove them; the file's record, from the parts' (their worst row moved by the
    part's first row). Run again after it committed (its worker died), it finds the parts gone,
    as they are removed only after the commit, and returns the same record."""
    t0 = time.perf_counter()
    target = dst.path(task.output)
    with contextlib.ExitStack() as cleanup:
        if all(storage.exists(dst, p.rel) for p in parts):
            local = [local_input(dst, p.rel, cleanup, run)[0] for p in parts]
            staged = stage_output(dst, task.output, cleanup, run)
            parquetio.join_parquet(local, staged)
            with interrupts.held():
                if dst.local:
                    flushed(staged, dst.name(task.output))
                    commit_output(staged, target, task.overwrite, dst.name(task.output))
                else:
                    storage.put(staged, dst, task.output)
        remove_parts(parts, dst)
    size = os.path.getsize(target) if dst.local else storage.file_info(dst, task.output).size
    tally = Tally("", "")
    for part, r in zip(parts, records):
        row = None if r.worst_row is None else part.start + r.worst_row  # a part counts from its start
        tally.add_counts(r.rows, r.statuses, r.engines, r.worst_residual, row)
    worst = tally.worst_residual
    return FileRecord(
        input=task.input.rel,
        output=task.output,
        input_size=task.input.size,
        input_mtime_ns=task.input.mtime_ns,
        input_etag=records[0].input_etag if records else None,
        output_size=size,
        rows=tally.rows,
        statuses=tally.counts(),
        worst_residual=None if np.isnan(worst) else worst,
        worst_row=tally.worst_row,
        engines=dict(tally.engines),
        seconds=sum(r.seconds for r in records) + time.perf_counter() - t0,
    )


def remove_parts(parts: list[Part], dst: Place) -> None:
    """Remove the part files of one output, those that are there."""
    for p in parts:
        storage.remove(dst, p.rel)


def remove_orphan_parts(plan: Plan, say: Callable[[str], None]) -> None:
    """Remove the parts (:func:`split`) of an earlier run whose driver was killed outright, as its
    manifest names them; left alone while that driver may still run (another host)."""
    before = (plan.manifest_before or {}).get("parts_run")
    if not isinstance(before, dict) or not temporaries.maker_gone(str(before.get("driver", ""))):
        return
    run = str(before.get("id", ""))
    if not re.fullmatch(r"[0-9a-f]+", run):
        return
    if plan.dst.local:
        gone = temporaries.remove_run_temporaries(plan.dst.root, run, recursive=True)
    else:
        gone = storage.remove_run_objects(plan.dst, run)
    if gone:
        say(f"removed {len(gone)} part file{'s' if len(gone) != 1 else ''} left by a run whose driver was killed")
