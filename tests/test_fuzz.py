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
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
from helpers import mp_solve, rel_err, run_hconv, run_inprocess
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


# --- damaged files: a seeded sweep ------------------------------------------------------------
# Damage as disks, networks and half-finished copies make it, to a small valid file: flipped
# bits, cut tails, inserted or lost bytes, a page overwritten, other encodings, repeated headers.
# Every outcome must be exit 0 with right numbers for the rows as read, or exit 3 with one line
# that names the input; never 1 or 4 (the output is not at fault), never a file left behind.

SWEEP_ROWS = 240
TENSOR = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]


def sweep_table(seed: int, rows: int = SWEEP_ROWS) -> pa.Table:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, 3, 3))
    inertia = a @ a.transpose(0, 2, 1) + 0.5 * np.eye(3)  # symmetric positive definite
    cols = {"id": pa.array(np.arange(rows)), "label": pa.array([f"body-{k % 7}" for k in range(rows)])}
    for c in ["Hx", "Hy", "Hz"]:
        cols[c] = pa.array(rng.normal(size=rows))
    for c, (i, j) in zip(TENSOR, [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)], strict=True):
        cols[c] = pa.array(inertia[:, i, j])
    return pa.table(cols)


def damage(data: bytes, rng: np.random.Generator, kind: str) -> bytes:
    b = bytearray(data)
    at = int(rng.integers(1, len(b) - 1))
    if kind == "flip":  # a few bits anywhere
        for _ in range(int(rng.integers(1, 4))):
            b[int(rng.integers(0, len(b)))] ^= 1 << int(rng.integers(0, 8))
    elif kind == "bytes":  # a few bytes replaced
        for _ in range(int(rng.integers(1, 6))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
    elif kind == "run":  # a run of bytes overwritten, as a bad sector or a page of garbage
        n = int(rng.integers(8, 200))
        b[at : at + n] = rng.integers(0, 256, min(n, len(b) - at), dtype=np.uint8).tobytes()
    elif kind == "cut":  # a copy that stopped early
        del b[at:]
    elif kind == "insert":
        b[at:at] = rng.integers(0, 256, int(rng.integers(1, 30)), dtype=np.uint8).tobytes()
    elif kind == "delete":
        del b[at : at + int(rng.integers(1, 30))]
    elif kind == "zeros":  # a hole, as a sparse file's unwritten region
        b[at : at + int(rng.integers(16, 4096))] = bytes(min(4096, len(b) - at))[: len(b[at : at + 4096])]
    return bytes(b)


PARQUET_DAMAGE = ["flip", "bytes", "run", "cut", "insert", "delete", "zeros"]
CSV_DAMAGE = PARQUET_DAMAGE + ["latin1", "header_again", "header_twice", "quote", "join", "nul", "utf16_tail"]


def damage_csv(data: bytes, rng: np.random.Generator, kind: str) -> bytes:
    lines = data.split(b"\n")
    k = int(rng.integers(1, len(lines) - 1))
    if kind == "latin1":  # a label typed on another machine
        lines[k] = lines[k].replace(b"body", "bödy".encode("latin-1"))
    elif kind == "header_again":  # two files concatenated with their headers
        lines.insert(k, lines[0])
    elif kind == "header_twice":  # a column named twice
        lines[0] = lines[0].replace(b"label", b"Hx")
    elif kind == "quote":  # a quote opened and never closed
        lines[k] = b'"' + lines[k]
    elif kind == "join":  # a lost line end
        lines[k : k + 2] = [lines[k] + lines[k + 1]]
    elif kind == "nul":
        lines[k] = lines[k][:3] + b"\x00" + lines[k][3:]
    elif kind == "utf16_tail":
        lines[k] = lines[k].decode().encode("utf-16-le")
    else:
        return damage(data, rng, kind)
    return b"\n".join(lines)


def check_converted(src, dst, code: int, err: str, before: set, counts: dict) -> None:
    """The sweep's checks for one run; ``counts`` gathers the figures."""
    counts[code] = counts.get(code, 0) + 1
    assert code in (0, 3), (src.name, code, err)
    assert "Traceback" not in err and "internal error" not in err, err
    if code == 3:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("hconv: error: "), (src.name, err)
        assert str(src) in lines[0], (src.name, err)  # names the input
        counts["named"] = counts.get("named", 0) + 1
        assert {p.name for p in src.parent.iterdir()} == before, src.name  # no output, no temporary file
        return
    assert {p.name for p in src.parent.iterdir()} == before | {dst.name}, src.name
    out = pq.read_table(dst)
    if src.suffix == ".csv":  # every row kept: as many as Python's csv module reads
        rows = [r for r in csv.reader(io.StringIO(src.read_bytes().decode("utf-8-sig"))) if r]
        assert out.num_rows == len(rows) - 1, src.name
    else:
        assert out.num_rows == pq.ParquetFile(src).metadata.num_rows, src.name
    ok = np.asarray(out.column("status").to_pylist()) == "ok"
    H = np.stack([out.column(c).to_numpy() for c in ["Hx", "Hy", "Hz"]], axis=1)[ok]
    t = {c: out.column(c).to_numpy()[ok] for c in TENSOR}
    inertia = np.stack(
        [
            np.stack([t["Ixx"], t["Ixy"], t["Ixz"]], axis=1),
            np.stack([t["Ixy"], t["Iyy"], t["Iyz"]], axis=1),
            np.stack([t["Ixz"], t["Iyz"], t["Izz"]], axis=1),
        ],
        axis=1,
    )
    w = np.stack([out.column(c).to_numpy() for c in ["wx", "wy", "wz"]], axis=1)[ok]
    if ok.any():  # ω of each ok row, against numpy's solve of the row as hconv read it
        want = np.linalg.solve(inertia, H[..., None])[..., 0]
        assert np.all(rel_err(w, want) < 1e-9), src.name
    dst.unlink()


def sweep(tmp_path, capsys, fmt: str, n: int, kinds: list, goods: list[bytes]) -> dict:
    """``n`` damaged copies of the files ``goods``, each converted in this process; the figures."""
    folder = tmp_path / "runs"
    folder.mkdir()
    counts: dict = {}
    for seed in range(n):
        rng = np.random.default_rng(seed)
        kind = kinds[seed % len(kinds)]
        src = folder / f"damaged-{seed:03d}-{kind}.{fmt}"
        src.write_bytes((damage_csv if fmt == "csv" else damage)(goods[seed % len(goods)], rng, kind))
        dst = folder / "out.parquet"
        before = {p.name for p in folder.iterdir()}
        code, _, err = run_inprocess("convert", str(src), str(dst), "-q", capsys=capsys)
        check_converted(src, dst, code, err, before, counts)
        if seed == 1:  # the real command says the same
            proc = run_hconv("convert", str(src), str(dst), "-q")
            assert (proc.returncode, proc.stderr.decode()) == (code, err)
            dst.unlink(missing_ok=True)
        src.unlink()
    return counts


def test_convert_damaged_parquet_sweep_is_exit_0_right_or_3_naming_the_input(tmp_path, capsys):
    table, goods = sweep_table(0), []
    for checksums in (False, True):  # pages without checksums (pyarrow's default) and with them
        buf = pa.BufferOutputStream()
        pq.write_table(table, buf, row_group_size=40, write_page_checksum=checksums)
        goods.append(buf.getvalue().to_pybytes())
    counts = sweep(tmp_path, capsys, "parquet", 100, PARQUET_DAMAGE, goods)
    print(f"\ndamaged Parquet: 100 inputs, exit codes {counts}")
    assert counts.get(3, 0) > 50  # the sweep damages what is read, not only what no one reads


def test_convert_damaged_csv_sweep_is_exit_0_right_or_3_naming_the_input(tmp_path, capsys):
    buf = pa.BufferOutputStream()
    pacsv.write_csv(sweep_table(0, 700), buf)  # 150 KB: most damage lies past the 64 KiB hconv checks first
    counts = sweep(tmp_path, capsys, "csv", 50, CSV_DAMAGE, [buf.getvalue().to_pybytes()])
    print(f"\ndamaged CSV: 50 inputs, exit codes {counts}")
    assert counts.get(3, 0) > 20
