"""What ``hconv convert IN OUT --cluster ...`` gains and costs against the one-process
``hconv convert`` of the same dataset, on this machine: rows per second per worker with one and
two Dask workers, on local disk and through a local S3-compatible server (moto, the ``test-s3``
extra, if installed); the per-task overhead (many tiny files); Dask's own cost per task; and one
large file of many row groups, converted as one task and split into parts (``--task-rows``), with
what a part and the join cost in one process.

    python benchmarks/cluster.py --rows 2000000 --files 16 --s3-rows 400000
    python benchmarks/cluster.py --rows 2000000 --split-only --task-rows 524288

Each figure is one run of the real command in a fresh process (the figures are ratios within one
run): the time its summary reports, from the plan to the manifest, which for a cluster includes
connecting to it and checking its workers. The scheduler and the workers are started here as
processes (``dask scheduler``, ``dask worker --nthreads 1 --no-nanny``), each worker converting one
file at a time with ``--threads 1``; each cluster run is made twice, on fresh workers and on warm
ones. docs/scaling.md keeps the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from datasets import S3_ENV, free_port, moto_server, run, write_dataset

from hconv.tools import leftovers

SRC = str(Path(__file__).resolve().parents[1] / "src")


class Cluster:
    """A Dask scheduler and ``workers`` worker processes on this machine."""

    def __init__(self, workers: int, env: dict):
        import distributed

        self.address = f"tcp://127.0.0.1:{free_port()}"
        env = dict(os.environ, PYTHONPATH=SRC, **env)
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
        port = self.address.rsplit(":", 1)[1]
        self.procs = [
            subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", port]
                + ["--no-dashboard"],
                **quiet,
            )
        ]
        self.procs += [
            subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--nthreads", "1"]
                + ["--no-nanny", "--no-dashboard"],
                **quiet,
            )
            for _ in range(workers)
        ]
        with distributed.Client(self.address, timeout=30, set_as_default=False) as client:
            client.wait_for_workers(workers, timeout=60)

    def per_task_seconds(self, tasks: int) -> float:
        """Dask's own cost per task: ``tasks`` no-op tasks submitted and gathered, per task."""
        import distributed

        with distributed.Client(self.address, set_as_default=False) as client:
            client.gather(client.map(abs, range(100), pure=False))  # warm the connections
            t0 = time.perf_counter()
            client.gather(client.map(abs, range(tasks), pure=False))
            return (time.perf_counter() - t0) / tasks

    def close(self) -> None:
        for p in self.procs[::-1]:
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def line(name: str, rows: int, reported: float, base: float, workers: int = 1) -> None:
    rate = rows / reported
    print(
        f"  {name:>46}: {reported:7.2f} s, {rate:10,.0f} rows/s, {rate / workers:10,.0f} per worker, "
        f"{base / reported:.2f}x the one-process speed"
    )


def compare(work: Path, src: str, dst: str, rows: int, env: dict | None = None, tasks: bool = False) -> None:
    """The one-process run of ``src``, then on one and two workers; each into a fresh ``dst``."""
    k = iter(range(100))

    def out() -> str:
        return f"{dst}-{next(k)}" if "://" in dst else str(work / f"{dst}-{next(k)}")

    _, base = run([src, out()], env)
    line("hconv convert (default threads)", rows, base, base)
    _, one_thread = run([src, out(), "--threads", "1"], env)
    line("hconv convert --threads 1", rows, one_thread, base)
    for workers in (1, 2):
        cluster = Cluster(workers, env or {})
        try:
            # the first run meets fresh workers, which pay their first file's start-up once
            name = f"--cluster tcp:// ({workers} worker{'s' if workers > 1 else ''})"
            for when in ("fresh workers", "warm workers"):
                _, reported = run([src, out(), "--cluster", cluster.address, "--threads", "1"], env)
                line(f"{name}, {when}", rows, reported, base, workers)
            if tasks and workers == 2:
                per_task = cluster.per_task_seconds(10_000)
                print(f"  Dask's own cost per task (10,000 no-op tasks): {per_task * 1e6:.0f} µs")
        finally:
            cluster.close()


def split(work: Path, rows: int, task_rows: int) -> None:
    """One file of ``rows`` rows in 16 row groups: in one process, the whole file, its parts one
    by one and their join; on 1 and 2 workers (warm), as one task and split into parts."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from hconv.tables import parquetio, parts, pipeline, planning, storage
    from hconv.tools.scene import make_scene

    big = work / "split" / "big.parquet"
    big.parent.mkdir(parents=True)
    pq.write_table(pa.table(make_scene(rows, seed=1, cond_max=1e6)), big, row_group_size=-(-rows // 16))
    task = planning.Task(
        storage.Listed("big.parquet", big.stat().st_size, None), "big.parquet", "parquet", "parquet", False
    )
    parts = parts.split(task, storage.place(str(big.parent)), task_rows, "0")
    print(f"one file of {rows:,} rows in 16 row groups; --task-rows {task_rows}: {len(parts)} parts")
    t0 = time.perf_counter()
    pipeline.convert_file(str(big), str(work / "whole.parquet"), threads=1, force=True)
    whole = time.perf_counter() - t0
    paths, each = [], []
    for p in parts:
        paths.append(str(work / f"part-{p.k}.parquet"))
        t0 = time.perf_counter()
        pipeline.convert_file(str(big), paths[-1], threads=1, force=True, rows=(p.start, p.stop))
        each.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    parquetio.join_parquet(paths, str(work / "joined.parquet"))
    join = time.perf_counter() - t0
    same = (work / "joined.parquet").read_bytes() == (work / "whole.parquet").read_bytes()
    print(
        f"  one process, --threads 1: whole {whole:.2f} s; parts {sum(each):.2f} s in all "
        f"({sum(each) / whole:.2f}x the whole), {max(each):.2f} s the longest; join {join:.2f} s "
        f"({join / whole:.2f}x the whole); joined file {'==' if same else '!='} whole file, byte for byte"
    )
    _, base = run([str(big.parent), str(work / "split-base")])
    line("hconv convert (default threads)", rows, base, base)
    for workers in (1, 2):
        cluster = Cluster(workers, {})
        try:
            run([str(big.parent), str(work / f"warm-{workers}"), "--cluster", cluster.address, "--task-rows", "0"])
            name = f"({workers} worker{'s' if workers > 1 else ''})"
            for how, n in (("one task", 0), (f"{len(parts)} parts", task_rows)):
                dst = str(work / f"split-{workers}-{n}")
                _, reported = run(
                    [str(big.parent), dst, "--cluster", cluster.address, "--threads", "1", "--task-rows", str(n)]
                )
                line(f"--cluster tcp:// {name}, {how}", rows, reported, base, workers)
        finally:
            cluster.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=2_000_000)
    ap.add_argument("--files", type=int, default=16)
    ap.add_argument("--tiny-files", type=int, default=400)
    ap.add_argument("--s3-rows", type=int, default=400_000)
    ap.add_argument("--task-rows", type=int, default=524_288, help="parts' size for the large file's split")
    ap.add_argument("--split-only", action="store_true", help="only the large file, whole and split")
    ap.add_argument("--dir", default=None, help="where to write the datasets (default: a temporary directory)")
    a = ap.parse_args()
    leftovers.remove_stale_folders(print, a.dir)  # of runs of this or hconv bench killed outright
    work = Path(tempfile.mkdtemp(prefix=leftovers.folder_prefix("cluster-"), dir=a.dir))
    print(f"this machine: {os.cpu_count()} cores; each figure is one run")
    try:
        split(work, a.rows, a.task_rows)
        if a.split_only:
            return
        print(f"local disk, {a.rows:,} rows in {a.files} files")
        write_dataset(work / "data", a.rows, a.files)
        compare(work, str(work / "data"), "out", a.rows, tasks=True)

        print(f"local disk, one file of {a.rows:,} rows (one task)")
        write_dataset(work / "big", a.rows, 1)
        compare(work, str(work / "big"), "big-out", a.rows)

        tiny_rows = a.tiny_files * 10
        print(f"per-task overhead: {a.tiny_files} files of 10 rows")
        write_dataset(work / "tiny", tiny_rows, a.tiny_files)
        _, base = run([str(work / "tiny"), str(work / "tiny-one"), "--threads", "1"])
        cluster = Cluster(2, {})
        try:
            _, reported = run([str(work / "tiny"), str(work / "tiny-2"), "--cluster", cluster.address])
        finally:
            cluster.close()
        print(
            f"  one process: {base / a.tiny_files * 1e3:.1f} ms per file; 2 workers: "
            f"{reported / a.tiny_files * 1e3:.1f} ms per file of wall time ({reported * 2 / a.tiny_files * 1e3:.1f} "
            "ms of worker time)"
        )
        s3(work, a.s3_rows, a.files)
    finally:
        shutil.rmtree(work)


def s3(work: Path, rows: int, files: int) -> None:
    import pyarrow.fs as pafs

    with moto_server() as url:
        if url is None:
            return
        fs = pafs.S3FileSystem(endpoint_override=url, allow_bucket_creation=True)
        fs.create_dir("bench")
        write_dataset(work / "s3-data", rows, files)
        pafs.copy_files(
            str(work / "s3-data"), "bench/raw", source_filesystem=pafs.LocalFileSystem(), destination_filesystem=fs
        )
        print(f"moto S3 server (one Python process on this machine), s3:// in and out, {rows:,} rows in {files} files")
        compare(work, "s3://bench/raw/", "s3://bench/conv", rows, env=dict(S3_ENV, AWS_ENDPOINT_URL=url))


if __name__ == "__main__":
    main()
