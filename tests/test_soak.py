"""The soak test of benchmarks/soak.py, scaled down for CI (the full 50M-row run is by hand)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

SOAK = Path(__file__).resolve().parent.parent / "benchmarks" / "soak.py"


def test_soak_scaled_down_keeps_every_row_in_bounded_memory(tmp_path):
    spec = importlib.util.spec_from_file_location("soak", SOAK)
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    r = soak.soak(300_000, tmp_path, sample=500)
    assert r["rows_out"] == 300_000 and r["in_order"]
    assert r["statuses"] == {"ok": 300_000}
    assert r["sampled"] == 500 and r["worst_vs_true_omega"] < 1e-9 and r["worst_vs_numpy_solve"] < 1e-9
    assert 0 < r["convert_peak_rss_mb"] <= soak.RSS_LIMIT_MB
