"""Datasets: a directory, a glob or a prefix of files converted file by file into a directory or
prefix, with a manifest written last; the CLI's ``convert`` is thin over :func:`convert_dataset`
when IN or OUT is one.

Each input file gives one output file at the same relative path (hive partition folders such as
``date=2026-01-01/`` kept; with ``dst_format`` the extension becomes the format's), written
atomically (:mod:`hconv.tables.storage` says how, locally and on object storage). The manifest,
``OUT/_hconv_manifest.json``, is written last, and again whenever a run stops early: it lists
only outputs that are complete and were made from their input as it is now, by the job it
records, and says ``"complete": true`` only when every input file has one. During a run that
will rewrite files, it is first written without them, so it never claims a file being replaced.

A re-run converts only what is missing or stale: an input whose size or modification time
differs from the manifest's record, an output missing or not of the recorded size, or every
file when the job (the Job's fields and the formats) or the input's place differs. A file in OUT
that hconv did not write (the manifest's ``hconv_outputs``) is never overwritten without
``force``, and hconv deletes nothing in OUT.

One file's failure (hconv's one-line errors) is named and the others still run; the run then
raises :class:`DatasetError`, whose exit code is the failures' (the highest when they differ).
The unit of work, :func:`convert_one`, takes and returns picklable values, so that a runner on
other machines can map it over :attr:`Plan.todo` and hand the records to the same manifest.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import json
import os
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from hconv import interrupts
from hconv.errors import HconvError, OutputError, UsageError, option
from hconv.solve import methods
from hconv.tables import output, parquetio, storage, temporaries
from hconv.tables.formats import EXTENSIONS, FORMATS
from hconv.tables.job import Job, check_job
from hconv.tables.pipeline import Tally, check_callback, check_threads, convert_file
from hconv.tables.storage import Listed, Place, Source
from hconv.version import __version__

MANIFEST = "_hconv_manifest.json"
MANIFEST_KIND = "hconv dataset manifest"
MANIFEST_VERSION = 1
#: While files convert, the manifest is rewritten at most this often, so that a run killed
#: outright (kill -9, a lost machine) loses the record of this much work at most: the next run
#: converts those files again (the manifest claimed their paths before the run wrote them).
CHECKPOINT_SECONDS = 10.0


def is_dataset(src: str, dst: str) -> bool:
    """Whether ``hconv convert SRC DST`` converts a dataset: SRC is a directory, a glob or a URI,
    or DST is a URI. One file (or stdin) into a file keeps :func:`convert_file`'s behaviour."""
    if src == "-":
        return False
    if storage.is_uri(src) or storage.is_uri(dst):
        return True
    return os.path.isdir(src) or (storage.has_glob(src) and not os.path.exists(src))


@dataclass
class FileRecord:
    """One complete output, as the manifest lists it."""

    input: str  #: path relative to IN
    output: str  #: path relative to OUT
    input_size: int
    input_mtime_ns: int | None
    input_etag: str | None  #: where the store gives one (object storage)
    output_size: int
    rows: int
    statuses: dict  #: status -> rows
    worst_residual: float | None
    worst_row: int | None  #: 1-based data row in this file
    engines: dict  #: engine -> rows
    seconds: float

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> FileRecord:
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class Task:
    """One input file to convert: picklable, for :func:`convert_one` wherever it runs."""

    input: Listed
    output: str  #: path relative to OUT
    src_format: str
    dst_format: str
    overwrite: bool  #: the output exists and may be replaced (hconv's own, stale; or force)


@dataclass
class Plan:
    """What a run will do: files kept from the manifest, files to convert, files refused."""

    src: Source
    dst: Place
    job: Job
    identity: dict  #: the job and the formats, as the manifest records them
    inputs: list[Listed]
    kept: list[FileRecord]  #: up to date: listed in the manifest, left alone
    todo: list[Task]
    refused: list[tuple[str, HconvError]]  #: (input, why): outputs in the way that hconv did not write
    why: str | None  #: why files that look converted are converted again (the job changed), if so
    manifest_before: dict | None

    def describe(self) -> str:
        n, kept = len(self.inputs), len(self.kept)
        if self.why:
            return f"{self.why}; converting all {len(self.todo)} files"
        if not self.todo:
            return f"all {n} files already converted and up to date; nothing to convert" if kept == n else ""
        if kept:
            return f"{kept} of {n} files already converted and up to date; converting {len(self.todo)}"
        return f"converting {len(self.todo)} files" if n > 1 else f"converting {len(self.todo)} file"


@dataclass
class DatasetResult:
    """What a dataset run did, and what the dataset now holds."""

    src: str
    dst: str
    manifest: str  #: where the manifest is
    files: list[FileRecord]  #: every complete output, in input order
    converted: list[str]  #: inputs converted by this run
    failed: list[tuple[str, HconvError]]  #: (input, error)
    pending: list[str]  #: inputs neither converted nor failed (an interrupted run)
    total: int  #: input files
    tally: Tally  #: the whole dataset's rows per status and worst residual; seconds: this run's
    #: the input file holding the worst residual, as IN names it (``data/part-0.csv``): the file
    #: the user looks at for the row, which the output (perhaps in another format) only echoes
    worst_file: str | None
    rows_converted: int  #: rows converted by this run
    seconds: float
    ran_on: str | None = None  #: the Dask cluster the files were converted on, if any
    split_files: int = 0  #: files this run converted in parts on the cluster (:func:`split`)
    split_parts: int = 0  #: the parts those files were split into
    task_rows: int = 0  #: the rows per part the run asked for (0: every file whole)

    @property
    def complete(self) -> bool:
        return len(self.files) == self.total


class DatasetError(HconvError):
    """Some files of a dataset failed; the others were converted. ``result`` holds the run."""

    def __init__(self, message: str, exit_code: int, result: DatasetResult):
        super().__init__(message)
        self.exit_code = exit_code
        self.result = result


def job_identity(job: Job, src_format: str | None, dst_format: str | None) -> dict:
    """The job as the manifest records it: every Job field, and the formats asked for."""
    d = dataclasses.asdict(job)
    d["src_format"], d["dst_format"] = src_format, dst_format
    return json.loads(json.dumps(d))  # tuples as lists, as they come back from the file


def _output_rel(rel: str, fmt_in: str, dst_format: str | None) -> tuple[str, str]:
    if dst_format is None or dst_format == fmt_in:
        return rel, fmt_in
    stem, ext = os.path.splitext(rel)
    return (stem if storage.format_by_name(rel) else rel) + EXTENSIONS[dst_format][0], dst_format


def _difference(before: dict, now: dict) -> str:
    """The first job setting that differs, as ``method: exact → refined``."""
    for key in list(now) + [k for k in before if k not in now]:
        if before.get(key) != now.get(key):
            return f"{key}: {before.get(key)!r} → {now.get(key)!r}"
    return ""


def _read_manifest(dst: Place, force: bool) -> dict | None:
    raw = storage.read_bytes(dst, MANIFEST)
    if raw is None:
        return None
    try:
        m = json.loads(raw)
        if m.get("kind") != MANIFEST_KIND:
            raise ValueError("not an hconv manifest")
        [FileRecord.from_json(d) for d in m["files"]]
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        if force:
            return None
        raise OutputError(
            f"{dst.name(MANIFEST)}: is not a manifest hconv can read ({exc}); move it away, "
            f"or pass {option('force', True)} to convert every file and write a new one"
        ) from None
    return m


def plan_dataset(
    src: str,
    dst: str,
    *,
    job: Job,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    endpoint_url: str | None = None,
) -> Plan:
    """List the input files and OUT, read the manifest, and decide what to convert."""
    for flag, fmt in (("src_format", src_format), ("dst_format", dst_format)):
        if fmt is not None and fmt not in FORMATS:
            raise UsageError(f"{option(flag)} must be {' or '.join(FORMATS)}, got {fmt!r}")
    if dst == "-":
        raise UsageError("a dataset is written into a directory or prefix, not to stdout ('-')")
    if endpoint_url and not any(s.lower().startswith("s3://") for s in (src, dst)):
        raise UsageError(f"{option('endpoint_url')} is for s3:// URIs, and neither {src} nor {dst} is one")
    source = storage.source(src, endpoint_url)
    out = storage.place(dst, endpoint_url)
    overlap = UsageError(
        f"{dst} and {src} overlap; write the dataset outside its input, so that a re-run does not read outputs"
    )
    if out.contains(source.place) or (source.pattern is None and source.place.contains(out)):
        raise overlap
    if storage.format_by_name(out.root) and storage.file_info(out, "").type != storage.DIRECTORY:
        stem = os.path.splitext(out.shown)[0]
        raise UsageError(
            f"{dst}: names a file, but {src} is a dataset, converted file by file into a directory; "
            f"give a directory for OUT, such as {stem}/ (hconv makes it)"
        )
    if out.local:
        if os.path.isfile(out.root):
            raise OutputError(f"{dst}: is a file; a dataset is written into a directory (it is made if missing)")
        parent = os.path.dirname(out.root)
        if not os.path.isdir(parent):
            shown = os.path.dirname(out.shown) or parent
            raise OutputError(f"{dst}: the directory {shown!r} does not exist; create it first")
    if out.local and source.place.local:
        _refuse_links_into_out(source, out)
    inputs = source.files(src_format)
    if source.place.contains(out):  # a glob's folder holds OUT: fine unless the glob takes outputs
        inside = out.resolved[len(source.place.resolved) :].strip("/")
        match = storage.glob_regex(source.pattern or "**").match
        if any(match(f"{inside}/{_output_rel(f.rel, src_format or '', dst_format)[0]}") for f in inputs):
            raise overlap
    if out.local and source.place.local:
        _refuse_linked_overlap(source, out, inputs, src_format, dst_format)
    identity = job_identity(job, src_format, dst_format)
    before = _read_manifest(out, force)
    existing = {f.rel: f for f in out.list(OutputError)}
    same_job = before is not None and before.get("job") == identity
    same_source = before is not None and before.get("source") == source.place.identity
    why = None
    if before is not None and before.get("files") and not force:
        if not same_source:
            why = f"the input differs from the one {MANIFEST} records ({before.get('source')})"
        elif not same_job:
            why = f"the job differs from the one {MANIFEST} records ({_difference(before.get('job') or {}, identity)})"
    recorded = {d["output"]: FileRecord.from_json(d) for d in before["files"]} if before else {}
    ours = set(before.get("hconv_outputs", [])) | set(recorded) if before else set()
    kept: list[FileRecord] = []
    todo: list[Task] = []
    refused: list[tuple[str, HconvError]] = []
    outputs: dict[str, str] = {}
    for f in inputs:
        fmt_in = src_format or storage.format_by_name(f.rel) or ""
        out_rel, fmt_out = _output_rel(f.rel, fmt_in, dst_format)
        if out_rel in outputs:
            raise UsageError(
                f"{source.place.name(outputs[out_rel])} and {source.place.name(f.rel)} would both be written to "
                f"{out.name(out_rel)}; convert them into separate directories"
            )
        outputs[out_rel] = f.rel
        rec = recorded.get(out_rel)
        there = existing.get(out_rel)
        if (
            not force
            and same_job
            and same_source
            and rec is not None
            and rec.input == f.rel
            and (rec.input_size, rec.input_mtime_ns) == (f.size, f.mtime_ns)
            and there is not None
            and there.size == rec.output_size
        ):
            kept.append(rec)
            continue
        if there is not None and not force and out_rel not in ours:
            refused.append(
                (
                    f.rel,
                    OutputError(
                        f"{out.name(out_rel)}: already exists, and {MANIFEST} does not say hconv wrote it; "
                        f"move it away, or pass {option('force', True)} to overwrite it"
                    ),
                )
            )
            continue
        todo.append(Task(f, out_rel, fmt_in, fmt_out, overwrite=there is not None))
    return Plan(source, out, job, identity, inputs, kept, todo, refused, why if todo else None, before)


def _refuse_links_into_out(source: Source, out: Place) -> None:
    """UsageError, before IN is listed, when a folder link in IN leads into OUT or to a folder
    holding it: the listing follows links, so outputs would come back as inputs (and a link to a
    folder holding IN would be listed without end). Comparing the two paths cannot see it."""
    out_real = os.path.realpath(out.root)
    for folder, dirs, _ in os.walk(source.place.root):
        for d in dirs:
            path = os.path.join(folder, d)
            real = os.path.realpath(path)
            if os.path.islink(path) and (storage.inside(real, out_real) or storage.inside(out_real, real)):
                rel = os.path.relpath(path, source.place.root).replace(os.sep, "/")
                raise UsageError(
                    f"{source.place.name(rel)} is a link that leads to {out.shown}; "
                    "remove the link, or write the dataset to a directory it does not lead to"
                )


def _refuse_linked_overlap(
    source: Source, out: Place, inputs: list[Listed], src_format: str | None, dst_format: str | None
) -> None:
    """UsageError when a link joins IN and OUT file by file: an input that is a link to a file of
    OUT, or an output that a folder link in OUT would put into IN."""
    out_real = os.path.realpath(out.root)
    in_real = os.path.realpath(source.place.root)
    for f in inputs:
        if storage.inside(os.path.realpath(source.place.path(f.rel)), out_real):
            raise UsageError(
                f"{source.place.name(f.rel)} is a link to a file in {out.shown}; "
                "remove the link, or write the dataset to another directory"
            )
        rel = _output_rel(f.rel, src_format or storage.format_by_name(f.rel) or "", dst_format)[0]
        folder = os.path.dirname(out.path(rel))
        real = os.path.realpath(folder)
        lexical = os.path.normpath(os.path.join(out_real, os.path.relpath(folder, out.root)))
        if real != lexical and storage.inside(real, in_real):
            raise UsageError(
                f"{out.name(rel)} would be written into {source.place.shown} (through a link in {out.shown}); "
                "remove the link, or write the dataset to another directory"
            )


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
) -> FileRecord:
    """Convert one input file into its output; raises HconvError subclasses naming the file.
    ``progress`` is :func:`convert_file`'s; ``run`` tags the temporary files' names
    (:func:`hconv.tables.storage.stage`). Paths are absolute, so that it runs from any working
    directory, such as a cluster worker's.

    The file is converted into a temporary file (beside the output, or a local one for object
    storage), then committed: renamed into place, or uploaded. The commit and ``done(record)``
    (the caller recording the file for the manifest) happen with interrupts held
    (:class:`hconv.interrupts.held`), so that a Ctrl-C leaves the output either not there or
    there and recorded, never there and unrecorded."""
    t0 = time.perf_counter()
    rel = task.input.rel
    name = src.name(rel)
    with contextlib.ExitStack() as cleanup:
        local_in, etag = _local_input(src, rel, cleanup, run)
        target = dst.path(task.output)
        staged = _staged(dst, task.output, cleanup, run)
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
            dst_name=_shown_output(dst, task.output, staged),
        )
        worst = tally.worst_residual
        record = FileRecord(
            input=rel,
            output=task.output,
            input_size=task.input.size,
            input_mtime_ns=task.input.mtime_ns,
            input_etag=etag,
            output_size=_flushed(staged, dst.name(task.output)) if dst.local else os.path.getsize(staged),
            rows=tally.rows,
            statuses=tally.counts(),
            worst_residual=None if np.isnan(worst) else worst,
            worst_row=tally.worst_row,
            engines=dict(tally.engines),
            seconds=0.0,
        )
        with interrupts.held():
            if dst.local:
                _commit(staged, target, task.overwrite, dst.name(task.output))
            else:
                storage.put(staged, dst, task.output)
            record.seconds = time.perf_counter() - t0
            if done is not None:
                done(record)
            interrupts.point("file")
    return record


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
    """What converting one part gave: :class:`FileRecord`'s counts, rows counted from its start."""

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
    :func:`convert_one` converts a whole file: through a temporary file, committed whole, so that a
    second run of the same part (its worker died) writes the same part again."""
    t0 = time.perf_counter()
    rel = task.input.rel
    with contextlib.ExitStack() as cleanup:
        # the whole object, for each part: reading only its row groups from the store is not built
        local_in, etag = _local_input(src, rel, cleanup, run)
        target = dst.path(part.rel)
        staged = _staged(dst, part.rel, cleanup, run)
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
            dst_name=_shown_output(dst, part.rel, staged),
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
    """Join the part files of ``task`` into its output, committed as :func:`convert_one` commits
    one, then remove them; the file's record, from the parts' (their worst row moved by the
    part's first row). Run again after it committed (its worker died), it finds the parts gone,
    as they are removed only after the commit, and returns the same record."""
    t0 = time.perf_counter()
    target = dst.path(task.output)
    with contextlib.ExitStack() as cleanup:
        if all(storage.exists(dst, p.rel) for p in parts):
            local = [_local_input(dst, p.rel, cleanup, run)[0] for p in parts]
            staged = _staged(dst, task.output, cleanup, run)
            parquetio.join_parquet(local, staged)
            with interrupts.held():
                if dst.local:
                    _flushed(staged, dst.name(task.output))
                    _commit(staged, target, task.overwrite, dst.name(task.output))
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


def _local_input(src: Place, rel: str, cleanup: contextlib.ExitStack, run: str | None) -> tuple[str, str | None]:
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


def _staged(dst: Place, rel: str, cleanup: contextlib.ExitStack, run: str | None) -> str:
    """A temporary file (removed by ``cleanup``) to write ``rel`` of ``dst`` into before it is
    committed: beside it (its missing folders made), or a local one for object storage."""
    target = dst.path(rel)
    if dst.local:
        _make_folders(os.path.dirname(target), cleanup)
    with interrupts.held():
        try:
            staged = storage.stage(target if dst.local else None, run=run)
        except OSError as exc:  # mkstemp in a folder that is full or not writable
            where = os.path.dirname(target) if dst.local else "the temporary directory (TMPDIR)"
            err = OutputError(f"{dst.name(rel)}: cannot make its temporary file in {where} ({exc.strerror or exc})")
            err.errno = exc.errno  # a full disk stops the run (convert_dataset)
            raise err from None
        cleanup.callback(_remove, staged)
    return staged


def _commit(staged: str, target: str, overwrite: bool, shown: str) -> None:
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
    remove those it made that stayed empty, so that a failed file leaves nothing behind."""
    made = []
    while folder and not os.path.isdir(folder):
        made.append(folder)
        folder = os.path.dirname(folder)
    for path in reversed(made):
        with interrupts.held():
            try:
                os.mkdir(path)
            except FileExistsError:
                continue
            except OSError as exc:
                raise OutputError(f"{path}: cannot make this folder ({exc.strerror or exc})") from None
            cleanup.callback(_remove_if_empty, path)


def _remove_if_empty(path: str) -> None:
    with contextlib.suppress(OSError):  # not empty: the output, or another file, is in it
        os.rmdir(path)


def _remove(path: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


def _flushed(path: str, shown: str) -> int:
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


def _shown_output(dst: Place, rel: str, staged: str) -> str:
    """How messages name the output ``rel`` while it is written into ``staged``: its own name, and
    for object storage where it is staged, whose disk a full disk is."""
    if dst.local:
        return dst.name(rel)
    return f"{dst.name(rel)} (staged in {os.path.dirname(staged)!r}; set TMPDIR to a directory with room)"


def convert_dataset(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    method: str = "exact",
    precision: int = 64,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    diagnostics: bool = True,
    job: Job | None = None,
    strict: bool = False,
    threads: int | None = None,
    endpoint_url: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    log: Callable[[str], None] | None = None,
    cluster: object = None,
    workers: int | None = None,
    cluster_timeout: float = 10.0,
    task_rows: int | None = None,
) -> DatasetResult:
    """Convert every file of the dataset ``src`` (a directory, a glob or a URI) into ``dst`` (a
    directory or prefix), each at its relative path, and write the manifest last; see the module.

    The keywords are :func:`~hconv.tables.pipeline.convert_file`'s, plus: ``force``: convert every
    file again, and overwrite outputs the manifest does not list (nothing is ever deleted);
    ``endpoint_url``: an S3-compatible server (default: AWS_ENDPOINT_URL_S3, AWS_ENDPOINT_URL);
    ``progress(done, total)`` after each file to convert; ``log(line)`` for what the run decided
    and for each failing file (``error: ...``); ``cluster``: convert the files on a Dask cluster
    (:mod:`hconv.tables.cluster`, the ``hconv[dask]`` extra): ``"local"`` (``workers`` processes,
    default one per core), a scheduler's address (``"tcp://HOST:PORT"``, given ``cluster_timeout``
    seconds to answer) or a ``distributed.Client``; ``threads`` is then each worker's;
    ``task_rows``: a Parquet file of more rows (and 2 row groups or more) is converted by several
    tasks of about this many rows each, and joined into the same output (:func:`split`; default
    :data:`TASK_ROWS`: 0, one task per file). Raises
    :class:`DatasetError` after the run if a file failed, KeyboardInterrupt (with what was kept)
    if interrupted, and HconvError subclasses if the dataset cannot be read or written at all.
    """
    t0 = time.perf_counter()
    check_job(job)
    check_threads(threads)  # before anything is written: a bad option fails the run, not each file
    check_callback("progress", progress)
    check_callback("log", log)
    check_task_rows(task_rows)
    if task_rows is not None and cluster is None:
        raise UsageError(f"{option('task_rows')} sets how {option('cluster')} splits large files; add that")
    if cluster is not None or workers is not None:
        from hconv.tables import cluster as dask_cluster  # dask, only when asked for

        dask_cluster.check(cluster, workers, cluster_timeout)
    src_path, dst_path = os.fspath(src), os.fspath(dst)
    job = job or Job(method, precision, diagnostics)
    say = log or (lambda line: None)
    plan = plan_dataset(
        src_path,
        dst_path,
        job=job,
        src_format=src_format,
        dst_format=dst_format,
        force=force,
        endpoint_url=endpoint_url,
    )
    if plan.describe():
        say(plan.describe())
    records: dict[str, FileRecord] = {r.input: r for r in plan.kept}
    failed: dict[str, HconvError] = {}
    for rel, exc in plan.refused:
        failed[rel] = exc
        say(f"error: {exc}")
    converted: list[str] = []
    # Before any file is written: the manifest takes back what it said of the files about to be
    # replaced, and claims the paths this run will write, so that a run killed outright leaves
    # outputs the next run knows as hconv's own.
    written = _written_before(plan) | {t.output for t in plan.todo}
    _remove_orphan_parts(plan, say)
    parts_run = None  #: while parts may exist: this run's tag and driver, in every manifest written

    def keep(rec: FileRecord) -> None:
        records[rec.input] = rec
        converted.append(rec.input)

    ran_on = None
    split_files = split_parts = 0
    rows = TASK_ROWS if task_rows is None else task_rows
    stopped: HconvError | None = None  #: a file's output found no room on the disk: the others would not either
    # OUT made by this run is removed again when the run ends having put nothing in it (the manifest
    # cannot be written, an interrupt before the first file): a failed run leaves no output.
    created = plan.dst.local and not os.path.lexists(plan.dst.root)
    try:
        with contextlib.ExitStack() as stack:
            if cluster is not None and plan.todo:
                # connected (and the workers' hconv checked) before anything is written
                session = stack.enter_context(dask_cluster.connect(cluster, workers, cluster_timeout, threads))
                ran_on = session.describe()
                say(f"running on {ran_on}")
                outcomes = session.run(plan, keep, strict=strict, task_rows=rows)
                if rows:
                    parts_run = {"id": session.run_id, "driver": temporaries.maker()}
            else:
                outcomes = _in_process(plan, keep, strict=strict, threads=threads)
            if plan.todo:
                _write_manifest(plan, records, failed, written, t0, parts_run)
            last = time.monotonic()
            try:
                for k, (task, error) in enumerate(outcomes):
                    if error is not None:
                        failed[task.input.rel] = error
                        say(f"error: {error}")
                        if getattr(error, "errno", None) in output.NO_ROOM:
                            stopped = error
                            break
                    if progress is not None:
                        progress(k + 1, len(plan.todo))
                    if time.monotonic() - last > CHECKPOINT_SECONDS:
                        _write_manifest(plan, records, failed, written, t0, parts_run)
                        last = time.monotonic()
            except KeyboardInterrupt:
                if any(t.input.rel not in records and t.input.rel not in failed for t in plan.todo):
                    if created and not converted:
                        raise  # nothing to keep: OUT is removed below
                    _write_manifest(plan, records, failed, written, t0, parts_run)
                    raise KeyboardInterrupt(
                        f"interrupted; {len(records)} of {len(plan.inputs)} files are converted and listed in "
                        f"{plan.dst.name(MANIFEST)} (complete: false), and no other file was written; "
                        "run the same command again to convert the rest"
                    ) from None
                # else too late to stop: every file is done; the run ends as it would have
            finally:
                if hasattr(outcomes, "close"):  # stopped early: no further file starts
                    outcomes.close()
            if ran_on is not None:
                ran_on = session.describe_end()
                split_files, split_parts = session.split_files, session.parts
        if plan.todo or plan.refused or _manifest_stale(plan, records, failed):
            # The last manifest settles the run: from here an interrupt cannot make it exit 130
            # with OUT complete (hconv.interrupts.settle), which a caller would retry and fail.
            interrupts.point("manifest")
            with interrupts.held():
                _write_manifest(plan, records, failed, written, t0)
                interrupts.settle()
                interrupts.point("settled")
    except BaseException:
        if created and not converted:
            _remove_created_out(plan)
        raise
    result = _result(plan, records, failed, converted, t0)
    result.ran_on = ran_on
    result.split_files, result.split_parts, result.task_rows = split_files, split_parts, rows
    if stopped is not None:
        raise DatasetError(
            f"stopped: no room left for {_named(stopped)} (named above); {len(result.files)} of {result.total} "
            f"files are converted and listed in {result.manifest}, which says complete: false; "
            "make room and run the same command again to convert the rest",
            stopped.exit_code,
            result,
        )
    if failed:
        codes = [exc.exit_code for exc in failed.values()]
        raise DatasetError(
            f"{len(failed)} of {result.total} files failed (named above); {len(result.files)} are converted "
            f"and listed in {result.manifest}, which says complete: false",
            max(codes),
            result,
        )
    return result


def _named(exc: HconvError) -> str:
    """The file an error's one-line message names (the part before its first ``: ``)."""
    return str(exc).split(": ", 1)[0]


def _remove_created_out(plan: Plan) -> None:
    """Remove OUT, made by this run, and its manifest: the run ends having converted nothing into it."""
    storage.remove(plan.dst, MANIFEST)
    with contextlib.suppress(OSError):  # not empty: something else is in it, which hconv never deletes
        os.rmdir(plan.dst.root)


def _in_process(
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


def _written_before(plan: Plan) -> set[str]:
    """Outputs hconv wrote, or began to write, into this OUT in earlier runs (the manifest's)."""
    before = plan.manifest_before or {}
    return {d["output"] for d in before.get("files", [])} | set(before.get("hconv_outputs", []))


def _manifest(plan: Plan, records: dict[str, FileRecord], failed: dict[str, HconvError], written: set[str]) -> dict:
    files = [records[f.rel] for f in plan.inputs if f.rel in records]
    tally, worst = _sum(plan.job, files)
    return {
        "kind": MANIFEST_KIND,
        "version": MANIFEST_VERSION,
        "complete": len(files) == len(plan.inputs),
        "hconv": __version__,
        "source": plan.src.place.identity,
        "job": plan.identity,
        "inputs": len(plan.inputs),
        "rows": tally.rows,
        "statuses": tally.counts(),
        "worst_residual": None
        if worst is None
        else {"value": tally.worst_residual, "file": worst.output, "input": worst.input, "row": tally.worst_row},
        "files": [r.to_json() for r in files],
        "failed": [{"input": rel, "error": str(exc)} for rel, exc in failed.items()],
        "pending": [f.rel for f in plan.inputs if f.rel not in records and f.rel not in failed],
        # every path hconv has written, or begun to write, into OUT, listed in files or not: the
        # files it may replace without force (it never deletes one)
        "hconv_outputs": sorted(written),
    }


def _remove_orphan_parts(plan: Plan, say: Callable[[str], None]) -> None:
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


def _manifest_stale(plan: Plan, records: dict, failed: dict) -> bool:
    """Whether the manifest on disk says anything else than this run would write."""
    before = plan.manifest_before
    if before is None:
        return True
    now = _manifest(plan, records, failed, _written_before(plan))
    keys = ("complete", "source", "job", "files", "failed", "pending", "version")
    return any(before.get(k) != now[k] for k in keys)


def _write_manifest(
    plan: Plan, records: dict, failed: dict, written: set[str], t0: float, parts_run: dict | None = None
) -> None:
    m = _manifest(plan, records, failed, written)
    if parts_run is not None:
        # A driver killed outright (kill -9, a lost machine) cannot remove the parts its tasks
        # wrote; the next run, reading this, removes them once it can tell the driver has ended.
        m["parts_run"] = parts_run
    m["written_at"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    m["seconds"] = round(time.perf_counter() - t0, 3)
    storage.write_bytes(plan.dst, MANIFEST, (json.dumps(m, indent=1) + "\n").encode())


def _sum(job: Job, files: list[FileRecord]) -> tuple[Tally, FileRecord | None]:
    """The whole dataset's tally from its files' records, and the file with the worst residual."""
    tally = Tally(methods.get(job.method).name, job.unit)
    worst = None
    for r in files:
        if tally.add_counts(r.rows, r.statuses, r.engines, r.worst_residual, r.worst_row):
            worst = r
    return tally, worst


def _result(plan: Plan, records: dict, failed: dict, converted: list[str], t0: float) -> DatasetResult:
    files = [records[f.rel] for f in plan.inputs if f.rel in records]
    tally, worst = _sum(plan.job, files)
    seconds = time.perf_counter() - t0
    tally.seconds = seconds
    return DatasetResult(
        src=plan.src.spec,
        dst=plan.dst.shown,
        manifest=plan.dst.name(MANIFEST),
        files=files,
        converted=converted,
        failed=list(failed.items()),
        pending=[f.rel for f in plan.inputs if f.rel not in records and f.rel not in failed],
        total=len(plan.inputs),
        tally=tally,
        worst_file=None if worst is None else plan.src.place.name(worst.input),
        rows_converted=sum(records[rel].rows for rel in converted),
        seconds=seconds,
    )
