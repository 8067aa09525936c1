"""One file of a dataset converted and committed: fetched if it is on object storage, converted
into a temporary file beside its output (a local one for object storage), flushed, and renamed
into place or uploaded, with its record handed over while interrupts are held. Its values are
picklable, so that it runs on other machines too (:mod:`hconv.tables.cluster`)."""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable

import numpy as np

from hconv import interrupts
from hconv.errors import OutputError
from hconv.tables import output, storage, temporaries
from hconv.tables.job import Job
from hconv.tables.manifest import FileRecord
from hconv.tables.pipeline import convert_file
from hconv.tables.planning import Task
from hconv.tables.storage import Place

#: A file smaller than this (bytes) is converted whole, on one thread, with no threads of its own
#: (several side by side: :func:`hconv.tables.runners.in_process`); a larger one streams on its
#: own batch threads, as one file does. A Parquet file this size holds about one batch (65,536
#: rows) of hconv's inputs.
SMALL_FILE_BYTES = 8 << 20


def convert_one(
    task: Task,
    src: Place,
    dst: Place,
    job: Job,
    *,
    strict: bool = False,
    threads: int | None = None,
    done: Callable[[FileRecord], None] | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    run: str | None = None,
    flush: bool = True,
    whole: bool = False,
) -> FileRecord:
    """Convert one input file into its output; raises HconvError subclasses naming the file.
    ``progress`` is :func:`hconv.tables.pipeline.convert_file`'s; ``run`` tags the temporary files' names
    (:func:`hconv.tables.storage.stage`). Paths are absolute, so that it runs from any working
    directory, such as a cluster worker's.

    The file is converted into a temporary file (beside the output, or a local one for object
    storage), then committed: renamed into place, or uploaded. The commit and ``done(record)``
    (the caller recording the file for the manifest) happen with interrupts held
    (:class:`hconv.interrupts.held`), so that a Ctrl-C leaves the output either not there or
    there and recorded, never there and unrecorded.

    ``flush``: flush the output to the disk before its commit; without it the caller makes it
    durable later, with others (:class:`hconv.tables.manifest.GroupCommit`), before any manifest
    lists it. ``whole``: a small file, converted on this thread alone
    (:func:`hconv.tables.pipeline.convert_file`'s ``whole``)."""
    t0 = time.perf_counter()
    rel = task.input.rel
    name = src.name(rel)
    with contextlib.ExitStack() as cleanup:
        local_in, etag = local_input(src, rel, cleanup, run)
        target = dst.path(task.output)
        staged = stage_output(dst, task.output, cleanup, run)
        tally = convert_file(
            local_in,
            staged,
            src_format=task.src_format,
            dst_format=task.dst_format,
            force=True,
            job=job,
            strict=strict,
            threads=threads,
            progress=progress,
            name=name,
            dst_name=shown_output(dst, task.output, staged),
            whole=whole,
            staged=True,
        )
        worst = tally.worst_residual
        record = FileRecord(
            input=rel,
            output=task.output,
            input_size=task.input.size,
            input_mtime_ns=task.input.mtime_ns,
            input_etag=etag,
            output_size=flushed(staged, dst.name(task.output)) if dst.local and flush else os.path.getsize(staged),
            rows=tally.rows,
            statuses=tally.counts(),
            worst_residual=None if np.isnan(worst) else worst,
            worst_row=tally.worst_row,
            engines=dict(tally.engines),
            seconds=0.0,
        )
        with interrupts.held():
            if dst.local:
                commit_output(staged, target, task.overwrite, dst.name(task.output))
            else:
                storage.put(staged, dst, task.output)
            record.seconds = time.perf_counter() - t0
            record.encoded()  # here, on the thread or process that converted it, not the manifest's writer
            if done is not None:
                done(record)
            interrupts.point("file")
    return record


def local_input(src: Place, rel: str, cleanup: contextlib.ExitStack, run: str | None) -> tuple[str, str | None]:
    """The file ``rel`` of ``src`` as a local path, fetched into a temporary file (removed by
    ``cleanup``) from object storage; and its ETag there."""
    if src.local:
        return src.path(rel), None
    # Each temporary file is made and its removal registered with interrupts held, so that a
    # Ctrl-C cannot fall between the two; the long work that fills it can be interrupted.
    with interrupts.held():
        local = storage.stage(kind="fetch", run=run)
        cleanup.callback(_remove, local)
    return local, storage.fetch(src, rel, local)


#: Held while a folder is made and a temporary file put in it, and while a folder a failed file
#: made is removed if empty: without it, a file failing on one thread removed the folder another
#: thread had just found there, before that thread's temporary file was in it.
_FOLDERS = threading.Lock()
#: Attempts at a temporary file whose folder vanished meanwhile (another process's failed file
#: removing the folder it made, which the lock above cannot hold back).
_STAGE_ATTEMPTS = 3


def stage_output(dst: Place, rel: str, cleanup: contextlib.ExitStack, run: str | None) -> str:
    """A temporary file (removed by ``cleanup``) to write ``rel`` of ``dst`` into before it is
    committed: beside it (its missing folders made), or a local one for object storage."""
    target = dst.path(rel)
    with interrupts.held():
        try:
            for attempt in range(_STAGE_ATTEMPTS):
                try:
                    with _FOLDERS:
                        if dst.local:
                            _make_folders(os.path.dirname(target), cleanup)
                        staged = storage.stage(target if dst.local else None, run=run)
                    break
                except FileNotFoundError:
                    if not dst.local or attempt == _STAGE_ATTEMPTS - 1:
                        raise
        except OSError as exc:  # mkstemp in a folder that is full or not writable
            where = os.path.dirname(target) if dst.local else "the temporary directory (TMPDIR)"
            err = OutputError(f"{dst.name(rel)}: cannot make its temporary file in {where} ({exc.strerror or exc})")
            err.errno = exc.errno  # a full disk stops the run (convert_dataset)
            raise err from None
        cleanup.callback(_remove, staged)
    if dst.local:  # mkstemp makes it 0600; renamed into place, it is the output, with the usual permissions
        os.chmod(staged, 0o666 & ~temporaries.umask())
    return staged


def commit_output(staged: str, target: str, overwrite: bool, shown: str) -> None:
    """Rename a finished output into place; refuse one that appeared since the plan was made.
    ``shown``: the output as messages name it."""
    if not overwrite and os.path.lexists(target):
        raise OutputError(f"{shown}: appeared while hconv was converting its input; move it away and run again")
    try:
        os.replace(staged, target)
    except OSError as exc:
        raise OutputError(f"{shown}: could not be written ({exc.strerror or exc}); nothing was written") from None


def _make_folders(folder: str, cleanup: contextlib.ExitStack) -> None:
    """Make ``folder`` and its missing parents (partition folders); if the conversion then fails,
    remove those it made that stayed empty, so that a failed file leaves nothing behind. Called
    with :data:`_FOLDERS` held and interrupts held."""
    made = []
    while folder and not os.path.isdir(folder):
        made.append(folder)
        folder = os.path.dirname(folder)
    for path in reversed(made):
        try:
            os.mkdir(path)
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"{path}: cannot make this folder ({exc.strerror or exc})") from None
        cleanup.callback(_remove_if_empty, path)


def _remove_if_empty(path: str) -> None:
    with _FOLDERS, contextlib.suppress(OSError):  # not empty: the output, or another file, is in it
        os.rmdir(path)


def _remove(path: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


def flushed(path: str, shown: str) -> int:
    """Flush a finished output to the disk before the manifest can claim it; its size. ``shown``:
    the output as messages name it (a full disk may refuse the flush)."""
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
            return os.fstat(fd).st_size
        finally:
            os.close(fd)
    except OSError as exc:
        raise output.write_failure(shown, exc) from None


def shown_output(dst: Place, rel: str, staged: str) -> str:
    """How messages name the output ``rel`` while it is written into ``staged``: its own name, and
    for object storage where it is staged, whose disk a full disk is."""
    if dst.local:
        return dst.name(rel)
    return f"{dst.name(rel)} (staged in {os.path.dirname(staged)!r}; set TMPDIR to a directory with room)"
