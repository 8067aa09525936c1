"""numpy arrays as Arrow arrays and back, through their buffers, and Arrow arrays and scalars of
Python values, without pyarrow's pandas shim.

pyarrow's own conversions (``pa.array`` of a list or of a numpy array, ``pa.scalar`` of a Python
value, ``Array.to_numpy``, ``np.asarray`` of an Arrow array, a compute function given a Python
number or string) ask that shim whether their argument is a pandas object, and the shim imports
pandas to answer, when it is installed: a third of the start-up of a process that converts a
small file (docs/engines.md). hconv's own columns are plain numbers, bits and text, whose Arrow
buffers are numpy's memory as it is, so hconv builds them here from their buffers instead; pandas
is imported only where a pandas object is handed to hconv (:mod:`hconv.tables.arrow`).

Conventions: a column is one-dimensional; "primitive" is a fixed-width integer or float type, or
boolean (one bit a value, least significant bit first, as Arrow packs it). Copies are as pyarrow's
own conversions make them: a contiguous numpy array and an Arrow array without nulls share their
memory (read-only on the numpy side), anything else is copied.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyarrow as pa


def numpy_dtype(t: pa.DataType) -> np.dtype:
    """The numpy dtype whose memory is ``t``'s values: a primitive type's (TypeError otherwise)."""
    if pa.types.is_boolean(t):
        return np.dtype(np.bool_)
    kind = "i" if pa.types.is_signed_integer(t) else "u" if pa.types.is_unsigned_integer(t) else "f"
    if not (pa.types.is_integer(t) or pa.types.is_floating(t)):
        raise TypeError(f"{t} is not a primitive type")
    return np.dtype(f"{kind}{t.bit_width // 8}")


def arrow_type(dtype: np.dtype) -> pa.DataType:
    """The Arrow type of a numeric or boolean numpy dtype (TypeError otherwise)."""
    dtype = np.dtype(dtype)
    if dtype == np.bool_:
        return pa.bool_()
    if dtype.kind not in "iuf" or dtype.byteorder == ">":
        raise TypeError(f"numpy dtype {dtype} has no primitive Arrow type here")
    return _ARROW_TYPES[dtype.kind][dtype.itemsize]()


_ARROW_TYPES = {
    "i": {1: pa.int8, 2: pa.int16, 4: pa.int32, 8: pa.int64},
    "u": {1: pa.uint8, 2: pa.uint16, 4: pa.uint32, 8: pa.uint64},
    "f": {2: pa.float16, 4: pa.float32, 8: pa.float64},
}


def _bits(buffer: pa.Buffer, offset: int, n: int) -> np.ndarray:
    """``n`` bits of an Arrow bitmap from bit ``offset``, as booleans."""
    packed = np.frombuffer(buffer, dtype=np.uint8, count=(offset + n + 7) // 8)
    return np.unpackbits(packed, count=offset + n, bitorder="little")[offset:].view(np.bool_)


def _chunk(a: pa.Array, null: object) -> np.ndarray:
    dtype = numpy_dtype(a.type)
    n = len(a)
    if n == 0:
        return np.empty(0, dtype)
    validity, data = a.buffers()[:2]
    if dtype == np.bool_:
        values = _bits(data, a.offset, n)
    else:
        values = np.frombuffer(data, dtype=dtype, count=n, offset=a.offset * dtype.itemsize)
    if a.null_count:
        if null is None:
            raise ValueError(f"a {a.type} array with {a.null_count} nulls, and no value given for them")
        values = values.copy()
        values[~_bits(validity, a.offset, n)] = null
    return values


def to_numpy(col: pa.Array | pa.ChunkedArray, null: object = None) -> np.ndarray:
    """A primitive column's values as a numpy array of its own dtype (:func:`numpy_dtype`), its
    nulls as ``null`` (a column with nulls and no ``null``: ValueError). A float column's nulls as
    NaN are ``Array.to_numpy(zero_copy_only=False)``'s values."""
    if isinstance(col, pa.ChunkedArray):
        chunks = [_chunk(c, null) for c in col.chunks]
        if len(chunks) == 1:
            return chunks[0]
        return np.concatenate(chunks) if chunks else np.empty(0, numpy_dtype(col.type))
    return _chunk(col, null)


def from_numpy(values: np.ndarray, type: pa.DataType | None = None) -> pa.Array:
    """A one-dimensional numeric or boolean numpy array as an Arrow array without nulls, of
    ``type`` (which must be the dtype's own: :func:`arrow_type`, the default)."""
    if values.ndim != 1:
        raise ValueError(f"a column is one-dimensional, not of shape {values.shape}")
    own = arrow_type(values.dtype)
    if type is not None and type != own:
        raise TypeError(f"numpy dtype {values.dtype} holds {own}, not {type}")
    if values.dtype == np.bool_:
        data = pa.py_buffer(np.packbits(values, bitorder="little"))
    else:
        data = pa.py_buffer(np.ascontiguousarray(values))
    return pa.Array.from_buffers(own, len(values), [None, data], null_count=0)


def strings(values: Sequence[str | None], type: pa.DataType | None = None) -> pa.Array:
    """Python strings (None: null) as an Arrow ``string`` array, or ``large_string``."""
    type = pa.string() if type is None else type
    wide = pa.types.is_large_string(type)
    if not (wide or pa.types.is_string(type)):
        raise TypeError(f"strings are string or large_string, not {type}")
    encoded = [b"" if v is None else v.encode("utf-8") for v in values]
    offsets = np.zeros(len(encoded) + 1, dtype=np.int64 if wide else np.int32)
    np.cumsum([len(e) for e in encoded], out=offsets[1:])
    valid = np.fromiter((v is not None for v in values), dtype=np.bool_, count=len(encoded))
    nulls = len(encoded) - int(valid.sum())
    validity = pa.py_buffer(np.packbits(valid, bitorder="little")) if nulls else None
    buffers = [validity, pa.py_buffer(offsets), pa.py_buffer(b"".join(encoded))]
    return pa.Array.from_buffers(type, len(encoded), buffers, null_count=nulls)


def scalar(value: str | float | int | bool | None, type: pa.DataType) -> pa.Scalar:
    """``value`` as an Arrow scalar of ``type`` (string, large_string or primitive; None: its
    null), for a compute function's argument."""
    if value is None:
        return pa.nulls(1, type)[0]
    if pa.types.is_string(type) or pa.types.is_large_string(type):
        return strings([str(value)], type)[0]
    return from_numpy(np.array([value], dtype=numpy_dtype(type)), type)[0]
