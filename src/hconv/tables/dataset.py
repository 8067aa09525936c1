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
The unit of work, :func:`hconv.tables.onefile.convert_one`, takes and returns picklable values,
so that a runner on other machines can map it over :attr:`hconv.tables.planning.Plan.todo` and
hand the records to the same manifest.

This module is the run: it asks :mod:`hconv.tables.planning` what to do, has the files converted
by a runner (:mod:`hconv.tables.runners`: this process, or a Dask cluster), and writes
:mod:`hconv.tables.manifest` as files complete; :mod:`hconv.tables.parts` converts a large
Parquet file in parts on a cluster.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from hconv import interrupts
from hconv.errors import HconvError, UsageError, option
from hconv.solve import options
from hconv.tables import output, runners, storage, temporaries
from hconv.tables.job import Job
from hconv.tables.manifest import (
    MANIFEST,
    FileRecord,
    GroupCommit,
    manifest_stale,
    tally_of,
    write_manifest,
    written_before,
)
from hconv.tables.parts import TASK_ROWS, check_task_rows, remove_orphan_parts
from hconv.tables.pipeline import Tally, check_callback, check_threads
from hconv.tables.planning import Plan, plan_dataset


def is_dataset(src: str, dst: str) -> bool:
    """Whether ``hconv convert SRC DST`` converts a dataset: SRC is a directory, a glob or a URI,
    or DST is a URI. One file (or stdin) into a file keeps
    :func:`hconv.tables.pipeline.convert_file`'s behaviour."""
    if src == "-":
        return False
    if storage.is_uri(src) or storage.is_uri(dst):
        return True
    return os.path.isdir(src) or (storage.has_glob(src) and not os.path.exists(src))


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
    split_files: int = 0  #: files this run converted in parts on the cluster (:func:`hconv.tables.parts.split`)
    split_parts: int = 0  #: the parts those files were split into
    task_rows: int = 0  #: the rows per part the run asked for (0: every file whole)
    #: outputs in OUT that earlier runs wrote and no input of this one maps to (left in place)
    orphans: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return len(self.files) == self.total


class DatasetError(HconvError):
    """Some files of a dataset failed; the others were converted. ``result`` holds the run."""

    def __init__(self, message: str, exit_code: int, result: DatasetResult):
        super().__init__(message)
        self.exit_code = exit_code
        self.result = result


def _spec_of(src: object, src_format: str | None) -> tuple[str, str | None]:
    """The dataset ``src`` as a path spec, and its format: a path (str or PathLike) as it is; a
    pyarrow ``FileSystemDataset`` of local files as their directory, if they are all the files
    hconv would read there (its format, unless ``src_format`` says it); UsageError for anything else."""
    if isinstance(src, (str, os.PathLike)):
        return os.fspath(src), src_format
    import pyarrow.dataset as pads
    import pyarrow.fs as pafs

    pass_path = "pass the directory, a glob or the URI as a str, as hconv convert takes it"
    if isinstance(src, pads.FileSystemDataset):
        files = [os.path.abspath(f) for f in src.files]
        if not isinstance(src.filesystem, pafs.LocalFileSystem):
            raise UsageError(f"convert_dataset: a pyarrow dataset on {src.filesystem.type_name}: {pass_path}")
        if not files:
            raise UsageError(f"convert_dataset: the pyarrow dataset has no files; {pass_path}")
        fmt = src_format or next(
            (name for kind, name in _PYARROW_FORMATS if isinstance(src.format, getattr(pads, kind, ()))), None
        )
        root = os.path.commonpath(files) if len(files) > 1 else os.path.dirname(files[0])
        if os.path.isfile(root):
            root = os.path.dirname(root)
        listed = {os.path.join(root, f.rel) for f in storage.source(root).files(fmt)}
        if listed != set(files):
            raise UsageError(
                f"convert_dataset: the pyarrow dataset holds {len(files)} of the files in {root} that hconv would "
                f"read ({len(listed)}); {pass_path}, such as a glob that matches those files"
            )
        return root, fmt
    if isinstance(src, pads.Dataset):
        raise UsageError(
            "convert_dataset: a pyarrow dataset in memory has no files; convert it with "
            "hconv.convert_table(dataset.to_table())"
        )
    raise UsageError(
        f"convert_dataset takes a directory, a glob or a URI (a str or path), or a pyarrow dataset of files, "
        f"got {type(src).__name__}; for a table in memory, use hconv.convert_table"
    )


#: pyarrow.dataset's file formats, and hconv's name for each (first match wins: Feather is IPC).
_PYARROW_FORMATS = (
    ("ParquetFileFormat", "parquet"),
    ("CsvFileFormat", "csv"),
    ("IpcFileFormat", "arrow"),
    ("JsonFileFormat", "jsonl"),
)


def convert_dataset(
    src: object,
    dst: str | os.PathLike[str],
    *,
    method: str | None = None,
    precision: int | None = None,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    diagnostics: bool | None = None,
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
    prefix: str | None = None,
) -> DatasetResult:
    """Convert every file of the dataset ``src`` (a directory, a glob or a URI, or a pyarrow
    ``FileSystemDataset`` of all the files of a local directory) into ``dst`` (a directory or
    prefix), each at its relative path, and write the manifest last; see the module.

    The keywords are :func:`~hconv.tables.pipeline.convert_file`'s (``prefix`` among them), plus:
    ``force``: convert every file again, and overwrite outputs the manifest does not list (nothing
    is ever deleted); ``endpoint_url``: an S3-compatible server (default: AWS_ENDPOINT_URL_S3, AWS_ENDPOINT_URL);
    ``progress(done, total)`` after each file to convert; ``log(line)`` for what the run decided
    and for each failing file (``error: ...``); ``cluster``: convert the files on a Dask cluster
    (:mod:`hconv.tables.cluster`, the ``hconv[dask]`` extra): ``"local"`` (``workers`` processes,
    default one per core), a scheduler's address (``"tcp://HOST:PORT"``, given ``cluster_timeout``
    seconds to answer) or a ``distributed.Client``; ``threads`` is then each worker's;
    ``task_rows``: a Parquet file of more rows (and 2 row groups or more) is converted by several
    tasks of about this many rows each, and joined into the same output (:func:`hconv.tables.parts.split`;
    default :data:`hconv.tables.parts.TASK_ROWS`: 0, one task per file). Raises
    :class:`DatasetError` after the run if a file failed, KeyboardInterrupt (with what was kept)
    if interrupted, and HconvError subclasses if the dataset cannot be read or written at all.
    """
    t0 = time.perf_counter()
    job = options.configure(
        Job, "convert_dataset", job, method=method, precision=precision, diagnostics=diagnostics, prefix=prefix
    )
    check_threads(threads)  # before anything is written: a bad option fails the run, not each file
    check_callback("progress", progress)
    check_callback("log", log)
    check_task_rows(task_rows)
    if task_rows is not None and cluster is None:
        raise UsageError(f"{option('task_rows')} sets how {option('cluster')} splits large files; add that")
    runners.check_cluster(cluster, workers, cluster_timeout)
    src_path, src_format = _spec_of(src, src_format)
    if not isinstance(dst, (str, os.PathLike)):
        raise UsageError(
            f"convert_dataset writes into a directory, a prefix or a URI (a str), got {type(dst).__name__}"
        )
    dst_path = os.fspath(dst)
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
    written = written_before(plan) | {t.output for t in plan.todo}
    remove_orphan_parts(plan, say)
    parts_run = None  #: while parts may exist: this run's tag and driver, in every manifest written

    def keep(rec: FileRecord) -> None:
        if rec.input not in records:  # a todo file is not among the kept ones
            converted.append(rec.input)
        records[rec.input] = rec

    # outputs are listed once durable, a group at a time, the manifest rewritten once per group
    commit = GroupCommit(keep, lambda: write_manifest(plan, records, failed, written, t0, parts_run))

    ran_on = None
    split_files = split_parts = 0
    rows = TASK_ROWS if task_rows is None else task_rows
    stopped: HconvError | None = None  #: a file's output found no room on the disk: the others would not either
    # OUT made by this run is removed again when the run ends having put nothing in it (the manifest
    # cannot be written, an interrupt before the first file): a failed run leaves no output.
    created = plan.dst.local and not os.path.lexists(plan.dst.root)
    try:
        # From the end of the files to the last manifest, interrupts wait (settling): one
        # that landed there (the last group's commit, the cluster's shutdown) exited 130 with OUT
        # complete and no word of what was kept; it now acts after the settle, so is ignored.
        with contextlib.ExitStack() as settling, contextlib.ExitStack() as stack:
            stack.enter_context(temporaries.sweeping_once())
            if cluster is not None and plan.todo:
                # connected (and the workers' hconv checked) before anything is written
                session = stack.enter_context(runners.on_cluster(cluster, workers, cluster_timeout, threads))
                ran_on = session.describe()
                say(f"running on {ran_on}")
                outcomes = session.run(plan, commit, strict=strict, task_rows=rows)
                if rows:
                    parts_run = {"id": session.run_id, "driver": temporaries.maker()}
            else:
                outcomes = runners.in_process(plan, commit, strict=strict, threads=threads)
            if plan.todo:
                write_manifest(plan, records, failed, written, t0, parts_run)
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
                commit.close()  # the last group; inside the try, so that an interrupt in it is handled below
            except KeyboardInterrupt:
                # the files under way finish (or stop) and the committed ones join the group,
                # which is made durable and kept before the manifest below lists them
                if hasattr(outcomes, "close"):
                    outcomes.close()
                with contextlib.suppress(HconvError):  # not flushed: not listed, converted again next run
                    commit.close()
                if any(t.input.rel not in records and t.input.rel not in failed for t in plan.todo):
                    if created and not converted:
                        raise  # nothing to keep: OUT is removed below
                    write_manifest(plan, records, failed, written, t0, parts_run)
                    raise KeyboardInterrupt(
                        f"interrupted; {len(records)} of {len(plan.inputs)} files are converted and listed in "
                        f"{plan.dst.name(MANIFEST)} (complete: false), and no other file was written; "
                        "run the same command again to convert the rest"
                    ) from None
                # else too late to stop: every file is done; the run ends as it would have
            finally:
                if hasattr(outcomes, "close"):  # stopped early: no further file starts
                    outcomes.close()
            settling.enter_context(interrupts.held())
            interrupts.point("files done")
            commit.close()  # a run stopped by a full disk: the files committed meanwhile
            if ran_on is not None:
                ran_on = session.describe_end()
                split_files, split_parts = session.split_files, session.parts
            stack.close()  # the cluster shut down (and the sweep's scope ended), still held
            if plan.todo or plan.refused or manifest_stale(plan, records, failed):
                # The last manifest settles the run: from here an interrupt cannot make it exit
                # 130 with OUT complete (hconv.interrupts.settle), which a caller would retry and fail.
                interrupts.point("manifest")
                write_manifest(plan, records, failed, written, t0)
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


def _result(plan: Plan, records: dict, failed: dict, converted: list[str], t0: float) -> DatasetResult:
    files = [records[f.rel] for f in plan.inputs if f.rel in records]
    tally, worst = tally_of(plan.job, files)
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
        orphans=[plan.dst.name(rel) for rel in plan.orphans],
    )
