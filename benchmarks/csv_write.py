"""hconv's CSV writer against pyarrow's own, on the same converted table: bytes per second of
each, and their ratio (above 1: hconv's is faster), measured in the same run.

    python benchmarks/csv_write.py [rows] [--quoted] [--repeats N]   # default 2,000,000 rows, 5 repeats

Both format with pyarrow's formatting, pyarrow's writer on one thread, hconv's on every core (a
block's pieces on threads, hconv.tables.csvwrite): the wall-clock ratio is what the other cores
bring, the CPU ratio what cutting the rows into pieces and quoting only the values that need it
cost. On a machine whose other cores are busy, the wall-clock ratio falls to the CPU one.

The table is what `hconv convert` writes for a CSV of H, a sym6 inertia and a text column read
as text: the input's columns, ω, residual, cond and status (dictionary), and `w_unit`. Each
writer writes it N times (``--repeats``, 5 by default), interleaved with the other's, in blocks
of the pipeline's size, to a file in a temporary folder, and the fastest of its writes counts
(wall-clock and CPU time apart); pyarrow's writer is given the same table with `status` as text
and its own default quoting. ``--quoted`` adds a table where one id in 100 holds a comma, so
that its value needs quotes (the other path of hconv's writer).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv

import hconv
from hconv.solve import engines
from hconv.tables.csvwrite import CsvWriter
from hconv.tools import leftovers
from hconv.tools.scene import make_scene

BLOCK_ROWS = 50_000  # about a 4 MiB CSV block's rows, as the pipeline hands them to the writer


def converted(n: int, quoted: bool) -> pa.Table:
    """``quoted``: one id in 100 holds a comma, so that its value needs quotes."""
    cols = make_scene(n, seed=1)
    names = ("Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
    ids = [f"body-{k:07d}" + (", spare" if quoted and k % 100 == 0 else "") for k in range(n)]
    return hconv.convert_table(pa.table({"id": pa.array(ids)} | {c: cols[c] for c in names}))


def timed(write) -> tuple[float, float]:
    """Wall-clock and CPU seconds (all threads) of ``write()``."""
    t0, c0 = time.perf_counter(), time.process_time()
    write()
    return time.perf_counter() - t0, time.process_time() - c0


def ratio(n: int, quoted: bool, repeats: int) -> None:
    table = converted(n, quoted)
    blocks = table.to_batches(BLOCK_ROWS)
    with leftovers.temporary_folder("csv-write-") as work:
        ours, theirs = Path(work) / "hconv.csv", Path(work) / "pyarrow.csv"

        def hconv_writes() -> None:
            w = CsvWriter(str(ours), table.schema)
            for b in blocks:
                w.write(pa.Table.from_batches([b]))
            w.close()

        plain = table.set_column(table.schema.get_field_index("status"), "status", table["status"].cast(pa.string()))
        plain_blocks = plain.to_batches(BLOCK_ROWS)

        def pyarrow_writes() -> None:
            with pacsv.CSVWriter(str(theirs), plain.schema) as w:
                for b in plain_blocks:
                    w.write_batch(b)

        # interleaved, the fastest of each: on a shared machine one write can be slowed by others
        runs_ours, runs_theirs = [], []
        for _ in range(repeats):
            runs_ours.append(timed(hconv_writes))
            runs_theirs.append(timed(pyarrow_writes))
        b_ours, b_theirs = os.path.getsize(ours), os.path.getsize(theirs)
    (wall_ours, cpu_ours), (wall_theirs, cpu_theirs) = (tuple(map(min, zip(*r))) for r in (runs_ours, runs_theirs))
    what = "1 id in 100 needs quotes" if quoted else "no value needs quotes"
    print(
        f"{n:,} rows, {what}: hconv {b_ours / 1e6:.0f} MB in {wall_ours:.2f} s ({cpu_ours:.2f} s CPU), "
        f"pyarrow {b_theirs / 1e6:.0f} MB in {wall_theirs:.2f} s ({cpu_theirs:.2f} s CPU); per byte, hconv's "
        f"speed over pyarrow's: {b_ours / wall_ours / (b_theirs / wall_theirs):.2f} wall-clock, "
        f"{b_ours / cpu_ours / (b_theirs / cpu_theirs):.2f} CPU"
    )


def main() -> None:
    args = sys.argv[1:]
    repeats = int(args.pop(args.index("--repeats") + 1)) if "--repeats" in args else 5
    counts = [a for a in args if a.isdigit()]
    n = int(counts[0]) if counts else 2_000_000
    print(f"{engines.available_cores()} cores available")
    leftovers.remove_stale_folders(print)
    for quoted in (False, True) if "--quoted" in sys.argv else (False,):
        ratio(n, quoted, repeats)


if __name__ == "__main__":
    main()
