"""Each option has one check and one message, wherever it comes in: hconv.convert, Conventions,
Job, and the command line."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import hconv_inprocess

import hconv
from hconv.errors import UsageError
from hconv.solve import options
from hconv.solve.options import Conventions
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
