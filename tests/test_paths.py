"""hconv.convert_path: a file or a dataset by what the path is, as hconv convert decides."""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import hconv
from hconv.errors import UsageError
from hconv.tables.dataset import DatasetResult
from hconv.tables.pipeline import Tally


def _write(path) -> None:
    names = ["Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]
    pq.write_table(pa.table({n: [v] for n, v in zip(names, [1.0, 2.0, 3.0, 2.0, 3.0, 4.0, 0.0, 0.0, 0.0])}), path)


def test_convert_path_converts_a_file_into_a_file(tmp_path):
    _write(tmp_path / "in.parquet")
    result = hconv.convert_path(tmp_path / "in.parquet", tmp_path / "out.parquet")
    assert isinstance(result, Tally) and result.rows == 1
    assert pq.read_table(tmp_path / "out.parquet").column("status").to_pylist() == ["ok"]


def test_convert_path_converts_a_directory_as_a_dataset(tmp_path):
    (tmp_path / "in").mkdir()
    _write(tmp_path / "in" / "a.parquet")
    lines = []
    result = hconv.convert_path(tmp_path / "in", tmp_path / "out", log=lines.append)
    assert isinstance(result, DatasetResult) and result.converted == ["a.parquet"]
    assert pq.read_table(tmp_path / "out" / "a.parquet").column("status").to_pylist() == ["ok"]


def test_convert_path_refuses_an_endpoint_for_local_files(tmp_path):
    _write(tmp_path / "in.parquet")
    src, dst = tmp_path / "in.parquet", tmp_path / "out.parquet"
    with pytest.raises(UsageError) as info:
        hconv.convert_path(src, dst, endpoint_url="http://127.0.0.1:1")
    assert str(info.value) == f"endpoint_url is for s3:// URIs; {src} and {dst} are local"
    assert not dst.exists()


def test_convert_path_refuses_a_cluster_for_one_file(tmp_path):
    _write(tmp_path / "in.parquet")
    src = tmp_path / "in.parquet"
    with pytest.raises(UsageError) as info:
        hconv.convert_path(src, tmp_path / "out.parquet", workers=2)
    assert str(info.value) == (  # it named cluster, which was not given
        f"workers is for a dataset's files on a cluster; {src} is one file, converted here "
        "(give its directory, or a glob, to use cluster)"
    )
