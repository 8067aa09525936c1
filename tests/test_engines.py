"""Which engine converts: the auto rule, the environment override, the compiled-code marker, and
the promise that numba is imported only when it runs."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hconv
from hconv.errors import UsageError
from hconv.solve import engines, methods, rows

NUMBA = importlib.util.find_spec("numba") is not None
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """auto's state as in a new process, with the marker in an empty cache directory."""
    monkeypatch.delenv("HCONV_ENGINE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(engines, "_spent", 0.0)
    monkeypatch.setattr(engines, "_ready", None)
    monkeypatch.delitem(sys.modules, "hconv.solve.compiled", raising=False)
    return tmp_path


def _auto(n: int, **kw) -> str:
    args = {"method": "exact", "precision": 64, "degenerate": "error", "form": "sym6", **kw}
    m = methods.get(args["method"])
    return engines.resolve("auto", n, m, args["precision"], args["degenerate"], args["form"])


def test_resolve_auto_one_body_is_python_and_small_batches_numpy(fresh):
    assert _auto(1) == "python"
    assert _auto(100) == "numpy"
    assert _auto(10**7) == "numpy"  # numba not compiled here (empty cache): auto never compiles


def test_resolve_auto_runs_the_rest_on_numpy(fresh):
    assert _auto(1, method="eigen") == "numpy"
    assert _auto(1, precision=32) == "numpy"
    assert _auto(1, degenerate="pinv") == "numpy"
    assert _auto(1, form="principal") == "numpy"
    assert engines.resolve("python", 5, methods.get("lapack"), 64, "error", "sym6") == "numpy"
    assert engines.resolve("python", 5, methods.get("exact"), 64, "error", "sym6", degenerate_rtol=1e-9) == "numpy"


def test_resolve_auto_numba_once_compiled_and_worth_it(fresh, monkeypatch):
    monkeypatch.setattr(engines, "numba_installed", lambda: True)
    monkeypatch.setattr(engines, "compiled_ready", lambda: True)
    assert _auto(engines.AUTO_MIN_ROWS - 1) == "numpy"
    assert _auto(engines.AUTO_MIN_ROWS) == "numba"
    engines.spend(engines.START_COST)  # many small calls have cost as much as loading numba
    assert _auto(100) == "numba"
    assert _auto(1) == "python"
    sys.modules["hconv.solve.compiled"] = sys  # loaded (a stand-in: the rule looks at the name only)
    assert _auto(1) == "numba"


def test_resolve_environment_sets_what_auto_means(fresh, monkeypatch):
    monkeypatch.setenv("HCONV_ENGINE", "python")
    assert _auto(10**6) == "python"
    assert engines.resolve("numpy", 10, methods.get("exact"), 64, "error", "sym6") == "numpy"  # a named engine wins
    monkeypatch.setenv("HCONV_ENGINE", "fortran")
    with pytest.raises(UsageError, match="HCONV_ENGINE must be one of auto, numpy, numba, python, got 'fortran'"):
        _auto(10)


def test_for_files_auto_is_numpy_unless_the_environment_says(fresh, monkeypatch):
    assert engines.for_files("auto") == "numpy"
    assert engines.for_files("numba") == "numba"  # asked for by name: as asked
    monkeypatch.setenv("HCONV_ENGINE", "numba")
    assert engines.for_files("auto") == "numba"


def test_resolve_numba_without_numba_names_the_fix(fresh, monkeypatch):
    monkeypatch.setattr(engines, "numba_installed", lambda: False)
    fix = r"engine='numba' needs numba: pip install 'hconv\[fast\]' \(or use engine='auto'\)"
    with pytest.raises(UsageError, match=fix):
        hconv.convert(np.ones(3), np.eye(3), engine="numba")
    with pytest.raises(UsageError, match="engine must be one of auto, numpy, numba, python, got 'gpu'"):
        hconv.convert(np.ones(3), np.eye(3), engine="gpu")
    with pytest.raises(UsageError, match="engine='numba' needs numba"):
        hconv.Job(engine="numba")
    monkeypatch.setenv("HCONV_ENGINE", "numba")  # the message names what asked for numba
    with pytest.raises(UsageError, match=r"HCONV_ENGINE=numba needs numba: .* \(or unset HCONV_ENGINE\)"):
        hconv.convert(np.ones((5, 3)), np.tile(np.eye(3), (5, 1, 1)))


def test_compiled_ready_reads_the_marker_and_its_files(fresh):
    assert not engines.compiled_ready()
    index = fresh / "rows.convert_rows-1.py311.nbi"
    index.write_text("")
    path = engines.marker_path()
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"index": [str(index)]}))
    engines.forget_ready()
    assert engines.compiled_ready()
    index.unlink()  # numba's cache cleared: the marker no longer counts
    engines.forget_ready()
    assert not engines.compiled_ready()
    path.write_text("{not json")
    engines.forget_ready()
    assert not engines.compiled_ready()


def test_marker_path_is_another_for_a_copy_of_the_same_row_code(fresh, monkeypatch):
    """A fresh clone or environment beside a compiled one has compiled nothing: numba caches
    beside each copy of rows.py, so the marker of one copy must not speak for another (a trial
    found auto compiling for 13 s in a fresh clone that another checkout's marker called ready)."""
    here = engines.marker_path()
    copy = fresh / "elsewhere" / "rows.py"
    copy.parent.mkdir()
    copy.write_bytes(Path(rows.__file__).read_bytes())
    with monkeypatch.context() as m:
        m.setattr(rows, "__file__", str(copy))
        assert engines.marker_path() != here
    assert engines.marker_path() == here


@pytest.mark.skipif(not NUMBA, reason="needs hconv[fast]")
def test_warm_compiles_and_marks(fresh):
    from hconv.solve import compiled

    compiled._marked = False  # a module imported afresh by the fixture
    assert not engines.marker_path().exists()
    compiled.warm()
    assert engines.marker_path().exists() and engines.compiled_ready()


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


def test_one_never_imports_numba():
    code = (
        "import sys\nfrom hconv.cli import main\n"
        "sys.argv = ['hconv', 'one', '--H', '1,2,3', '--I', '2,3,4,0.1,0,0.2']\n"
        "try:\n    main()\nexcept SystemExit:\n    pass"
    )
    assert "numba" not in _modules_after(code)


def test_convert_small_batches_never_import_numba():
    code = (
        "import numpy as np, hconv\n"
        "for n in (1, 100, 10000):\n"
        "    hconv.convert(np.ones((n, 3)), np.tile(np.diag([1.0, 2.0, 2.5]), (n, 1, 1)))"
    )
    assert "numba" not in _modules_after(code)


def test_covers_follows_the_row_engine_field():
    exact = methods.get("exact")
    assert engines.covers(exact, 64, "error", "sym6")
    assert not engines.covers(dataclasses.replace(exact, name="exact-numpy", row_engine=False), 64, "error", "sym6")
    assert engines.covers(dataclasses.replace(exact, name="exact-twin"), 64, "error", "full9")
    assert engines.scope_text().startswith("--method exact or refined on sym6 or full9 tensors")
