"""convert_table, the Arrow edge of the library: its own options against a whole Job."""

from __future__ import annotations

import pyarrow as pa
import pytest

import hconv
from hconv.errors import UsageError


def _table() -> pa.Table:
    return pa.table({"Hx": [1.0], "Hy": [2.0], "Hz": [3.0], "Ixx": [2.0], "Iyy": [3.0], "Izz": [4.0],
                     "Ixy": [0.1], "Ixz": [0.0], "Iyz": [0.2]})  # fmt: skip


@pytest.mark.parametrize("beside", [{"method": "refined"}, {"precision": 32}, {"diagnostics": False}])
def test_convert_table_refuses_options_beside_a_job(beside):
    name = next(iter(beside))
    with pytest.raises(UsageError, match=f"convert_table: {name} given beside job=; put them in the Job"):
        hconv.convert_table(_table(), job=hconv.Job(), **beside)


def test_convert_table_options_alone_and_job_alone_are_honoured():
    plain = hconv.convert_table(_table())
    assert "residual" in plain.column_names
    assert "residual" not in hconv.convert_table(_table(), diagnostics=False).column_names
    assert "residual" not in hconv.convert_table(_table(), job=hconv.Job(diagnostics=False)).column_names
    doc = hconv.convert_table(_table().append_column("rx", pa.array([0.1])).append_column("ry", pa.array([0.2]))
                              .append_column("rz", pa.array([0.3])), method="document")  # fmt: skip
    assert doc.schema.field("wx").metadata[b"unit"] == b"m^2/s"
