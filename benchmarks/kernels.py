"""Kernel throughput of every method, as ratios to the `lapack` kernel measured in the same run.

    python benchmarks/kernels.py [rows] [cond]

Only the method's own arithmetic, in 16k-row blocks as `hconv.convert` runs it: no statuses, no
diagnostics, no I/O. Median of 5 repeats, float64.
"""
import sys
import time

import numpy as np

from hconv import methods
from hconv.core import BLOCK_ROWS
from hconv.inertia import Sym3
from hconv.scene import random_rotations, rotate_tensors

n = int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000
cond = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
rng = np.random.default_rng(0)
moments = np.stack([np.ones(n), 10 ** (-np.log10(cond) * rng.random(n)), np.full(n, 1 / cond)], axis=1)
M = rotate_tensors(random_rotations(rng, n), moments)
I = Sym3(*(np.ascontiguousarray(c) for c in (M[:, 0, 0], M[:, 1, 1], M[:, 2, 2], M[:, 0, 1], M[:, 0, 2], M[:, 1, 2])))
H = np.ascontiguousarray(rng.normal(size=(3, n)))
r = np.ascontiguousarray(rng.normal(size=(3, n)))
blocks = [(I.take(slice(lo, lo + BLOCK_ROWS)), H[:, lo:lo + BLOCK_ROWS], r[:, lo:lo + BLOCK_ROWS])
          for lo in range(0, n, BLOCK_ROWS)]


def rate(kernel) -> float:
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        for b in blocks:
            kernel(*b)
        times.append(time.perf_counter() - t0)
    return n / float(np.median(times))


rates = {name: rate(m.kernel) for name, m in methods.METHODS.items()}
base = rates["lapack"]
print(f"{n:,} rows, cond {cond:g}; lapack kernel {base / 1e6:.2f} M rows/s")
for name, v in rates.items():
    print(f"{name:20s} {v / 1e6:8.2f} M rows/s  {v / base:6.2f}x lapack")
