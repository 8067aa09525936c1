"""Tables and notes (hconv.terminal): fitted to a terminal without cutting a name or a number."""

from __future__ import annotations

from helpers import BOX, assert_fits, shown, terminal

import hconv.terminal


def test_show_prints_a_list_when_even_one_column_beside_the_keys_is_too_wide():
    cols = [hconv.terminal.Col("name"), hconv.terminal.Col("a"), hconv.terminal.Col("b", right=True)]
    rows = [["document-principal", "x" * 50, "1e+300"]]
    console = terminal(60)
    hconv.terminal.show(console, cols, rows)
    lines = shown(console)
    assert_fits(lines, 60, ["document-principal", "x" * 50, "1e+300"])
    assert lines[0].strip() == "document-principal" and not BOX & set("".join(lines))


def test_note_wraps_on_a_terminal_without_trailing_spaces():
    """Before: rich kept the space it wrapped at on the end of each line."""
    console = terminal(40)
    hconv.terminal.note(console, "every row is explained by at least one hypothesis, and then some more words")
    lines = shown(console)
    assert len(lines) > 1 and all(ln == ln.rstrip() and len(ln) <= 40 for ln in lines)
    assert " ".join(lines) == "every row is explained by at least one hypothesis, and then some more words"
