"""`hconv stability`: its exact reference, its sweeps, and the real command writing real charts."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import EPS, hconv_inprocess, mp_solve, physical_bodies, rel_err, spd_bodies

import hconv
from hconv.tools import stability


def test_exact_solve_matches_mpmath(rng):
    I = np.concatenate([physical_bodies(rng, 20), spd_bodies(rng, 20, 1e12), spd_bodies(rng, 10, 1e3) * 1e-180])
    H = rng.normal(size=(50, 3))
    assert rel_err(stability.exact_solve(I, H), mp_solve(I, H)).max() <= EPS


def test_exact_solve_singular_is_nan():
    assert np.isnan(stability.exact_solve(np.diag([0.0, 1, 1])[None], np.ones((1, 3)))).all()


@pytest.fixture(scope="module")
def points():
    return stability.run(rows=8, seed=1)


def test_stability_run_covers_every_sweep_method_and_precision(points):
    want = sum(len(s.params) for s in stability.SWEEPS) * len(hconv.METHODS) * 2
    assert len(points) == want
    assert {p.sweep for p in points} == {s.name for s in stability.SWEEPS}


def test_stability_run_refined_at_rounding_through_cond_1e12(points):
    refined = [
        p for p in points if p.sweep == "cond" and p.method == "refined" and p.precision == 64 and p.param <= 1e12
    ]
    assert len(refined) == 13
    assert max(p.worst_error for p in refined) <= 2 * EPS


def test_stability_run_document_methods_far_from_exact_everywhere(points):
    doc = [p for p in points if p.method.startswith("document") and np.isfinite(p.worst_error)]
    assert min(p.worst_error for p in doc) > 1e-2


def test_stability_run_float32_flags_past_its_digits(points):
    f32 = [p for p in points if p.sweep == "cond" and p.method == "exact" and p.precision == 32 and p.param >= 1e3]
    assert all(p.flagged == 1.0 for p in f32)


def test_stability_command_writes_png_and_tables(tmp_path, capsys):
    out = tmp_path / "stab.png"
    proc = hconv_inprocess("stability", "--rows", "4", "--out", str(out), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 50_000
    text = proc.stdout.decode()
    for s in stability.SWEEPS:
        assert s.title in text


def test_stability_command_svg_and_json(tmp_path, capsys):
    out = tmp_path / "stab.svg"
    proc = hconv_inprocess("stability", "--rows", "4", "--out", str(out), "--json", capsys=capsys)
    assert proc.returncode == 0
    assert out.read_text().lstrip().startswith("<?xml")
    rows = json.loads(proc.stdout)
    assert {"sweep", "param", "method", "precision", "median_error", "worst_error", "flagged"} <= set(rows[0])


def test_stability_command_rejects_other_chart_formats(tmp_path, capsys):
    proc = hconv_inprocess("stability", "--out", str(tmp_path / "stab.jpg"), capsys=capsys)
    assert proc.returncode == 2 and "name the chart .png or .svg" in proc.stderr.decode()
