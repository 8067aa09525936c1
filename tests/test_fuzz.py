"""Fuzzing the readers and `hconv one`'s arguments: the only allowed outcomes are a clean one-line
error (exit 2 or 3) or a correct result with every row kept. Never exit 1 (an internal error).

CI runs HCONV_FUZZ_EXAMPLES cases per test (default 120); a longer run for the notes:
    HCONV_FUZZ_EXAMPLES=5000 .venv/bin/python -m pytest tests/test_fuzz.py
"""

from __future__ import annotations

import csv
import io
import json
import os

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from helpers import mp_solve, rel_err, run_inprocess
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

EXAMPLES = int(os.environ.get("HCONV_FUZZ_EXAMPLES", "120"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

NAMES = [
    "Hx",
    "Hy",
    "Hz",
    "Ixx",
    "Iyy",
    "Izz",
    "Ixy",
    "Ixz",
    "Iyz",
    "I",
    "I1",
    "I2",
    "I3",
    "rx",
    "ry",
    "rz",
    "qw",
    "qx",
    "qy",
    "qz",
    "m",
    "wx",
    "id",
    "note",
    "Iyx",
    "H",
    "",
]
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**20), 10**20).map(str),
    st.sampled_from(
        [
            "",
            "nan",
            "NaN",
            "inf",
            "-inf",
            "1e309",
            "1e-320",
            "0x10",
            "1_000",
            "1,5",
            '"2"',
            " 3 ",
            "true",
            "null",
            "N/A",
            "—",
            "１",
            "\t",
        ]
    ),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=8),
)


def outcome_is_clean(code: int, err: str) -> None:
    assert code in (0, 2, 3, 4), (code, err)
    assert "Traceback" not in err and "internal error" not in err, err
    if code:
        assert len([ln for ln in err.splitlines() if ln.strip()]) == 1 and err.startswith("hconv: error: "), err


@FUZZ
@given(
    header=st.lists(st.sampled_from(NAMES), min_size=1, max_size=14),
    rows=st.lists(st.lists(CELLS, min_size=0, max_size=16), max_size=6),
    crlf=st.booleans(),
    bom=st.booleans(),
    to=st.sampled_from(["csv", "parquet"]),  # into Parquet, the other columns get types (csvtypes)
)
def test_fuzz_csv_reader(tmp_path, capsys, header, rows, crlf, bom, to):
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\r\n" if crlf else "\n").writerows([header] + rows)
    src = tmp_path / "fuzz.csv"
    src.write_bytes((b"\xef\xbb\xbf" if bom else b"") + buf.getvalue().encode("utf-8", "surrogatepass"))
    dst = tmp_path / f"out.{to}"
    dst.unlink(missing_ok=True)
    code, _, err = run_inprocess("convert", str(src), str(dst), "-q", capsys=capsys)
    outcome_is_clean(code, err)
    if code == 0 and to == "parquet":
        assert pq.read_table(dst).num_rows == len(rows)  # every row kept
    elif code == 0:
        got = list(csv.reader(io.StringIO(dst.read_text(encoding="utf-8"))))
        assert len(got) == len(rows) + 1  # every row kept
    else:
        assert not dst.exists()


COLUMN_TYPES = st.sampled_from(["float", "int", "string", "bool", "null", "list3", "list4", "listvar", "struct"])


def column(kind: str, n: int, rng) -> pa.Array:
    if kind == "float":
        return pa.array(rng.choice([0.0, 1.0, -2.5, 1e308, 1e-320, np.nan, np.inf, 3.0], n))
    if kind == "int":
        return pa.array(rng.integers(-5, 5, n))
    if kind == "string":
        return pa.array(rng.choice(["1", "x", ""], n))
    if kind == "bool":
        return pa.array(rng.integers(0, 2, n).astype(bool))
    if kind == "null":
        return pa.nulls(n)
    if kind == "struct":
        return pa.array([{"a": 1.0}] * n)
    if kind == "listvar":
        return pa.array([list(rng.normal(size=int(rng.integers(0, 5)))) for _ in range(n)])
    k = 3 if kind == "list3" else 4
    return pa.FixedSizeListArray.from_arrays(pa.array(rng.normal(size=n * k)), k)


@FUZZ
@given(
    cols=st.dictionaries(st.sampled_from(NAMES[:-1]), COLUMN_TYPES, min_size=1, max_size=12),
    n=st.integers(0, 5),
    seed=st.integers(0, 2**16),
)
def test_fuzz_parquet_reader(tmp_path, capsys, cols, n, seed):
    rng = np.random.default_rng(seed)
    src = tmp_path / "fuzz.parquet"
    pq.write_table(pa.table({name: column(kind, n, rng) for name, kind in cols.items()}), src)
    dst = tmp_path / "out.parquet"
    dst.unlink(missing_ok=True)
    code, _, err = run_inprocess("convert", str(src), str(dst), "-q", capsys=capsys)
    outcome_is_clean(code, err)
    if code == 0:
        assert pq.read_table(dst).num_rows == n
    else:
        assert not dst.exists()


ARG = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=10).map(
        lambda v: ",".join(repr(x) for x in v)
    ),
    st.text(max_size=20),
    st.sampled_from(["1,2,3", "1,,2,3", ",", "1;2;3", "1 2 3", "1e999,0,0", "--H", "-1,-2,-3", "0,0,0"]),
)


@FUZZ
@given(
    H=ARG,
    I=ARG,
    r=st.one_of(st.none(), ARG),
    q=st.one_of(st.none(), ARG),
    method=st.sampled_from(["exact", "refined", "document", "diagonal", "bogus"]),
)
def test_fuzz_one_arguments(capsys, H, I, r, q, method):
    args = ["one", f"--H={H}", f"--I={I}", "--method", method, "--json"]
    args += [] if r is None else [f"--r={r}"]
    args += [] if q is None else [f"--q={q}"]
    code, out, err = run_inprocess(*args, capsys=capsys)
    outcome_is_clean(code, err)
    if code == 0:
        res = json.loads(out)
        assert res["status"] and len(res["w"]) == 3
        if res["status"] == "ok" and method in ("exact", "refined") and q is None:
            h = np.array([float(x) for x in H.split(",")])  # the CLI took them, so float() must too
            i = np.array([float(x) for x in I.split(",")])
            tensor = {
                1: lambda: np.eye(3) * i[0],
                3: lambda: np.diag(i),
                6: lambda: np.array([[i[0], i[3], i[4]], [i[3], i[1], i[5]], [i[4], i[5], i[2]]]),
                9: lambda: i.reshape(3, 3),
            }[len(i)]()
            want = mp_solve(tensor[None], h[None])
            got = np.array([res["w"]], dtype=float)
            if not want.any():
                assert not got.any()  # H = 0: ω = 0 exactly
            else:
                assert rel_err(got, want)[0] < 1e-6
