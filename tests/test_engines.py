"""Which engine converts: the auto rule, the environment override, the engines hconv no longer
has, and the promise that nothing is compiled or loaded at run time beyond the extension."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import hconv_inprocess

import hconv
from hconv.errors import UsageError
from hconv.solve import engines, methods

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def fresh(monkeypatch):
    """auto as a user gets it: no HCONV_ENGINE."""
    monkeypatch.delenv("HCONV_ENGINE", raising=False)


def _auto(n: int, **kw) -> str:
    args = {"method": "exact", "precision": 64, "degenerate": "error", "form": "sym6", **kw}
    m = methods.get(args["method"])
    return engines.resolve("auto", n, m, args["precision"], args["degenerate"], args["form"])


def test_resolve_auto_is_compiled_at_every_size(fresh):
    for n in (1, 100, 10**7):
        assert _auto(n) == "compiled"
        assert _auto(n, method="refined", form="full9") == "compiled"


def test_resolve_auto_runs_the_rest_on_numpy(fresh):
    assert _auto(1, method="eigen") == "numpy"
    assert _auto(1, precision=32) == "numpy"
    assert _auto(1, degenerate="pinv") == "numpy"
    assert _auto(1, form="principal") == "numpy"
    assert engines.resolve("compiled", 5, methods.get("lapack"), 64, "error", "sym6") == "numpy"
    assert engines.resolve("compiled", 5, methods.get("exact"), 64, "error", "sym6", degenerate_rtol=1e-9) == "numpy"


def test_resolve_environment_sets_what_auto_means(fresh, monkeypatch):
    monkeypatch.setenv("HCONV_ENGINE", "numpy")
    assert _auto(10**6) == "numpy"
    assert engines.resolve("compiled", 10, methods.get("exact"), 64, "error", "sym6") == "compiled"  # named wins
    monkeypatch.setenv("HCONV_ENGINE", "fortran")
    with pytest.raises(UsageError, match="HCONV_ENGINE must be one of auto, numpy, compiled, got 'fortran'"):
        _auto(10)


def test_convert_file_auto_runs_the_engine_a_library_call_runs(fresh, tmp_path, monkeypatch):
    """A file converts on the engine hconv.convert uses for the same rows, so that hconv convert
    and a DataFrame through convert_table give the same bits (docs/recipes.md's engines)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    monkeypatch.delenv("HCONV_ENGINE", raising=False)
    rng = np.random.default_rng(7)
    n = 500
    A = rng.normal(size=(n, 3, 3))
    I = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(3)
    H = rng.normal(size=(n, 3))
    cols = {"Hx": H[:, 0], "Hy": H[:, 1], "Hz": H[:, 2]}
    for name, (i, j) in zip(
        ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"), ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
    ):
        cols[name] = I[:, i, j]
    pq.write_table(pa.table(cols), tmp_path / "in.parquet")
    summary = hconv.convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "out.parquet"))
    assert summary.engines == {"compiled": n}
    table = hconv.convert_table(pa.table(cols))
    assert pq.read_table(tmp_path / "out.parquet").equals(table.replace_schema_metadata(None), check_metadata=False)


@pytest.mark.parametrize("gone", ["numba", "python"])
def test_check_engine_refuses_a_gone_engine_naming_compiled(gone, fresh):
    message = rf"^engine='{gone}' is gone: the compiled engine is built into hconv now; use engine='compiled'"
    with pytest.raises(UsageError, match=message):
        hconv.convert(np.ones(3), np.eye(3), engine=gone)
    with pytest.raises(UsageError, match=message):
        hconv.Job(engine=gone)
    with pytest.raises(UsageError, match="engine must be one of auto, numpy, compiled, got 'gpu'"):
        hconv.convert(np.ones(3), np.eye(3), engine="gpu")


@pytest.mark.parametrize("gone", ["numba", "python"])
def test_resolve_environment_refuses_a_gone_engine_naming_compiled(gone, fresh, monkeypatch):
    monkeypatch.setenv("HCONV_ENGINE", gone)
    message = rf"^HCONV_ENGINE={gone} is gone: .*; use HCONV_ENGINE=compiled \(or unset it for auto\)$"
    with pytest.raises(UsageError, match=message):
        hconv.convert(np.ones(3), np.eye(3))
    with pytest.raises(UsageError, match=message):
        hconv.convert(np.ones((5, 3)), np.tile(np.eye(3), (5, 1, 1)), method="refined")


def test_engines_command_lists_the_compiled_engine_and_compile_does_nothing(capsys, fresh):
    proc = hconv_inprocess("engines", "--compile", capsys=capsys)
    out = proc.stdout.decode()
    assert proc.returncode == 0, proc.stderr.decode()
    assert out.startswith("nothing to compile: the compiled engine is built when hconv is installed\n")
    assert "compiled" in out.splitlines()[1] and "numba" not in out


def test_convert_one_body_and_batches_are_the_compiled_engine(fresh):
    h, i = np.array([1.0, 2.0, 3.0]), np.array([[2.0, 0.1, 0.0], [0.1, 3.0, 0.2], [0.0, 0.2, 4.0]])
    one = hconv.convert(h, i)
    assert one.engine == "compiled" and one.status == "ok" and one.w.shape == (3,)
    assert np.array_equal(one.w, hconv.convert(h, i, engine="numpy").w)
    many = hconv.convert(np.tile(h, (1000, 1)), np.tile(i, (1000, 1, 1)))
    assert many.engine == "compiled" and np.array_equal(many.w[-1], one.w)


def _modules_after(code: str) -> set:
    """The modules a fresh interpreter has loaded after ``code``, with auto meaning auto."""
    env = {k: v for k, v in os.environ.items() if k != "HCONV_ENGINE"}
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys; print(' '.join(sorted(sys.modules)))"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
        env=env,
    )
    return set(out.stdout.split())


def test_convert_in_a_fresh_process_loads_the_extension_and_no_jit():
    """The first call of a process is the compiled engine's, with nothing compiled at run time: no
    numba, no LLVM."""
    code = (
        "import numpy as np, hconv\n"
        "for n in (1, 100, 10000):\n"
        "    assert hconv.convert(np.ones((n, 3)), np.tile(np.diag([1.0, 2.0, 2.5]), (n, 1, 1))).engine == 'compiled'"
    )
    loaded = _modules_after(code)
    assert "hconv.solve.rowcode" in loaded
    assert not {"numba", "llvmlite"} & loaded


def test_covers_follows_the_row_engine_field():
    exact = methods.get("exact")
    assert engines.covers(exact, 64, "error", "sym6")
    assert not engines.covers(dataclasses.replace(exact, name="exact-numpy", row_engine=False), 64, "error", "sym6")
    assert engines.covers(dataclasses.replace(exact, name="exact-twin"), 64, "error", "full9")
    assert engines.scope_text().startswith("--method exact or refined on sym6 or full9 tensors")


def _same_result(a: hconv.Result, b: hconv.Result) -> None:
    """Every field the same, bits, types and shapes (NaN equal to NaN)."""
    assert dataclasses.fields(a) == dataclasses.fields(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        assert type(x) is type(y), f.name
        if isinstance(x, (np.ndarray, np.generic)):
            assert x.shape == y.shape and np.array_equal(x, y, equal_nan=True), f.name
        else:
            assert x == y, f.name


@pytest.mark.parametrize("method", [None, "refined"])
@pytest.mark.parametrize("diagnostics", [None, False])
def test_convert_plain_call_gives_the_general_paths_result(method, diagnostics, rng, fresh):
    """Plain calls (float64 arrays, default options) skip the general path's checks: one body by
    its own C entry, a small stack by another; the Result is the one the general path gives
    (precision=64 spelled out takes that path)."""
    from helpers import hard_bodies, physical_bodies, six

    I, H = physical_bodies(rng, 50), rng.normal(size=(50, 3))
    hard, Hh = hard_bodies(rng)  # rows the compiled engine leaves: the short path must too
    kw = {"method": method, "diagnostics": diagnostics}
    for h, i in [(H[0], I[0]), (H[0], six(I)[0]), (H, I), (H, six(I)), (Hh[0], hard[0]), (Hh, hard), (Hh[5], hard[5])]:
        _same_result(hconv.convert(h, i, **kw), hconv.convert(h, i, precision=64, **kw))
    assert hconv.convert(H[0], I[0], **kw).engine == "compiled"
    assert hconv.convert(Hh[0], hard[0], **kw).status == "invalid_input"  # a NaN: the numpy engine's row


def test_convert_plain_call_follows_the_environment(fresh, monkeypatch):
    h, i = np.array([1.0, 2.0, 3.0]), np.diag([1.0, 2.0, 3.0])
    monkeypatch.setenv("HCONV_ENGINE", "numpy")
    assert hconv.convert(h, i).engine == "numpy" and hconv.convert(h[None], i[None]).engine == "numpy"
    assert hconv.convert(h, i, engine="compiled").engine == "compiled"
    monkeypatch.setenv("HCONV_ENGINE", "gpu")
    with pytest.raises(UsageError, match="HCONV_ENGINE must be one of auto, numpy, compiled, got 'gpu'"):
        hconv.convert(h, i)


def test_shared_pool_is_kept_grown_when_asked_more_and_new_in_a_forked_process(monkeypatch):
    from hconv.solve import engines

    shared = engines.SharedPool("hconv-test")
    first = shared(2)
    assert shared(1) is first and shared(2) is first  # kept: no threads started per call
    grown = shared(3)
    assert grown is not first and grown._max_workers >= 3
    monkeypatch.setattr(engines.os, "getpid", lambda: -1)  # as in a process forked from this one
    assert shared(1) is not grown
