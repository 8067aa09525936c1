"""Each option has one check and one message, wherever it comes in: hconv.convert, Conventions,
Job, and the command line."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import hconv_inprocess

import hconv
from hconv.errors import UsageError
from hconv.solve import options
from hconv.solve.options import Conventions, Options
from hconv.tables.job import Job

H, I = np.ones(3), np.array([1.0, 2.0, 3.0])


def _message(fn) -> str:
    with pytest.raises(UsageError) as info:
        fn()
    return str(info.value)


def test_check_precision_one_message_from_every_entry(tmp_path, capsys):
    want = "precision must be 64 or 32, got 16"  # Python callers are told the keyword
    assert _message(lambda: hconv.convert(H, I, precision=16)) == want
    assert _message(lambda: Job(precision=16)) == want
    want = "--precision must be 64 or 32, got 16"  # the command line, its option
    src = tmp_path / "in.csv"
    src.write_text("Hx,Hy,Hz,I\n1,2,3,4\n")
    for args in (
        ["convert", str(src), str(tmp_path / "o.csv"), "--precision", "16"],
        ["one", "--H", "1,2,3", "--I", "1", "--precision", "16"],
    ):
        proc = hconv_inprocess(*args, capsys=capsys)
        assert proc.returncode == 2 and proc.stderr.decode().strip() == f"hconv: error: {want}"


def test_check_degenerate_only_for_the_exact_family():
    want = "degenerate='pinv' applies to the exact methods, not to 'document'"
    r = np.ones(3)
    assert _message(lambda: hconv.convert(H, I, r, method="document", degenerate="pinv")) == want
    assert _message(lambda: Job("document", conventions=Conventions(degenerate="pinv"))) == want
    assert (
        _message(lambda: Conventions(degenerate_rtol=1.0)) == "degenerate_rtol must be at least 0 and below 1, got 1.0"
    )
    assert _message(lambda: hconv.convert(H, I, degenerate_rtol=-1e-3)).startswith("degenerate_rtol must be at least 0")


@pytest.mark.parametrize(
    "field, value, option",
    [
        ("frame", "sideways", "frame"),
        ("omega_frame", "up", "omega_frame"),
        ("about", "corner", "about"),
        ("products", "minus", "products"),
        ("degenerate", "drop", "degenerate"),
    ],
)
def test_conventions_bad_choice_names_the_option_and_choices(field, value, option):
    msg = _message(lambda: Conventions(**{field: value}))
    assert msg.startswith(f"{option} must be one of ") and msg.endswith(f"got {value!r}")


def test_conventions_needs_name_each_reason():
    need = Conventions(about="free", omega_frame="body").needs("document")
    assert list(need) == ["r", "m", "v", "q"]
    assert need["r"] == "method 'document' needs the offset r"


def test_choices_are_the_clis(capsys):
    # the CLI builds its choices from these tuples: an unknown one is refused by the command line itself
    proc = hconv_inprocess("one", "--H", "1,2,3", "--I", "1", "--about", "corner", capsys=capsys)
    assert proc.returncode == 2 and all(c in proc.stderr.decode() for c in options.ABOUT)


# One run configuration rule (options.configure) for every entry point: job= or the keywords, not
# both. Each entry converts one body with method lapack and gives back the method it used.
def _table():
    import pyarrow as pa

    names = ["Hx", "Hy", "Hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]
    return pa.table({n: [v] for n, v in zip(names, [1.0, 2.0, 3.0, 2.0, 3.0, 4.0, 0.0, 0.0, 0.0])})


def _parquet_method(path) -> str:
    import pyarrow.parquet as pq

    return pq.read_schema(path).metadata[b"hconv.method"].decode()


def _via_convert(tmp_path, **kw):
    return hconv.convert([1.0, 2.0, 3.0], [2.0, 3.0, 4.0], **kw).method


def _via_convert_body(tmp_path, **kw):
    return hconv.convert_body([1.0, 2.0, 3.0], [2.0, 3.0, 4.0], **kw).method


def _via_convert_table(tmp_path, **kw):
    return hconv.convert_table(_table(), **kw).schema.metadata[b"hconv.method"].decode()


def _via_output_schema(tmp_path, **kw):
    return hconv.output_schema(_table().schema, **kw).metadata[b"hconv.method"].decode()


def _via_convert_file(tmp_path, **kw):
    import pyarrow.parquet as pq

    pq.write_table(_table(), tmp_path / "in.parquet")
    hconv.convert_file(str(tmp_path / "in.parquet"), str(tmp_path / "out.parquet"), **kw)
    return _parquet_method(tmp_path / "out.parquet")


def _via_convert_dataset(tmp_path, **kw):
    import pyarrow.parquet as pq

    (tmp_path / "in").mkdir()
    pq.write_table(_table(), tmp_path / "in" / "a.parquet")
    hconv.convert_dataset(tmp_path / "in", tmp_path / "out", **kw)
    return _parquet_method(tmp_path / "out" / "a.parquet")


def _via_convert_path(tmp_path, **kw):
    import pyarrow.parquet as pq

    pq.write_table(_table(), tmp_path / "in.parquet")
    hconv.convert_path(tmp_path / "in.parquet", tmp_path / "out.parquet", **kw)
    return _parquet_method(tmp_path / "out.parquet")


ENTRIES = {
    "hconv.convert": _via_convert,
    "convert_body": _via_convert_body,
    "convert_table": _via_convert_table,
    "output_schema": _via_output_schema,
    "convert_file": _via_convert_file,
    "convert_dataset": _via_convert_dataset,
    "convert_path": _via_convert_path,
}


@pytest.mark.parametrize("entry", ENTRIES)
def test_configure_every_entry_point_takes_a_job(entry, tmp_path):
    job = Options(method="lapack") if entry == "hconv.convert" else Job(method="lapack")
    assert ENTRIES[entry](tmp_path, job=job) == "lapack"


@pytest.mark.parametrize("entry", ENTRIES)
def test_configure_every_entry_point_takes_the_keywords(entry, tmp_path):
    assert ENTRIES[entry](tmp_path, method="lapack", precision=64) == "lapack"


@pytest.mark.parametrize("entry", ENTRIES)
def test_configure_every_entry_point_refuses_a_job_and_keywords(entry, tmp_path):
    job = Options(method="lapack") if entry == "hconv.convert" else Job(method="lapack")
    kind = "Options" if entry == "hconv.convert" else "Job"
    message = _message(lambda: ENTRIES[entry](tmp_path, job=job, method="exact", precision=32))
    assert message == (
        f"{entry}: method, precision given beside job=; put them in the {kind} ({kind}(method=...)), "
        "which then holds the whole run configuration"
    )
    assert not (tmp_path / "out.parquet").exists() and not (tmp_path / "out").exists()


def test_configure_names_a_conventions_keyword_where_it_goes():
    message = _message(lambda: hconv.convert(H, I, job=Options(), degenerate="pinv"))
    assert "put them in the Options (Options(conventions=hconv.Conventions(degenerate=...)))" in message


def test_configure_folds_conventions_keywords_into_the_conventions():
    res = hconv.convert([1.0, 1.0, 0.0], [0.0, 1.0, 1.0], degenerate="pinv", degenerate_rtol=1e-9)
    same = hconv.convert(
        [1.0, 1.0, 0.0], [0.0, 1.0, 1.0], job=Options(conventions=Conventions(degenerate="pinv", degenerate_rtol=1e-9))
    )
    assert res.status == same.status == "degenerate" and np.array_equal(res.w, same.w)


def test_configure_makes_a_job_of_solve_options():
    out = hconv.convert_table(_table(), job=Options(method="lapack", precision=32))
    assert out.schema.field("wx").type == "float" and out.schema.metadata[b"hconv.method"] == b"lapack"


def test_configure_refuses_what_is_not_a_run_configuration():
    assert _message(lambda: hconv.convert(H, I, job="exact")) == (
        "job takes a hconv.Options, got 'exact' (str); for the method alone pass method='exact'"
    )


def test_convert_refuses_a_scene_it_would_ignore():
    job = Options(conventions=Conventions(about="pivot"))
    assert _message(lambda: hconv.convert(H, I, job=job)) == (
        "hconv.convert takes H and I as given, about one point and in one frame: about='pivot' "
        "is for hconv.convert_body (one body) or hconv.convert_table"
    )
    assert _message(lambda: hconv.convert(H, I, job=Job(omega_unit="deg/s"))) == (
        "hconv.convert reads no columns and gives ω in rad/s: omega_unit='deg/s' is for hconv.convert_table "
        "(or hconv.convert_body); give hconv.convert a hconv.Options"
    )


def test_options_diagnostics_takes_a_numpy_truth_and_refuses_text():
    """A numpy bool (what a comparison gives) is a truth; text such as 'no' would read as True."""
    assert hconv.convert([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], diagnostics=np.False_).residual is None
    assert hconv.convert([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], diagnostics=np.True_).residual == 0.0
    with pytest.raises(UsageError, match=r"^diagnostics must be True or False, got 'no'$"):
        hconv.convert([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], diagnostics="no")
