"""Messages spell an option as their reader does: Python keywords for callers of the library, the
command line's options inside a command."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import hconv_inprocess

import hconv
from hconv import errors
from hconv.errors import UsageError


def test_option_spelled_as_a_keyword_outside_a_command():
    assert errors.option("degenerate_rtol") == "degenerate_rtol"
    assert errors.option("omega_unit", "deg/s") == "omega_unit='deg/s'"
    assert errors.entry("mapping", "Hx", "Lx") == "mapping={'Hx': 'Lx'}"


def test_option_spelled_as_a_flag_inside_a_command_and_restored_after_an_error():
    with pytest.raises(RuntimeError), errors.command_line():
        assert errors.option("degenerate_rtol") == "--degenerate-rtol"
        assert errors.option("omega_unit", "deg/s") == "--omega-unit deg/s"
        assert errors.entry("mapping", "Hx", "Lx") == "--map Hx=Lx"
        assert errors.entry("unit_options", "I", "g*cm**2") == "--unit I=g*cm**2"
        raise RuntimeError
    assert errors.option("engine", "numba") == "engine='numba'"


@pytest.mark.parametrize(
    "kwargs, python, command",
    [
        ({"precision": 16}, "precision must be 64 or 32", ["--precision", "16"]),
        ({"degenerate_rtol": 2.0}, "degenerate_rtol must be at least 0", ["--degenerate-rtol", "2"]),
    ],
)
def test_option_error_names_the_keyword_in_python_and_the_flag_on_the_command_line(kwargs, python, command, capsys):
    with pytest.raises(UsageError) as info:
        hconv.convert(np.ones(3), np.eye(3), **kwargs)
    assert str(info.value).startswith(python) and "--" not in str(info.value)
    proc = hconv_inprocess("one", "--H", "1,2,3", "--I", "1,2,3", *command, capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 2 and err.startswith(f"hconv: error: {command[0]} ") and len(err.splitlines()) == 1


@pytest.mark.parametrize("n", [0, 1, 39, 40, 41, 5000])
def test_quoted_clips_a_long_value_to_its_start_and_end(n):
    """A value from a file is quoted in at most 40 characters (it was quoted whole: a CSV value of
    5,000 characters made a 5,156-column message), its start and end kept either side of "…"."""
    text = "".join(chr(ord("a") + k % 26) for k in range(n))
    shown = errors.quoted(text)
    inner = eval(shown)  # the repr of a str: the clipped text back
    assert len(inner) == min(n, 40)
    if n <= 40:
        assert inner == text
    else:
        head, tail = inner.split("…")
        assert text.startswith(head) and text.endswith(tail) and len(head) > len(tail) > 0


def test_quoted_keeps_a_line_break_escaped():
    assert errors.quoted("a\nb") == "'a\\nb'"


def test_entries_echo_a_long_value_clipped_on_the_command_line_and_in_python():
    """Before (second trial): `--unit I=<560 characters>` was echoed whole, twice, in a line of
    about 1,100 characters; a mapping option's value is echoed in at most ECHOED characters, and
    an option spelling a fix (a path) whole."""
    long = "q" * 300
    with errors.command_line():
        shown = errors.entry("unit_options", "I", long)
        mapped = errors.entry("mapping", "Hx", "L" * 300)
        path = errors.option("root", "/" + "d" * 300)  # a fix to copy: whole
    assert shown.startswith("--unit I=qqq") and len(shown) == len("--unit I=") + errors.ECHOED and "…" in shown
    assert mapped.startswith("--map Hx=LLL") and len(mapped) == len("--map Hx=") + errors.ECHOED
    assert path == "--root /" + "d" * 300
    python = errors.entry("unit_options", "I", long)
    assert python.startswith("unit_options={'I': 'q") and len(python) == len("unit_options=") + errors.ECHOED
    assert errors.entry("mapping", "Hx", "Lx") == "mapping={'Hx': 'Lx'}"  # short values whole


def test_cli_long_values_in_option_errors_are_clipped(capsys):
    """`--unit`, an invalid `--from` (click's own message) and `--omega-unit` with a pasted page
    of text: one line each, well under the 400 to 1,100 characters they were."""
    long = "q" * 300
    for args in (
        ("one", "--H", "1,2,3", "--I", "1", "--unit", f"I={long}"),
        ("one", "--H", "1,2,3", "--I", "1", "--omega-unit", long),
        ("convert", "in.csv", "-", "--from", long),
    ):
        proc = hconv_inprocess(*args, capsys=capsys)
        err = proc.stderr.decode()
        assert proc.returncode == 2 and err.count("\n") == 1 and len(err) < 300 and "…" in err, err
