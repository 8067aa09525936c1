"""Planning a dataset run: which input files there are, where each output goes, which outputs are
up to date (kept), which must be converted (the input or the job changed, the output is missing
or not the recorded one) and which are refused (a file in OUT that hconv did not write); and
refusing an OUT that overlaps IN, even through links. See :mod:`hconv.tables.dataset`."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from hconv.errors import HconvError, OutputError, UsageError, option
from hconv.tables import storage
from hconv.tables.formats import EXTENSIONS, FORMATS, NAMES, WRITES, choices
from hconv.tables.job import Job
from hconv.tables.manifest import MANIFEST, FileRecord, job_identity, read_manifest
from hconv.tables.storage import Listed, Place, Source


@dataclass(frozen=True)
class Task:
    """One input file to convert: picklable, for :func:`hconv.tables.onefile.convert_one` wherever it runs."""

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
    #: outputs hconv wrote in earlier runs that no input of this run maps to (their input gone or
    #: renamed, or another output format), still in OUT: hconv leaves them (they may be wanted)
    #: but says so, since the manifest's "complete" does not account for them
    orphans: list[str] = field(default_factory=list)

    def describe(self) -> str:
        n, kept = len(self.inputs), len(self.kept)
        if self.why:
            return f"{self.why}; converting all {len(self.todo)} files"
        if not self.todo:
            return f"all {n} files already converted and up to date; nothing to convert" if kept == n else ""
        todo = len(self.todo)
        if kept:
            said = f"{kept} of {n} files already converted and up to date; converting {todo}"
        elif self.refused:  # the summary counts every input: say both counts here
            said = f"converting {todo} of {n} files"
        else:
            said = f"converting {todo} file" + ("s" if todo != 1 else "")
        if self.refused:
            said += f" ({len(self.refused)} in the way, named below)"
        return said


def _output_rel(rel: str, fmt_in: str, dst_format: str | None) -> tuple[str, str]:
    if dst_format is None and fmt_in in NAMES and fmt_in not in WRITES:  # JSON lines is read only
        raise UsageError(
            f"{rel}: is {NAMES[fmt_in]}, which hconv reads but does not write; pass "
            f"{option('dst_format', 'FORMAT')} ({choices(WRITES)}) for the dataset's outputs"
        )
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
    if dst_format is not None and dst_format not in WRITES:
        raise UsageError(f"{option('dst_format')}: hconv does not write {NAMES[dst_format]}; give {choices(WRITES)}")
    if dst == "-":
        raise UsageError("a dataset is written into a directory or prefix, not to stdout ('-')")
    if endpoint_url and not any(s.lower().startswith("s3://") for s in (src, dst)):
        raise UsageError(f"{option('endpoint_url')} is for s3:// URIs, and neither {src} nor {dst} is one")
    source = storage.source(src, endpoint_url)
    out = storage.place(dst, endpoint_url)
    overlap = OutputError(
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
        if os.path.exists(out.root) and not os.path.isdir(out.root):  # a file, or a device such as /dev/full
            what = "a file" if os.path.isfile(out.root) else "not a directory"
            raise OutputError(f"{dst}: is {what}; a dataset is written into a directory (it is made if missing)")
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
    before = read_manifest(out, force)
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
    orphans = sorted(rel for rel in ours if rel not in outputs and rel in existing)
    return Plan(source, out, job, identity, inputs, kept, todo, refused, why if todo else None, before, orphans)


def _refuse_links_into_out(source: Source, out: Place) -> None:
    """Before IN is listed: OutputError when a link in IN leads into OUT or to a folder holding
    it (the listing follows links, so outputs would come back as inputs); UsageError when one
    leads back to IN or a folder holding it (a loop: the listing would take IN's files again at
    every turn, until the system's limit on links). Comparing the two paths cannot see either. A
    link that leads nowhere yet is judged by where it leads: OUT is made by this run."""
    out_real = os.path.realpath(out.root)
    in_real = os.path.realpath(source.place.root)
    for folder, dirs, files in os.walk(source.place.root):
        # a link that leads nowhere yet is listed among the files; one to a file is
        # _refuse_linked_overlap's, which names the file
        dangling = [name for name in files if not os.path.exists(os.path.join(folder, name))]
        for name in (*dirs, *dangling):
            path = os.path.join(folder, name)
            if not os.path.islink(path):
                continue
            real = os.path.realpath(path)
            rel = os.path.relpath(path, source.place.root).replace(os.sep, "/")
            if storage.inside(real, out_real) or storage.inside(out_real, real):
                raise OutputError(
                    f"{source.place.name(rel)} is a link that leads to {out.shown}; "
                    "remove the link, or write the dataset to a directory it does not lead to"
                )
            if storage.inside(in_real, real):
                raise UsageError(
                    f"{source.place.name(rel)} is a link that leads back to {source.place.shown}, a loop that "
                    "would take its files again and again; remove the link"
                )


def _refuse_linked_overlap(
    source: Source, out: Place, inputs: list[Listed], src_format: str | None, dst_format: str | None
) -> None:
    """OutputError when a link joins IN and OUT file by file: an input that is a link to a file of
    OUT, or an output that a folder link in OUT would put into IN."""
    out_real = os.path.realpath(out.root)
    in_real = os.path.realpath(source.place.root)
    for f in inputs:
        if storage.inside(os.path.realpath(source.place.path(f.rel)), out_real):
            raise OutputError(
                f"{source.place.name(f.rel)} is a link to a file in {out.shown}; "
                "remove the link, or write the dataset to another directory"
            )
        rel = _output_rel(f.rel, src_format or storage.format_by_name(f.rel) or "", dst_format)[0]
        folder = os.path.dirname(out.path(rel))
        real = os.path.realpath(folder)
        lexical = os.path.normpath(os.path.join(out_real, os.path.relpath(folder, out.root)))
        if real != lexical and storage.inside(real, in_real):
            raise OutputError(
                f"{out.name(rel)} would be written into {source.place.shown} (through a link in {out.shown}); "
                "remove the link, or write the dataset to another directory"
            )
