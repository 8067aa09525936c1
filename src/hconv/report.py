"""What the CLI shows people: the run summary, the progress bar and the methods table (rich).

rich is imported here only, so that ``hconv one`` does not pay for it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console
from rich.table import Table

from hconv.solve.methods import METHODS

if TYPE_CHECKING:
    from hconv.solve.methods import Method
    from hconv.tables.pipeline import Tally
    from hconv.tools.bench import Result as BenchResult
    from hconv.tools.compare import Comparison
    from hconv.tools.diagnose import Diagnosis
    from hconv.tools.stability import Point, Sweep


def summary(tally: Tally, console: Console | None = None) -> None:
    """Print a run's summary: rows, rows per status, the worst residual and the time taken."""
    console = console or Console(stderr=True)
    rate = f"{tally.rows / tally.seconds:,.0f} rows/s" if tally.seconds > 0 and tally.rows else "-"
    engines = " + ".join(tally.engines) or "-"
    console.print(f"[bold]hconv convert[/bold] · method {tally.method} · ω in {tally.unit} · engine {engines}")
    t = Table(show_header=True, header_style="bold")
    t.add_column("status")
    t.add_column("rows", justify="right")
    for name, n in tally.counts().items():
        t.add_row(name, f"{n:,}", style=None if name == "ok" else "yellow")
    t.add_row("total", f"{tally.rows:,}", style="bold")
    console.print(t)
    if tally.worst_row is not None:
        console.print(f"worst residual {tally.worst_residual:.3g} (data row {tally.worst_row}), relative to I⁻¹H")
    console.print(f"time {tally.seconds:.3f} s ({rate})")


class ProgressBar:
    """A transient rich progress bar; call it as ``bar(done, total)``."""

    def __init__(self, description: str, console: Console | None = None):
        from rich.progress import BarColumn, Progress, TaskProgressColumn, TimeRemainingColumn

        self._p = Progress(
            "[progress.description]{task.description}",
            BarColumn(),
            TaskProgressColumn(),
            TimeRemainingColumn(),
            console=console or Console(stderr=True),
            transient=True,
        )
        self._task = self._p.add_task(description, total=None)

    def __call__(self, done: int, total: int | None) -> None:
        self._p.update(self._task, completed=done, total=total)

    def __enter__(self) -> ProgressBar:
        self._p.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._p.stop()


def envelope(m: Method) -> str:
    """The cond(I) up to which a method's error stays within 1e-6, per precision, as text."""
    if not m.exact:
        return "n/a: not I⁻¹H"
    return " · ".join(
        f"{'singular' if lim == float('inf') else f'{lim:.1e}'} (f{p})"
        for p, lim in ((64, m.cond_limit(64)), (32, m.cond_limit(32)))
    )


def methods_table(console: Console | None = None) -> None:
    """Print the registered methods: unit, exactness, cost and when each fails."""
    console = console or Console()
    t = Table(show_lines=True)
    for col in ("method", "unit", "exact", "trusted to 1e-6 up to cond", "what it computes", "cost", "fails when"):
        t.add_column(col)
    for m in METHODS.values():
        t.add_row(m.name, m.unit, "yes" if m.exact else "no", envelope(m), m.summary, m.cost, m.fails)
    console.print(t)


def stability_tables(points: list[Point], sweeps: tuple[Sweep, ...], console: Console | None = None) -> None:
    """Per sweep and precision, a table of worst errors: rows are sweep points, columns methods;
    a trailing * marks a cell where most rows are flagged, — one where no row had an answer."""
    console = console or Console()
    names = list(METHODS)

    def cell(p: Point | None) -> str:
        if p is None or not np.isfinite(p.worst_error):
            text = "—"
        else:
            text = "0" if p.worst_error == 0 else f"{p.worst_error:.0e}"
        return text + ("*" if p is not None and p.flagged >= 0.5 else "")

    for sw in sweeps:
        for prec in (64, 32):
            t = Table(
                title=f"{sw.title}, float{prec}: worst relative error vs I⁻¹H (* most rows flagged)",
                title_justify="left",
                header_style="bold",
            )
            t.add_column(sw.xlabel, justify="right")
            for n in names:
                t.add_column(n, justify="right")
            for param in sw.params:
                got = {p.method: p for p in points if p.sweep == sw.name and p.precision == prec and p.param == param}
                t.add_row(f"{param:g}", *(cell(got.get(n)) for n in names))
            console.print(t)


def _duration(s: float) -> str:
    return f"{s * 1e6:.1f} µs" if s < 1e-3 else (f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s")


def user_table(user: dict, console: Console) -> None:
    """What users call: numpy.linalg.solve's time per call on the same rows, and each
    hconv.convert call by each engine as the ratio of that time to its own (above 1: faster)."""
    if not user:
        return
    engines = list(
        dict.fromkeys(e for times in user.values() for v in times.values() if isinstance(v, dict) for e in v)
    )
    t = Table(
        title="what users call: numpy.linalg.solve time / hconv.convert time (above 1: faster)",
        title_justify="left",
        header_style="bold",
    )
    t.add_column("rows", justify="right")
    t.add_column("I, diagnostics")
    t.add_column("solve", justify="right")
    for e in engines:
        t.add_column(e, justify="right")
    for n, times in user.items():
        solve = times["numpy.linalg.solve"]
        first = True
        for call, by_engine in times.items():
            if call == "numpy.linalg.solve":
                continue
            size = n if not n.isdigit() else f"{int(n):,}"
            t.add_row(
                size if first else "",
                call,
                _duration(solve) if first else "",
                *(f"{solve / by_engine[e]:.2f}" if e in by_engine else "" for e in engines),
            )
            first = False
    console.print(t)


def cold_table(cold: dict, console: Console) -> None:
    """A fresh process's first call by engine: import, first and second hconv.convert."""
    if not cold:
        return
    t = Table(title="first call of a fresh process, 100 rows", title_justify="left", header_style="bold")
    for col in ("engine", "import hconv", "first call", "second call"):
        t.add_column(col, justify="right" if col != "engine" else "left")
    for name, c in cold.items():
        t.add_row(name, _duration(c["import_s"]), _duration(c["first_call_s"]), _duration(c["second_call_s"]))
    console.print(t)


def bench_tables(res: BenchResult, console: Console | None = None) -> None:
    """The benchmark: a row per method and precision, then the targets as measured ratios."""
    console = console or Console()
    console.print(f"[bold]hconv bench[/bold] · {res.rows:,} rows · {res.machine}")
    user_table(res.user, console)
    cold_table(res.cold, console)
    console.print("[bold]kernels[/bold] (the arithmetic alone, for comparison; not what a user calls)")
    conds = list(next(iter(res.accuracy.values())))
    t = Table(header_style="bold")
    for col in ("method", "prec", "kernel Mrows/s", "× lapack", "convert Mrows/s"):
        t.add_column(col, justify="right" if col != "method" else "left")
    for c in conds:
        t.add_column(f"error at cond {float(c):g}\nmedian / worst", justify="right")
    lapack = res.kernel["lapack/64"]
    for key, speed in res.kernel.items():
        name, prec = key.split("/")
        errs = [res.accuracy[key][c] for c in conds]
        t.add_row(
            name,
            prec,
            f"{speed / 1e6:.2f}",
            f"{speed / lapack:.2f}",
            f"{res.convert[key] / 1e6:.2f}",
            *(f"{m:.0e} / {w:.0e}" for m, w in errs),
        )
    console.print(t)
    g = Table(title="targets (ratios of rates measured in this run)", title_justify="left", header_style="bold")
    for col in ("target", "measured", "required", "met"):
        g.add_column(col, justify="left" if col == "target" else "right")
    for name, value, required, met in res.targets:
        g.add_row(
            name,
            "skipped" if value is None else f"{value:.2f}",
            f"≥ {required:g}",
            "—" if met is None else ("[green]yes[/green]" if met else "[red]no[/red]"),
        )
    console.print(g)
    b = res.baselines
    if "plain_script_ceiling" in b:
        console.print(
            f"An hconv that computed nothing (start-up {b['hconv_startup_s']:.2f} s plus the I/O roofline "
            f"{res.rows / b['io_roofline_rows_per_s']:.2f} s) would be {b['plain_script_ceiling']:.2f}× "
            f"faster than the plain script ({b['plain_script_s']:.2f} s)."
        )


def _g(x: float) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{x:.3g}"


def diagnosis_tables(d: Diagnosis, console: Console | None = None) -> None:
    """Print ``hconv diagnose``'s ranking, what was left out, and the rows nothing explains."""
    console = console or Console()
    console.print(
        f"[bold]hconv diagnose[/bold] · {d.rows:,} rows · a row is explained when |ω - ω_obs| / |ω_obs| <= {d.tol:g}"
    )
    t = Table(show_header=True, header_style="bold")
    for col, at_left in (
        ("rank", False),
        ("hypothesis", True),
        ("explains", False),
        ("median residual", False),
        ("median angle °", False),
        ("worst residual", False),
    ):
        t.add_column(col, justify="left" if at_left else "right", no_wrap=True)
    ranking = d.ranking()
    for k, s in enumerate(ranking, 1):
        share = s.residual.share_within
        t.add_row(
            str(k),
            s.hypothesis,
            "-" if not np.isfinite(share) else f"{100 * share:.1f} %",
            _g(s.residual.median),
            _g(s.angle.median),
            _g(s.residual.maximum),
            style="bold green" if k == 1 and share > 0 else None,
        )
    console.print(t)
    if ranking:
        console.print(f"best: [bold]{ranking[0].hypothesis}[/bold]: {ranking[0].summary}")
    left = [s for s in d.scores if not s.applicable]
    if left:
        console.print("not scored: " + "; ".join(f"{s.hypothesis} ({s.why_not})" for s in left))
    if d.unexplained:
        rows = ", ".join(f"row {r + 1} (closest: {name}, {_g(res)})" for r, name, res in d.examples)
        console.print(f"[yellow]{d.unexplained:,} rows no hypothesis explains[/yellow]; first: {rows}")
    elif d.rows:
        console.print("every row is explained by at least one hypothesis")


def comparison_tables(c: Comparison, console: Console | None = None) -> None:
    """Print ``hconv compare``: each method against exact, and where the shortcuts fail."""
    from hconv.tools.compare import OFFDIAG_BINS, R_AXIS_BINS, SHORTCUTS

    console = console or Console()
    console.print(
        f"[bold]hconv compare[/bold] · {c.rows:,} rows · difference from the exact ω, "
        "|ω_m - ω_exact| / |ω_exact| (bare numbers for m²/s methods)"
    )
    t = Table(show_header=True, header_style="bold")
    nan_col = any(s.diff.missing for s in c.scores)
    for col in ("method", "med diff", "max diff", "max row", "med °", "max °") + (("NaN",) if nan_col else ()):
        t.add_column(col, justify="left" if col == "method" else "right", no_wrap=True)

    def g2(x: float) -> str:  # short, so that the table fits 80 columns
        return "-" if not np.isfinite(x) else (f"{x:.3g}" if x == 0 or 0.01 <= abs(x) < 1000 else f"{x:.1e}")

    for s in c.scores:
        t.add_row(
            s.method + (" (m²/s)" if s.unit != "rad/s" else ""),
            g2(s.diff.median),
            g2(s.diff.maximum),
            "-" if s.diff.max_row is None or not s.diff.maximum > 0 else str(s.diff.max_row + 1),
            g2(s.angle.median),
            g2(s.angle.maximum),
            *((f"{s.diff.missing:,}",) if nan_col else ()),
        )
    console.print(t)
    if c.skipped:
        console.print("not run: " + "; ".join(f"{m} ({why})" for m, why in c.skipped))
    shortcuts = [s for s in c.scores if s.method in SHORTCUTS]
    for title, edges, attr in (
        ("off-diagonal ratio max|Iij|/√(Iii·Ijj)", OFFDIAG_BINS, "by_offdiag"),
        ("offset geometry min (|r|² - r_i²)/|r|² (0: r on an axis)", R_AXIS_BINS, "by_r_axis"),
    ):
        if not shortcuts or all(sum(b.rows for b in getattr(s, attr)) == 0 for s in shortcuts):
            continue
        t = Table(title=f"median diff of the shortcuts by {title}", show_header=True, header_style="bold")
        t.add_column("bin", justify="left")
        t.add_column("rows", justify="right")
        for s in shortcuts:
            t.add_column(s.method, justify="right")
        for b in range(len(edges) - 1):
            n = getattr(shortcuts[0], attr)[b].rows
            if n:
                t.add_row(
                    f"[{edges[b]:g}, {edges[b + 1]:g})", f"{n:,}", *(_g(getattr(s, attr)[b].median) for s in shortcuts)
                )
        console.print(t)
    for s in shortcuts:
        if s.worst:
            t = Table(title=f"rows where {s.method} is furthest off", show_header=True, header_style="bold")
            for col in ("row", "diff", "offdiag", "|r| m", "r_axis"):
                t.add_column(col, justify="right")
            for diff, row, off, rn, ra in s.worst:
                t.add_row(str(row + 1), _g(diff), _g(off), _g(rn), _g(ra))
            console.print(t)
