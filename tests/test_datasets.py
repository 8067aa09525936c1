"""Datasets: ``hconv convert IN OUT`` with IN a directory, a glob or a URI and OUT a directory or
prefix. Every test runs the real command (or ``hconv.convert_dataset``) on real files; the object
storage tests run against a local S3-compatible server started as a process (moto's server mode,
the ``test-s3`` extra) and skip without it."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import StopAt, run_hconv, run_inprocess, terminal_signals

import hconv
from hconv.tables import dataset, pipeline, runners, storage
from hconv.tables.manifest import MANIFEST
from hconv.tools.scene import make_scene

PARTS = ("date=2026-01-01/part-0.parquet", "date=2026-01-01/part-1.parquet", "date=2026-01-02/part-0.parquet")


def _write(path: Path, rows: int, seed: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.table(make_scene(rows, seed=seed, cond_max=1e6))
    if path.suffix == ".csv":
        pacsv.write_csv(table, path)
    else:
        pq.write_table(table, path)


def _dataset(root: Path, rows: int = 300) -> Path:
    """A hive-partitioned dataset: three Parquet parts, a CSV, and files a dataset leaves out."""
    for k, rel in enumerate(PARTS):
        _write(root / rel, rows + k, seed=k)
    _write(root / "date=2026-01-02" / "extra.csv", rows, seed=9)
    (root / "_SUCCESS").write_bytes(b"")
    (root / "date=2026-01-01" / ".part-0.parquet.crc").write_bytes(b"\x00")
    (root / "notes.txt").write_text("not a table\n")
    return root


def _manifest(out: Path) -> dict:
    return json.loads((out / MANIFEST).read_text())


def _files(root: Path) -> set[str]:
    return {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()}


def _hconv(*args: str, capsys) -> tuple[int, str]:
    """``hconv ARGS`` in this process, in the working directory (the tests chdir to tmp_path);
    (exit code, stderr)."""
    code, _, err = run_inprocess(*args, capsys=capsys)
    return code, err


def _single(src: Path, tmp: Path, **kw) -> bytes:
    """The bytes `hconv convert SRC OUT` writes for one file (the single-file path)."""
    suffix = "." + kw["dst_format"] if kw.get("dst_format") else src.suffix  # the name agrees with --to
    dst = tmp / f"single-{os.urandom(4).hex()}{suffix}"
    pipeline.convert_file(str(src), str(dst), **kw)
    return dst.read_bytes()


def test_convert_dataset_directory_keeps_hive_folders_and_each_file_is_its_single_conversion(tmp_path):
    data = _dataset(tmp_path / "data")
    proc = run_hconv("convert", "data", "out", cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    out = tmp_path / "out"
    converted = set(PARTS) | {"date=2026-01-02/extra.csv"}
    assert _files(out) == converted | {MANIFEST}
    for rel in converted:
        assert (out / rel).read_bytes() == _single(data / rel, tmp_path), rel
    m = _manifest(out)
    assert m["complete"] is True and m["inputs"] == 4 and m["failed"] == [] and m["pending"] == []
    assert m["hconv"] == hconv.__version__ and m["job"]["method"] == "exact"
    assert [f["output"] for f in m["files"]] == sorted(converted)
    assert sum(f["rows"] for f in m["files"]) == m["rows"] == 300 + 301 + 302 + 300
    for f in m["files"]:
        st = (data / f["input"]).stat()
        assert (f["input_size"], f["input_mtime_ns"]) == (st.st_size, st.st_mtime_ns)
        assert f["output_size"] == (out / f["output"]).stat().st_size
        assert f["rows"] == sum(f["statuses"].values())
    assert "converting 4 files" in err and "# hconv convert · 4 files" in err
    assert "says the dataset is complete" in err
    worst = m["worst_residual"]
    assert f"worst residual {worst['value']:.3g} (data/{worst['input']}, data row {worst['row']})" in err


def test_convert_dataset_outputs_get_the_usual_permissions_and_the_umask_is_not_set_per_file(tmp_path, monkeypatch):
    """Each output is written into its temporary file (mkstemp's, 0600) and renamed into place:
    it gets 0666 less the umask, as a file the shell makes; the umask is read once for the run,
    since reading it sets it, for a moment, for every thread making files beside."""
    _dataset(tmp_path / "data")
    old = os.umask(0o027)
    swaps = []
    real_umask = os.umask
    monkeypatch.setattr(os, "umask", lambda mask: swaps.append(mask) or real_umask(mask))
    try:
        hconv.convert_dataset(str(tmp_path / "data"), str(tmp_path / "out"))
    finally:
        real_umask(old)
    outputs = [p for p in (tmp_path / "out").rglob("*") if p.is_file()]
    assert len(outputs) == 5  # four outputs and the manifest
    assert {oct(p.stat().st_mode & 0o777) for p in outputs} == {oct(0o640)}
    # read (umask(0), then the mask put back) once for the files, once for the last manifest,
    # written when the files' threads have ended; not once per file
    assert swaps == [0, 0o027, 0, 0o027], swaps


def test_convert_dataset_worst_residual_names_the_input_file(tmp_path, capsys, monkeypatch):
    """The summary named the output, which a newcomer could not open beside the row they meant
    to check (here another format); it names the input as IN spells it, the manifest both."""
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data")
    code, err = _hconv("convert", "data/date=*/part-0.parquet", "out", "--to", "csv", capsys=capsys)
    assert code == 0, err
    worst = _manifest(tmp_path / "out")["worst_residual"]
    assert worst["input"] in ("date=2026-01-01/part-0.parquet", "date=2026-01-02/part-0.parquet")
    assert worst["file"] == worst["input"].replace(".parquet", ".csv")
    shown = f"worst residual {worst['value']:.3g} (data/{worst['input']}, data row {worst['row']})"
    assert shown in " ".join(err.replace("#", "").split()), err
    # the row is the input's: its residual, converted alone, is the worst
    rows = pacsv.read_csv(tmp_path / "out" / worst["file"]).column("residual").to_pylist()
    assert rows[worst["row"] - 1] == worst["value"] == max(rows)


def test_convert_dataset_glob_takes_the_files_it_matches(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data")
    code, err = _hconv("convert", "data/date=*/part-0.parquet", "out", "--to", "csv", capsys=capsys)
    assert code == 0, err
    out = tmp_path / "out"
    assert _files(out) == {"date=2026-01-01/part-0.csv", "date=2026-01-02/part-0.csv", MANIFEST}
    assert _manifest(out)["job"]["dst_format"] == "csv"
    ref = _single(tmp_path / "data" / PARTS[0], tmp_path, dst_format="csv")
    assert (out / "date=2026-01-01/part-0.csv").read_bytes() == ref


@pytest.mark.parametrize(
    "pattern, matches, misses",
    [
        ("*.parquet", ["a.parquet"], ["d=1/a.parquet", "a.csv"]),
        ("d=*/*.parquet", ["d=1/a.parquet"], ["a.parquet", "d=1/x/a.parquet"]),
        ("**/*.parquet", ["a.parquet", "d=1/a.parquet", "d=1/x/a.parquet"], ["a.csv"]),
        ("d=**", ["d=1/a.csv", "d=2/x/y.pq"], ["e=1/a.csv"]),
        ("part-?.csv", ["part-1.csv"], ["part-10.csv"]),
        ("part-[01].csv", ["part-0.csv", "part-1.csv"], ["part-2.csv"]),
        ("part-[!01].csv", ["part-2.csv"], ["part-0.csv"]),
        ("a[.csv", ["a[.csv"], ["a.csv"]),
    ],
)
def test_glob_regex_matches_as_a_shell_with_globstar(pattern, matches, misses):
    rx = storage.glob_regex(pattern)
    assert [m for m in matches if rx.match(m)] == matches
    assert [m for m in misses if rx.match(m)] == []


def test_convert_dataset_rerun_converts_only_missing_or_stale_files(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = _dataset(tmp_path / "data")
    out = tmp_path / "out"
    assert _hconv("convert", "data", "out", capsys=capsys)[0] == 0
    before = {rel: (out / rel).stat().st_mtime_ns for rel in _files(out)}
    _write(data / PARTS[1], 50, seed=42)  # changed input
    (out / PARTS[2]).unlink()  # missing output
    _write(data / "date=2026-01-03" / "part-0.parquet", 40, seed=7)  # new input
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 0, err
    assert "hconv: 2 of 5 files already converted and up to date; converting 3\n" in err
    assert "files: 3 converted, 2 already up to date;" in err
    after = {rel: (out / rel).stat().st_mtime_ns for rel in _files(out)}
    kept = {PARTS[0], "date=2026-01-02/extra.csv"}
    assert {rel for rel in kept if after[rel] == before[rel]} == kept
    assert after[PARTS[1]] != before[PARTS[1]]
    assert (out / PARTS[1]).read_bytes() == _single(data / PARTS[1], tmp_path)
    assert (out / PARTS[2]).exists() and (out / "date=2026-01-03/part-0.parquet").exists()
    m = _manifest(out)
    assert m["complete"] and m["inputs"] == 5 and m["rows"] == 300 + 50 + 302 + 300 + 40
    again = _hconv("convert", "data", "out", capsys=capsys)[1]
    assert "hconv: all 5 files already converted and up to date; nothing to convert\n" in again
    assert {rel: (out / rel).stat().st_mtime_ns for rel in _files(out)} == after  # not even the manifest


def test_convert_dataset_output_of_a_deleted_input_is_left_and_named(tmp_path, capsys, monkeypatch):
    """An input deleted since the last run: its output stays in OUT (it may be wanted), but the
    rerun says so, since the manifest no longer lists it and "complete" would not tell."""
    monkeypatch.chdir(tmp_path)
    data = _dataset(tmp_path / "data")
    assert _hconv("convert", "data", "out", capsys=capsys)[0] == 0
    (data / PARTS[1]).unlink()
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 0, err
    assert (tmp_path / "out" / PARTS[1]).exists()
    assert f"1 output(s) in OUT belong to no input of this run ({Path('out') / PARTS[1]})" in " ".join(err.split())
    run = hconv.convert_dataset("data", "out")
    assert run.complete and run.orphans == [str(Path("out") / PARTS[1])]
    # an output the user removed as told is not named again
    (tmp_path / "out" / PARTS[1]).unlink()
    assert hconv.convert_dataset("data", "out").orphans == []


def test_convert_dataset_changed_job_converts_every_file_and_says_why(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data")
    assert _hconv("convert", "data", "out", capsys=capsys)[0] == 0
    code, err = _hconv("convert", "data", "out", "--method", "refined", capsys=capsys)
    assert code == 0, err
    assert (
        f"hconv: the job differs from the one {MANIFEST} records (method: 'exact' → 'refined'); converting all 4 files"
        in err
    )
    assert _manifest(tmp_path / "out")["job"]["method"] == "refined"


def test_convert_dataset_prefix_names_the_appended_columns_and_the_manifest_records_it(tmp_path):
    src = tmp_path / "data"
    _write(src / "a.parquet", 20, seed=1)
    result = hconv.convert_dataset(src, tmp_path / "out", prefix="hc_")
    assert result.tally.rows == 20 and result.tally.per_status.sum() == 20
    names = pq.read_schema(tmp_path / "out" / "a.parquet").names
    assert names[-6:] == ["hc_wx", "hc_wy", "hc_wz", "hc_residual", "hc_cond", "hc_status"]
    assert _manifest(tmp_path / "out")["job"]["prefix"] == "hc_"
    logged: list[str] = []
    hconv.convert_dataset(src, tmp_path / "out", log=logged.append)  # no prefix now: another job
    assert any("the job differs" in line and "prefix: 'hc_' →" in line for line in logged), logged
    assert "prefix" not in _manifest(tmp_path / "out")["job"]


def test_convert_dataset_failing_file_is_named_the_others_finish_and_exit_code_is_its(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = _dataset(tmp_path / "data")
    bad = data / "date=2026-01-01" / "part-1.parquet"
    bad.write_bytes(b"PAR1 truncated")
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 3, err
    errors = [line for line in err.splitlines() if line.startswith("hconv: error:")]
    assert len(errors) == 2
    assert errors[0].startswith("hconv: error: data/date=2026-01-01/part-1.parquet: not a readable Parquet file")
    assert errors[1] == (
        f"hconv: error: 1 of 4 files failed (named above); 3 are converted and listed in out/{MANIFEST}, "
        "which says complete: false"
    )
    out = tmp_path / "out"
    assert _files(out) == {PARTS[0], PARTS[2], "date=2026-01-02/extra.csv", MANIFEST}
    m = _manifest(out)
    assert m["complete"] is False and [f["input"] for f in m["failed"]] == [PARTS[1]]
    assert len(m["files"]) == 3 and m["pending"] == []
    _write(bad, 30, seed=5)
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 0 and "3 of 4 files already converted and up to date; converting 1" in err
    assert _manifest(out)["complete"] is True and _manifest(out)["failed"] == []


def test_convert_dataset_strict_fails_only_the_file_with_flagged_rows(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = tmp_path / "data"
    _write(data / "a.parquet", 100, seed=1)
    t = pa.table(make_scene(100, seed=2))
    pq.write_table(
        t.set_column(t.schema.get_field_index("Hx"), "Hx", pa.array([float("nan")] * 100)), data / "b.parquet"
    )
    code, err = _hconv("convert", "data", "out", "--strict", capsys=capsys)
    assert code == 5, err
    assert "hconv: error: data/b.parquet: --strict, and row 1 (invalid_input)" in err
    assert _files(tmp_path / "out") == {"a.parquet", MANIFEST}


def test_convert_dataset_never_overwrites_or_deletes_files_it_did_not_write_without_force(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    data = _dataset(tmp_path / "data")
    out = tmp_path / "out"
    (out / "date=2026-01-01").mkdir(parents=True)
    (out / PARTS[0]).write_bytes(b"someone else's")
    (out / "README.txt").write_text("mine\n")
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 4
    # the start counts what it converts of the inputs, which the summary counts (newcomer trial)
    n = len(PARTS) + 1  # and the CSV
    assert f"hconv: converting {n - 1} of {n} files (1 in the way, named below)\n" in err
    assert f"# hconv convert · {n} files" in err
    assert (
        f"hconv: error: out/{PARTS[0]}: already exists, and {MANIFEST} does not say hconv wrote it; move it away, "
        "or pass --force to overwrite it\n"
    ) in err
    assert (out / PARTS[0]).read_bytes() == b"someone else's"
    assert _manifest(out)["complete"] is False
    code, err = _hconv("convert", "data", "out", "--force", capsys=capsys)
    assert code == 0, err
    assert (out / PARTS[0]).read_bytes() == _single(data / PARTS[0], tmp_path)
    assert (out / "README.txt").read_text() == "mine\n" and _manifest(out)["complete"] is True


def test_convert_dataset_force_converts_every_file_again(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data")
    assert _hconv("convert", "data", "out", capsys=capsys)[0] == 0
    code, err = _hconv("convert", "data", "out", "--force", capsys=capsys)
    assert code == 0 and "files: 4 converted, 0 already up to date" in err


@pytest.mark.parametrize(
    "args, code, message",
    [
        (("data", "out.parquet"), 2, "out.parquet: names a file, but data is a dataset, converted file by file "
         "into a directory; give a directory for OUT, such as out/ (hconv makes it)"),
        (("data", "data/converted"), 4, "data/converted and data overlap; write the dataset outside its input, so "
         "that a re-run does not read outputs"),
        (("data", "-", "--to", "csv"), 2, "a dataset is written into a directory or prefix, not to stdout ('-')"),
        (("data", "nowhere/out"), 4, "nowhere/out: the directory 'nowhere' does not exist; create it first"),
        (("data/*.pq", "out"), 3, "no file matches 'data/*.pq' (names starting with . or _ are left out); "
         "check the path"),
        (("empty", "out"), 3, "empty: holds no file (names starting with . or _ are left out); check the path"),
        (("data", "out", "--endpoint-url", "http://127.0.0.1:1"), 2, "--endpoint-url is for s3:// URIs, and "
         "neither data nor out is one"),
        (("data/date=2026-01-01/part-0.parquet", "data/*.parquet", "out"), 2, "1 extra argument after IN and OUT: "
         "for several files, quote the glob so that hconv expands it, or give their directory ('out')"),
    ],
)  # fmt: skip
def test_convert_dataset_that_cannot_run_says_why_in_one_line_and_writes_nothing(
    args, code, message, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    (tmp_path / "empty").mkdir()
    got, err = _hconv("convert", *args, capsys=capsys)
    assert (got, err.count("\n")) == (code, 1), err
    assert err.startswith(f"hconv: error: {message}")
    assert not (tmp_path / "out").exists() and not (tmp_path / "data" / "converted").exists()


def test_convert_dataset_python_api_returns_the_run_and_raises_with_it_on_failure(tmp_path):
    data = _dataset(tmp_path / "data")
    lines: list[str] = []
    result = hconv.convert_dataset(str(data), str(tmp_path / "out"), method="refined", log=lines.append)
    assert result.complete and len(result.files) == 4 and result.rows_converted == result.tally.rows == 1203
    assert result.tally.method == "refined" and lines == ["converting 4 files"]
    (data / "late.csv").write_text("Hx,Hy\n1,2\n")
    with pytest.raises(dataset.DatasetError, match=r"^1 of 5 files failed") as info:
        hconv.convert_dataset(str(data), str(tmp_path / "out"), method="refined")
    assert info.value.exit_code == 3 and not info.value.result.complete
    assert [rel for rel, _ in info.value.result.failed] == ["late.csv"]


def _no_temporaries(*roots: Path) -> list[str]:
    return [str(p) for root in roots for p in root.rglob("*") if p.name.endswith(".hconv-tmp")]


def test_convert_dataset_interrupted_keeps_complete_files_in_a_partial_manifest_and_no_temporary(tmp_path):
    """Ctrl-C (SIGINT to the real command) while the files convert: the outputs already written
    stay, the manifest lists exactly those and says complete: false, no temporary file is left
    in OUT or TMPDIR, and the same command then converts the rest."""
    data = tmp_path / "data"
    for k in range(10):
        _write(data / f"day={k:02d}" / "part.parquet", 30_000, seed=k)
    spools = tmp_path / "tmp"
    spools.mkdir()
    out = tmp_path / "out"
    # The child stops as its third file starts, two written (helpers.StopAt): the signal lands
    # mid-run however slow the machine.
    stop = StopAt(tmp_path / "hook", "hconv.tables.processes:convert_one#3")
    env = stop.env(dict(os.environ, TMPDIR=str(spools), COLUMNS="200"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "data", "out", "--threads", "1"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=terminal_signals,
        pass_fds=stop.fds,
    )
    stop.started()
    assert stop.reached(), proc.communicate()[1].decode()
    proc.send_signal(signal.SIGINT)
    stop.release()
    _, err = proc.communicate()
    assert proc.returncode == 130, err.decode()
    m = _manifest(out)
    listed = [f["output"] for f in m["files"]]
    assert m["complete"] is False and 2 <= len(listed) < 10
    assert err.decode().endswith(
        f"hconv: error: interrupted; {len(listed)} of 10 files are converted and listed in out/{MANIFEST} "
        "(complete: false), and no other file was written; run the same command again to convert the rest\n"
    )
    assert _files(out) == set(listed) | {MANIFEST}  # the file being converted is not there
    for f in m["files"]:
        assert pq.ParquetFile(out / f["output"]).metadata.num_rows == f["rows"] == 30_000
    assert _no_temporaries(out, spools) == [] and list(spools.iterdir()) == []
    assert set(m["pending"]) == {f"day={k:02d}/part.parquet" for k in range(10)} - {f["input"] for f in m["files"]}
    proc2 = run_hconv("convert", "data", "out", cwd=tmp_path)
    assert proc2.returncode == 0
    assert f"{len(listed)} of 10 files already converted and up to date; converting {10 - len(listed)}" in (
        proc2.stderr.decode()
    )
    assert _manifest(out)["complete"] is True


# Object storage: a local S3-compatible server (moto's server mode, conftest.py's s3 fixture).


def _objects(fs, prefix: str) -> dict[str, bytes]:
    import pyarrow.fs as pafs

    infos = fs.get_file_info(pafs.FileSelector(prefix, recursive=True))
    return {
        i.path[len(prefix) + 1 :]: fs.open_input_stream(i.path).read() for i in infos if i.type == pafs.FileType.File
    }


def test_convert_dataset_s3_to_s3_is_bit_for_bit_the_local_conversion(s3, tmp_path):
    import pyarrow.fs as pafs

    url, fs, bucket = s3
    data = _dataset(tmp_path / "data")
    pafs.copy_files(str(data), f"{bucket}/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs)
    proc = run_hconv("convert", f"s3://{bucket}/raw/", f"s3://{bucket}/conv/", "--endpoint-url", url, cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    assert "converting 4 files" in err and f"s3://{bucket}/conv/{MANIFEST} says the dataset is complete" in err
    assert run_hconv("convert", "data", "local", cwd=tmp_path).returncode == 0
    local = tmp_path / "local"
    stored = _objects(fs, f"{bucket}/conv")
    assert set(stored) == _files(local)
    for rel, body in stored.items():
        if rel != MANIFEST:
            assert body == (local / rel).read_bytes(), rel
    m = json.loads(stored[MANIFEST])
    assert m["complete"] and m["source"] == f"s3://{bucket}/raw"
    assert all(f["input_etag"] for f in m["files"])  # S3 gives ETags; a local input has none
    again = run_hconv("convert", f"s3://{bucket}/raw/", f"s3://{bucket}/conv/", "--endpoint-url", url, cwd=tmp_path)
    assert "all 4 files already converted and up to date; nothing to convert" in again.stderr.decode()


def test_convert_dataset_s3_endpoint_from_aws_endpoint_url_glob_in_and_local_out(s3, tmp_path, monkeypatch):
    import pyarrow.fs as pafs

    url, fs, bucket = s3
    data = _dataset(tmp_path / "data")
    pafs.copy_files(str(data), f"{bucket}/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs)
    monkeypatch.setenv("AWS_ENDPOINT_URL", url)  # pyarrow 26 does not read it; hconv does
    proc = run_hconv("convert", f"s3://{bucket}/raw/date=*/part-0.parquet", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr.decode()
    assert _files(tmp_path / "out") == {"date=2026-01-01/part-0.parquet", "date=2026-01-02/part-0.parquet", MANIFEST}
    assert (tmp_path / "out" / PARTS[0]).read_bytes() == _single(data / PARTS[0], tmp_path)


def test_convert_dataset_s3_failing_file_and_missing_bucket_are_named(s3, tmp_path):
    import pyarrow.fs as pafs

    url, fs, bucket = s3
    data = _dataset(tmp_path / "data")
    (data / PARTS[1]).write_bytes(b"PAR1 truncated")
    pafs.copy_files(str(data), f"{bucket}/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs)
    proc = run_hconv("convert", f"s3://{bucket}/raw", f"s3://{bucket}/conv", "--endpoint-url", url, cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.returncode == 3, err
    assert f"hconv: error: s3://{bucket}/raw/{PARTS[1]}: not a readable Parquet file" in err
    assert set(_objects(fs, f"{bucket}/conv")) == {PARTS[0], PARTS[2], "date=2026-01-02/extra.csv", MANIFEST}
    proc = run_hconv("convert", "data", "s3://no-such-bucket-here/conv", "--endpoint-url", url, cwd=tmp_path)
    assert proc.returncode == 4
    err = proc.stderr.decode()
    assert f"hconv: error: s3://no-such-bucket-here/conv/{MANIFEST}: could not be written (" in err
    assert "The specified bucket does not exist" in err
    assert "); the bucket does not exist: create it, or check the URI; it was left as it was" in err


@pytest.mark.parametrize(
    "text, hint",
    [
        # what pyarrow 26 said to the trial's workers that lacked the credentials the driver had
        (
            "When reading information for key 'raw/a.parquet' in bucket 'b': AWS Error ACCESS_DENIED during "
            "HeadObject operation: No response body.",
            "; the store refused the credentials: check AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or "
            "AWS_PROFILE), and with --cluster each worker's too",
        ),
        ("AWS Error NETWORK_CONNECTION ... InvalidAccessKeyId", "the store refused the credentials"),
        ("When uploading part for key 'x' in bucket 'gone': AWS Error NO_SUCH_BUCKET", "the bucket does not exist"),
        ("When reading 'x': AWS Error NETWORK_CONNECTION during GetObject", None),
    ],
)
def test_store_failure_names_the_common_causes(text, hint):
    from hconv.errors import command_line

    with command_line():
        said = storage.store_failure(OSError(text + "\nsecond line"))
    assert said.startswith(f"({text})")
    assert (said == f"({text})") if hint is None else (hint in said)


def test_convert_dataset_glob_may_write_into_its_own_folder_unless_it_would_take_the_outputs(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(_dataset(tmp_path / "data", rows=20))
    assert _hconv("convert", "*/*.parquet", "out", capsys=capsys)[0] == 0  # out/date=…/x is not */*
    assert _hconv("convert", "*/*.parquet", "out", capsys=capsys)[0] == 0  # nor taken by the re-run
    code, err = _hconv("convert", "**/*.parquet", "out2", capsys=capsys)
    assert code == 4 and "out2 and **/*.parquet overlap" in err


_HELD = """
import signal
from hconv import interrupts

done = []
try:
    with interrupts.held():
        signal.raise_signal(signal.SIGINT)  # its handler has run when this returns
        done.append(1)
except KeyboardInterrupt:
    print("KeyboardInterrupt", done, signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


def test_held_interrupt_waits_for_the_block_then_acts():
    """In a process of its own, with Ctrl-C at its default: in the test runner's, a signal sent
    to the process could be lost (another thread's C system() call ignores SIGINT meanwhile)."""
    proc = subprocess.run(
        [sys.executable, "-c", _HELD], capture_output=True, text=True, preexec_fn=terminal_signals, check=False
    )
    assert (proc.returncode, proc.stdout) == (0, "KeyboardInterrupt [1] True\n"), proc.stderr


@pytest.mark.parametrize("keyword", ["progress", "log"])
def test_convert_dataset_callback_not_callable_fails_at_once_and_writes_nothing(keyword, tmp_path):
    """Before, progress=5 converted the first file and then failed with a TypeError."""
    from hconv.errors import UsageError

    _dataset(tmp_path / "data")
    with pytest.raises(UsageError, match=f"^{keyword} takes a function or None, got 5"):
        dataset.convert_dataset(tmp_path / "data", tmp_path / "out", **{keyword: 5})
    assert not (tmp_path / "out").exists()


def test_convert_dataset_bad_threads_fails_at_once_and_writes_nothing(tmp_path):
    from hconv.errors import UsageError

    _dataset(tmp_path / "data")
    for threads in (0, "2"):
        with pytest.raises(UsageError, match="threads must be a whole number, 1 or more"):
            dataset.convert_dataset(tmp_path / "data", tmp_path / "out", threads=threads)  # paths as Path too
    assert not (tmp_path / "out").exists()
    proc = run_hconv("convert", "data", "out", "--threads", "0", cwd=tmp_path)
    assert proc.returncode == 2 and len(proc.stderr.decode().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("driver_ended", [True, False])
def test_convert_dataset_removes_parts_of_a_run_whose_driver_was_killed(driver_ended, tmp_path):
    """A cluster run splitting files (--task-rows) whose driver was killed outright leaves its
    parts in OUT, hidden; its manifest names the run and the driver, and the next run removes
    them once the driver has surely ended, never while it may still run."""
    from hconv.tables import temporaries

    data = _dataset(tmp_path / "data")
    out = tmp_path / "out"
    dataset.convert_dataset(data, out)
    pid, start, tag = temporaries.maker().split("-")
    driver = f"{pid}-{int(start) + 1}-{tag}" if driver_ended else temporaries.maker()
    m = _manifest(out)
    m["parts_run"] = {"id": "0123abcd", "driver": driver}
    (out / MANIFEST).write_text(json.dumps(m))
    parts = [out / "date=2026-01-01" / temporaries.part_name("part-0.parquet", "0123abcd", k) for k in range(2)]
    other = out / "date=2026-01-01" / temporaries.part_name("part-0.parquet", "99999999", 0)  # another run's
    for p in [*parts, other]:
        p.write_bytes(b"PAR1")
    said: list[str] = []
    dataset.convert_dataset(data, out, log=said.append)
    assert [p.exists() for p in parts] == [not driver_ended] * 2 and other.exists()
    assert ("removed 2 part files left by a run whose driver was killed" in said) is driver_ended, said


@pytest.mark.parametrize("length", [40, 200, 250])
def test_stage_beside_a_long_name_or_its_part_fits_a_file_name(length, tmp_path):
    """A cluster run's temporary file beside an output (or beside a part of a split file) added
    the run's tag, the maker and a suffix to the whole name: past about 150 bytes of input name,
    "File name too long"."""
    from hconv.tables import temporaries

    name = "é" * (length // 2 - 4) + ".parquet"  # two bytes a character
    for beside in (name, temporaries.part_name(name, "0123abcd", 3)):
        path = storage.stage(str(tmp_path / beside), run="0123abcd")
        base = os.path.basename(path)
        assert len(os.fsencode(base)) <= 255 and temporaries.is_run_temporary(base, "0123abcd")
        assert temporaries.remove_run_temporaries(str(tmp_path), "0123abcd") == [path]


@pytest.mark.parametrize(
    "link, target, args, message",
    [
        # OUT named through a link to IN: the paths as written do not overlap, the places do
        ("dslink", "data", ("data", "dslink/converted"), "dslink/converted and data overlap"),
        # a folder link in IN that leads to OUT, or to a folder holding it: outputs read back as inputs
        ("data/back", "../out", ("data", "out"), "data/back is a link that leads to out; remove the link"),
        ("data/up", "..", ("data", "out"), "data/up is a link that leads to out; remove the link"),
        # a folder link in OUT that leads into IN: outputs written into IN
        ("out/date=2026-01-01", "../data/date=2026-01-01", ("data", "out"),
         "out/date=2026-01-01/part-0.parquet would be written into data (through a link in out); remove the link"),
    ],
)  # fmt: skip
def test_convert_dataset_refuses_in_and_out_joined_by_a_link(
    link, target, args, message, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    (tmp_path / "out").mkdir()
    os.symlink(target, tmp_path / link)
    before = _files(tmp_path / "data")
    code, err = _hconv("convert", *args, capsys=capsys)
    assert code == 4 and err.startswith(f"hconv: error: {message}") and len(err.splitlines()) == 1, err
    assert _files(tmp_path / "data") == before and _files(tmp_path / "out") == set()


@pytest.mark.parametrize(
    "link, target, message",
    [
        # back to IN or a folder holding it: the listing took IN's files again at every turn
        # (40 nested copies, exit 0), until the system's limit on links
        ("data/self", ".", "data/self is a link that leads back to data, a loop"),
        ("data/date=2026-01-01/back", "..", "data/date=2026-01-01/back is a link that leads back to data, a loop"),
        # to OUT before this run makes it: a link that leads nowhere yet was let through
        ("data/outlink", "../out", "data/outlink is a link that leads to out; remove the link"),
    ],
)  # fmt: skip
def test_convert_dataset_refuses_a_link_that_loops_or_will_lead_to_out(
    link, target, message, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    os.symlink(target, tmp_path / link)
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    expected = 2 if "a loop" in message else 4  # a loop is the input's; a link to OUT, the output's
    assert code == expected and err.startswith(f"hconv: error: {message}") and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_convert_dataset_out_that_is_a_device_is_not_a_directory(tmp_path, capsys, monkeypatch):
    """OUT /dev/full said that its manifest could not be read (Not a directory)."""
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    code, err = _hconv("convert", "data", "/dev/full", capsys=capsys)
    assert (code, err) == (
        4,
        "hconv: error: /dev/full: is not a directory; a dataset is written into a directory (it is made if missing)\n",
    )


def test_convert_dataset_refuses_an_input_that_links_to_an_output(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    assert _hconv("convert", "data", "out", capsys=capsys)[0] == 0
    os.symlink(f"../out/{PARTS[0]}", tmp_path / "data" / "again.parquet")
    code, err = _hconv("convert", "data", "out", capsys=capsys)
    assert code == 4 and "data/again.parquet is a link to a file in out; remove the link" in err, err


@pytest.mark.parametrize("dst", ["s3://bucket/out", "s3://bucket/out.parquet"])
def test_convert_dataset_store_that_cannot_be_reached_names_the_output(dst, tmp_path, capsys, monkeypatch):
    """A store that does not answer (here: nothing listens at the endpoint) fails naming the
    object asked about, never ``output:``."""
    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    for name, value in {"AWS_ACCESS_KEY_ID": "x", "AWS_SECRET_ACCESS_KEY": "y", "AWS_REGION": "us-east-1"}.items():
        monkeypatch.setenv(name, value)
    code, err = _hconv("convert", "data", dst, "--endpoint-url", "http://127.0.0.1:1", capsys=capsys)
    shown = f"{dst}/{MANIFEST}" if dst.endswith("out") else dst
    assert code == 4 and err.startswith(f"hconv: error: {shown}: cannot reach it (") and len(err.splitlines()) == 1, err


def test_convert_dataset_stops_on_a_full_disk_naming_the_file(tmp_path, capsys, monkeypatch):
    """The disk fills while the second file is written: that file is named (not ``output:``), the
    run stops there (no other file could be written either), the manifest lists the first. One
    thread, so that the second Parquet write is the second file's; the file under way when the
    run stops (on the pool, :func:`hconv.tables.runners.in_process`) finishes, and is listed."""
    import errno

    from hconv.tables import parquetio

    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)
    real, calls = parquetio.ParquetWriter.write, []

    def fills(self, table):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")
        real(self, table)

    monkeypatch.setattr(parquetio.ParquetWriter, "write", fills)
    code, err = _hconv("convert", "data", "out", "-q", "--threads", "1", capsys=capsys)
    assert code == 4, err
    listed = [f["output"] for f in _manifest(tmp_path / "out")["files"]]
    # the file under way when the run stopped (a CSV one: its writer is not the one made to fail) finished
    assert listed in ([PARTS[0]], [PARTS[0], "date=2026-01-02/extra.csv"]), listed
    assert err.splitlines() == [
        f"hconv: error: out/{PARTS[1]}: could not be written (No space left on device); nothing was written",
        f"hconv: error: stopped: no room left for out/{PARTS[1]} (named above); {len(listed)} of 4 files are "
        f"converted and listed in out/{MANIFEST}, which says complete: false; make room and run the same command "
        "again to convert the rest",
    ]
    assert len(calls) in (2, 3) and _files(tmp_path / "out") == {*listed, MANIFEST}  # 3: a Parquet file under way


def test_convert_dataset_whose_manifest_cannot_be_written_leaves_no_out(tmp_path, capsys, monkeypatch):
    """The disk is full before anything is written: the manifest, written first, fails; the run
    exits 4 naming it and removes the OUT it made, so that it wrote nothing, as the README says."""
    import errno

    monkeypatch.chdir(tmp_path)
    _dataset(tmp_path / "data", rows=20)

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    code, err = _hconv("convert", "data", "out", "-q", capsys=capsys)
    assert code == 4 and err == f"hconv: error: out/{MANIFEST}: could not be written (No space left on device)\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]
    (tmp_path / "out").mkdir()  # an OUT that was there stays
    code, err = _hconv("convert", "data", "out", "-q", capsys=capsys)
    assert code == 4 and (tmp_path / "out").is_dir() and _files(tmp_path / "out") == set()


def test_convert_dataset_small_files_share_a_pool_of_threads_and_start_none(tmp_path, monkeypatch):
    """Small files convert side by side on the run's pool (at most --threads threads, reused
    across files, not this thread) and start no threads of their own; a large one streams on
    this thread with its batch writer, as one file does. Each output is its single conversion."""
    import threading

    from hconv.tables import onefile, processes, runners

    data = tmp_path / "data"
    for k in range(9):
        _write(data / f"day={k % 3}" / f"part-{k}.parquet", 200 if k == 0 else 40 + k, seed=k)
    big = data / "day=0" / "part-0.parquet"
    monkeypatch.setattr(runners, "SMALL_FILE_BYTES", big.stat().st_size)  # part-0 alone is "large"
    where, writers = {}, []
    real_convert, real_enter = onefile.convert_one, pipeline.BackgroundWriter.__enter__

    def convert_one(task, *args, **kw):
        where[task.input.rel] = threading.current_thread()
        return real_convert(task, *args, **kw)

    def enter(self):
        writers.append(threading.current_thread())
        return real_enter(self)

    monkeypatch.setattr(runners, "convert_one", convert_one)  # a large file
    monkeypatch.setattr(processes, "convert_one", convert_one)  # small ones, on threads below PROCESS_FILES
    monkeypatch.setattr(pipeline.BackgroundWriter, "__enter__", enter)
    run = hconv.convert_dataset(str(data), str(tmp_path / "out"), threads=2)
    assert run.complete and len(run.files) == 9
    small = {t for rel, t in where.items() if rel != "day=0/part-0.parquet"}
    assert len(small) <= 2 and threading.main_thread() not in small
    assert all(t.name.startswith("hconv-file") for t in small)
    assert where["day=0/part-0.parquet"] is threading.main_thread()
    assert writers == [threading.main_thread()]  # the large file's writer only
    for rel in where:
        assert (tmp_path / "out" / rel).read_bytes() == _single(data / rel, tmp_path), rel


def test_convert_dataset_lists_outputs_only_once_flushed_a_group_at_a_time(tmp_path, monkeypatch):
    """Small files' outputs are not flushed one by one: each group of them is made durable
    (hconv.tables.manifest.make_durable) before the manifest written next lists any of them."""
    from hconv.tables import manifest, onefile

    data = tmp_path / "data"
    for k in range(6):
        _write(data / f"part-{k}.parquet", 30, seed=k)
    durable: set[str] = set()
    flushed_one_by_one = []
    real_durable, real_write = manifest.make_durable, manifest.storage.write_bytes

    def make_durable(paths):
        real_durable(paths)
        durable.update(os.path.basename(p) for p in paths)

    def write_bytes(where, rel, payload):
        listed = {f["output"] for f in json.loads(payload)["files"]}
        assert listed <= durable, listed - durable  # listed before it was flushed
        real_write(where, rel, payload)

    monkeypatch.setattr(manifest, "make_durable", make_durable)
    monkeypatch.setattr(manifest.storage, "write_bytes", write_bytes)
    monkeypatch.setattr(onefile, "flushed", lambda *a: flushed_one_by_one.append(a))
    run = hconv.convert_dataset(str(data), str(tmp_path / "out"))
    assert run.complete and durable == {f"part-{k}.parquet" for k in range(6)} and flushed_one_by_one == []


def test_convert_dataset_lists_the_small_files_before_a_large_one_starts(tmp_path, monkeypatch):
    """A large file converts for long: the group of small files before it is committed (flushed
    and listed in the manifest) before it starts, not after."""
    from hconv.tables import runners

    data = tmp_path / "data"
    for k in range(4):
        _write(data / f"a-{k}.parquet", 30, seed=k)
    _write(data / "z-big.parquet", 400, seed=9)
    monkeypatch.setattr(runners, "SMALL_FILE_BYTES", (data / "z-big.parquet").stat().st_size)
    listed_at_start = []
    real = runners.convert_one

    def convert_one(task, *args, **kw):
        if task.input.rel == "z-big.parquet":
            listed_at_start.extend(f["output"] for f in _manifest(tmp_path / "out")["files"])
        return real(task, *args, **kw)

    monkeypatch.setattr(runners, "convert_one", convert_one)
    assert hconv.convert_dataset(str(data), str(tmp_path / "out")).complete
    assert sorted(listed_at_start) == [f"a-{k}.parquet" for k in range(4)]


def test_convert_dataset_of_arrow_and_json_lines_files(tmp_path):
    """Before: a directory of .feather and .jsonl files 'holds no file with a .csv, .parquet or .pq name'."""
    import pyarrow.feather as feather

    src = tmp_path / "in"
    t = pa.table(make_scene(50, seed=3))
    (src / "a").mkdir(parents=True)
    feather.write_feather(t, src / "a" / "one.feather")
    (src / "two.jsonl").write_text("".join(json.dumps(r) + "\n" for r in t.to_pylist()))
    with pytest.raises(
        hconv.errors.UsageError, match=r"two.jsonl: is JSON lines, which hconv reads but does not write"
    ):
        hconv.convert_dataset(src, tmp_path / "out")
    res = hconv.convert_dataset(src, tmp_path / "out", dst_format="arrow")
    assert res.complete and sorted(res.converted) == ["a/one.feather", "two.jsonl"]
    assert _files(tmp_path / "out") == {"a/one.feather", "two.arrow", MANIFEST}  # Feather is Arrow: its name kept
    ref = hconv.convert_table(t)
    for rel in ("a/one.feather", "two.arrow"):
        got = pa.ipc.open_file(str(tmp_path / "out" / rel)).read_all()
        assert got.column("wx").to_pylist() == ref.column("wx").to_pylist()


def test_convert_dataset_takes_a_pyarrow_dataset_of_files(tmp_path):
    """Before: convert_dataset(pyarrow.dataset.dataset(...)) raised a raw TypeError from os.fspath."""
    import pyarrow.dataset as pads

    src = _dataset(tmp_path / "in")
    parquet = pads.dataset(src, format="parquet", exclude_invalid_files=True, partitioning="hive")
    whole = pads.dataset(str(tmp_path / "in" / "date=2026-01-01"), format="parquet")
    res = hconv.convert_dataset(whole, tmp_path / "out")
    assert res.complete and res.total == len(whole.files)
    assert res.rows_converted == whole.count_rows()
    with pytest.raises(hconv.errors.UsageError, match=r"^convert_dataset: the pyarrow dataset holds \d+ of the files"):
        hconv.convert_dataset(parquet, tmp_path / "out2")  # not the CSV beside them
    with pytest.raises(
        hconv.errors.UsageError, match=r"in memory has no files; .*convert_table\(dataset.to_table\(\)\)"
    ):
        hconv.convert_dataset(pads.dataset(pa.table({"Hx": [1.0]})), tmp_path / "out3")
    with pytest.raises(hconv.errors.UsageError, match=r"^convert_dataset takes a directory, .* got dict"):
        hconv.convert_dataset({"Hx": [1.0]}, tmp_path / "out4")


# Many small files: worker processes (hconv.tables.processes), from runners.PROCESS_FILES files.


def _small_dataset(root: Path, files: int) -> Path:
    for k in range(files):
        _write(root / f"day={k % 4}" / f"part-{k:04d}.parquet", 20 + k % 7, seed=k)
    return root


def _worker_pids(pid: int) -> list[int]:
    """The children of process ``pid`` (Linux's /proc)."""
    pids = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        pids += [int(p) for p in (task / "children").read_text().split()]
    return pids


def _rerun_completes(tmp_path: Path, data: Path, out: Path) -> None:
    """The same command run again on tmp_path/data: it completes the manifest and leaves nothing
    temporary; each output the stopped run listed, and every tenth of the rest, is its file's
    single conversion (all of them cost seconds more, and the rerun's come from the same code)."""
    kept = {f["output"] for f in _manifest(out)["files"]}
    proc = run_hconv("convert", "data", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr.decode()
    assert _manifest(out)["complete"] is True and _no_temporaries(out) == []
    rest = sorted(_files(out) - kept - {MANIFEST})
    for rel in sorted(kept) + rest[::10]:
        assert (out / rel).read_bytes() == _single(data / rel, tmp_path), rel


@pytest.fixture(scope="module")
def process_dataset(tmp_path_factory) -> Path:
    """A dataset of runners.PROCESS_FILES small files, written once for the tests that copy it."""
    return _small_dataset(tmp_path_factory.mktemp("many") / "data", runners.PROCESS_FILES)


def test_convert_dataset_many_small_files_on_worker_processes_write_what_threads_write(tmp_path, monkeypatch):
    """From PROCESS_FILES small files a run converts them on worker processes: each output is
    its file's single conversion, a bad file fails alone with the message a run on threads
    gives, a large file still converts on this thread, and nothing temporary is left."""
    from hconv.tables import processes

    data = _small_dataset(tmp_path / "data", 11)
    (data / "day=1" / "part-bad.parquet").write_bytes(b"PAR1 not really")
    _write(data / "day=2" / "z-big.parquet", 400, seed=99)
    made = []
    real_init = processes.Workers.__init__

    def init(self, count, *args, **kw):
        made.append(count)
        real_init(self, count, *args, **kw)

    monkeypatch.setattr(processes.Workers, "__init__", init)
    monkeypatch.setattr(runners, "SMALL_FILE_BYTES", (data / "day=2" / "z-big.parquet").stat().st_size)
    errors = {}
    for mode, at_least in (("threads", 10**9), ("processes", 4)):
        monkeypatch.setattr(runners, "PROCESS_FILES", at_least)
        with pytest.raises(dataset.DatasetError) as caught:
            hconv.convert_dataset(str(data), str(tmp_path / mode), threads=2)
        run = caught.value.result
        assert len(run.files) == 12 and [rel for rel, _ in run.failed] == ["day=1/part-bad.parquet"]
        errors[mode] = str(run.failed[0][1])
        assert _no_temporaries(tmp_path / mode) == []
    assert made == [2]  # the second run only
    monkeypatch.setattr(processes, "available", lambda: False)  # Python embedded in an application
    with pytest.raises(dataset.DatasetError) as caught:
        hconv.convert_dataset(str(data), str(tmp_path / "embedded"), threads=2)
    assert made == [2] and len(caught.value.result.files) == 12
    assert errors["processes"] == errors["threads"] and "day=1/part-bad.parquet" in errors["threads"]
    for rel in _files(tmp_path / "threads") - {MANIFEST}:
        assert (tmp_path / "processes" / rel).read_bytes() == _single(data / rel, tmp_path), rel
    records = [{k: v for k, v in f.items() if k != "seconds"} for f in _manifest(tmp_path / "processes")["files"]]
    assert records == [{k: v for k, v in f.items() if k != "seconds"} for f in _manifest(tmp_path / "threads")["files"]]


def test_convert_dataset_on_worker_processes_interrupted_keeps_what_it_lists(tmp_path, process_dataset):
    """Ctrl-C at a terminal (SIGINT to the whole process group, workers too) while worker
    processes convert: the command exits 130, the manifest lists only complete outputs, no
    temporary file and no worker is left, and the same command then converts the rest, each
    output its file's single conversion."""
    # More files than the runner hands out ahead of those it settled (17 chunks of 8 for 2
    # workers): the workers cannot finish them all while the run is stopped, however slow the
    # machine, so the Ctrl-C finds files to leave (with all done, a run ends as if never stopped).
    files = runners.PROCESS_FILES
    assert files > (runners.WORKER_CHUNKS_AHEAD * 2 + 1) * runners.CHUNK_FILES + 24
    data = Path(shutil.copytree(process_dataset, tmp_path / "data"))
    out = tmp_path / "out"
    stop = StopAt(tmp_path / "hook", "hconv.tables.manifest:GroupCommit.add#20")  # 19 files settled
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "data", "out", "--threads", "2"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=stop.env(),
        preexec_fn=lambda: (terminal_signals(), os.setpgrp()),
        pass_fds=stop.fds,
    )
    stop.started()
    assert stop.reached(), proc.communicate()[1].decode()
    workers = _worker_pids(proc.pid)
    assert len(workers) == 2
    os.killpg(proc.pid, signal.SIGINT)
    stop.release()
    _, err = proc.communicate()
    assert proc.returncode == 130, err.decode()
    m = _manifest(out)
    listed = [f["output"] for f in m["files"]]
    assert m["complete"] is False and 19 <= len(listed) < files, err.decode()
    assert _files(out) == set(listed) | {MANIFEST}
    assert not [pid for pid in workers if Path(f"/proc/{pid}").exists()]
    _rerun_completes(tmp_path, data, out)


def test_convert_dataset_killed_outright_on_worker_processes_takes_its_workers_along(tmp_path, process_dataset):
    """kill -9 of the command while its worker processes convert: the workers end with it (none
    goes on writing into OUT behind the next run), and the next run converts what the manifest
    does not list, each output its file's single conversion, leaving nothing temporary."""
    data = Path(shutil.copytree(process_dataset, tmp_path / "data"))
    out = tmp_path / "out"
    stop = StopAt(tmp_path / "hook", "hconv.tables.manifest:GroupCommit.add#20")
    proc = subprocess.Popen(
        [sys.executable, "-m", "hconv", "convert", "data", "out", "--threads", "2"],
        cwd=tmp_path,
        stderr=subprocess.PIPE,
        env=stop.env(),
        pass_fds=stop.fds,
    )
    stop.started()
    assert stop.reached(), proc.communicate()[1].decode()
    workers = _worker_pids(proc.pid)
    assert len(workers) == 2
    proc.kill()
    proc.communicate()
    for _ in range(500):  # the kernel ends them as their parent ends: within moments
        if not [pid for pid in workers if Path(f"/proc/{pid}").exists()]:
            break
        time.sleep(0.01)
    assert not [pid for pid in workers if Path(f"/proc/{pid}").exists()]
    _rerun_completes(tmp_path, data, out)
