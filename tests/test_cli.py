"""The real `hconv` command on real files, through real pipes, including bad input on purpose."""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import StopAt, command_imports, hconv_inprocess, need, run_hconv, run_inprocess, run_on_terminal

import hconv

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "data"
CONTRACT = ["Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz", "rx", "ry", "rz"]
OUT_COLS = ["wx", "wy", "wz", "residual", "cond", "status"]


def assert_one_line_error(proc, code: int, *needles: str) -> str:
    err = proc.stderr.decode()
    assert proc.returncode == code, (proc.returncode, err)
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("hconv: error: ")
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def no_leftovers(folder: Path, allowed: set[str]) -> None:
    assert {p.name for p in folder.iterdir()} == allowed


def write_csv(path: Path, header: list[str], rows: list[list[str]]) -> Path:
    path.write_text("\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n")
    return path


# --- conversions that work -------------------------------------------------------------------


def test_convert_example_parquet_keeps_rows_columns_and_units(tmp_path, capsys):
    out = tmp_path / "out.parquet"
    proc = hconv_inprocess("convert", str(EXAMPLES / "scene.parquet"), str(out), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    src, got = pq.read_table(EXAMPLES / "scene.parquet"), pq.read_table(out)
    assert got.column_names == src.column_names + OUT_COLS
    assert got.slice(0).select(src.column_names).equals(src)  # pass-through, in order
    for c in ("wx", "wy", "wz"):
        assert got.schema.field(c).metadata[b"unit"] == b"rad/s"
    w = np.column_stack([got.column(c).to_numpy() for c in ("wx", "wy", "wz")])
    w_true = np.column_stack([got.column(f"w_true_{a}").to_numpy() for a in "xyz"])
    assert (np.linalg.norm(w - w_true, axis=1) / np.linalg.norm(w_true, axis=1)).max() < 1e-10
    assert set(got.column("status").to_pylist()) == {"ok"}
    assert np.nanmax(got.column("residual").to_numpy()) < 1e-12


def test_convert_csv_document_carries_unit_column(tmp_path, capsys):
    out = tmp_path / "out.csv"
    proc = hconv_inprocess("convert", str(EXAMPLES / "scene.csv"), str(out), "--method", "document", capsys=capsys)
    assert proc.returncode == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 400
    assert {r["w_unit"] for r in rows} == {"m^2/s"}
    assert min(float(r["residual"]) for r in rows) > 1e-3  # far from I⁻¹H, as it should be
    header = out.read_text().splitlines()[0]
    assert header.endswith("wx,wy,wz,residual,cond,status,w_unit")


def test_convert_csv_passthrough_text_is_exact(tmp_path, capsys):
    src = tmp_path / "in.csv"
    src.write_text(
        "id,label,Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz,note\n"
        '007,"a,b",1,2,3,2,3,4,0,0,0,"say ""hi"""\n'
        "1e3,,1,0,0,1,1,1,0,0,0,é ü\n"
        "x,plain,0,0,1,1,2,2.5,0,0,0,\n"
    )
    out = tmp_path / "out.csv"
    assert hconv_inprocess("convert", str(src), str(out), capsys=capsys).returncode == 0
    got = list(csv.reader(out.open(encoding="utf-8")))
    want = list(csv.reader(src.open(encoding="utf-8")))
    assert [r[:12] for r in got] == want  # every input value, as text, unchanged
    assert got[1][12:15] == ["0.5", "0.6666666666666666", "0.75"]


def test_convert_csv_float_values_round_trip_exactly(tmp_path, rng, capsys):
    vals = rng.normal(size=(50, 9)) * 10.0 ** rng.integers(-200, 200, (50, 9))
    vals[:, 3:6] = np.abs(vals[:, 3:6]) + 1  # keep the tensors sane; the values are what matters
    t = pa.table({c: vals[:, k] for k, c in enumerate(CONTRACT[:9])})
    src, out = tmp_path / "in.parquet", tmp_path / "out.csv"
    pq.write_table(t, src)
    assert hconv_inprocess("convert", str(src), str(out), capsys=capsys).returncode == 0
    back = pacsv.read_csv(out)
    for c in CONTRACT[:9]:
        np.testing.assert_array_equal(back.column(c).to_numpy(), t.column(c).to_numpy())


def test_convert_parquet_passthrough_types(tmp_path, capsys):
    n = 5
    t = pa.table(
        {
            "t": pa.array(np.arange(n).astype("datetime64[ms]")),
            "flag": [True, False, True, False, None],
            "tags": pa.array([[1], [], None, [2, 3], [4]], type=pa.list_(pa.int32())),
            **{c: np.full(n, v) for c, v in zip(CONTRACT[:9], [1, 2, 3, 2, 3, 4, 0, 0, 0], strict=True)},
            "name": ["a", "b", None, "d", "e"],
        }
    )
    src, out = tmp_path / "in.parquet", tmp_path / "out.parquet"
    pq.write_table(t, src)
    assert hconv_inprocess("convert", str(src), str(out), capsys=capsys).returncode == 0
    got = pq.read_table(out)
    assert got.select(t.column_names).equals(t)


def test_convert_pipeline_csv_stdin_to_stdout(tmp_path):
    cmd = (
        f'cat "{EXAMPLES / "scene.csv"}" | "{sys.executable}" -m hconv convert - - --from csv --to csv -q'
        " | cut -d, -f1,24,25 | tail -n 2"
    )
    proc = subprocess.run(cmd, shell=True, capture_output=True, timeout=120)
    assert proc.returncode == 0
    assert proc.stdout.decode().splitlines() == ["399,ok,rad/s", "400,ok,rad/s"]


def test_convert_pipeline_parquet_stdin_to_stdout(tmp_path):
    data = (EXAMPLES / "scene.parquet").read_bytes()
    proc = run_hconv("convert", "-", "-", "--from", "parquet", "--to", "parquet", input=data)
    assert proc.returncode == 0, proc.stderr.decode()
    got = pq.read_table(io.BytesIO(proc.stdout))
    assert got.num_rows == 400
    assert "status" in proc.stderr.decode()  # the summary goes to stderr, never into the data


@pytest.mark.parametrize("keep", [False, True])
def test_convert_pipeline_csv_stdin_to_parquet_types_or_keeps_text(keep, capsys):
    data = (EXAMPLES / "scene.csv").read_bytes()
    args = ["--keep-text"] if keep else []
    proc = run_hconv("convert", "-", "-", "--from", "csv", "--to", "parquet", "-q", *args, input=data)
    assert proc.returncode == 0, proc.stderr.decode()
    got = pq.read_table(io.BytesIO(proc.stdout))
    assert got.schema.field("id").type == (pa.string() if keep else pa.int64())
    assert got.schema.field("w_true_x").type == (pa.string() if keep else pa.float64())
    assert "--keep-text" in hconv_inprocess("convert", "--help", capsys=capsys).stdout.decode()


def test_convert_empty_tables_give_empty_outputs(tmp_path, capsys):
    src = write_csv(tmp_path / "in.csv", CONTRACT[:9], [])
    out = tmp_path / "out.csv"
    assert hconv_inprocess("convert", str(src), str(out), capsys=capsys).returncode == 0
    assert out.read_text().splitlines() == [",".join(CONTRACT[:9] + OUT_COLS + ["w_unit"])]
    pq.write_table(pa.table({c: pa.array([], pa.float64()) for c in CONTRACT[:9]}), tmp_path / "e.parquet")
    assert (
        hconv_inprocess(
            "convert", str(tmp_path / "e.parquet"), str(tmp_path / "e_out.parquet"), capsys=capsys
        ).returncode
        == 0
    )
    got = pq.read_table(tmp_path / "e_out.parquet")
    assert got.num_rows == 0 and got.column_names == CONTRACT[:9] + OUT_COLS


def test_convert_flagged_rows_keep_place_and_summary_counts(tmp_path, capsys):
    rows = [
        ["1", "2", "3", "2", "3", "4", "0", "0", "0"],
        ["1", "2", "3", "0", "2", "2", "0", "0", "0"],  # rod: singular
        ["", "2", "3", "2", "3", "4", "0", "0", "0"],  # blank H: invalid_input
        ["1", "2", "3", "1", "1", "3", "0", "0", "0"],
    ]  # breaks the triangle inequality
    src = write_csv(tmp_path / "in.csv", CONTRACT[:9], rows)
    out = tmp_path / "out.csv"
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    assert proc.returncode == 0
    got = list(csv.DictReader(out.open()))
    assert [r["status"] for r in got] == ["ok", "singular", "invalid_input", "not_physical"]
    assert got[1]["wx"] == "nan"
    err = proc.stderr.decode()
    for word in ("singular", "invalid_input", "not_physical", "worst residual", "rows/s"):
        assert word in err


def test_convert_precision_32_writes_float32(tmp_path, capsys):
    out = tmp_path / "out.parquet"
    assert (
        hconv_inprocess(
            "convert", str(EXAMPLES / "scene.parquet"), str(out), "--precision", "32", capsys=capsys
        ).returncode
        == 0
    )
    got = pq.read_table(out)
    assert got.schema.field("wx").type == pa.float32()
    res, cond = got.column("residual").to_numpy(), got.column("cond").to_numpy()
    eps32 = np.finfo(np.float32).eps
    assert (res <= 4 * cond * eps32).all()  # float32 rounding of inputs and arithmetic, no worse
    assert res.max() > np.finfo(np.float64).eps * 1e3  # and it really did compute in float32


def test_convert_refuses_to_overwrite_without_force(tmp_path, capsys):
    out = tmp_path / "out.csv"
    out.write_text("precious\n")
    proc = hconv_inprocess("convert", str(EXAMPLES / "scene.csv"), str(out), capsys=capsys)
    assert_one_line_error(proc, 4, "already exists", "--force")
    assert out.read_text() == "precious\n"
    assert hconv_inprocess("convert", str(EXAMPLES / "scene.csv"), str(out), "--force", capsys=capsys).returncode == 0
    assert len(out.read_text().splitlines()) == 401
    no_leftovers(tmp_path, {"out.csv"})


# --- bad input on purpose --------------------------------------------------------------------


def test_convert_missing_column_names_it(tmp_path, capsys):
    src = write_csv(tmp_path / "in.csv", ["Hx", "Hy", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], [["1"] * 8])
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 3, "in.csv", "missing column Hz")
    no_leftovers(tmp_path, {"in.csv"})


def test_convert_document_without_r_says_what_it_needs(tmp_path, capsys):
    proc = hconv_inprocess(
        "convert", str(EXAMPLES / "scene.csv"), str(tmp_path / "o.csv"), "--method", "document", capsys=capsys
    )
    assert proc.returncode == 0  # the example has r
    src = write_csv(tmp_path / "in.csv", CONTRACT[:9], [["1"] * 9])
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), "--method", "document", capsys=capsys)
    assert_one_line_error(proc, 3, "missing columns rx, ry, rz", "'document' needs")


def test_convert_non_numeric_names_column_value_and_row(tmp_path, capsys):
    rows = [["1", "2", "3", "2", "3", "4", "0", "0", "0"]] * 3 + [["1", "two", "3", "2", "3", "4", "0", "0", "0"]]
    src = write_csv(tmp_path / "in.csv", CONTRACT[:9], rows)
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 3, "column 'Hy'", "'two'", "data row 4")
    no_leftovers(tmp_path, {"in.csv"})


def test_convert_non_numeric_parquet_column(tmp_path, capsys):
    t = pa.table({c: ["1"] if c == "Izz" else [1.0] for c in CONTRACT[:9]})
    pq.write_table(t, tmp_path / "in.parquet")
    proc = hconv_inprocess("convert", str(tmp_path / "in.parquet"), str(tmp_path / "out.parquet"), capsys=capsys)
    assert_one_line_error(proc, 3, "column 'Izz' has type string", "must be numeric")


@pytest.mark.parametrize(
    "name,content,needle",
    [
        ("empty.csv", b"", "the file is empty"),
        ("empty.parquet", b"", "the file is empty"),
        ("junk.parquet", b"this is not parquet at all, just text\n" * 20, "is CSV text, not Parquet: rename it"),
        ("binary.csv", bytes(range(256)) * 4, "in.csv" if False else "binary.csv"),
    ],
)
def test_convert_unreadable_or_empty_file(tmp_path, name, content, needle, capsys):
    src = tmp_path / name
    src.write_bytes(content)
    out = tmp_path / ("out" + src.suffix)
    proc = hconv_inprocess("convert", str(src), str(out), capsys=capsys)
    assert_one_line_error(proc, 3, needle)
    no_leftovers(tmp_path, {name})


def test_convert_missing_input_file(tmp_path, capsys):
    proc = hconv_inprocess("convert", str(tmp_path / "nope.csv"), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 3, "nope.csv", "check the path")


def test_convert_unknown_extension_is_usage_error(tmp_path, capsys):
    proc = hconv_inprocess("convert", str(EXAMPLES / "scene.csv"), str(tmp_path / "out.txt"), capsys=capsys)
    # the formats hconv writes, by name: "name it .csv or .parquet" was wrong advice for a file of another format
    assert_one_line_error(proc, 2, "out.txt", "pass --to FORMAT, one of csv, parquet or arrow")


def test_convert_output_directory_missing(tmp_path, capsys):
    proc = hconv_inprocess("convert", str(EXAMPLES / "scene.csv"), str(tmp_path / "no" / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 4, "does not exist")


def test_convert_output_is_input(tmp_path, capsys):
    src = tmp_path / "scene.csv"
    src.write_bytes((EXAMPLES / "scene.csv").read_bytes())
    proc = hconv_inprocess("convert", str(src), str(src), "--force", capsys=capsys)
    assert_one_line_error(proc, 4, "is the input file")
    assert src.read_bytes() == (EXAMPLES / "scene.csv").read_bytes()


def test_convert_failure_midway_leaves_no_partial_output(tmp_path, capsys):
    """The bad value sits past the first batches, so a careless writer would have written them."""
    n = 400_000
    src = tmp_path / "big.csv"
    line = "1.25,2.5,3.75,2.0,3.0,4.0,0.125,0.0,0.0\n"
    with src.open("w") as f:
        f.write(",".join(CONTRACT[:9]) + "\n")
        f.write(line * (n - 1))
        f.write("1,2,3,2,3,oops,0,0,0\n")
    assert src.stat().st_size > 3 * (4 << 20)  # several reader blocks
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.parquet"), capsys=capsys)
    assert_one_line_error(proc, 3, "column 'Izz'", "'oops'", f"data row {n}")
    no_leftovers(tmp_path, {"big.csv"})


# Interrupts during a conversion (SIGINT, SIGTERM, to a file and to stdout): tests/test_invariants.py


def _terminal_signals() -> None:  # as from a terminal: the test runner may have these ignored
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)


ENTRIES = {
    "python -m hconv": [sys.executable, "-m", "hconv"],
    "console script": [str(Path(sys.executable).parent / "hconv")],
}


#: Where the child stops and tells the test, by the module whose import starts there: hconv's
#: first line has run (its handlers are in place); inside numpy's import; inside typer's; inside
#: hconv.cli's, its last import.
START_POINTS = ["hconv.solve", "numpy._core.multiarray", "typer.main", "hconv.tools.scene"]


@pytest.mark.parametrize("entry", list(ENTRIES))
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_while_starting_exits_130_in_one_line(tmp_path, entry, sig):
    """Ctrl-C or SIGTERM while numpy, typer and hconv.cli are imported: exit 130 and at most one
    line, never a traceback. The child says when it has reached each point (START_POINTS) and
    waits there for the signal (helpers.StopAt); a signal before hconv's first line meets
    CPython's own start-up, which prints its own traceback whatever hconv does."""
    command = ENTRIES[entry]
    if not Path(command[0]).exists():
        pytest.skip(f"no {command[0]}")
    for point in START_POINTS:
        stop = StopAt(tmp_path, point)
        proc = subprocess.Popen(
            [*command, "methods"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=stop.env(),
            pass_fds=stop.fds,
            preexec_fn=_terminal_signals,
        )
        stop.started()
        reached = stop.reached()
        if reached:
            proc.send_signal(sig)
        stop.release()
        out, err = proc.communicate()
        text = err.decode()
        assert reached, (point, proc.returncode, text)
        assert proc.returncode == 130 and "Traceback" not in text, (point, proc.returncode, text)
        assert text.strip() in ("", "hconv: error: interrupted; no output was written"), (point, text)
        assert out == b""


def test_import_hconv_keeps_the_programs_signal_handlers():
    """Only the hconv command ends at once on Ctrl-C while starting; a program importing hconv keeps its own."""
    code = (
        "import signal, hconv; "
        "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler, "
        "signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60, preexec_fn=_terminal_signals)
    assert proc.stdout.decode().split() == ["True", "True"]


# --- hconv one and hconv methods -------------------------------------------------------------


def test_one_prints_w_unit_residual_cond_status(capsys):
    proc = hconv_inprocess("one", "--H", "1,2,3", "--I", "2,3,4,0,0,0", "--r", "0.1,0.2,0.3", capsys=capsys)
    out = proc.stdout.decode()
    assert proc.returncode == 0
    assert "[0.5, 0.6666666666666666, 0.75] rad/s" in out
    for word in ("residual", "cond", "status   = ok"):
        assert word in out


def test_one_json_has_the_documented_keys(capsys):
    proc = hconv_inprocess(
        "one",
        "--H",
        "-1,2,3",
        "--I",
        "2,3,4,0,0,0",
        "--r",
        "0.1,0.2,0.3",
        "--method",
        "document",
        "--json",
        capsys=capsys,
    )
    obj = json.loads(proc.stdout)
    assert set(obj) == {"w", "unit", "residual", "cond", "status", "method"}
    assert obj["unit"] == "m^2/s" and obj["method"] == "document" and obj["status"] == "ok"
    np.testing.assert_allclose(obj["w"], [-0.065, 1 / 15, 0.0375], rtol=1e-15)


def test_one_nine_values_row_major_and_asymmetry(capsys):
    ok = json.loads(
        hconv_inprocess("one", "--H", "1,2,3", "--I", "2,0.5,0,0.5,3,0,0,0,4", "--json", capsys=capsys).stdout
    )
    six = json.loads(hconv_inprocess("one", "--H", "1,2,3", "--I", "2,3,4,0.5,0,0", "--json", capsys=capsys).stdout)
    assert ok["w"] == six["w"]
    bad = json.loads(
        hconv_inprocess("one", "--H", "1,2,3", "--I", "2,0.5,0,0.4,3,0,0,0,4", "--json", capsys=capsys).stdout
    )
    assert bad["status"] == "not_symmetric" and bad["w"] == [None, None, None]


def test_one_numbers_in_brackets_as_python_or_json_prints_them(capsys):
    """A paste from Python or JSON: [1,2,3], (1., 2., 3.), and --I as a matrix's rows."""
    plain = hconv_inprocess(
        "one", "--H", "1,2,3", "--I", "2,0.5,0,0.5,3,0,0,0,4", "--r", "0.1,0,0", "--json", capsys=capsys
    ).stdout
    pasted = hconv_inprocess(
        "one",
        "--H",
        "[1, 2, 3]",
        "--I",
        "[[2, 0.5, 0], [0.5, 3, 0], [0, 0, 4]]",
        "--r",
        "(0.1, 0., 0.)",
        "--json",
        capsys=capsys,
    ).stdout
    assert json.loads(pasted) == json.loads(plain)
    w = json.loads(pasted)["w"]
    np.testing.assert_allclose(w, np.linalg.solve([[2, 0.5, 0], [0.5, 3, 0], [0, 0, 4]], [1, 2, 3]), rtol=1e-15)


def test_one_singular_json_has_null_w_and_inf_cond(capsys):
    obj = json.loads(hconv_inprocess("one", "--H", "1,2,3", "--I", "0,2,2", "--json", capsys=capsys).stdout)
    assert obj["status"] == "singular" and obj["w"] == [None, None, None]
    assert obj["cond"] is None and obj["residual"] is None  # infinite and absent: null, valid JSON


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--H", "1,2", "--I", "1,1,1"], "--H takes 3"),
        (["--H", "1,2,x", "--I", "1,1,1"], "comma-separated numbers"),
        (["--H", "1,2,3", "--I", "1,1,1,1"], "--I takes 1, 3, 6 or 9"),
        (["--H", "1,2,3", "--I", "1,1,1", "--method", "document"], "--r rx,ry,rz"),
        (["--H", "[1,2,3", "--I", "1,1,1"], "--H: the brackets in '[1,2,3' do not pair"),
        (["--H", "[1,2,3]", "--I", "[[1,0],[0,1]]"], "--I takes nested brackets only for an inertia matrix"),
        (["--H", "[[1,2,3]]", "--I", "1,1,1"], "--H takes nested brackets only for an inertia matrix"),
        (["--H", "[1,2,3]", "--I", "[[1,0,0][0,1,0],[0,0,1]]"], "needs a comma between the rows"),
        (["--H", "[1 2 3]", "--I", "1,1,1"], "--H takes comma-separated numbers"),
        # Python's float() reads 1_0 as 10 (before: I = 10, 2, 3, and a status for those)
        (
            ["--H", "1,2,3", "--I", "1_0,2,3"],
            "--I: '1_0' in '1_0,2,3' has an underscore; write '10' for that number, or '1,0' for two",
        ),
        # numpy's print of a matrix (before: "needs a comma between the rows", as if rows were the only lack)
        (
            ["--H", "1,2,3", "--I", "[[1. 0. 0.]\n [0. 2. 0.]\n [0. 0. 3.]]"],
            "needs commas between the numbers of each row and between the rows, like [[1,0,0],[0,2,0],[0,0,3]]",
        ),
    ],
)
def test_one_bad_arguments_one_line_exit_2(args, needle, capsys):
    assert_one_line_error(hconv_inprocess("one", *args, capsys=capsys), 2, needle)


@pytest.mark.parametrize(
    "args,hint",
    [
        (["--q", "0,0,0,0"], "q = 0,0,0,0 is not a rotation (zero norm); give a unit quaternion w,x,y,z"),
        (["--q", "nan,0,0,1"], "q = nan,0,0,1 is not finite"),
        (["--H", "1,nan,3"], "H = 1,nan,3 is not finite"),
        (["--I", "1,inf,3"], "I = 1,inf,3 is not finite"),
        (["--m", "-5"], "m = -5 is not positive, but a body with inertia needs m > 0"),
        (["--m", "0"], "m = 0 is not positive"),
        (["--about", "pivot", "--m", "-1", "--r", "1,0,0"], "m = -1 is a negative mass"),
        (["--about", "free", "--m", "1", "--r", "1,0,0", "--v", "nan,0,0"], "v = nan,0,0 is not finite"),
        (["--method", "document", "--r", "nan,0,0"], "r = nan,0,0 is not finite"),
        (["--precision", "32", "--H", "1e39,0,0"], "H = 1e39,0,0 is beyond float32's range"),
        (["--about", "pivot", "--m", "1e300", "--r", "1e200,0,0"], "every value is finite, but one overflows"),
    ],
)
def test_one_invalid_input_says_which_value_on_stderr(capsys, args, hint):
    base = {"--H": "1,2,3", "--I": "1,2,3"}
    for a, b in zip(args[::2], args[1::2]):
        base[a] = b
    argv = [x for kv in base.items() for x in kv]
    code, out, err = run_inprocess("one", *argv, capsys=capsys)
    assert code == 0 and "status   = invalid_input" in out  # stdout as ever; the hint beside it
    assert err.startswith(f"hconv: {hint}") and len(err.splitlines()) == 1, err
    code, out, err_json = run_inprocess("one", *argv, "--json", capsys=capsys)
    assert json.loads(out)["status"] == "invalid_input" and err_json == err


@pytest.mark.parametrize(
    "I, status, fix",
    [
        (
            "1,1,5",
            "not_physical",
            "the point I is about; a thin plate computed in float32 is on the boundary only to its roundings: "
            "give --precision 32",
        ),
        ("0,0,0", "singular", "--degenerate pinv or lock"),
        (
            "1,2,3,4,5,6,7,8,9",
            "not_symmetric",
            "xx,yy,zz,xy,xz,yz; numbers computed in float32 are symmetric only to its roundings: give --precision 32",
        ),
        ("1,1,1,0,0,-2", "not_positive_definite", "the products' sign (--products)"),
    ],
)
def test_one_status_of_the_tensor_says_its_usual_causes_on_stderr(capsys, I, status, fix):
    """A newcomer saw not_physical or singular with no word on why or what to do (only
    invalid_input was explained); stdout stays the result, the hint goes to stderr."""
    code, out, err = run_inprocess("one", "--H", "1,2,3", "--I", I, capsys=capsys)
    said = " ".join(err.split())
    assert code == 0 and f"status   = {status}" in out
    assert said.startswith(f"hconv: {status}: ") and fix in said, err
    assert run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", capsys=capsys)[2] == ""  # ok: nothing said


def test_one_status_hint_names_precision_32_only_where_it_was_not_given(capsys):
    """A tensor that is not symmetric at --precision 32 is beyond float32's roundings: the hint
    that float32 numbers want --precision 32 would be wrong there (review)."""
    asym = ["one", "--H", "1,2,3", "--I", "1,0.3,0,0.31,2,0,0,0,2.5"]
    said = " ".join(run_inprocess(*asym, "--precision", "32", capsys=capsys)[2].split())
    assert said.startswith("hconv: not_symmetric: ") and "precision" not in said
    assert "give --precision 32" in " ".join(run_inprocess(*asym, capsys=capsys)[2].split())


SATELLITE = ["--H", "1,2,52500000000003", "--I", "1000", "--m", "1000", "--r", "7e6,0,0", "--v", "0,7500,0"]


def test_one_cancellation_says_what_it_means_and_the_fix(capsys):
    """A newcomer saw status cancellation with a residual labelled as measured, and no word on
    what to do; the label now says the bound is in it, and stderr says what the status means."""
    code, out, err = run_inprocess("one", *SATELLITE, "--about", "free", capsys=capsys)
    assert code == 0 and "status   = cancellation" in out
    assert "residual = 0.00623  (|w - I⁻¹H_C| / |I⁻¹H_C| + cond(I)·ε_C, H_C = H - r × m·v)" in out
    said = " ".join(err.split())
    assert said.startswith("hconv: cancellation: H - r × m·v cancels most of H's")
    assert "off by up to 0.0062 of |ω|" in said and said.endswith("with --about same")
    code, out, err_json = run_inprocess("one", *SATELLITE, "--about", "free", "--json", capsys=capsys)
    assert json.loads(out)["status"] == "cancellation" and err_json == err


def test_one_cancellation_hint_wraps_at_80_columns_without_trailing_spaces(capsys):
    """Before: a single 199-character line."""
    code, out, err = run_inprocess("one", *SATELLITE, "--about", "free", capsys=capsys)
    lines = err.splitlines()
    assert code == 0 and len(lines) > 1 and all(len(ln) <= 80 and ln == ln.rstrip() for ln in lines)
    assert all(ln.startswith("  ") for ln in lines[1:])  # one hint, its later lines indented
    assert "H - r × m·v" in err and "--about same" in err  # a formula and an option never split


def test_one_cancellation_under_another_status_is_still_told(capsys):
    """Before: with m = 1, I = 1000 the row is unit_suspect (first in the order of statuses) and
    lost digits to H - r × m·v by the same bound, but nothing said so."""
    args = ["--H", "1,2,52500000003", "--I", "1000", "--m", "1", "--r", "7e6,0,0", "--v", "0,7500,0"]
    code, out, err = run_inprocess("one", *args, "--about", "free", capsys=capsys)
    assert code == 0 and "status   = unit_suspect" in out
    said = " ".join(err.split())
    assert said.startswith("hconv: cancellation (the status shows unit_suspect, which comes first): H - r × m·v")
    assert "off by up to 6.2e-06 of |ω|" in said
    # the same numbers one digit further from the origin lose none: no hint
    args[1] = "1,2,52500000000003"
    code, out, err = run_inprocess("one", *args, "--about", "free", capsys=capsys)
    assert "status   = unit_suspect" in out and err == ""


def test_one_cancellation_total_says_omega_is_unknown(capsys):
    """Before: a residual of 23 was offered as "off by up to 23 of |ω|", a bound it is not once it
    reaches 1 (a trial row was off by 48 |ω| with a residual of 10.6)."""
    args = [*SATELLITE]
    args[1] = "0.001,0,52500000000000"
    code, out, err = run_inprocess("one", *args, "--about", "free", capsys=capsys)
    assert "status   = cancellation" in out and "residual = 23.3" in out
    said = " ".join(err.split())
    assert "so ω is unknown: not one digit of it holds, and the residual (23) is no bound on its error" in said
    assert "off by up to" not in said


@pytest.mark.parametrize(
    "given, needs, wanted",
    [
        (
            [],
            "needs r, the centre of mass relative to the origin of H; the mass m; and v,",
            "--r rx,ry,rz --m MASS --v vx,vy,vz",
        ),
        (
            ["--m", "1"],
            "needs r, the centre of mass relative to the origin of H; and v,",
            "pass --r rx,ry,rz --v vx,vy,vz",
        ),
        (["--m", "1", "--r", "1,0,0"], "needs v, the velocity", "pass --v vx,vy,vz"),
    ],
)
def test_one_about_free_names_every_missing_value(capsys, given, needs, wanted):
    """Before, only the first missing value was named, so a user found them one run at a time."""
    code, out, err = run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", "--about", "free", *given, capsys=capsys)
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert err.startswith("hconv: error: --about free " + needs) and err.rstrip().endswith(wanted), err


def test_one_valid_input_prints_nothing_on_stderr(capsys):
    code, out, err = run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", "--q", "1,0,0,0", capsys=capsys)
    assert code == 0 and "status   = ok" in out and err == ""


@pytest.mark.parametrize(
    "given, unread",
    [
        (["--r", "1,0,0"], ["--r"]),
        (["--v", "0,1,0"], ["--v"]),
        (["--r", "1,0,0", "--v", "0,1,0"], ["--r", "--v"]),
        (["--v", "0,1,0", "--r", "1,0,0", "--about", "pivot", "--m", "2"], ["--v"]),
    ],
)  # the unused values first: the run without them drops them
def test_one_value_no_run_reads_is_told_not_silently_ignored(capsys, given, unread):
    """Before, --r without --about (and an exact method) or --v without --about free was ignored
    without a word, and the answer read as if it had used them. The answer is still printed (one
    command re-run with another --method is a habit), and a note on stderr says what was unused."""
    code, out, err = run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", *given, capsys=capsys)
    without = run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", *given[len(unread) * 2 :], capsys=capsys)
    assert code == 0 and out == without[1]  # the same answer as without the unused values
    assert err.startswith(f"hconv: this run did not use {' or '.join(unread)}: "), err
    for flag in unread:
        assert f"{flag} is read only " in " ".join(err.split())


@pytest.mark.parametrize(
    "given",
    [
        ["--r", "1,0,0", "--method", "document"],
        ["--r", "1,0,0", "--about", "pivot", "--m", "2"],
        ["--r", "7,0,0", "--v", "0,1,0", "--about", "free", "--m", "2"],
    ],
)
def test_one_value_a_run_reads_is_accepted(capsys, given):
    code, out, err = run_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", *given, capsys=capsys)
    assert code == 0 and out.startswith("w        = [") and err == "", err


def test_one_does_not_import_pyarrow_rich_pint_or_a_jit():
    code = (
        "import sys; sys.argv = ['hconv', 'one', '--H', '1,2,3', '--I', '1,2,2.5'];"
        "from hconv.cli import main\ntry: main()\nexcept SystemExit: pass\n"
        "print(sorted(m for m in ('pyarrow', 'rich', 'pint', 'numba', 'llvmlite') if m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert proc.stdout.decode().splitlines()[-1] == "[]"


def _pandas_inputs(folder: Path) -> dict[str, Path]:
    """A CSV with a blank value and a text column whose values need quotes, the same under a row
    of units, a Parquet file with a list column and a null row: the paths where pyarrow's
    conversions reach pandas (docs/engines.md, start-up)."""
    rows = '1,rod,1,2,3,1,2,3\n2,007,,2,3,1,2,2.5\n3,"arm, ""left""",1,2,3,1,2,3\n'
    (folder / "in.csv").write_text("id,body,Hx,Hy,Hz,I1,I2,I3\n" + rows)
    (folder / "units.csv").write_text("id,body,Hx,Hy,Hz,I1,I2,I3\n,,kg*m^2/s,,,kg*m^2,,\n" + rows)
    lists = pa.list_(pa.float64())
    table = pa.table({"H": pa.array([[1.0, 2.0, 3.0], None], lists), "I": pa.array([[1.0, 2.0, 3.0]] * 2, lists)})
    pq.write_table(table.append_column("w", pa.array([1, None], pa.int64())), folder / "in.parquet")
    (folder / "folder").mkdir()  # a dataset: files of float64 columns, read whole
    floats = pa.table({c: pa.array([1.0, 2.0, 3.0]) for c in ("Hx", "Hy", "Hz", "I1", "I2", "I3")})
    for k in range(2):
        pq.write_table(floats, folder / "folder" / f"part{k}.parquet")
    return {
        "csv": folder / "in.csv",
        "units": folder / "units.csv",
        "parquet": folder / "in.parquet",
        "folder": folder / "folder",
    }


@pytest.mark.parametrize(
    "source, to",
    [
        ("csv", "parquet"),
        ("csv", "arrow"),
        ("parquet", "parquet"),
        ("parquet", "arrow"),
        ("csv", "csv"),
        ("units", "csv"),
        ("parquet", "csv"),
        ("folder", "dataset"),
    ],
)
def test_convert_does_not_import_pandas(tmp_path, source, to):
    need("pandas")  # installed, so that a path to it would import it
    given = _pandas_inputs(tmp_path)[source]
    out = tmp_path / f"out.{to}"
    exit_code, imported, err = command_imports(["convert", given, out, "--quiet"], "pandas")
    assert (exit_code, imported) == (0, False), err
    assert out.exists()


def test_convert_quiet_does_not_import_rich(tmp_path):
    given, out = _pandas_inputs(tmp_path)["csv"], tmp_path / "out.parquet"
    exit_code, imported, err = command_imports(["convert", given, out, "-q"], "rich")
    assert (exit_code, imported) == (0, False), err
    assert pq.read_table(out).num_rows == 3


def test_methods_json_lists_every_method_with_unit(capsys):
    listed = json.loads(hconv_inprocess("methods", "--json", capsys=capsys).stdout)
    assert [m["name"] for m in listed] == list(hconv.METHODS)
    units = {m["name"]: m["unit"] for m in listed}
    assert units["exact"] == "rad/s" and units["document"] == "m^2/s"
    assert all(m["fails"] and m["cost"] for m in listed)


def test_engines_lists_each_engine_within_80_columns(capsys, monkeypatch):
    monkeypatch.delenv("HCONV_ENGINE", raising=False)
    code, out, _ = run_inprocess("engines", capsys=capsys)
    assert code == 0 and [ln.split()[0] for ln in out.splitlines() if not ln.startswith(" ")] == [
        "compiled",
        "numpy",
        "auto",
    ]
    assert "built in" in out and "numba" not in out
    assert max(len(ln) for ln in out.splitlines()) <= 80


def test_convert_engine_option_rejects_others_in_one_line(tmp_path, capsys):
    proc = hconv_inprocess(
        "convert", "examples/data/scene.csv", str(tmp_path / "o.csv"), "--engine", "gpu", capsys=capsys
    )
    assert proc.returncode == 2 and b"Traceback" not in proc.stderr and b"gpu" in proc.stderr


def test_methods_table_renders(capsys):
    out = hconv_inprocess("methods", capsys=capsys).stdout.decode()
    for name in hconv.METHODS:
        assert name in out


NARROW = [
    (["methods"], (80, 60)),
    (["diagnose", str(EXAMPLES / "engine-log.csv")], (80, 60)),
    (["diagnose", str(EXAMPLES / "free-body-log.csv")], (80, 60)),
    (["compare", str(EXAMPLES / "scene.parquet")], (80, 60)),
    (["stability", "--no-chart", "--rows", "4"], (80,)),
    (["engines"], (80, 60)),
    (["one", "--H", "1,2,3", "--I", "2.5,2.5,4,-0.5,0,0", "--r", "0.1,0.2,0.3", "--method", "document"], (80,)),
    (["convert", str(EXAMPLES / "scene.csv"), "out.csv"], (80, 60)),
    (["generate", "g.csv", "--rows", "10"], (80, 60)),
]


@pytest.mark.parametrize("args,width", [(a, w) for a, widths in NARROW for w in widths], ids=lambda x: str(x)[:12])
def test_commands_on_a_narrow_terminal_cut_nothing(tmp_path, args, width):
    """What a user at an 80- or 60-column terminal sees: no line runs over, no '…' stands for a
    cut name or number, and every method name the command shows is whole."""
    code, shown = run_on_terminal(*args, columns=width, cwd=tmp_path)
    assert code == 0, shown
    lines = shown.splitlines()
    assert max(len(ln) for ln in lines) <= width, max(lines, key=len)
    assert "…" not in shown and "Traceback" not in shown
    if args[0] in ("methods", "compare", "stability"):
        for name in hconv.METHODS:
            assert any(name in ln for ln in lines), name


@pytest.mark.parametrize("width", [80, 60])
def test_convert_progress_tells_long_names_apart_on_a_narrow_terminal(tmp_path, width):
    """Two files whose long names differ only at their end: every frame of the progress bar keeps
    the end of the name it converts and fits the terminal (cut at the end, both looked alike)."""
    names = [f"spacecraft-attitude-flight-recorder-2024-06-01T12-00-00Z-ground-station-run-000{k}.csv" for k in (1, 2)]
    for name, other in (names, names[::-1]):
        (tmp_path / name).write_bytes((EXAMPLES / "scene.csv").read_bytes())
        code, shown = run_on_terminal("convert", name, "out.csv", "--force", columns=width, cwd=tmp_path)
        assert code == 0, shown
        lines = shown.splitlines()
        assert max(len(ln) for ln in lines) < width, max(lines, key=len)  # the last column left free
        frames = [ln for ln in lines if ln.startswith("converting ")]
        assert frames and all(name[-12:] in ln and other[-12:] not in ln for ln in frames), shown


def test_methods_in_a_pipe_is_tab_separated_text(capsys):
    proc = hconv_inprocess("methods", capsys=capsys)
    lines = proc.stdout.decode().splitlines()
    assert proc.returncode == 0 and "\x1b" not in proc.stdout.decode() and not set("┃━│─") & set(proc.stdout.decode())
    assert lines[0].split("\t")[:3] == ["method", "unit", "exact"]
    assert [ln.split("\t")[0] for ln in lines[1:]] == list(hconv.METHODS)
    assert {len(ln.split("\t")) for ln in lines} == {7}


def test_convert_table_accepts_record_batch():
    batch = pa.RecordBatch.from_pydict({c: [1.0, 2.0] for c in CONTRACT[:9]} | {"id": ["a", "b"]})
    got = hconv.convert_table(batch)
    assert isinstance(got, pa.Table)
    assert got.column_names == CONTRACT[:9] + ["id"] + OUT_COLS


@pytest.mark.parametrize(
    "args,needle",
    [
        (["convert", "in.csv", "out.csv", "--method", "nope"], "'nope' is not one of"),
        (["convert", "in.csv", "out.csv", "--precision", "16"], "must be 64 or 32"),
        (["convert", "in.csv", "out.csv", "--threads", "0"], "--threads must be a whole number, 1 or more"),
        (["convert", "in.csv"], "Missing argument 'OUT'"),
        (["bogus"], "No such command 'bogus'"),
    ],
)
def test_cli_usage_errors_are_one_line_exit_2(args, needle, capsys):
    assert_one_line_error(hconv_inprocess(*args, capsys=capsys), 2, needle)


def test_convert_excel_semicolon_csv_with_decimal_commas_converts_right(tmp_path, capsys):
    """Before: refused with "convert the delimiter to commas first", which turned 1,5 into two
    values. The file as Excel saves "CSV (semicolon)": a byte-order mark, CRLF, a quoted ';'."""
    from fractions import Fraction

    src = tmp_path / "excel.csv"
    src.write_bytes(
        "\ufeffname;Hx;Hy;Hz;I1;I2;I3\r\n"
        '"Rad 1; vorne";1,5;-2,25;0,5;0,5;1,5;2,5\r\n'
        "Rad 2;3;0;1e-1;2;4;0,25\r\n".encode()
    )
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert "# read as CSV: ';' separated, decimal ','" in proc.stderr.decode()
    rows = list(csv.DictReader(io.StringIO((tmp_path / "out.csv").read_text())))
    assert [r["name"] for r in rows] == ["Rad 1; vorne", "Rad 2"]
    H = [("1.5", "-2.25", "0.5"), ("3", "0", "1e-1")]
    I = [("0.5", "1.5", "2.5"), ("2", "4", "0.25")]
    for r, h, i in zip(rows, H, I, strict=True):
        want = [float(Fraction(a) / Fraction(b)) for a, b in zip(h, i, strict=True)]
        assert [float(r[c]) for c in ("wx", "wy", "wz")] == want
        assert [float(r[c]) for c in ("Hx", "Hy", "Hz")] == [float(x) for x in h]


def test_convert_tsv_reads_and_writes_tabs(tmp_path, capsys):
    """Before: "cannot tell the format" of a .tsv, and "separated by tabs" with --from csv."""
    src = tmp_path / "log.tsv"
    src.write_text("label\tHx\tHy\tHz\tI1\tI2\tI3\na,b\t1\t2\t3\t1\t2\t4\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.tsv"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert "# read as CSV: tab separated, decimal '.'" in proc.stderr.decode()
    head, row = (tmp_path / "out.tsv").read_text().splitlines()
    assert head.split("\t")[:8] == ["label", "Hx", "Hy", "Hz", "I1", "I2", "I3", "wx"]
    assert row.split("\t")[:10] == ["a,b", "1", "2", "3", "1", "2", "4", "1", "1", "0.75"]
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), "-q", capsys=capsys)
    assert (tmp_path / "out.csv").read_text().splitlines()[1].startswith('"a,b",1,2,3,')


def test_convert_commented_csv_skips_comment_lines(tmp_path, capsys):
    """Before: the first comment line was taken for the header: "the header names 1 columns"."""
    src = tmp_path / "logger.csv"
    src.write_text("# logger v2, 2026-12-01\n# H in kg*m^2/s\nHx,Hy,Hz,I1,I2,I3\n2,4,6,1,2,4\n2,4,6,2,2,2\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert "2 comment lines skipped" in proc.stderr.decode()
    rows = list(csv.DictReader(io.StringIO((tmp_path / "out.csv").read_text())))
    assert [(r["wx"], r["wy"], r["wz"]) for r in rows] == [("2", "2", "1.5"), ("1", "2", "3")]


def test_convert_units_row_csv_takes_the_units(tmp_path, capsys):
    """Before: the row of units was data ("column 'Hx' must be numeric but holds 'kg*m^2/s'")."""
    src = tmp_path / "cad.csv"
    src.write_text(
        "part,Hx,Hy,Hz,I1,I2,I3\n-,kg*m^2/s,kg*m^2/s,kg*m^2/s,g*cm^2,g*cm^2,kg*mm^2\nwheel,1,2,3,2e7,4e7,5e6\n"
    )
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr
    assert "units from the row under the header" in proc.stderr.decode()
    units, *rows = list(csv.DictReader(io.StringIO((tmp_path / "out.csv").read_text())))
    assert len(rows) == 1 and rows[0]["part"] == "wheel"  # the units row is not a data row
    assert units["part"] == "-" and units["I3"] == "kg*mm^2" and units["wx"] == "rad/s"  # it is the output's
    # 2e7 g*cm^2 = 2 kg*m^2, 4e7 g*cm^2 = 4 kg*m^2, 5e6 kg*mm^2 = 5 kg*m^2
    assert [float(rows[0][c]) for c in ("wx", "wy", "wz")] == [0.5, 0.5, 0.6]


def test_convert_delimiter_and_decimal_options_override_the_sniff(tmp_path, capsys):
    src = tmp_path / "in.txt.csv"
    # a header that splits alike at ',' and ';', each naming one of hconv's columns
    src.write_text("Hx,Hy;Hz\n1,2;3\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 2, "cannot tell the delimiter", "pass --delimiter ',' or --delimiter ';'")
    src.write_text("Hx;Hy;Hz;I1;I2;I3\n1;2;3;4;5;8\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), "--delimiter", "tab", capsys=capsys)
    assert_one_line_error(proc, 3, "separated by semicolons, not tabs: pass --delimiter semicolon or drop --delimiter")
    named = tmp_path / "in.tsv"  # the name says tabs; the file has semicolons
    named.write_text(src.read_text())
    proc = hconv_inprocess("convert", str(named), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(proc, 3, "pass --delimiter semicolon, or name the file .csv)")
    src.write_text("Hx;Hy;Hz;I1;I2;I3\n1,5;2;3;4;5;7,5\n")
    proc = hconv_inprocess(
        "convert", str(src), str(tmp_path / "out.csv"), "--delimiter", ";", "--decimal", ",", "-q", capsys=capsys
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out.csv").read_text().splitlines()[1].startswith("1.5,2,3,4,5,7.5,0.375,0.4,0.4,")


def test_convert_ambiguous_decimal_mark_names_the_option(tmp_path, capsys):
    src = tmp_path / "in.csv"
    src.write_text("Hx;Hy;Hz;I1;I2;I3\n1,5;2.5;3;4;5;8\n")
    proc = hconv_inprocess("convert", str(src), str(tmp_path / "out.csv"), capsys=capsys)
    assert_one_line_error(
        proc, 2, "cannot tell the decimal mark: column 'Hx' holds '1,5' and column 'Hy' holds '2.5'", "--decimal ','"
    )


@pytest.mark.parametrize(
    "args, needle",
    [
        (
            ["--delimiter", "x"],
            "--delimiter takes one of ',', ';', '\\t', '|' (or comma, semicolon, tab, bar), got 'x'",
        ),
        (["--decimal", ";"], "--decimal takes '.' or ',', got ';'"),
        (["--decimal", ",", "--delimiter", ","], "--decimal , needs another delimiter than the comma"),
    ],
)
def test_convert_bad_delimiter_or_decimal_is_one_line(args, needle, tmp_path, capsys):
    proc = hconv_inprocess("convert", "in.csv", str(tmp_path / "out.csv"), *args, capsys=capsys)
    assert_one_line_error(proc, 2, needle)


def test_convert_file_write_failure_midway_leaves_nothing(tmp_path, monkeypatch, rng):
    """A full disk on the writer thread: the error reaches the caller and no file is left."""
    import errno

    from hconv.tables import output, pipeline

    n = 300_000
    t = pa.table({c: rng.normal(size=n) + (3.0 if c in ("Ixx", "Iyy", "Izz") else 0.0) for c in CONTRACT[:9]})
    pq.write_table(t, tmp_path / "in.parquet")
    calls = {"n": 0}
    real = output.Output.write

    def failing(self, table):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, table)

    monkeypatch.setattr(output.Output, "write", failing)
    with pytest.raises(OSError, match="No space left"):
        pipeline.convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "out.parquet"))
    assert calls["n"] == 3
    no_leftovers(tmp_path, {"in.parquet"})


@pytest.mark.parametrize("args", [["methods", "--json"], ["generate", "-", "--rows", "200000", "--to", "csv"]])
def test_cli_reader_closing_pipe_early_is_quiet(args):
    cmd = f'"{sys.executable}" -m hconv {" ".join(args)} | head -n 1'
    proc = subprocess.run(cmd, shell=True, capture_output=True, timeout=120, executable="/bin/bash")
    assert len(proc.stdout.decode().splitlines()) == 1
    assert "error" not in proc.stderr.decode() and "Traceback" not in proc.stderr.decode()


@pytest.mark.parametrize("to", ["parquet", "arrow"])
def test_convert_into_pipe_reader_closing_early_is_quiet(tmp_path, rng, to):
    """A Parquet or Arrow file output into a pipe is spooled and copied at the end; a reader that
    stops early (`| head -c 10`) stops the command as it stops one writing CSV: exit 0, quietly,
    no summary of rows that never reached it."""
    n = 200_000
    t = pa.table({c: rng.normal(size=n) + (3.0 if c in ("Ixx", "Iyy", "Izz") else 0.0) for c in CONTRACT[:9]})
    pq.write_table(t, tmp_path / "in.parquet")
    convert = f'"{sys.executable}" -m hconv convert in.parquet - --to {to}'
    cmd = f"{convert} | head -c 10 > /dev/null; echo ${{PIPESTATUS[0]}}"
    proc = subprocess.run(cmd, shell=True, capture_output=True, timeout=120, executable="/bin/bash", cwd=tmp_path)
    err = proc.stderr.decode()
    assert proc.stdout.decode().split() == ["0"], err
    assert "# time" not in err and "error" not in err and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.parquet"]  # no spool left


def test_version_is_one_source(capsys):
    import importlib.metadata

    proc = hconv_inprocess("--version", capsys=capsys)
    assert proc.returncode == 0
    assert proc.stdout.decode().strip() == f"hconv {hconv.__version__}"
    assert importlib.metadata.version("hconv") == hconv.__version__


def test_help_short_option_on_every_command(capsys):
    from hconv import cli

    commands = [c.name or c.callback.__name__ for c in cli.app.registered_commands]
    assert "convert" in commands and "engines" in commands
    for command in ["", *commands]:
        args = [command] if command else []
        short, long = hconv_inprocess(*args, "-h", capsys=capsys), hconv_inprocess(*args, "--help", capsys=capsys)
        assert short.returncode == 0 and b"Usage:" in short.stdout and short.stdout == long.stdout, command


def test_help_at_80_columns_splits_no_choice(capsys):
    """Every command's --help at 80 columns: no line runs over, and every choice of every option
    shows whole on one line (as a metavar, [exact|refined|c/holesky|...] was split mid-name)."""
    import re

    import click
    import typer

    from hconv import cli

    root = typer.main.get_command(cli.app)
    for name, command in [("", root), *root.commands.items()]:  # type: ignore[attr-defined]
        proc = hconv_inprocess(*([name] if name else []), "--help", capsys=capsys, columns="80")
        text = proc.stdout.decode()
        lines = text.splitlines()
        assert proc.returncode == 0 and max(len(ln) for ln in lines) <= 80, name
        assert "…" not in text, name
        for param in command.params:
            if isinstance(param.type, click.Choice):
                for choice in param.type.choices:
                    whole = re.compile(rf"(?<![\w-]){re.escape(str(choice))}(?![\w-])")
                    assert any(whole.search(ln) for ln in lines), (name, param.name, choice)


def test_show_completion_bash_prints_the_script_for_hconv(capsys):
    proc = hconv_inprocess("--show-completion", "bash", capsys=capsys)
    script = proc.stdout.decode()
    assert proc.returncode == 0, proc.stderr.decode()
    assert "_HCONV_COMPLETE=complete_bash" in script and script.rstrip().endswith("hconv")
    assert hconv_inprocess("--show-completion", "zsh", capsys=capsys).stdout.startswith(b"#compdef hconv")
    assert_one_line_error(hconv_inprocess("--show-completion", "tcsh", capsys=capsys), 2, "'tcsh' is not one of")


def test_completion_completes_choices_and_adds_no_option_to_commands(capsys):
    env = dict(os.environ, _HCONV_COMPLETE="complete_bash", COMP_WORDS="hconv convert --method doc", COMP_CWORD="3")
    proc = subprocess.run([sys.executable, "-m", "hconv"], capture_output=True, env=env, timeout=60)
    assert proc.returncode == 0 and proc.stdout.decode().split() == ["document", "document-principal"]
    import typer

    from hconv import cli

    root = typer.main.get_command(cli.app)
    assert {"install_completion", "show_completion"} <= {p.name for p in root.params}
    for name, command in root.commands.items():  # type: ignore[attr-defined]
        assert not {p.name for p in command.params} & {"install_completion", "show_completion"}, name
        assert b"completion" not in hconv_inprocess(name, "--help", capsys=capsys).stdout, name


@pytest.mark.parametrize(
    "words, want",
    [
        ("hconv convert a.csv b.csv --precision ", ["64", "32"]),
        ("hconv one --H 1,2,3 --I 1 --precision 3", ["32"]),
        ("hconv bodies m.urdf --form ", ["sym6", "principal"]),
        ("hconv generate o.csv --scene cy", ["cylinder"]),
    ],
)
def test_completion_completes_options_that_are_not_choice_types(words, want):
    """An int option and options the library checks itself completed nothing before."""
    cword = len(words.split()) - (0 if words.endswith(" ") else 1)
    env = dict(os.environ, _HCONV_COMPLETE="complete_bash", COMP_WORDS=words, COMP_CWORD=str(cword))
    proc = subprocess.run([sys.executable, "-m", "hconv"], capture_output=True, env=env, timeout=60)
    assert proc.returncode == 0 and proc.stdout.decode().split() == want, proc.stderr.decode()


def test_one_has_no_short_method_option_beside_mass(capsys):
    """--m is the mass; a short -m for --method sat one keystroke away from it."""
    proc = hconv_inprocess("one", "--H", "1,0,0", "--I", "1", "-m", "5", capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 2 and "-m" in err and len(err.strip().splitlines()) == 1
    ok = hconv_inprocess("one", "--H", "1,0,0", "--I", "1", "--m", "5", "--method", "refined", capsys=capsys)
    assert ok.returncode == 0 and b"status   = ok" in ok.stdout


def test_help_usage_lines_name_arguments_plainly_and_generate_says_stdout(capsys):
    """Before: 'Usage: hconv convert [OPTIONS] {IN} {OUT}' (typer's braces for a required
    argument), no help for generate's --seed, and 'hconv generate: 1,000 rows to - in …'."""
    from helpers import run_inprocess

    for command, usage in [("convert", "IN OUT"), ("bodies", "MODEL [OUT]"), ("generate", "OUT")]:
        code, out, _ = run_inprocess(command, "--help", capsys=capsys)
        assert code == 0 and f"Usage: hconv {command} [OPTIONS] {usage}" in out, out
    code, out, _ = run_inprocess("generate", "--help", capsys=capsys)
    assert "the random draw; the same seed gives" in out
    code, _, err = run_inprocess("generate", "-", "--rows", "3", "--to", "csv", capsys=capsys)
    assert code == 0 and err.startswith("hconv generate: 3 rows to stdout in "), err


def test_convert_unquoted_glob_of_many_files_is_one_short_line(tmp_path, capsys):
    """Before: typer's message listed every file (99 files: 2,421 columns), the hint at its end."""
    files = []
    for k in range(99):
        f = tmp_path / f"part-{k:02d}.csv"
        f.write_bytes((EXAMPLES / "scene.csv").read_bytes()[:200])
        files.append(str(f))
    proc = hconv_inprocess("convert", *files, capsys=capsys)
    err = proc.stderr.decode()
    assert (proc.returncode, err.count("\n")) == (2, 1)
    assert err.startswith(
        "hconv: error: 97 extra arguments after IN and OUT: for several files, quote the glob so that hconv "
        "expands it, or give their directory (the first: '"
    )
    assert len(err) < 250
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(os.path.basename(f) for f in files)
