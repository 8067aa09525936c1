"""Soak test: convert a big generated Parquet file with bounded memory and check what came out.

    python benchmarks/soak.py --rows 50000000 --dir /path/with/20GB/free

It generates the scene (hconv generate), converts it (hconv convert, a separate process whose peak
RSS is read from the kernel by a small wrapper process), then checks that every row came out, in order, and that
a random sample of rows agrees with the ω that generated them and with numpy's own solve. It is
not run in CI at full size; tests/test_soak.py runs it scaled down.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

RSS_LIMIT_MB = 400


# A small wrapper process whose only child is the command: the child's peak RSS then cannot
# include the memory of a big parent (ru_maxrss counts the pages a child shared before its exec).
_WRAPPER = (
    "import resource, subprocess, sys, time; t = time.perf_counter(); "
    "p = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE); "
    "print(p.returncode, time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
    "sys.stderr.write(p.stderr.decode(errors='replace'))"
)


def _run(args: list[str]) -> tuple[float, float]:
    """Run a command; returns (seconds, peak RSS in MB) of that process alone."""
    out = subprocess.run([sys.executable, "-c", _WRAPPER, *args], capture_output=True, text=True)
    code, seconds, kib = out.stdout.split()
    if int(code):
        raise SystemExit(f"soak: {' '.join(args[2:4])} failed with exit {code}: {out.stderr.strip()}")
    return float(seconds), int(kib) / 1024  # ru_maxrss is in KiB on Linux


def soak(rows: int, workdir: Path, sample: int = 2000, seed: int = 0) -> dict:
    src, dst = workdir / "soak-in.parquet", workdir / "soak-out.parquet"
    hconv = [sys.executable, "-m", "hconv"]
    gen_s, gen_mb = _run(hconv + ["generate", str(src), "--rows", str(rows), "--seed", str(seed), "--force"])
    conv_s, conv_mb = _run(hconv + ["convert", str(src), str(dst), "--force", "-q"])
    rng = np.random.default_rng(seed + 1)
    picks = np.sort(rng.choice(rows, size=min(sample, rows), replace=False)) if rows else np.array([], int)
    f = pq.ParquetFile(dst)
    n_out, last_id, in_order, worst_true, worst_numpy, statuses = 0, 0, True, 0.0, 0.0, {}
    cols = [
        "id",
        "Hx",
        "Hy",
        "Hz",
        "Ixx",
        "Iyy",
        "Izz",
        "Ixy",
        "Ixz",
        "Iyz",
        "w_true_x",
        "w_true_y",
        "w_true_z",
        "wx",
        "wy",
        "wz",
        "status",
    ]
    for batch in f.iter_batches(batch_size=1 << 20, columns=cols):
        ids = batch.column(0).to_numpy()
        in_order &= bool(ids.size == 0 or (ids[0] == last_id + 1 and np.all(np.diff(ids) == 1)))
        last_id = int(ids[-1]) if ids.size else last_id
        for s in batch.column(16).to_pylist():
            statuses[s] = statuses.get(s, 0) + 1
        sel = picks[(picks >= n_out) & (picks < n_out + batch.num_rows)] - n_out
        if sel.size:
            c = {name: batch.column(k).to_numpy(zero_copy_only=False)[sel] for k, name in enumerate(cols[:16])}
            I = np.empty((sel.size, 3, 3))
            I[:, 0, 0], I[:, 1, 1], I[:, 2, 2] = c["Ixx"], c["Iyy"], c["Izz"]
            I[:, 0, 1] = I[:, 1, 0] = c["Ixy"]
            I[:, 0, 2] = I[:, 2, 0] = c["Ixz"]
            I[:, 1, 2] = I[:, 2, 1] = c["Iyz"]
            H = np.column_stack([c["Hx"], c["Hy"], c["Hz"]])
            w = np.column_stack([c["wx"], c["wy"], c["wz"]])
            truth = np.column_stack([c["w_true_x"], c["w_true_y"], c["w_true_z"]])
            ref = np.linalg.solve(I, H[..., None])[..., 0]
            rel = lambda a, b: np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)  # noqa: E731
            worst_true = max(worst_true, float(rel(w, truth).max()))
            worst_numpy = max(worst_numpy, float(rel(w, ref).max()))
        n_out += batch.num_rows
    return {
        "rows_in": rows,
        "rows_out": n_out,
        "in_order": in_order,
        "statuses": statuses,
        "sampled": int(picks.size),
        "worst_vs_true_omega": worst_true,
        "worst_vs_numpy_solve": worst_numpy,
        "generate_seconds": round(gen_s, 2),
        "generate_peak_rss_mb": round(gen_mb, 1),
        "convert_seconds": round(conv_s, 2),
        "convert_peak_rss_mb": round(conv_mb, 1),
        "convert_rows_per_second": round(rows / conv_s) if conv_s > 0 else None,
        "input_mb": round(src.stat().st_size / 2**20, 1),
        "output_mb": round(dst.stat().st_size / 2**20, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=50_000_000)
    ap.add_argument("--dir", default=None, help="where the two files go (default: a temporary folder, removed after)")
    ap.add_argument("--sample", type=int, default=2000)
    ap.add_argument("--keep", action="store_true", help="keep the files")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(dir=a.dir) as tmp:
        report = soak(a.rows, Path(tmp), a.sample)
        if a.keep:
            for p in Path(tmp).iterdir():
                p.rename(Path(a.dir or ".") / p.name)
    print(json.dumps(report, indent=1))
    ok = (
        report["rows_out"] == report["rows_in"]
        and report["in_order"]
        and report["worst_vs_true_omega"] < 1e-9
        and report["convert_peak_rss_mb"] <= RSS_LIMIT_MB
    )
    print("soak: " + ("passed" if ok else "FAILED"), file=sys.stderr)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
