"""A seeded kill -9 sweep over a dataset run of many small files (issue 28): the same ``hconv
convert IN OUT`` is killed outright at random moments, run again each time, and at the end let
finish. After every kill, each output the manifest lists must be there with the bytes of a
clean run's; at the end, every output must be the clean run's, byte for byte, and the manifest
complete.

    python benchmarks/kill_sweep.py                       # 4,000 files, 6 kills, seed 1
    python benchmarks/kill_sweep.py --files 400 --kills 3 # a quick look

Prints each kill's moment and what the manifest then listed, and exits 1 on any violation.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from hconv.tools import leftovers
from hconv.tools.scene import make_scene

MANIFEST = "_hconv_manifest.json"


def write_dataset(root: Path, files: int, rows: int) -> None:
    table = pa.table(make_scene(files * rows, seed=3, cond_max=1e6))
    for k in range(files):
        path = root / f"day={k % 4}" / f"part-{k:05d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table.slice(k * rows, rows), path)


def digests(out: Path) -> dict[str, str]:
    return {
        p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in out.rglob("*")
        if p.is_file() and p.name != MANIFEST and not p.name.endswith(".hconv-tmp")
    }


def command(src: Path, dst: Path) -> list[str]:
    return [sys.executable, "-m", "hconv", "convert", str(src), str(dst), "-q"]


def check_listed(out: Path, reference: dict[str, str]) -> tuple[int, list[str]]:
    """(files the manifest lists, violations): a listed output missing, of another size, or not
    the clean run's bytes."""
    if not (out / MANIFEST).exists():
        return 0, []
    m = json.loads((out / MANIFEST).read_text())
    bad = []
    for f in m["files"]:
        path = out / f["output"]
        if not path.exists():
            bad.append(f"{f['output']}: listed, missing")
        elif path.stat().st_size != f["output_size"]:
            bad.append(f"{f['output']}: listed, size {path.stat().st_size} != {f['output_size']}")
        elif hashlib.sha256(path.read_bytes()).hexdigest() != reference[f["output"]]:
            bad.append(f"{f['output']}: listed, bytes differ from the clean run's")
    return len(m["files"]), bad


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", type=int, default=4000)
    ap.add_argument("--rows", type=int, default=100, help="rows per file")
    ap.add_argument("--kills", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dir", default=None, help="where to write the datasets (default: a temporary directory)")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    leftovers.remove_stale_folders(print, a.dir)
    work = Path(tempfile.mkdtemp(prefix=leftovers.folder_prefix("kill-sweep-"), dir=a.dir))
    violations: list[str] = []
    try:
        src = work / "data"
        write_dataset(src, a.files, a.rows)
        t0 = time.perf_counter()
        subprocess.run(command(src, work / "clean"), check=True)
        clean = time.perf_counter() - t0
        reference = digests(work / "clean")
        print(f"{a.files} files of {a.rows} rows; clean run {clean:.1f} s; seed {a.seed}, {a.kills} kills")
        out = work / "out"
        for k in range(a.kills):
            # a moment within the run still to go: the earlier kills left less to convert
            delay = rng.uniform(0.05, 1.0) * clean * (a.kills - k) / a.kills
            proc = subprocess.Popen(command(src, out), stderr=subprocess.PIPE)
            time.sleep(delay)
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            listed, bad = check_listed(out, reference)
            violations += [f"kill {k + 1}: {b}" for b in bad]
            print(f"  kill {k + 1} at {delay:5.2f} s: manifest lists {listed} files; {len(bad)} violations")
        proc = subprocess.run(command(src, out), stderr=subprocess.PIPE)
        err = proc.stderr.decode()
        if proc.returncode != 0:
            violations.append(f"the last run exited {proc.returncode}: {err}")
        m = json.loads((out / MANIFEST).read_text())
        got = digests(out)
        if not m["complete"] or len(m["files"]) != a.files:
            violations.append(f"manifest: complete {m['complete']}, {len(m['files'])} of {a.files} files")
        if got != reference:
            differ = sorted(k for k in reference.keys() | got.keys() if got.get(k) != reference.get(k))
            violations.append(f"{len(differ)} outputs differ from the clean run's, e.g. {differ[:3]}")
        temps = [str(p) for p in out.rglob("*.hconv-tmp")]
        removed = err.count("removed stale temporary file")
        print(
            f"  rerun to the end: exit {proc.returncode}; {len(got)} outputs, "
            f"{'identical to' if got == reference else 'NOT identical to'} the clean run's; manifest complete: "
            f"{m['complete']}; stale temporary files removed {removed}, left {len(temps)}"
        )
        if temps:
            violations.append(f"{len(temps)} temporary files left, e.g. {temps[:2]}")
    finally:
        shutil.rmtree(work)
    for v in violations:
        print("VIOLATION:", v)
    print("kill sweep:", "passed" if not violations else f"FAILED ({len(violations)} violations)")
    sys.exit(1 if violations else 0)


if __name__ == "__main__":
    main()
