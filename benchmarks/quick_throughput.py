"""Rows per second of every method, in memory, as ratios to `lapack` measured in the same run.

    python benchmarks/quick_throughput.py [rows]

A quick check, not the full benchmark: median of 5 repeats, one process, float64.
"""

import sys
import time

import numpy as np

import hconv
from hconv.tools.scene import make_scene


def median_seconds(fn, repeats=5):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
cols = make_scene(n, seed=1)
H = np.column_stack([cols[c] for c in ("Hx", "Hy", "Hz")])
I = np.column_stack([cols[c] for c in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")])
r = np.column_stack([cols[c] for c in ("rx", "ry", "rz")])
rates = {}
for diag in (False, True):
    for name in hconv.METHODS:
        s = median_seconds(lambda name=name, diag=diag: hconv.convert(H, I, r, method=name, diagnostics=diag))
        rates[(name, diag)] = n / s
base = rates[("lapack", False)]
print(f"{n:,} rows; ratios to lapack without diagnostics ({base / 1e6:.2f} M rows/s)")
print(f"{'method':20s} {'no diagnostics':>15s} {'with diagnostics':>17s}")
for name in hconv.METHODS:
    print(f"{name:20s} {rates[(name, False)] / base:14.2f}x {rates[(name, True)] / base:16.2f}x")
