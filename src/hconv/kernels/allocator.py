"""The C allocator's settings for hconv's own processes: keep block temporaries off mmap.

Every numpy operation on a block of rows allocates its result. A block of 16384 float64 rows is
128 KiB, glibc's default ``mmap`` threshold, and its dynamic thresholds then trim the heap back
after nearly every block, so each new temporary is faulted in and zeroed by the kernel again,
which cost the kernels several times their arithmetic (figures: docs/measurements.md). Raising
the two thresholds keeps freed temporaries in the heap for the next block, at the price of up to
:data:`TRIM_THRESHOLD` of freed memory held until the process ends.

The ``hconv`` command calls :func:`tune` at start-up. A program that uses hconv as a library may
call it too; hconv never calls it on import, since it changes the whole process's allocator.
"""

from __future__ import annotations

import ctypes
import sys

#: Requests of at least this many bytes get their own mapping (glibc's default: 128 KiB, dynamic).
MMAP_THRESHOLD = 4 << 20
#: Free memory at the top of the heap above this is returned to the system (default 128 KiB).
TRIM_THRESHOLD = 32 << 20

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # mallopt's parameter numbers in glibc's malloc.h


def tune() -> bool:
    """Apply the thresholds above if the C library is glibc; True if they were applied."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        if not hasattr(libc, "gnu_get_libc_version"):  # musl and others: leave their allocator alone
            return False
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
