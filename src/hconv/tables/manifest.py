"""A dataset's manifest, ``OUT/_hconv_manifest.json``: the record of each complete output
(:class:`FileRecord`), the job it was made by, and which files failed or are pending; read when a
run is planned, and written while it runs and last (:mod:`hconv.tables.dataset` says when)."""

from __future__ import annotations

import dataclasses
import datetime
import json
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

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
        "files": [r.to_json() for r in files],
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
    storage.write_bytes(plan.dst, MANIFEST, (json.dumps(m, indent=1) + "\n").encode())


def tally_of(job: Job, files: list[FileRecord]) -> tuple[Tally, FileRecord | None]:
    """The whole dataset's tally from its files' records, and the file with the worst residual."""
    tally = Tally(methods.get(job.method).name, job.unit)
    worst = None
    for r in files:
        if tally.add_counts(r.rows, r.statuses, r.engines, r.worst_residual, r.worst_row):
            worst = r
    return tally, worst
