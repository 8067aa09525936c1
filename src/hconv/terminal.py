"""Tables and notes as the CLI prints them: fitted to a terminal, or tab-separated text for tools.

Every table goes through :func:`show`. On a terminal it fits the width without cutting a name or
a number: prose wraps at spaces, and a table too wide for that is split into several that repeat
its key columns, or, when even that does not fit, printed as a list. Anywhere else (a pipe, a
file) it is tab-separated text with a header line, and every line that is not a table row starts
with ``#``, so that ``cut``, ``awk -F'\t'`` and ``column -t -s$'\t'`` read it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rich.cells import cell_len
from rich.console import Console
from rich.padding import Padding
from rich.table import Table
from rich.text import Text


@dataclass(frozen=True)
class Col:
    """A table column: its header, whether it holds numbers (set right), and whether its cells
    are prose that may wrap at spaces. Names and numbers never wrap: they show whole or the table
    takes another layout."""

    header: str
    right: bool = False
    prose: bool = False


Cell = str | Text


def _text(cell: Cell) -> str:
    return cell.plain if isinstance(cell, Text) else cell


def _one_line(text: str) -> str:
    return " ".join(text.split())  # a tab or newline inside a cell would shift the columns after it


def _line(console: Console, text: str) -> None:
    console.file.write(text + "\n")  # as it is: rich would expand the tabs into spaces


def note(console: Console, text: Cell) -> None:
    """A line that is not a table row: wrapped at spaces on a terminal, one ``#`` line elsewhere."""
    if console.is_terminal:
        # rich keeps the space it wrapped at on the end of each line: wrap here and drop it
        for line in (text if isinstance(text, Text) else Text(text)).wrap(console, console.width):
            line.rstrip()
            console.print(line)
    else:
        _line(console, "# " + _one_line(_text(text)))


def count(console: Console, n: int) -> str:
    """A count in a table cell: with thousands separators for people, bare for tools."""
    return f"{n:,}" if console.is_terminal else str(n)


def _longest_word(text: str) -> int:
    return max((cell_len(w) for w in text.split()), default=0)


def _longest_line(text: str) -> int:
    return max((cell_len(ln) for ln in text.splitlines()), default=0)


def _frame(n: int) -> int:
    """The columns a rich table's borders and padding take beside ``n`` columns of text."""
    return 3 * n + 1


def _widths(cols: Sequence[Col], rows: Sequence[Sequence[Cell]]) -> tuple[list[int], list[int]]:
    """Per column, the narrowest width that cuts nothing and the width that wraps nothing."""
    least, most = [], []
    for k, c in enumerate(cols):
        cells = [_text(r[k]) for r in rows]
        least.append(
            max([_longest_word(c.header)] + [_longest_word(x) if c.prose else _longest_line(x) for x in cells])
        )
        most.append(max([_longest_line(c.header)] + [_longest_line(x) for x in cells]))
    return least, most


def _share(least: list[int], most: list[int], room: int) -> list[int]:
    """Widths from ``least`` up towards ``most``, in proportion to what each column lacks, within ``room``."""
    if sum(most) <= room:
        return list(most)
    spare, lack = room - sum(least), [m - n for n, m in zip(least, most)]
    widths = [n + spare * d // sum(lack) for n, d in zip(least, lack)]
    for k in sorted(range(len(widths)), key=lambda k: widths[k] - most[k]):
        if sum(widths) < room and widths[k] < most[k]:
            widths[k] += 1
    return widths


def show(
    console: Console,
    cols: Sequence[Col],
    rows: Sequence[Sequence[Cell]],
    *,
    title: Cell | None = None,
    keys: int = 1,
    styles: Sequence[str | None] | None = None,
    lines: bool = False,
    split: bool = True,
) -> None:
    """Print a table (see the module's docstring); ``keys`` leading columns name a row. A table
    too wide for the terminal is split into narrower ones, or with ``split=False`` (prose, which
    reads better whole) printed as a list."""
    if title is not None:
        note(console, title)
    if not console.is_terminal:
        _line(console, "\t".join(_one_line(c.header) for c in cols))
        for r in rows:
            _line(console, "\t".join(_one_line(_text(x)) for x in r))
        return
    least, most = _widths(cols, rows)
    fits = lambda idx: sum(least[k] for k in idx) + _frame(len(idx)) <= console.width  # noqa: E731
    everything = list(range(len(cols)))
    if fits(everything):
        parts = [everything]
    else:
        parts, key_cols = [], list(range(keys))
        for k in everything[keys:]:
            if parts and fits(parts[-1] + [k]):
                parts[-1].append(k)
            elif split and fits(key_cols + [k]):
                parts.append(key_cols + [k])
            else:
                _as_list(console, cols, rows, keys, styles)
                return
    for idx in parts:
        room = console.width - _frame(len(idx))
        widths = _share([least[k] for k in idx], [most[k] for k in idx], room)
        t = Table(header_style="bold", show_lines=lines)
        for k, w in zip(idx, widths):
            t.add_column(cols[k].header, justify="right" if cols[k].right else "left", width=w)
        for j, r in enumerate(rows):
            t.add_row(*(r[k] for k in idx), style=styles[j] if styles else None)
        console.print(t)


def _as_list(
    console: Console,
    cols: Sequence[Col],
    rows: Sequence[Sequence[Cell]],
    keys: int,
    styles: Sequence[str | None] | None,
) -> None:
    """A table too wide for the terminal: each row as its key, then one line per other column."""
    labels = [_one_line(c.header) + ":" for c in cols[keys:]]
    for j, r in enumerate(rows):
        if j:
            console.print()
        head = Text(" · ".join(_text(x) for x in r[:keys]), style="bold")
        if styles and styles[j]:
            head.stylize(styles[j])  # type: ignore[arg-type]
        console.print(head)
        g = Table.grid(padding=(0, 1))
        g.add_column(no_wrap=True)
        g.add_column()
        for label, x in zip(labels, r[keys:]):
            g.add_row(label, x)
        console.print(Padding(g, (0, 0, 0, 2)))
