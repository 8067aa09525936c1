"""A dataset's manifest, ``OUT/_hconv_manifest.json``: the record of each complete output
(:class:`FileRecord`), the job it was made by, and which files failed or are pending; read when a
run is planned, and written while it runs and last (:mod:`hconv.tables.dataset` says when).

While a run converts, outputs are listed by group commit (:class:`GroupCommit`), as databases
commit groups of transactions: an output renamed into place joins the open group; the group is
made durable together (small outputs with one ``syncfs`` of OUT's file system where Linux has it,
else an fsync of each output; then an fsync of each of their folders, which makes the renames
durable), and only then are its records kept and the manifest rewritten, once for the whole
group. So the manifest never lists an output that a crash could still take back, and a run killed
outright loses at most the open group, which the next run converts again (the manifest claimed
those paths first)."""

from __future__ import annotations

import ctypes
import ctypes.util
import dataclasses
import datetime
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from hconv import interrupts
from hconv.errors import HconvError, OutputError, option
from hconv.solve import methods
from hconv.tables import storage
from hconv.tables.job import Job
from hconv.tables.pipeline import Tally
from hconv.tables.storage import Place
from hconv.version import __version__

if TYPE_CHECKING:
    from hconv.tables.planning import Plan

MANIFEST = "_hconv_manifest.json"
MANIFEST_KIND = "hconv dataset manifest"
MANIFEST_VERSION = 1


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

    def encoded(self) -> str:
        """The record as the manifest writes it (``json.dumps(..., indent=1)`` at its depth in the
        manifest's ``files`` list), worked out once: a run rewrites the manifest with every record
        many times, and encoding thousands each time cost more than converting small files."""
        text = self.__dict__.get("_encoded")
        if text is None:
            text = json.dumps(self.to_json(), indent=1).replace("\n", "\n  ")
            self.__dict__["_encoded"] = text
        return text

    @classmethod
    def from_json(cls, d: dict) -> FileRecord:
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls)})


#: The order a manifest writes the job's fields in, fixed so that its bytes do not follow the
#: classes' field order (``engine`` is :class:`hconv.Options`' since ``Job`` extends it).
JOB_KEYS = ("method", "precision", "diagnostics", "conventions", "mapping", "unit_options", "quat_order",
            "omega_unit", "observed", "engine", "keep_text", "field_units", "prefix")  # fmt: skip


#: Fields added later, with their defaults: a manifest records each only when it is set, so that
#: a dataset converted before it existed is not all converted again for a job that does not set it.
RECORDED_WHEN_SET = {"prefix": "", "delimiter": None, "decimal": None}


def job_identity(job: Job, src_format: str | None, dst_format: str | None) -> dict:
    """The job as the manifest records it: every Job field, in :data:`JOB_KEYS`' order, and the
    formats asked for; :data:`RECORDED_WHEN_SET` only when set (a manifest written before they
    existed still records the same job)."""
    fields = dataclasses.asdict(job)
    for k, default in RECORDED_WHEN_SET.items():
        if fields.get(k) == default:
            del fields[k]
    d = {k: fields.pop(k) for k in JOB_KEYS if k in fields} | fields  # a field added later goes last
    d["src_format"], d["dst_format"] = src_format, dst_format
    return json.loads(json.dumps(d))  # tuples as lists, as they come back from the file


def read_manifest(dst: Place, force: bool) -> dict | None:
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


def written_before(plan: Plan) -> set[str]:
    """Outputs hconv wrote, or began to write, into this OUT in earlier runs (the manifest's)."""
    before = plan.manifest_before or {}
    return {d["output"] for d in before.get("files", [])} | set(before.get("hconv_outputs", []))


def _manifest(plan: Plan, records: dict[str, FileRecord], failed: dict[str, HconvError], written: set[str]) -> dict:
    files = [records[f.rel] for f in plan.inputs if f.rel in records]
    tally, worst = tally_of(plan.job, files)
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
        "files": files,  # FileRecords: manifest_text encodes them (manifest_stale compares them as JSON)
        "failed": [{"input": rel, "error": str(exc)} for rel, exc in failed.items()],
        "pending": [f.rel for f in plan.inputs if f.rel not in records and f.rel not in failed],
        # every path hconv has written, or begun to write, into OUT, listed in files or not: the
        # files it may replace without force (it never deletes one)
        "hconv_outputs": sorted(written),
    }


def manifest_stale(plan: Plan, records: dict, failed: dict) -> bool:
    """Whether the manifest on disk says anything else than this run would write."""
    before = plan.manifest_before
    if before is None:
        return True
    now = _manifest(plan, records, failed, written_before(plan))
    now["files"] = [r.to_json() for r in now["files"]]
    keys = ("complete", "source", "job", "files", "failed", "pending", "version")
    return any(before.get(k) != now[k] for k in keys)


def write_manifest(
    plan: Plan, records: dict, failed: dict, written: set[str], t0: float, parts_run: dict | None = None
) -> None:
    m = _manifest(plan, records, failed, written)
    if parts_run is not None:
        # A driver killed outright (kill -9, a lost machine) cannot remove the parts its tasks
        # wrote; the next run, reading this, removes them once it can tell the driver has ended.
        m["parts_run"] = parts_run
    m["written_at"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    m["seconds"] = round(time.perf_counter() - t0, 3)
    storage.write_bytes(plan.dst, MANIFEST, (manifest_text(m, files_of(plan, records)) + "\n").encode())


def files_of(plan: Plan, records: dict[str, FileRecord]) -> list[FileRecord]:
    return [records[f.rel] for f in plan.inputs if f.rel in records]


def manifest_text(m: dict, files: list[FileRecord]) -> str:
    """``json.dumps(m, indent=1)``, its ``files`` (the records ``files``) spliced in from each
    record's :meth:`FileRecord.encoded` text rather than encoded again."""
    listed = m["files"]
    m["files"] = []
    try:
        text = json.dumps(m, indent=1)
    finally:
        m["files"] = listed
    if not files:
        return text
    body = "[\n  " + ",\n  ".join(r.encoded() for r in files) + "\n ]"
    marker = '\n "files": [],'
    at = text.index(marker) + len(marker) - 3  # at the "[]"
    return text[:at] + body + text[at + 2 :]


def tally_of(job: Job, files: list[FileRecord]) -> tuple[Tally, FileRecord | None]:
    """The whole dataset's tally from its files' records, and the file with the worst residual."""
    tally = Tally(methods.get(job.method).name, job.unit, precision=job.precision)
    worst = None
    for r in files:
        if tally.add_counts(r.rows, r.statuses, r.engines, r.worst_residual, r.worst_row):
            worst = r
    return tally, worst


#: A group closes at this many outputs or this age, whichever comes first: small enough that a
#: kill loses little (half a second of work), large enough that the sync and the manifest's
#: rewrite are shared by many small files (docs/scaling.md measures both).
GROUP_FILES = 64
GROUP_SECONDS = 0.5
#: ... but no sooner than this many times the last commit's own cost after it ended: the
#: manifest grows with the dataset, and rewriting thousands of records for every 64 files of a
#: few hundred rows would cost more than converting them; this bounds the commits' share of a
#: run to about 1/(1 + GROUP_COST_SHARE).
GROUP_COST_SHARE = 10.0


class GroupCommit:
    """Outputs committed (in place) but not yet durable wait in the open group; :meth:`close`
    makes them durable together, hands their records to ``keep`` and calls ``write`` (the
    manifest's rewrite) once. See the module."""

    def __init__(self, keep: Callable[[FileRecord], None], write: Callable[[], None]):
        self._keep, self._write = keep, write
        self._records: list[FileRecord] = []
        self._paths: list[str] = []
        self._opened = 0.0
        self._ended = time.monotonic()
        self._cost = 0.0
        self.groups = 0  #: groups closed so far

    def add(self, record: FileRecord, path: str | None) -> None:
        """A committed output's record; ``path``: where it is, to make durable (None: already
        durable: flushed on its own, or uploaded to object storage)."""
        now = time.monotonic()
        if not self._records:
            self._opened = now
        self._records.append(record)
        if path is not None:
            self._paths.append(path)
        full = len(self._records) >= GROUP_FILES or now - self._opened >= GROUP_SECONDS
        if full and now - self._ended >= GROUP_COST_SHARE * self._cost:
            self.close()

    def close(self) -> None:
        """Make the open group durable, keep its records, rewrite the manifest; nothing if empty."""
        if not self._records:
            return
        t0 = time.monotonic()
        make_durable(self._paths)
        with interrupts.held():  # kept all, and the group emptied, or none
            for record in self._records:
                self._keep(record)
            self._records, self._paths = [], []
        self._write()
        self.groups += 1
        self._ended = time.monotonic()
        self._cost = self._ended - t0


#: Outputs averaging this many bytes or more are flushed with an fsync each rather than one
#: syncfs: syncfs flushes every writer's dirty data on the file system too (another program's,
#: or inputs written just before the run), and the run's own writers stall while it does; an
#: fsync costs a disk cache flush of its own, which many small outputs share in one syncfs
#: (docs/measurements.md).
SYNC_EACH_BYTES = 1 << 20


def make_durable(paths: list[str]) -> None:
    """Flush the files ``paths`` and their folders (so that the renames that put them there
    survive a crash) to the disk: small files (under :data:`SYNC_EACH_BYTES` on average) together,
    with one syncfs where they share a file system that has it, else an fsync of each; then each
    folder once. OutputError naming the file or folder if the disk refuses."""
    if not paths:
        return
    folders = sorted({os.path.dirname(p) or "." for p in paths})
    try:
        small = sum(os.stat(p).st_size for p in paths) < SYNC_EACH_BYTES * len(paths)
        if not small or len({os.stat(f).st_dev for f in folders}) > 1 or not _syncfs(folders[0]):
            for path in paths:
                _fsync(path, os.O_RDONLY)
        for folder in folders:
            _fsync(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError as exc:
        where = exc.filename or folders[0]
        raise OutputError(
            f"{where}: the outputs there could not be flushed to the disk ({exc.strerror or exc}); "
            "they are not listed in the manifest, and the next run converts them again"
        ) from None


def _fsync(path: str, flags: int) -> None:
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


_LIBC: list = []


def _syncfs(folder: str) -> bool:
    """Linux's syncfs(2) on the file system holding ``folder`` (every dirty file there flushed in
    one call, one journal commit); False where there is none."""
    if not _LIBC:
        name = ctypes.util.find_library("c")
        lib = ctypes.CDLL(name, use_errno=True) if name else None
        _LIBC.append(lib if lib is not None and hasattr(lib, "syncfs") else None)
    lib = _LIBC[0]
    if lib is None:
        return False
    fd = os.open(folder, os.O_RDONLY)
    try:
        if lib.syncfs(fd) != 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err), folder)
        return True
    finally:
        os.close(fd)
