"""Kernel throughput of every method at one condition number, as ratios to `lapack` in the same run.

    python benchmarks/kernels.py [rows] [cond]

Only the method's own arithmetic, in blocks as `hconv.convert` runs it (`hconv.bench.kernel_rates`),
on rotated bodies whose cond(I) is exactly ``cond``: the way to see how `refined` slows with cond.
"""
import sys

import numpy as np

from hconv import allocator, bench
from hconv.inertia import Sym3
from hconv.scene import random_rotations, rotate_tensors

allocator.tune()  # as the hconv command does
n = int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000
cond = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
rng = np.random.default_rng(0)
moments = np.stack([np.ones(n), 10 ** (-np.log10(cond) * rng.random(n)), np.full(n, 1 / cond)], axis=1)
M = rotate_tensors(random_rotations(rng, n), moments)
I = Sym3(*(np.ascontiguousarray(M[:, i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))))
H = np.ascontiguousarray(rng.normal(size=(3, n)))
rates = bench.kernel_rates(I, H, np.ascontiguousarray(rng.normal(size=(3, n))), repeats=5)
base = rates["lapack/64"]
print(f"{n:,} rows, cond {cond:g}; lapack kernel {base / 1e6:.2f} M rows/s")
for key, v in rates.items():
    print(f"{key:22s} {v / 1e6:8.2f} M rows/s  {v / base:6.2f}x lapack")
