"""A dataset's manifest (hconv.tables.manifest): its format is pinned, so that its bytes do not
move with the classes' field order."""

from __future__ import annotations

import json

import hconv
from hconv.tables.manifest import job_identity

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
