"""Kernel throughput of every method at one condition number, as ratios to `lapack` in the same run.

    python benchmarks/kernels.py [rows] [cond]

Only the method's own arithmetic, in blocks as `hconv.convert` runs it (`hconv.tools.bench.kernel_rates`),
on rotated bodies whose cond(I) is exactly ``cond`` (`hconv.tools.bench.cond_bodies`): the way to see how
`refined` slows with cond. `hconv bench` measures refined against lapack at a few cond itself.
"""

import sys

import numpy as np

from hconv.kernels import allocator
from hconv.tools import bench

allocator.tune()  # as the hconv command does
n = int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000
cond = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
I, H = bench.cond_bodies(np.random.default_rng(0), n, cond)
rates = bench.kernel_rates(I, H, np.ascontiguousarray(np.random.default_rng(1).normal(size=(3, n))), repeats=5)
base = rates["lapack/64"]
print(f"{n:,} rows, cond {cond:g}; lapack kernel {base / 1e6:.2f} M rows/s")
for key, v in rates.items():
    print(f"{key:22s} {v / 1e6:8.2f} M rows/s  {v / base:6.2f}x lapack")
