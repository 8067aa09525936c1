"""What the CLI shows people: the run summary, the progress bar and the methods table (rich).

rich is imported here only, so that ``hconv one`` does not pay for it.
"""
from __future__ import annotations

from typing import Optional

from rich.console import Console
from rich.table import Table

from hconv.methods import METHODS


def summary(tally, console: Optional[Console] = None) -> None:
    """Print a run's summary: rows, rows per status, the worst residual and the time taken."""
    console = console or Console(stderr=True)
    rate = f"{tally.rows / tally.seconds:,.0f} rows/s" if tally.seconds > 0 and tally.rows else "-"
    console.print(f"[bold]hconv convert[/bold] · method {tally.method} · ω in {tally.unit}")
    t = Table(show_header=True, header_style="bold")
    t.add_column("status")
    t.add_column("rows", justify="right")
    for name, n in tally.counts().items():
        t.add_row(name, f"{n:,}", style=None if name == "ok" else "yellow")
    t.add_row("total", f"{tally.rows:,}", style="bold")
    console.print(t)
    if tally.worst_row is not None:
        console.print(f"worst residual {tally.worst_residual:.3g} (data row {tally.worst_row}), "
                      "relative to I⁻¹H")
    console.print(f"time {tally.seconds:.3f} s ({rate})")


class ProgressBar:
    """A transient rich progress bar; call it as ``bar(done, total)``."""

    def __init__(self, description: str, console: Optional[Console] = None):
        from rich.progress import BarColumn, Progress, TaskProgressColumn, TimeRemainingColumn

        self._p = Progress("[progress.description]{task.description}", BarColumn(), TaskProgressColumn(),
                           TimeRemainingColumn(), console=console or Console(stderr=True), transient=True)
        self._task = self._p.add_task(description, total=None)

    def __call__(self, done: int, total: Optional[int]) -> None:
        self._p.update(self._task, completed=done, total=total)

    def __enter__(self):
        self._p.start()
        return self

    def __exit__(self, *exc) -> None:
        self._p.stop()


def methods_table(console: Optional[Console] = None) -> None:
    """Print the registered methods: unit, exactness, cost and when each fails."""
    console = console or Console()
    t = Table(show_lines=True)
    for col in ("method", "unit", "exact", "what it computes", "cost", "fails when"):
        t.add_column(col)
    for m in METHODS.values():
        t.add_row(m.name, m.unit, "yes" if m.exact else "no", m.summary, m.cost, m.fails)
    console.print(t)
