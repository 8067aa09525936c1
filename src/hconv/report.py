"""What the CLI shows people: the run summary, the progress bar, the methods table and each
command's tables (rich), laid out by :mod:`hconv.terminal`.

rich is imported only here, in :mod:`hconv.terminal` and in :mod:`hconv.modelview`, so that
``hconv one`` does not pay for it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, RenderResult
from rich.table import Table
from rich.text import Text

from hconv.errors import option
from hconv.solve.methods import METHODS
from hconv.terminal import Col, count, note, show

if TYPE_CHECKING:
    from hconv.solve.methods import Method
    from hconv.tables.dataset import DatasetResult
    from hconv.tables.pipeline import Tally
    from hconv.tools.bench import Result as BenchResult
    from hconv.tools.compare import Comparison
    from hconv.tools.diagnose import Diagnosis
    from hconv.tools.stability import Point, Sweep


def summary(tally: Tally, console: Console | None = None, asked: str = "auto") -> None:
    """Print a run's summary: rows, rows per status, the worst residual and the time taken;
    ``asked``: the engine asked for, told when no row ran on it."""
    console = console or Console(stderr=True)
    rate = f"{tally.rows / tally.seconds:,.0f} rows/s" if tally.seconds > 0 and tally.rows else "-"
    engines = " + ".join(tally.engines) or "-"
    head = Text.assemble(("hconv convert", "bold"), f" · method {tally.method} · ω in {tally.unit} · engine {engines}")
    _status_table(console, tally, head)
    if tally.read_as:
        note(console, tally.read_as)
    if tally.worst_row is not None:
        note(console, f"worst residual {tally.worst_residual:.3g} (data row {tally.worst_row}), relative to I⁻¹H")
    _engine_note(console, tally, asked)
    _float32_note(console, tally)
    note(console, f"time {tally.seconds:.3f} s ({rate})")


def _engine_note(console: Console, tally: Tally, asked: str) -> None:
    """Say so when the engine asked for by name converted no row: a run it does not cover goes to
    the numpy engine whatever was asked (hconv.solve.engines), and the head's "engine numpy"
    alone reads like a mistake."""
    from hconv.solve import engines

    if asked not in ("auto", "numpy") and tally.rows and asked not in tally.engines:
        note(console, f"--engine {asked} computes {engines.scope_text()}; this run's rows went to numpy")


def _float32_note(console: Console, tally: Tally) -> None:
    """Where float64's tolerances flagged tensors, say that numbers computed in float32 meet
    them by its roundings alone, and what converts those (docs/input.md)."""
    from hconv.tables.body import FLOAT32_HINTS

    counts = tally.counts()
    flagged = [name for name in FLOAT32_HINTS if counts.get(name)]
    if tally.precision == 64 and flagged:
        note(
            console,
            f"{' and '.join(flagged)}: if I was computed in float32, give --precision 32, or its six "
            "numbers (docs/input.md, numbers computed in float32)",
        )


def _status_table(console: Console, tally: Tally, head: Text) -> None:
    """Rows per status and the total, under ``head``: the table both summaries open with."""
    counts = tally.counts()
    show(
        console,
        (Col("status"), Col("rows", right=True)),
        [(name, count(console, n)) for name, n in counts.items()] + [("total", count(console, tally.rows))],
        title=head,
        styles=[None if name == "ok" else "yellow" for name in counts] + ["bold"],
    )


def dataset_summary(result: DatasetResult, console: Console | None = None, asked: str = "auto") -> None:
    """Print a dataset run's summary: the whole dataset's rows per status and worst residual
    (naming its file), the files converted, up to date and failed, and this run's time;
    ``asked``: the engine asked for, told when no row ran on it."""
    console = console or Console(stderr=True)
    tally = result.tally
    engines = " + ".join(tally.engines) or "-"
    files = f"{result.total:,} file" + ("s" if result.total != 1 else "")
    head = Text.assemble(
        ("hconv convert", "bold"), f" · {files} · method {tally.method} · ω in {tally.unit} · engine {engines}"
    )
    _status_table(console, tally, head)
    if tally.worst_row is not None:
        note(
            console,
            f"worst residual {tally.worst_residual:.3g} ({result.worst_file}, data row {tally.worst_row}), "
            "relative to I⁻¹H",
        )
    done = len(result.converted)
    parts = [f"{done:,} converted", f"{len(result.files) - done:,} already up to date"]
    parts += [f"{len(result.failed):,} failed"] if result.failed else []
    parts += [f"{len(result.pending):,} not reached"] if result.pending else []
    state = "complete" if result.complete else "not complete"
    _float32_note(console, tally)
    note(console, f"files: {', '.join(parts)}; {result.manifest} says the dataset is {state}")
    if result.orphans:  # the manifest no longer lists them, so nothing else would say they are there
        shown = ", ".join(result.orphans[:3]) + (", …" if len(result.orphans) > 3 else "")
        note(
            console,
            f"{len(result.orphans):,} output(s) in OUT belong to no input of this run ({shown}): an earlier "
            "run wrote them, and their input is gone or renamed, or was written in another format; hconv "
            "leaves them: remove them if they should go",
        )
    if result.ran_on:
        note(console, f"converted on {result.ran_on}")
    if result.split_files:  # a run's time follows its tasks, here more than its files
        files = f"{result.split_files:,} file" + ("s" if result.split_files != 1 else "")
        note(console, f"split {files} into {result.split_parts:,} parts ({option('task_rows', result.task_rows)})")
    if result.converted:
        _engine_note(console, tally, asked)
    rate = f", {result.rows_converted / result.seconds:,.0f} rows/s" if result.seconds > 0 and done else ""
    note(console, f"time {result.seconds:.3f} s ({result.rows_converted:,} rows converted{rate})")


#: cells beside the bar on its line: the gaps, the percentage ("100%") and the time left ("0:00:03")
_BESIDE_BAR = 14
#: and, for bytes, their count ("123.4/567.8 MB" and a gap)
_BESIDE_BYTES = 15
#: the narrowest bar worth keeping the description beside it on one line
_MIN_BAR = 10


def _elide_middle(text: str, width: int) -> str:
    """``text`` in at most ``width`` cells: whole if it fits, else its start and its end either
    side of "…". The end keeps two thirds, because what tells a file from its neighbours (a
    counter, a date, the extension) is most often at the end of its name."""
    if cell_len(text) <= width:
        return text
    if width < 2:
        return "…"[:width]
    tail_room = (width - 1) * 2 // 3
    head, tail = "", ""
    for ch in text:
        if cell_len(head + ch) > width - 1 - tail_room:
            break
        head += ch
    for ch in reversed(text):
        if cell_len(ch + tail) > tail_room:
            break
        tail = ch + tail
    return f"{head}…{tail}"


class ProgressBar:
    """A transient rich progress bar; call it as ``bar(done, total)``; ``counts``: what ``done``
    counts, ``rows``, ``files`` or ``bytes`` (shown beside the percentage).

    The description goes before the bar when both fit on a line, else on a line of its own above
    it, shortened in the middle only when it is wider than the terminal: a long file name cut at
    its end looked the same for every file of a series."""

    def __init__(self, description: str, console: Console | None = None, counts: str = "rows"):
        from rich.live import Live
        from rich.progress import BarColumn, DownloadColumn, Progress, TaskProgressColumn, TimeRemainingColumn

        console = console or Console(stderr=True)
        self._description = description
        self._bar = BarColumn()
        # bytes read (a CSV file) show beside the percentage: "12.6/69.4 MB"
        shown = (DownloadColumn(),) if counts == "bytes" else ()
        self._beside = _BESIDE_BAR + (_BESIDE_BYTES if shown else 0)
        # never started: it keeps the task's counts and times and draws its row, laid out here
        self._p = Progress(self._bar, TaskProgressColumn(), *shown, TimeRemainingColumn(), console=console)
        self._task = self._p.add_task(description, total=None)
        self._live = Live(self, console=console, transient=True, refresh_per_second=10)

    def __call__(self, done: int, total: int | None) -> None:
        self._p.update(self._task, completed=done, total=total)

    def __enter__(self) -> ProgressBar:
        self._live.start(refresh=True)
        return self

    def __exit__(self, *exc: object) -> None:
        self._live.stop()

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        """Laid out anew for the width of each refresh: the terminal may be resized meanwhile.
        One column is left free: a line that fills the last one wraps early on some terminals,
        and the redraw then climbs a line too few."""
        width = options.max_width - 1
        beside = width - cell_len(self._description) - 1 - self._beside
        if beside >= _MIN_BAR:
            self._bar.bar_width = min(40, beside)
            line = Table.grid(padding=(0, 1))
            line.add_row(Text(self._description), self._p.make_tasks_table(self._p.tasks))
            yield line
        else:
            self._bar.bar_width = max(1, min(40, width - self._beside))
            yield Text(_elide_middle(self._description, width), no_wrap=True)
            yield self._p.make_tasks_table(self._p.tasks)


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
    cols = [Col("method"), Col("unit"), Col("exact")]
    cols += [Col(c, prose=True) for c in ("trusted to 1e-6 up to cond", "what it computes", "cost", "fails when")]
    rows = [
        (m.name, m.unit, "yes" if m.exact else "no", envelope(m), m.summary, m.cost, m.fails) for m in METHODS.values()
    ]
    show(console, cols, rows, lines=True, split=False)


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

    cols = [Col(n, right=True) for n in names]
    legend = "*: most rows flagged; —: no row had an answer"
    for sw in sweeps:
        for prec in (64, 32):
            rows = []
            for param in sw.params:
                got = {p.method: p for p in points if p.sweep == sw.name and p.precision == prec and p.param == param}
                rows.append([f"{param:g}", *(cell(got.get(n)) for n in names)])
            show(
                console,
                [Col(sw.xlabel, right=True), *cols],
                rows,
                title=f"{sw.title}, float{prec}: worst relative error vs I⁻¹H ({legend})",
            )


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
    rows = []
    for n, times in user.items():
        solve = times["numpy.linalg.solve"]
        first = True
        for call, by_engine in times.items():
            if call == "numpy.linalg.solve":
                continue
            size = n if not n.isdigit() else count(console, int(n))
            rows.append(
                [
                    size if first or not console.is_terminal else "",
                    call,
                    _duration(solve) if first or not console.is_terminal else "",
                    *(f"{solve / by_engine[e]:.2f}" if e in by_engine else "" for e in engines),
                ]
            )
            first = False
    cols = [Col("rows", right=True), Col("I, diagnostics"), Col("solve", right=True)]
    show(
        console,
        cols + [Col(e, right=True) for e in engines],
        rows,
        title="what users call: numpy.linalg.solve time / hconv.convert time (above 1: faster)",
        keys=2,
    )


def cold_table(cold: dict, console: Console) -> None:
    """A fresh process's first call by engine: import, first and second hconv.convert."""
    if not cold:
        return
    cols = [Col("engine")] + [Col(c, right=True) for c in ("import hconv", "first call", "second call")]
    rows = [
        (name, _duration(c["import_s"]), _duration(c["first_call_s"]), _duration(c["second_call_s"]))
        for name, c in cold.items()
    ]
    show(console, cols, rows, title="first call of a fresh process, 100 rows")


def _error_pair(median: float, worst: float) -> str:
    """A method's median and worst error, or "flagged" where no row had an answer to score."""
    if not (np.isfinite(median) and np.isfinite(worst)):
        return "flagged"
    return " / ".join("0" if x == 0 else f"{x:.0e}" for x in (median, worst))


def bench_tables(res: BenchResult, console: Console | None = None) -> None:
    """The benchmark: a row per method and precision, then the targets as measured ratios."""
    console = console or Console()
    note(console, Text.assemble(("hconv bench", "bold"), f" · {res.rows:,} rows · {res.machine}"))
    user_table(res.user, console)
    cold_table(res.cold, console)
    conds = list(next(iter(res.accuracy.values())))
    cols = [Col("method"), Col("prec", right=True)]
    cols += [Col(c, right=True) for c in ("kernel Mrows/s", "× lapack", "convert Mrows/s")]
    cols += [Col(f"error at cond {float(c):g}\nmedian / worst", right=True) for c in conds]
    lapack = res.kernel["lapack/64"]
    rows = []
    for key, speed in res.kernel.items():
        name, prec = key.split("/")
        errs = [res.accuracy[key][c] for c in conds]
        rows.append(
            [
                name,
                prec,
                f"{speed / 1e6:.2f}",
                f"{speed / lapack:.2f}",
                f"{res.convert[key] / 1e6:.2f}",
                *(_error_pair(m, w) for m, w in errs),
            ]
        )
    kernels = Text.assemble(("kernels", "bold"), " (the arithmetic alone, for comparison; not what a user calls)")
    show(console, cols, rows, title=kernels, keys=2)
    if any(x == "flagged" for r in rows for x in r):
        note(console, "flagged: every row was flagged and has no ω, so there is no error to measure")
    cols = [Col("target", prose=True), Col("measured", right=True), Col("required", right=True), Col("met", right=True)]
    rows = [
        [
            name,
            "skipped" if value is None else f"{value:.2f}",
            f"≥ {required:g}",
            "—" if met is None else (Text("yes", style="green") if met else Text("no", style="red")),
        ]
        for name, value, required, met in res.targets
    ]
    show(console, cols, rows, title="targets (ratios of rates measured in this run)")
    b = res.baselines
    if "plain_script_ceiling" in b:
        note(
            console,
            f"An hconv that computed nothing (start-up {b['hconv_startup_s']:.2f} s plus the I/O roofline "
            f"{res.rows / b['io_roofline_rows_per_s']:.2f} s) would be {b['plain_script_ceiling']:.2f}× "
            f"faster than the plain script ({b['plain_script_s']:.2f} s).",
        )


def _g(x: float) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{x:.3g}"


def diagnosis_tables(d: Diagnosis, console: Console | None = None) -> None:
    """Print ``hconv diagnose``'s ranking, what was left out, and the rows nothing explains."""
    console = console or Console()
    head = Text.assemble(
        ("hconv diagnose", "bold"), f" · {d.rows:,} rows · a row is explained when |ω - ω_obs| / |ω_obs| <= {d.tol:g}"
    )
    cols = [Col("rank", right=True), Col("hypothesis")]
    cols += [Col(c, right=True) for c in ("explains", "median residual", "median angle °", "worst residual")]
    ranks = d.ranks()
    rows, styles = [], []
    for rank, s, _ in ranks:
        share = s.residual.share_within
        rows.append(
            (
                str(rank),
                s.hypothesis,
                "-" if not np.isfinite(share) else f"{100 * share:.1f} %",
                _g(s.residual.median),
                _g(s.angle.median),
                _g(s.residual.maximum),
            )
        )
        styles.append("bold green" if rank == 1 and share > 0 else None)
    show(console, cols, rows, title=head, keys=2, styles=styles)
    # A hypothesis can build a tensor with no inverse on every row (ordering-urdf on a diagonal
    # tensor puts two zeros on its diagonal): without a word its row of "-" reads like a fault.
    silent = [s.hypothesis for _, s, _ in ranks if d.rows and not s.residual.answered]
    if silent:
        note(
            console,
            f"-: {', '.join(silent)} {'gives' if len(silent) == 1 else 'give'} no ω on any row (the tensor "
            "read that way is singular or not valid on each), so there is no residual or angle to show",
        )
    groups = d.groups()
    groups = groups if d.rows else []  # no row: nothing is best or closest
    if groups and len(groups[0]) == 1:
        best = groups[0][0]
        label = "best: " if best.residual.within else "closest, though it explains no row: "
        note(console, Text.assemble(label, (best.hypothesis, "bold"), f": {best.summary}"))
    elif groups:  # the data cannot tell these apart: name them all, none above the others
        names = ", ".join(s.hypothesis for s in groups[0])
        note(console, f"tied for best, explaining the same rows with the same ω (to the data's precision): {names}")
        for s in groups[0]:
            note(console, Text.assemble("  ", (s.hypothesis, "bold"), f": {s.summary}"))
    for g in groups[1:]:
        if len(g) > 1:
            rank = next(r for r, s, _ in ranks if s is g[0])
            note(console, f"tied at rank {rank}, explaining the same rows: {', '.join(s.hypothesis for s in g)}")
    left: dict[str, list[str]] = {}  # reason -> hypotheses, so that a reason shows once
    for s in d.scores:
        if not s.applicable:
            left.setdefault(s.why_not, []).append(s.hypothesis)
    if left:
        note(console, "not scored: " + "; ".join(f"{', '.join(names)} ({why})" for why, names in left.items()))
    if d.unexplained:
        rows_text = ", ".join(f"row {r + 1} (closest: {name}, {_g(res)})" for r, name, res in d.examples)
        note(
            console,
            Text.assemble((f"{d.unexplained:,} rows no hypothesis explains", "yellow"), f"; first: {rows_text}"),
        )
    elif d.rows:
        note(console, "every row is explained by at least one hypothesis")


def comparison_tables(c: Comparison, console: Console | None = None) -> None:
    """Print ``hconv compare``: each method against exact, and where the shortcuts fail."""
    from hconv.tools.compare import OFFDIAG_BINS, R_AXIS_BINS, SHORTCUTS

    console = console or Console()
    head = Text.assemble(
        ("hconv compare", "bold"),
        f" · {c.rows:,} rows · difference from the exact ω, |ω_m - ω_exact| / |ω_exact|",
        " (bare numbers for m²/s methods)",
    )
    nan_col = any(s.diff.missing for s in c.scores)
    names = ("method", "med diff", "max diff", "max row", "med °", "max °") + (("NaN",) if nan_col else ())
    cols = [Col(n, right=n != "method", prose=n == "method") for n in names]  # "(m²/s)" may go below the name

    def g2(x: float) -> str:  # short, so that the table fits 80 columns
        return "-" if not np.isfinite(x) else (f"{x:.3g}" if x == 0 or 0.01 <= abs(x) < 1000 else f"{x:.1e}")

    rows: list[list[str]] = [
        [
            s.method + (" (m²/s)" if s.unit != "rad/s" else ""),
            g2(s.diff.median),
            g2(s.diff.maximum),
            "-" if s.diff.max_row is None or not s.diff.maximum > 0 else str(s.diff.max_row + 1),
            g2(s.angle.median),
            g2(s.angle.maximum),
            *((count(console, s.diff.missing),) if nan_col else ()),
        ]
        for s in c.scores
    ]
    show(console, cols, rows, title=head)
    if c.skipped:
        note(console, "not run: " + "; ".join(f"{m} ({why})" for m, why in c.skipped))
    shortcuts = [s for s in c.scores if s.method in SHORTCUTS]
    for title, edges, attr in (
        ("off-diagonal ratio max|Iij|/√(Iii·Ijj)", OFFDIAG_BINS, "by_offdiag"),
        ("offset geometry min (|r|² - r_i²)/|r|² (0: r on an axis)", R_AXIS_BINS, "by_r_axis"),
    ):
        if not shortcuts or all(sum(b.rows for b in getattr(s, attr)) == 0 for s in shortcuts):
            continue
        rows = []
        for b in range(len(edges) - 1):
            n = getattr(shortcuts[0], attr)[b].rows
            if n:
                bounds = f"[{edges[b]:g}, {edges[b + 1]:g})"
                rows.append([bounds, count(console, n), *(_g(getattr(s, attr)[b].median) for s in shortcuts)])
        cols = [Col("bin"), Col("rows", right=True)] + [Col(s.method, right=True) for s in shortcuts]
        show(console, cols, rows, title=f"median diff of the shortcuts by {title}")
    for s in shortcuts:
        if s.worst:
            cols = [Col(n, right=True) for n in ("row", "diff", "offdiag", "|r| m", "r_axis")]
            rows = [[str(row + 1), _g(diff), _g(off), _g(rn), _g(ra)] for diff, row, off, rn, ra in s.worst]
            show(console, cols, rows, title=f"rows where {s.method} is furthest off")
