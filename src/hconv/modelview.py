"""What ``hconv bodies`` shows without OUT: each body's mass, principal moments and status, then
the reason for every body that is not ok.

On a terminal it is a rich table that fits the width without cutting a name or a number (a
table too wide for it becomes a list, one body per paragraph), and the reasons wrap at spaces.
Anywhere else (a pipe, a file) it is tab-separated text with a header line and the reason as the
last column; every other line starts with ``#``, so that ``cut``, ``awk -F'\\t'`` and ``grep``
read it. So is a model of more than :data:`MAX_TABLE` bodies on a terminal too: rich lays a
table out at some milliseconds a row, an hour for the million bodies a model may have.
"""

from __future__ import annotations

import io

from rich import box
from rich.cells import cell_len
from rich.console import Console
from rich.table import Table
from rich.text import Text

from hconv import terminal
from hconv.tools.models import Body, Model

_HEADERS = ("body", "m kg", "I1 kg·m²", "I2 kg·m²", "I3 kg·m²", "status")
#: The most bodies shown as a table on a terminal (a robot has tens to hundreds; docs/measurements.md).
MAX_TABLE = 2000


def _g(x: float) -> str:
    return "-" if x != x else f"{x:.4g}"


#: A name's tab, newline or carriage return (written in the file as &#9;, &#10;, &#13;) as its
#: escape: written out, it would split the body's row into columns or lines of its own.
_ESCAPES = str.maketrans({"\t": "\\t", "\n": "\\n", "\r": "\\r"})


def _cell(name: str) -> str:
    return name.translate(_ESCAPES)


def _cells(b: Body) -> list[str]:
    return [_cell(b.name), _g(b.m), *(_g(float(s)) for s in b.moments), b.status]


def summary_line(model: Model) -> str:
    """``7 bodies: 3 ok, 1 not_physical, ...``"""
    n = len(model.bodies)
    counts = ", ".join(f"{k} {s}" for s, k in model.counts().items())
    return f"{n} bod{'y' if n == 1 else 'ies'}" + (f": {counts}" if counts else "")


def show(model: Model, console: Console | None = None) -> None:
    """Print ``model``'s bodies (see the module's docstring)."""
    console = console or Console()
    title = f"hconv bodies · {model.path} ({model.format}) · {summary_line(model)}"
    principal = "I1 <= I2 <= I3: principal moments about the centre of mass"
    if not console.is_terminal or len(model.bodies) > MAX_TABLE:
        out = console.file
        out.write(f"# {title}\n# {principal}\n")
        if console.is_terminal:
            out.write(f"# more bodies than a table shows ({MAX_TABLE:,}): tab-separated text\n")
        out.write("\t".join(["body", "m", "I1", "I2", "I3", "status", "reason"]) + "\n")
        for b in model.bodies:
            numbers = [repr(float(x)) for x in (b.m, *b.moments)]
            out.write("\t".join([_cell(b.name), *numbers, b.status, " ".join(b.reason.split())]) + "\n")
        for note in model.notes:
            out.write(f"# note: {' '.join(note.split())}\n")
        return
    terminal.note(console, Text(title, style="bold"))  # terminal.note: wrapped, no trailing spaces
    terminal.note(console, principal)
    t = Table(box=box.SIMPLE_HEAD, pad_edge=False, show_edge=False, header_style="bold")
    for k, h in enumerate(_HEADERS):
        t.add_column(h, justify="left" if k in (0, 5) else "right", no_wrap=True)
    for b in model.bodies:
        t.add_row(*_cells(b), style=None if b.status == "ok" else "yellow")
    if _width(t) <= console.width:
        console.print(t)
    else:  # one body per paragraph: a name or a number is never cut
        for b in model.bodies:
            c = _cells(b)
            terminal.note(console, Text(c[0], style="bold"))
            terminal.note(console, f"  m {c[1]} kg · I1, I2, I3 {c[2]}, {c[3]}, {c[4]} kg·m² · {c[5]}")
    if any(b.reason for b in model.bodies):
        console.print()
    for b in model.bodies:
        if b.reason:
            line = Text()
            line.append(_cell(b.name), style="bold")
            line.append(f" ({b.status}): {b.reason}")
            terminal.note(console, line)
    for note in model.notes:
        terminal.note(console, f"note: {note}")


def _width(t: Table) -> int:
    """The columns ``t`` takes when nothing in it wraps."""
    buf = Console(file=io.StringIO(), width=10_000, color_system=None)
    buf.print(t)
    return max(cell_len(line) for line in buf.file.getvalue().splitlines())  # type: ignore[attr-defined]
