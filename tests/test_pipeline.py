"""The machinery under `hconv convert`'s speed: ordered parallel batches and the Parquet writer's
encodings (the allocator settings are in test_allocator.py)."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from hconv.tables import pipeline
from hconv.tables.job import Job
from hconv.tools.scene import make_scene


def _slow_square(k: int) -> int:
    time.sleep(0.002 * (k % 5))  # later items often finish first
    return k * k


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_ordered_map_keeps_input_order(threads):
    assert list(pipeline.ordered_map(_slow_square, range(40), threads)) == [k * k for k in range(40)]


def test_ordered_map_uses_several_threads():
    seen = set()

    def record(k):
        seen.add(threading.get_ident())
        time.sleep(0.01)
        return k

    assert list(pipeline.ordered_map(record, range(12), 3)) == list(range(12))
    assert len(seen) >= 2


def test_ordered_map_raises_the_first_error_in_order_and_stops_reading():
    read = []

    def items():
        for k in range(100):
            read.append(k)
            yield k

    def fail_at_5(k):
        if k == 5:
            raise ValueError("row 5")
        return k

    got = []
    with pytest.raises(ValueError, match="row 5"):
        for x in pipeline.ordered_map(fail_at_5, items(), 2):
            got.append(x)
    assert got == [0, 1, 2, 3, 4]
    assert len(read) <= 5 + 2 + 1  # bounded look-ahead: it did not read on to the end


def test_convert_file_same_output_for_any_threads(tmp_path):
    src = tmp_path / "in.parquet"
    pq.write_table(pa.table(make_scene(5000, seed=3, cond_max=1e8)), src)
    outs = []
    for threads in (1, 2, 3):
        dst = tmp_path / f"out{threads}.parquet"
        tally = pipeline.convert_file(str(src), str(dst), threads=threads)
        assert tally.rows == 5000
        outs.append(pq.read_table(dst))
    assert outs[0].equals(outs[1]) and outs[0].equals(outs[2])


def test_convert_file_threads_below_one_is_usage_error(tmp_path):
    from hconv.errors import UsageError

    with pytest.raises(UsageError, match="--threads must be 1 or more"):
        pipeline.convert_file("in.parquet", str(tmp_path / "out.parquet"), threads=0)


def test_default_threads_is_between_one_and_the_cap():
    assert 1 <= pipeline.default_threads() <= pipeline.MAX_THREADS


def test_parquet_output_floats_plain_labels_compressed(tmp_path):
    src, dst = tmp_path / "in.parquet", tmp_path / "out.parquet"
    cols = make_scene(3000, seed=1)
    pq.write_table(pa.table(cols), src)
    pipeline.convert_file(str(src), str(dst))
    meta = pq.ParquetFile(dst).metadata.row_group(0)
    codec = {meta.column(k).path_in_schema: meta.column(k).compression for k in range(meta.num_columns)}
    assert codec["wx"] == codec["residual"] == codec["Hx"] == "UNCOMPRESSED"
    assert codec["status"] == codec["body"] == "SNAPPY"
    np.testing.assert_array_equal(pq.read_table(dst).column("Hx").to_numpy(), cols["Hx"])  # nothing lost on the way


def test_convert_file_tally_names_the_engine_that_ran(tmp_path):
    """auto keeps files on numpy; a run the asked engine does not cover is numpy's, and says so."""
    import importlib.util

    src, dst = "examples/data/scene.parquet", str(tmp_path / "o.parquet")
    root = Path(__file__).resolve().parents[1]
    auto = pipeline.convert_file(str(root / src), dst, force=True)
    forced = os.environ.get("HCONV_ENGINE", "auto")  # CI's second run makes every auto numba
    assert auto.engines == {"numpy" if forced == "auto" else forced: 400}
    python = pipeline.convert_file(str(root / src), dst, force=True, job=Job(engine="python"))
    assert python.engines == {"python": 400}
    eigen = pipeline.convert_file(str(root / src), dst, force=True, job=Job(method="eigen", engine="python"))
    assert eigen.engines == {"numpy": 400}
    if importlib.util.find_spec("numba") is not None:
        assert pipeline.convert_file(str(root / src), dst, force=True, job=Job(engine="numba")).engines == {
            "numba": 400
        }
