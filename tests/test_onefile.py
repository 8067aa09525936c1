"""Tests of hconv.tables.onefile: one file of a dataset staged, converted and committed."""

from __future__ import annotations

import contextlib
import os

import pytest

from hconv.errors import OutputError
from hconv.tables import onefile, storage


def test_stage_output_folder_removed_meanwhile_is_made_again(tmp_path, monkeypatch):
    """A partition folder removed between being found and the temporary file being made in it
    (another worker's failed file removing the empty folder it made) is made again: the file was
    refused, 'cannot make its temporary file … (No such file or directory)', exit 4."""
    dst = storage.place(str(tmp_path / "out"))
    real, calls = storage.stage, []

    def vanishing(beside=None, **kw):
        calls.append(beside)
        if len(calls) == 1:  # the folder goes just before the first temporary file is made
            os.rmdir(os.path.dirname(beside))
        return real(beside, **kw)

    monkeypatch.setattr(storage, "stage", vanishing)
    with contextlib.ExitStack() as cleanup:
        staged = onefile.stage_output(dst, "day=1/part-0.parquet", cleanup, None)
        assert os.path.dirname(staged) == str(tmp_path / "out" / "day=1") and os.path.isfile(staged)
        assert len(calls) == 2
    assert not (tmp_path / "out" / "day=1").exists()  # nothing left behind, as before


def test_stage_output_folder_that_keeps_vanishing_is_an_output_error(tmp_path, monkeypatch):
    dst = storage.place(str(tmp_path / "out"))
    real = storage.stage

    def always(beside=None, **kw):
        os.rmdir(os.path.dirname(beside))
        return real(beside, **kw)

    monkeypatch.setattr(storage, "stage", always)
    with contextlib.ExitStack() as cleanup, pytest.raises(OutputError, match="cannot make its temporary file"):
        onefile.stage_output(dst, "day=1/part-0.parquet", cleanup, None)
