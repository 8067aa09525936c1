"""What converting a dataset file by file costs: the same rows as one file, as 40 files and as
400, with ``hconv convert``; and on object storage through a local S3-compatible server (moto's
server mode, the ``test-s3`` extra), if installed.

    python benchmarks/datasets.py --rows 2000000 --s3-rows 400000 --repeats 3
    python benchmarks/datasets.py --small-files            # issue 28's targets, one run each
    python benchmarks/datasets.py --small-files --profile  # and where a small file's time goes

``--small-files`` ends with a floor: pyarrow alone reading and writing each of the small files
(hconv's settings, nothing converted), on one thread and on one per core, with a start-up; what
any design writing one output per input with pyarrow costs at least.

``--small-files`` converts the same 2M rows as one Parquet file, as 40 files of 50k rows and as
4,000 files of 500 rows, and the 4,000 files again with ``--cluster local --workers 2``; one run
each, and prints each ratio against its target (wall times of the real command). ``--scale``
shrinks the rows (and the files' count with them) for a quick look; the targets are measured at
``--scale 1``.

Each figure is the median of ``--repeats`` runs of the real command, in a fresh process: the wall
time (with the command's start, about half a second) and the time the summary reports (from the
plan to the manifest). Per-file overhead is the difference in reported time between 400 files
and 1, over the 399 files more. docs/measurements.md keeps the figures.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from hconv.tools import leftovers
from hconv.tools.scene import make_scene

S3_ENV = {
    "AWS_ACCESS_KEY_ID": "bench",
    "AWS_SECRET_ACCESS_KEY": "bench",
    "AWS_DEFAULT_REGION": "us-east-1",
    "AWS_EC2_METADATA_DISABLED": "true",
}


def write_dataset(root: Path, rows: int, files: int) -> None:
    """``files`` Parquet files of ``rows // files`` rows each, in 4 hive partitions."""
    each = rows // files
    table = pa.table(make_scene(each * files, seed=1, cond_max=1e6))
    for k in range(files):
        path = root / f"day={k % 4}" / f"part-{k:04d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table.slice(k * each, each), path)


def run(args: list[str], env: dict | None = None) -> tuple[float, float]:
    """(wall seconds, the seconds the summary reports) for one ``hconv convert``."""
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "hconv", "convert", *args, "--force"],
        capture_output=True,
        env=dict(os.environ, **(env or {})),
    )
    wall = time.perf_counter() - t0
    err = proc.stderr.decode()
    if proc.returncode != 0:
        raise SystemExit(f"hconv convert {' '.join(args)} failed:\n{err}")
    return wall, float(re.search(r"time ([0-9.]+) s", err).group(1))


def median_of(repeats: int, args: list[str], env: dict | None = None) -> tuple[float, float]:
    runs = [run(args, env) for _ in range(repeats)]
    return statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)


def local(work: Path, rows: int, repeats: int) -> None:
    one = work / "one.parquet"
    pq.write_table(pa.table(make_scene(rows, seed=1, cond_max=1e6)), one)
    results = {"1 file": median_of(repeats, [str(one), str(work / "one-out.parquet")])}
    for files in (40, 400):
        write_dataset(work / f"d{files}", rows, files)
        results[f"{files} files"] = median_of(repeats, [str(work / f"d{files}"), str(work / f"d{files}-out")])
    print(f"local, {rows:,} rows, median of {repeats}")
    base = results["1 file"][1]
    for name, (wall, reported) in results.items():
        print(
            f"  {name:>9}: wall {wall:6.2f} s, reported {reported:6.2f} s, {rows / reported:12,.0f} rows/s, "
            f"{reported / base:.2f}x the one file's time"
        )
    per_file = (results["400 files"][1] - base) / 399
    print(f"  per-file overhead: {per_file * 1e3:.1f} ms ((400 files - 1 file) / 399)")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def moto_server() -> Iterator[str | None]:
    """The URL of a local moto S3 server, its credentials in the environment; None without moto."""
    import importlib.util

    if importlib.util.find_spec("moto") is None:
        print("s3: skipped (pip install -e '.[test-s3]')")
        yield None
        return
    port = free_port()
    server = subprocess.Popen(
        [sys.executable, "-m", "moto.server", "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        for _ in range(300):
            try:
                urllib.request.urlopen(url + "/", timeout=1).close()
                break
            except OSError:
                time.sleep(0.1)
        os.environ.update(S3_ENV)
        yield url
    finally:
        server.terminate()
        server.wait(timeout=10)


def s3(work: Path, rows: int, repeats: int) -> None:
    import pyarrow.fs as pafs

    with moto_server() as url:
        if url is None:
            return
        fs = pafs.S3FileSystem(endpoint_override=url, allow_bucket_creation=True)
        fs.create_dir("bench")
        data = work / "s3-data"
        write_dataset(data, rows, 40)
        pafs.copy_files(str(data), "bench/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs)
        env = dict(S3_ENV, AWS_ENDPOINT_URL=url)
        cases = {
            "local -> local": [str(data), str(work / "s3-local-out")],
            "s3 -> local": ["s3://bench/raw/", str(work / "s3-in-out")],
            "local -> s3": [str(data), "s3://bench/from-local/"],
            "s3 -> s3": ["s3://bench/raw/", "s3://bench/conv/"],
        }
        print(f"moto S3 server (one Python process on this machine), 40 files, {rows:,} rows, median of {repeats}")
        base = None
        for name, args in cases.items():
            wall, reported = median_of(repeats, args, env)
            base = base or reported
            print(
                f"  {name:>14}: wall {wall:6.2f} s, reported {reported:6.2f} s, {rows / reported:12,.0f} rows/s, "
                f"{reported / base:.2f}x local"
            )


#: issue 28's targets: (what, against what, the most its wall time may be, as a ratio)
SMALL_TARGETS = (
    ("40 files", "1 file", 1.1),
    ("4000 files", "1 file", 2.0),
    ("4000 files, --cluster local --workers 2", "4000 files", 1.3),
)


def small_files(work: Path, scale: float, profile: bool) -> None:
    """The same rows as one file, as 40 files and as 4,000 (and those on a local cluster of 2
    workers): one run each, each ratio against its target."""
    rows = int(2_000_000 * scale)
    shapes = {"1 file": 1, "40 files": 40, "4000 files": max(1, int(4000 * scale))}
    t0 = time.perf_counter()
    one = work / "one.parquet"
    pq.write_table(pa.table(make_scene(rows, seed=1, cond_max=1e6)), one)
    for files in shapes.values():
        if files > 1:
            write_dataset(work / f"s{files}", rows, files)
    if scale != 1:
        print(f"scaled by {scale}: '4000 files' is {shapes['4000 files']} files; the targets hold at --scale 1")
    print(f"small files: {rows:,} rows; datasets written in {time.perf_counter() - t0:.1f} s; one run each, wall time")
    walls = {}
    for name, files in shapes.items():
        src = str(one) if files == 1 else str(work / f"s{files}")
        walls[name], reported = run([src, str(work / (f"out-{files}" + (".parquet" if files == 1 else "")))])
        print(f"  {name:>40}: wall {walls[name]:6.2f} s, reported {reported:6.2f} s")
    files = shapes["4000 files"]
    name = "4000 files, --cluster local --workers 2"
    walls[name], reported = run(
        [str(work / f"s{files}"), str(work / "out-cluster"), "--cluster", "local", "--workers", "2"]
    )
    print(f"  {name:>40}: wall {walls[name]:6.2f} s, reported {reported:6.2f} s")
    for what, against, target in SMALL_TARGETS:
        ratio = walls[what] / walls[against]
        print(f"  {what} / {against}: {ratio:.2f}x (target <= {target}x: {'met' if ratio <= target else 'NOT met'})")
    floor(work / f"s{files}", work / "out-floor", walls["1 file"])
    if profile:
        profile_small(work / f"s{files}", work / "out-profile")
    model(work / f"s{files}", one)


def _floor_copy(path: Path, out: Path) -> None:
    """One small file as the floor converts it (see :func:`floor`): the quickest pyarrow ways
    measured, its bytes read at once and decoded on this thread, the output made in memory and
    written with one call."""
    from hconv.tables.parquetio import parquet_write_options

    t = pq.ParquetFile(pa.BufferReader(path.read_bytes())).read(use_threads=False)
    n = t.num_rows
    for name in ("wx", "wy", "wz", "residual", "cond"):
        t = t.append_column(name, pa.array(np.zeros(n)))
    t = t.append_column("status", pa.array(["ok"] * n).dictionary_encode())
    sink = pa.BufferOutputStream()
    pq.write_table(t, sink, **parquet_write_options(t.schema))
    tmp = out / (path.name + ".tmp")
    tmp.write_bytes(sink.getvalue().to_pybytes())
    os.replace(tmp, out / path.name)


def floor(small: Path, out: Path, one_file: float) -> None:
    """The least the 4,000 files can cost with one output written per input by pyarrow: each
    file read whole, the six columns hconv appends added, written with hconv's Parquet settings
    to a temporary name and renamed, on one thread, on a pool of one thread per core and on a
    pool of one process per core (its start included), with nothing converted, checked or
    recorded; beside it a process's start-up (importing hconv's CLI). Their sum over the one
    file's wall time bounds the 4,000-file ratio from below."""
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
    from functools import partial

    out.mkdir(exist_ok=True)
    paths = sorted(small.rglob("*.parquet"))
    copy = partial(_floor_copy, out=out)
    cores = os.cpu_count() or 1
    t0 = time.perf_counter()
    for path in paths:
        copy(path)
    serial = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ThreadPoolExecutor(cores) as pool:
        list(pool.map(copy, paths))
    pooled = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ProcessPoolExecutor(cores) as procs:
        list(procs.map(copy, paths, chunksize=max(1, len(paths) // (8 * cores))))
    processes = time.perf_counter() - t0
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import hconv.cli"], check=True)
    start = time.perf_counter() - t0
    best = min(serial, pooled, processes)
    print(
        f"  floor, pyarrow alone on the {len(paths)} files: {serial / len(paths) * 1e3:.2f} ms a file on one thread, "
        f"{pooled:.2f} s on {cores} threads, {processes:.2f} s on {cores} processes; with a start-up of {start:.2f} s "
        f"that is {(best + start) / one_file:.2f}x the one file, the least the 4,000-file ratio can be"
    )
    shutil.rmtree(out, ignore_errors=True)


def model(small: Path, one: Path) -> None:
    """The scaling model's inputs (docs/scaling.md): the driver's cost per file (listing and
    planning; the manifest's rewrite), a worker's rows per second on one thread, and Dask's own
    cost per task on a local cluster of 2 workers."""
    import distributed

    from hconv.tables import manifest, pipeline, planning
    from hconv.tables.job import Job

    t0 = time.perf_counter()
    plan = planning.plan_dataset(str(small), str(small) + "-model-out", job=Job())
    listing = time.perf_counter() - t0
    n = len(plan.inputs)
    record = manifest.FileRecord(
        "a/b.parquet", "a/b.parquet", 1, 1, None, 1, 500, {"ok": 500}, 1e-12, 3, {"numpy": 500}, 0.1
    )
    records = {f.rel: dataclasses.replace(record, input=f.rel, output=f.rel) for f in plan.inputs}
    t0 = time.perf_counter()
    manifest.write_manifest(plan, records, {}, set(records), t0)
    rewrite = time.perf_counter() - t0
    shutil.rmtree(str(small) + "-model-out", ignore_errors=True)
    part = one.parent / "model-400k.parquet"
    sliced = pq.read_table(one).slice(0, 400_000)
    pq.write_table(sliced, part)
    t0 = time.perf_counter()
    pipeline.convert_file(str(part), str(one.parent / "model-out.parquet"), threads=1, force=True)
    rate = sliced.num_rows / (time.perf_counter() - t0)
    with warnings.catch_warnings():  # "Port 8787 is already in use": no dashboard is wanted
        warnings.simplefilter("ignore", UserWarning)
        lc = distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=40)
    with lc, distributed.Client(lc) as client:
        client.gather(client.map(abs, range(200), pure=False))
        t0 = time.perf_counter()
        client.gather(client.map(abs, range(2000), pure=False))
        per_task = (time.perf_counter() - t0) / 2000
    print("scaling model inputs:")
    print(f"  driver: listing and planning {n} files {listing:.2f} s ({listing / n * 1e3:.2f} ms a file)")
    each = rewrite / n * 1e6
    print(f"  driver: the manifest rewritten with {n} records {rewrite * 1e3:.0f} ms ({each:.0f} µs a record)")
    print(f"  worker: {rate:,.0f} rows/s on one thread ({sliced.num_rows:,} rows, exact)")
    print(f"  Dask: {per_task * 1e3:.2f} ms a no-op task (2,000 tasks, local cluster of 2 workers)")


def profile_small(src: Path, dst: Path) -> None:
    """cProfile of convert_dataset over ``src`` in this process: the functions of most own time."""
    import cProfile
    import pstats

    import hconv

    hconv.convert_dataset(str(src), str(dst) + "-warm", force=True)  # imports and first-call costs
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    hconv.convert_dataset(str(src), str(dst), force=True)
    prof.disable()
    print(f"profile of convert_dataset over {src.name} (in this process): {time.perf_counter() - t0:.2f} s")
    pstats.Stats(prof).sort_stats("tottime").print_stats(25)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=2_000_000)
    ap.add_argument("--s3-rows", type=int, default=400_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", default=None, help="where to write the datasets (default: a temporary directory)")
    ap.add_argument("--small-files", action="store_true", help="issue 28's targets: 1, 40 and 4,000 files")
    ap.add_argument("--scale", type=float, default=1.0, help="--small-files: this share of the rows and files")
    ap.add_argument("--profile", action="store_true", help="--small-files: cProfile the 4,000 files in-process")
    a = ap.parse_args()
    leftovers.remove_stale_folders(print, a.dir)  # of runs of this or hconv bench killed outright
    work = Path(tempfile.mkdtemp(prefix=leftovers.folder_prefix("datasets-"), dir=a.dir))
    try:
        if a.small_files:
            small_files(work, a.scale, a.profile)
            return
        local(work, a.rows, a.repeats)
        s3(work, a.s3_rows, a.repeats)
    finally:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
