"""hconv.tables.arrays: numpy and Python values as Arrow arrays and back, built from their buffers,
held to pyarrow's own conversions (which import pandas, so only the tests call them)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest
from helpers import need

from hconv.tables import arrays

FLOATS = pa.array([1.5, None, -0.0, float("nan"), 2e300, None, 7.0, 8.0, 9.0], pa.float64())


@pytest.mark.parametrize(
    "col",
    [
        FLOATS,
        FLOATS.slice(1),  # an offset into the data and into the validity bits
        FLOATS.slice(3, 4),
        pa.array([1.0, 2.0, 3.0], pa.float32()),
        pa.chunked_array([FLOATS.slice(5), FLOATS.slice(0, 3)]),
        pa.chunked_array([], pa.float64()),
        pa.array([], pa.float64()),
    ],
)
def test_to_numpy_floats_with_nulls_as_nan_are_pyarrows(col):
    got = arrays.to_numpy(col, null=np.nan)
    expected = col.to_numpy(zero_copy_only=False) if isinstance(col, pa.Array) else col.to_numpy()
    assert got.dtype == expected.dtype
    np.testing.assert_array_equal(got, expected)  # NaN where NaN, -0.0 kept (bit for bit below)
    assert got.view(np.uint8).tobytes() == expected.view(np.uint8).tobytes()


@pytest.mark.parametrize(
    "col",
    [
        pa.array([True, False, True, True, False, False, True, True, True, False, True], pa.bool_()),
        pa.array([True, False, True, True, False, False, True, True, True, False, True], pa.bool_()).slice(3),
        pa.array(np.arange(-5, 6, dtype=np.int8)),
        pa.array(np.arange(10, dtype=np.uint32)).slice(7),
        pa.array(np.arange(10, dtype=np.int64)),
    ],
)
def test_to_numpy_bits_and_integers_are_pyarrows(col):
    got, expected = arrays.to_numpy(col), col.to_numpy(zero_copy_only=False)
    assert got.dtype == expected.dtype and got.tolist() == expected.tolist()


def test_to_numpy_nulls_as_a_value_given():
    lengths = pa.array([3, None, 4, None], pa.int32())
    assert arrays.to_numpy(lengths, null=-1).tolist() == [3, -1, 4, -1]
    assert arrays.to_numpy(pa.array([True, None, False]), null=False).tolist() == [True, False, False]


def test_to_numpy_nulls_without_a_value_are_refused():
    with pytest.raises(ValueError, match="2 nulls"):
        arrays.to_numpy(pa.array([1, None, None], pa.int64()))


def test_to_numpy_text_is_refused():
    with pytest.raises(TypeError, match="not a primitive type"):
        arrays.to_numpy(pa.array(["a"]))


@pytest.mark.parametrize(
    "values",
    [
        np.array([1.5, -0.0, np.nan, np.inf, 5e-324]),
        np.arange(12.0).reshape(4, 3)[:, 1],  # strided: a copy
        np.arange(5, dtype=np.float32),
        np.array([-3, 0, 127], dtype=np.int8),
        np.array([True, False, True, True, False, False, True, True, True]),
        np.array([], dtype=np.float64),
    ],
)
def test_from_numpy_is_pyarrows_array(values):
    got, expected = arrays.from_numpy(values), pa.array(values)
    got.validate(full=True)
    assert (got.type, len(got), got.null_count) == (expected.type, len(expected), 0)
    # bit for bit (equals would hold NaN unequal to itself), read back by pyarrow's own conversion
    assert got.to_numpy(zero_copy_only=False).tobytes() == values.tobytes()


def test_from_numpy_shares_a_contiguous_arrays_memory():
    values = np.arange(4.0)
    got = arrays.from_numpy(values)
    assert got.buffers()[1].address == values.ctypes.data


def test_from_numpy_another_type_is_refused():
    with pytest.raises(TypeError, match="holds double, not int8"):
        arrays.from_numpy(np.zeros(3), pa.int8())
    with pytest.raises(ValueError, match="one-dimensional"):
        arrays.from_numpy(np.zeros((2, 3)))


@pytest.mark.parametrize("type_", [pa.string(), pa.large_string()])
@pytest.mark.parametrize("values", [["a", None, "héllo ω", "", "x" * 300], [], [None, None], ["", ""]])
def test_strings_are_pyarrows_array(values, type_):
    got = arrays.strings(values, type_)
    got.validate(full=True)
    assert got.type == type_ and got.equals(pa.array(values, type_))


def test_scalar_is_pyarrows_scalar():
    for value, type_ in [("", pa.large_string()), ("kg", pa.string()), (None, pa.string()), (2.5, pa.float64())]:
        got = arrays.scalar(value, type_)
        assert got.type == type_ and got.equals(pa.scalar(value, type_))


def test_import_and_every_conversion_leave_pandas_unimported():
    need("pandas")  # without it, nothing to import
    # a process of its own: the test process has imported pandas through pyarrow's calls above
    code = (
        "import sys, numpy as np, pyarrow as pa, pyarrow.compute as pc\n"
        "from hconv.tables import arrays\n"
        "a = arrays.from_numpy(np.arange(3.0)); s = arrays.strings(['a', None])\n"
        "arrays.to_numpy(pc.is_valid(s)); arrays.to_numpy(a, null=np.nan); arrays.scalar('x', pa.string())\n"
        "print('pandas' in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.decode().split() == ["False"], proc.stderr.decode()
