"""Issue 27's file target: ``hconv convert`` of a Parquet file, whole process, against pyarrow
reading the same input and writing hconv's output with hconv's settings, in one run.

    python benchmarks/file_target.py [rows] [rounds]

The baseline is the I/O a conversion cannot avoid: a fresh Python that imports pyarrow, reads
IN and writes the table hconv wrote with ``hconv.parquet_write_options`` (it reads that table
from hconv's OUT first, and that read is taken off its time). Both are whole processes, timed
in interleaved rounds (every run once per round, so that a shared machine's drift falls on
both); the ratio is of the fastest of each, the round least disturbed by other jobs. Prints
hconv's time over the baseline's (target: at most 1.25) for the compiled engine and for the
numpy reference.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

_BASELINE = """
import sys, time, pyarrow.parquet as pq
import hconv
src, like, dst = sys.argv[1:4]
t = pq.read_table(src)
t0 = time.perf_counter()
out = pq.read_table(like)  # hconv's output, to write: reading it is not the baseline's, and is taken off
print(time.perf_counter() - t0)
pq.write_table(out, dst, **hconv.parquet_write_options(out.schema))
"""


def _run(cmd: list[str]) -> float:
    """The run's wall time, less what it prints it spent on other work (the baseline's read of
    the output it writes)."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True)
    return time.perf_counter() - t0 - (float(proc.stdout) if proc.stdout.strip() else 0.0)


def main() -> None:
    rows = int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    hconv_cmd = [sys.executable, "-m", "hconv"]
    with tempfile.TemporaryDirectory(prefix="hconv-file-target-") as d:
        src, dst, again = Path(d, "in.parquet"), Path(d, "out.parquet"), Path(d, "again.parquet")
        subprocess.run([*hconv_cmd, "generate", str(src), "--rows", str(rows), "-q"], check=True)
        runs = {
            "hconv convert (compiled)": [*hconv_cmd, "convert", str(src), str(dst), "--force", "-q"],
            "hconv convert (numpy)": [*hconv_cmd, "convert", str(src), str(dst), "--force", "-q", "--engine", "numpy"],
        }
        subprocess.run(runs["hconv convert (compiled)"], check=True)
        runs["pyarrow read + write"] = [sys.executable, "-c", _BASELINE, str(src), str(dst), str(again)]
        best = {name: float("inf") for name in runs}
        for _ in range(rounds):
            for name, cmd in runs.items():
                best[name] = min(best[name], _run(cmd))
    base = best["pyarrow read + write"]
    print(f"{rows:,} rows, fastest of {rounds} rounds, whole processes")
    for name, t in best.items():
        ratio = "" if t is base else f"   {t / base:.2f}× the baseline (target ≤ 1.25)"
        print(f"{name:<26} {t:6.2f} s{ratio}")


if __name__ == "__main__":
    main()
