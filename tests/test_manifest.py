"""A dataset's manifest (hconv.tables.manifest): its format is pinned, so that its bytes do not
move with the classes' field order; and its group commit."""

from __future__ import annotations

import dataclasses
import json
import os

import pytest

import hconv
from hconv.errors import OutputError
from hconv.tables import manifest
from hconv.tables.manifest import FileRecord, GroupCommit, job_identity, manifest_text

#: The job record's keys as release 0.1.0 wrote them (Job's fields then, and the formats).
RELEASED_KEYS = ["method", "precision", "diagnostics", "conventions", "mapping", "unit_options", "quat_order",
                 "omega_unit", "observed", "engine", "keep_text", "field_units",
                 "src_format", "dst_format"]  # fmt: skip


def test_job_identity_keeps_the_released_key_order():
    """``engine`` moved to hconv.Options, which Job extends: asdict put it fourth, and every
    manifest's bytes changed."""
    record = job_identity(hconv.Job(method="refined", engine="numpy"), "csv", None)
    assert list(record) == RELEASED_KEYS
    assert (record["method"], record["engine"], record["src_format"]) == ("refined", "numpy", "csv")
    assert json.loads(json.dumps(record)) == record  # what the file holds is what the next run compares


def test_job_identity_records_a_prefix_only_when_given():
    assert "prefix" not in job_identity(hconv.Job(), None, None)
    record = job_identity(hconv.Job(prefix="out_"), None, None)
    assert list(record) == RELEASED_KEYS[:-2] + ["prefix"] + RELEASED_KEYS[-2:] and record["prefix"] == "out_"


def test_job_identity_records_a_csv_dialect_only_when_given():
    """A dataset converted before --delimiter existed is not converted again for a job without it;
    one converted with another delimiter is."""
    record = job_identity(hconv.Job(delimiter="tab", decimal=","), None, None)
    assert list(record) == RELEASED_KEYS[:-2] + ["delimiter", "decimal"] + RELEASED_KEYS[-2:]
    assert (record["delimiter"], record["decimal"]) == ("\t", ",")


def _record(k: int, worst: float | None = 1.5e-12) -> FileRecord:
    return FileRecord(
        input=f"day={k % 2}/part-{k}.parquet",
        output=f"day={k % 2}/part-{k}.parquet",
        input_size=1000 + k,
        input_mtime_ns=None if k % 3 else 1_796_000_000_000_000_000 + k,
        input_etag=None,
        output_size=2000 + k,
        rows=500,
        statuses={"ok": 499, "singular": 1} if k % 2 else {},
        worst_residual=worst,
        worst_row=None if worst is None else 7,
        engines={"numpy": 500},
        seconds=0.25 + k,
    )


def test_manifest_text_is_json_dumps_with_indent_1():
    """The manifest's text, its records spliced in from their cached encodings, is byte for byte
    what encoding the whole manifest at once gives (the format readers and reruns rely on)."""
    files = [_record(k, None if k == 2 else 1.5e-12 * k) for k in range(5)]
    m = {"kind": "x", "files": files, "failed": [{"input": "a", "error": "b"}], "pending": [], "seconds": 1.0}
    whole = json.dumps({**m, "files": [dataclasses.asdict(r) for r in files]}, indent=1)
    assert manifest_text(m, files) == whole
    assert manifest_text({**m, "files": []}, []) == json.dumps({**m, "files": []}, indent=1)
    assert manifest_text(m, files) == whole  # the cached encodings, used again


def test_group_commit_keeps_records_only_once_durable_and_writes_once_per_group(monkeypatch):
    """Outputs added to the open group are not kept (not listed) until the group is closed; the
    close flushes them first, then keeps them all, then rewrites the manifest once."""
    log: list = []
    monkeypatch.setattr(manifest, "make_durable", lambda paths: log.append(("durable", list(paths))))
    group = GroupCommit(lambda r: log.append(("keep", r.input)), lambda: log.append(("write",)))
    group.add(_record(0), "out/a")
    group.add(_record(1), None)  # durable on its own (uploaded, flushed)
    assert log == []
    group.close()
    assert log == [("durable", ["out/a"]), ("keep", _record(0).input), ("keep", _record(1).input), ("write",)]
    group.close()  # nothing open: nothing flushed or written
    assert len(log) == 4


def test_group_commit_closes_a_group_at_its_count(monkeypatch):
    """A group closes by itself once it holds GROUP_FILES outputs (its age aside; the floor set
    by the last commit's cost off, which a slow machine would otherwise move)."""
    monkeypatch.setattr(manifest, "make_durable", lambda paths: None)
    monkeypatch.setattr(manifest, "GROUP_COST_SHARE", 0.0)
    writes: list = []
    group = GroupCommit(lambda r: None, lambda: writes.append(1))
    for k in range(manifest.GROUP_FILES * 2 + 1):
        group.add(_record(k), None)
    assert len(writes) == 2 and group.groups == 2


@pytest.mark.parametrize("average", ["small", "large"])
def test_make_durable_flushes_large_outputs_each_and_small_ones_together(average, tmp_path, monkeypatch):
    """Outputs of SYNC_EACH_BYTES or more on average get an fsync each, never a syncfs (which
    would flush every other writer's dirty data on the file system too); smaller ones one syncfs
    together. Their folder is flushed either way."""
    monkeypatch.setattr(manifest, "SYNC_EACH_BYTES", 1000)
    # by the average: one file over the limit does not make the group large; exactly on it does
    sizes = (200, 200, 2599) if average == "small" else (1800, 1100, 100)
    paths = [tmp_path / f"f{k}.parquet" for k in range(3)]
    for p, n in zip(paths, sizes):
        p.write_bytes(b"x" * n)
    synced, whole = [], []
    fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: synced.append(os.fstat(fd).st_ino) or fsync(fd))
    monkeypatch.setattr(manifest, "_syncfs", lambda folder: whole.append(folder) or True)
    manifest.make_durable([str(p) for p in paths])
    files = [p.stat().st_ino for p in paths] if average == "large" else []
    assert sorted(synced) == sorted([*files, tmp_path.stat().st_ino])
    assert whole == ([str(tmp_path)] if average == "small" else [])


def test_make_durable_flushes_files_and_their_folders(tmp_path):
    """Files in two folders: flushed without error (syncfs, or an fsync each), each folder once;
    a file that is gone is named in one OutputError."""
    paths = []
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        paths.append(tmp_path / folder / "f.parquet")
        paths[-1].write_bytes(b"x")
    manifest.make_durable([str(p) for p in paths])
    with pytest.raises(OutputError, match=r"could not be flushed to the disk"):
        manifest.make_durable([str(tmp_path / "gone" / "f.parquet")])
