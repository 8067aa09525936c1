"""hconv's temporary files (hconv.tables.temporaries): whose they are, and which a sweep removes."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from hconv.tables import temporaries


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="start times come from Linux's /proc")
def test_remove_stale_temporaries_leaves_live_and_unknown_makers_alone(tmp_path, capsys):
    pid, start, tag = temporaries._maker().split("-")
    other_tag = f"{(int(tag, 16) + 1) % (1 << 32):08x}"
    names = {
        f".out.parquet.{pid}-{start}-{tag}-abcd1234.hconv-tmp": "live",  # this process: running
        f"hconv-stdout-{pid}-{start}-{tag}-abcd1234.hconv-tmp": "live",
        f".out.csv.{pid}-{int(start) + 1}-{tag}-abcd1234.hconv-tmp": "stale",  # its pid, another start: reused
        f".out.csv.1-1-{other_tag}-abcd1234.hconv-tmp": "other host",  # pid 1 there means nothing here
        ".out.csv.abcd1234.hconv-tmp": "old name",  # an earlier hconv's: no maker to check
        "notes.txt": "not hconv's",
    }
    for name in names:
        (tmp_path / name).write_text("x")
    removed = temporaries.remove_stale_temporaries(str(tmp_path))
    stale = [n for n, why in names.items() if why == "stale"]
    assert removed == [str(tmp_path / n) for n in stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(n for n in names if n not in stale)
    assert capsys.readouterr().err == (
        f"hconv: removed stale temporary file {tmp_path / stale[0]} left by a run that was killed (pid {pid})\n"
    )


def test_remove_stale_temporaries_sweeps_a_killed_dataset_runs_fetched_and_staged_files(tmp_path, capsys):
    """A dataset run killed outright leaves hconv-fetch- and hconv-stage- files in TMPDIR, and
    .NAME.…hconv-tmp files beside outputs; the next run there removes those of ended processes."""
    pid, start, tag = temporaries._maker().split("-")
    gone = f"{pid}-{int(start) + 1}-{tag}"  # this pid with another start: a process that has ended
    names = [f"hconv-fetch-{gone}-abcd1234.hconv-tmp", f"hconv-stage-{gone}-abcd1234.hconv-tmp"]
    names += [f".part-0.parquet.{gone}-abcd1234.hconv-tmp"]
    for name in names:
        (tmp_path / name).write_bytes(b"")
    live = tmp_path / f"hconv-stage-{pid}-{start}-{tag}-abcd1234.hconv-tmp"
    live.write_bytes(b"")
    assert sorted(temporaries.remove_stale_temporaries(str(tmp_path))) == sorted(str(tmp_path / n) for n in names)
    assert [p.name for p in tmp_path.iterdir()] == [live.name]
    capsys.readouterr()


def test_remove_run_temporaries_takes_only_that_runs_files(tmp_path):
    (tmp_path / "d=1").mkdir()
    ours = tmp_path / "d=1" / ".part.parquet.run-abc123.99999-0-0000abcd-x1.hconv-tmp"
    other_run = tmp_path / ".part.parquet.run-def456.99999-0-0000abcd-x1.hconv-tmp"
    no_run = tmp_path / ".part.parquet.99999-0-0000abcd-x1.hconv-tmp"
    for p in (ours, other_run, no_run):
        p.write_bytes(b"")
    assert temporaries.remove_run_temporaries(str(tmp_path), "abc123") == []  # not recursive
    assert temporaries.remove_run_temporaries(str(tmp_path), "abc123", recursive=True) == [str(ours)]
    assert other_run.exists() and no_run.exists() and not ours.exists()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="start times come from Linux's /proc")
def test_temporary_file_sweeps_each_folder_once_while_sweeping_once(tmp_path):
    """A dataset run makes two temporary files per output; listing the folder for stale ones at
    each cost more than a small file's conversion: inside sweeping_once a folder is swept once."""
    pid, start, tag = temporaries._maker().split("-")
    stale = f".out.csv.{pid}-{int(start) + 1}-{tag}-abcd1234.hconv-tmp"  # its pid, another start: reused
    made = []
    with temporaries.sweeping_once():
        made.append(temporaries.temporary_file(".a.", str(tmp_path)))
        (tmp_path / stale).write_text("x")  # a run killed after the sweep
        made.append(temporaries.temporary_file(".b.", str(tmp_path)))
        assert (tmp_path / stale).exists()
    made.append(temporaries.temporary_file(".c.", str(tmp_path)))  # outside: swept again
    assert not (tmp_path / stale).exists()
    for fd, path in made:
        os.close(fd)
        os.unlink(path)
