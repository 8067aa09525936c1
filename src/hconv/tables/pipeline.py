"""Whole-file conversion: read batches, convert each, write atomically, tally the statuses.

The CLI's ``convert`` is a thin wrapper over :func:`convert_file`.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import queue
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
import pyarrow as pa

from hconv import interrupts
from hconv.errors import StrictError, UsageError, option
from hconv.solve import engines, methods, options, status
from hconv.tables import arrays, csvio, csvtypes, csvwrite, layout
from hconv.tables.arrow import convert_batch
from hconv.tables.inputs import Input
from hconv.tables.job import Job
from hconv.tables.output import Output, into_directory
from hconv.tables.sniff import format_of
from hconv.tables.tableio import open_input


@dataclass
class Tally:
    """What a run did: rows, rows per status, the worst residual and where it was."""

    method: str
    unit: str
    rows: int = 0
    per_status: np.ndarray = field(default_factory=lambda: np.zeros(len(status.STATUSES), dtype=np.int64))
    worst_residual: float = float("nan")
    worst_row: int | None = None  #: 1-based data row of the worst residual
    seconds: float = 0.0
    engines: dict = field(default_factory=dict)  #: engine -> rows it converted, in order of first use
    read_as: str = ""  #: how a CSV input was read, where it is not plain CSV (hconv.tables.sniff.Dialect)
    precision: int = 64  #: the working precision's bits (the summary's float32 hint)

    def add(self, table: pa.Table, engine: str | None = None) -> None:
        if engine is not None:
            self.engines[engine] = self.engines.get(engine, 0) + table.num_rows
        st = table.column(layout.output_name("status", table.schema)).combine_chunks()
        self.per_status += np.bincount(arrays.to_numpy(st.indices), minlength=len(status.STATUSES))
        residual = layout.output_name("residual", table.schema)
        if residual in table.column_names:
            res = arrays.to_numpy(table.column(residual), null=np.nan)
            if res.size and not np.isnan(res).all():
                k = int(np.nanargmax(res))
                if not res[k] <= self.worst_residual:  # also true while worst is NaN
                    self.worst_residual, self.worst_row = float(res[k]), self.rows + k + 1
        self.rows += table.num_rows

    def add_counts(
        self, rows: int, statuses: dict, engines: dict, worst_residual: float | None, worst_row: int | None
    ) -> bool:
        """Another tally's counts, as a record keeps them (a file's, a part's): rows per status,
        rows per engine, and its worst residual and row where it is worse than any so far (the
        first of equals kept, as :meth:`add` keeps it); whether it was."""
        index = {s: k for k, s in enumerate(status.STATUSES)}
        for s, n in statuses.items():
            self.per_status[index[s]] += n
        for e, n in engines.items():
            self.engines[e] = self.engines.get(e, 0) + n
        self.rows += rows
        if worst_residual is not None and not worst_residual <= self.worst_residual:  # also while NaN
            self.worst_residual, self.worst_row = worst_residual, worst_row
            return True
        return False

    def counts(self) -> dict[str, int]:
        return {status.STATUSES[k]: int(c) for k, c in enumerate(self.per_status) if c}


def main_thread_signals() -> None:
    """Block Ctrl-C and SIGTERM in the calling (worker) thread and in every thread it starts, such
    as the compiled engine's pool, so that the kernel delivers them to the main thread, which
    turns them into a clean stop: one that lands on another thread would leave the main thread
    asleep in its wait until the batch it waits for is done."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})


class BackgroundWriter:
    """Writes tables to an :class:`~hconv.tables.output.Output` on a second thread, so that encoding
    and compressing one batch (pyarrow releases the GIL) overlaps converting the next.

    At most ``depth`` tables wait in the queue, so memory stays bounded. Leaving the ``with``
    block always stops and joins the thread before the output is committed or removed; an error
    on the writer thread is raised in the caller's thread.
    """

    _DONE = object()

    def __init__(self, out: Output, depth: int = 2):
        self._out = out
        self._q: queue.Queue = queue.Queue(maxsize=depth)
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hconv-writer", daemon=True)

    def _run(self) -> None:
        main_thread_signals()
        while True:
            item = self._q.get()
            if item is self._DONE:
                return
            if self._error is None and not self._stop.is_set():
                try:
                    self._out.write(item)
                except BaseException as exc:  # handed to the caller's thread
                    self._error = exc

    def write(self, table: pa.Table) -> None:
        interrupts.point("batch")
        if self._error is not None:
            raise self._error
        self._q.put(table)

    def __enter__(self) -> BackgroundWriter:
        self._thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        # Interrupts held: a Ctrl-C landing in the join left the thread writing while the caller
        # closed the output under it (SIGSEGV in pyarrow's write_table, 3 of 80 interrupted
        # dataset runs); it now waits for the batch being written, then acts.
        with interrupts.held():
            if exc_type is not None:
                self._stop.set()
                while True:  # drop what is queued, so the sentinel fits
                    try:
                        self._q.get_nowait()
                    except queue.Empty:
                        break
            self._q.put(self._DONE)
            self._thread.join()
        if exc_type is None and self._error is not None:
            raise self._error


T = TypeVar("T")
R = TypeVar("R")

#: Most compute threads by default: beyond this the single Parquet writer sets the pace.
MAX_THREADS = 4


def default_threads() -> int:
    """The cores this process may run on, at most :data:`MAX_THREADS`."""
    return min(MAX_THREADS, engines.available_cores())


def ordered_map(fn: Callable[[T], R], items: Iterable[T], threads: int) -> Generator[R, None, None]:
    """``map(fn, items)`` on ``threads`` threads, results in the order of ``items``.

    ``items`` is consumed on the caller's thread (reading stays sequential), at most
    ``threads + 1`` items ahead of the result being yielded, so memory stays bounded. numpy and
    pyarrow release the GIL inside their loops, so batches convert in parallel. An error in
    ``fn`` is raised when its result is due; leaving early cancels what has not started and
    waits for what has (one batch each).
    """
    if threads <= 1:
        yield from map(fn, items)
        return
    with ThreadPoolExecutor(threads, thread_name_prefix="hconv-compute", initializer=main_thread_signals) as pool:
        pending: deque = deque()
        try:
            for item in items:
                pending.append(pool.submit(fn, item))
                if len(pending) > threads:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for f in pending:
                f.cancel()


def check_threads(threads: object) -> None:
    """UsageError unless ``threads`` is None (the default) or a whole number of at least 1."""
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise UsageError(f"{option('threads')} must be a whole number, 1 or more, got {threads!r}")


def check_callback(name: str, value: object) -> None:
    """UsageError unless ``value`` is None or callable: a callback checked before anything is
    read or written, not a TypeError after the first batch or file."""
    if value is not None and not callable(value):
        raise UsageError(f"{name} takes a function or None, got {value!r} ({type(value).__name__})")


def convert_file(
    src: str,
    dst: str,
    *,
    method: str | None = None,
    precision: int | None = None,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    diagnostics: bool | None = None,
    job: Job | None = None,
    strict: bool = False,
    threads: int | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    name: str | None = None,
    rows: tuple[int, int] | None = None,
    dst_name: str | None = None,
    prefix: str | None = None,
    whole: bool = False,
    staged: bool = False,
) -> Tally:
    """Convert the table in ``src`` into ``dst`` ("-" for stdin/stdout); returns the tally.

    ``job`` (conventions, units, mapping) is the whole run configuration; or ``method`` (default
    exact), ``precision`` (64), ``diagnostics`` (True) and ``prefix`` (before the name of every
    column hconv appends; none) make one; not both (:func:`hconv.solve.options.configure`).
    ``strict``: any row whose status is not ok fails the run (StrictError naming the first rows),
    and nothing is written.
    ``threads``: batches converted at once (default :func:`default_threads`); the output is the
    same, in the same order, for any number.
    ``progress(done, total)`` is called after each batch with rows or bytes read so far.
    ``name``: what messages call the input (default: ``src``), such as the URI of an object
    fetched into ``src`` (:func:`hconv.tables.dataset.convert_dataset`); ``dst_name`` the same for
    the output, such as a dataset's output whose temporary file ``dst`` is.
    ``rows``: (start, stop), convert only those rows of a Parquet ``src`` (a part of a file
    converted by one task of a cluster run: :func:`hconv.tables.parts.convert_part`); messages
    name the file's rows, the tally's ``worst_row`` counts from ``start``.
    ``whole``: a small file, read, converted and written on the calling thread, with no threads
    of its own (starting and joining them cost more than such a file's conversion; a dataset's
    pool converts several such files side by side: :mod:`hconv.tables.runners`).
    ``staged``: ``dst`` is the caller's own temporary file, written in place (not through another
    one) and left for the caller to commit or remove (:func:`hconv.tables.onefile.convert_one`).
    Raises :class:`hconv.errors.HconvError` subclasses with one-line messages.
    """
    check_threads(threads)
    check_callback("progress", progress)
    threads = threads or default_threads()
    job = options.configure(
        Job, "convert_file", job, method=method, precision=precision, diagnostics=diagnostics, prefix=prefix
    )
    if not staged:
        dst = into_directory(src, dst, src_format, dst_format)  # an existing directory: the file in it, as cp
    fin = format_of(src, src_format, "src_format")
    fout = format_of(dst, dst_format, "dst_format")
    # Straight into a pipe's reader where one pass writes it all: CSV keeps its text, and only
    # CSV's text columns can make a second pass (csvtypes.Retype); --strict promises nothing written.
    stream = not strict and (fout == "csv" or fin != "csv")
    # refuses early, and with --force an OUT that looks like an input rather than hconv's output
    source = "stdin" if src == "-" else name or src  # as open_input names it
    out = Output(
        dst, fout, force=force, input_path=src, shown=dst_name, stream=stream, staged=staged, reads=job, source=source
    )
    t0 = time.perf_counter()
    with open_input(src, fin, job, name, rows, whole) as inp:
        if fout == "csv":
            csvwrite.check_csv_columns(inp.schema, inp.name)  # before converting anything
        # CSV's text columns get types in Parquet, the first block's (csvtypes); CSV keeps them as they were
        typed = fout != "csv" and bool(inp.text) and not job.keep_text
        run = functools.partial(
            _convert, job=job, strict=strict, threads=1 if whole else threads, progress=progress, whole=whole
        )
        try:
            tally = run(inp, out, types=None if typed else {})
        except csvtypes.Retype:  # a later block does not fit them: type from every block, then again
            tally = None
        if tally is None:  # outside the except block, so that the first pass's batches are freed
            inp.batches = iter(())
            types = csvtypes.whole_file(csvio.text_batches(inp))
            with csvio.reopen(inp, job) as again:
                again_out = Output(dst, fout, force=force, input_path=src, shown=dst_name, staged=staged, source=source)
                tally = run(again, again_out, types=types)
    tally.seconds = time.perf_counter() - t0
    return tally


def _convert(
    inp: Input,
    out: Output,
    *,
    job: Job,
    types: dict | None,
    strict: bool,
    threads: int,
    progress: Callable[[int, int | None], None] | None,
    whole: bool = False,
) -> Tally:
    """One pass of :func:`convert_file`: every batch of ``inp`` into ``out``. ``types``: the
    types of ``inp``'s text columns (None: the first batch's; :class:`~hconv.tables.csvtypes.Retype`
    when a later one does not fit)."""
    tally = Tally(methods.get(job.method).name, job.unit, precision=job.precision)
    batches: Iterator[pa.RecordBatch] = inp.batches
    if types is None:
        first = next(batches, None)
        types = {} if first is None else csvtypes.infer(first, inp.text)
        batches = itertools.chain([first] if first is not None else [], batches)

    def one(numbered: tuple[int, pa.RecordBatch]) -> tuple[pa.Table, str]:
        first, batch = numbered
        table = pa.Table.from_batches([batch])
        if types:
            table = csvtypes.apply(table, types)
        return convert_batch(table, job, inp.plan, inp.name, first)

    # closing(): an interrupt that lands here, in the consumer (often while the writer's queue is
    # full), stops the compute threads now rather than when the suspended generator is collected,
    # so that none is still converting while a dataset run goes on to its next file or manifest.
    results = ordered_map(one, _numbered(batches, inp.first_row), threads)
    if inp.dialect is not None:
        tally.read_as = inp.dialect.describe()
    if out.fmt == "csv":  # a row of units, where the input carried units: they stay with the numbers
        written = inp.dialect.units_text if inp.dialect is not None and inp.dialect.units_row else ()
        out.units = csvwrite.units_row(inp.schema, inp.plan, job, written)
    if progress is not None:  # the size, before the first batch takes its time
        progress(0, inp.total)
    writing = contextlib.nullcontext(_Direct(out)) if whole else BackgroundWriter(out)
    with out, writing as writer, contextlib.closing(results):
        _write_all(inp, results, writer, tally, job=job, strict=strict, progress=progress)
    return tally


class _Direct:
    """A :class:`BackgroundWriter`'s ``write`` on the calling thread (a small file: ``whole``)."""

    def __init__(self, out: Output):
        self.write = out.write


def _write_all(
    inp: Input,
    results: Iterator[tuple[pa.Table, str]],
    writer: BackgroundWriter | _Direct,
    tally: Tally,
    *,
    job: Job,
    strict: bool,
    progress: Callable[[int, int | None], None] | None,
) -> None:
    """Each converted table of ``inp`` written and tallied, in order."""
    for table, engine in results:
        if strict:
            _check_strict(table, inp.first_row + tally.rows, inp.name)
        writer.write(table)
        tally.add(table, engine)
        if progress is not None:  # the rows converted, not how far the reader has got ahead of them
            progress(inp.reached(tally.rows), inp.total)
    if tally.rows == 0:  # a header and no rows is a valid empty table
        writer.write(convert_batch(inp.schema.empty_table(), job, inp.plan, inp.name)[0])


def _numbered(batches: Iterable[pa.RecordBatch], first: int = 0) -> Iterator[tuple[int, pa.RecordBatch]]:
    """Each batch with the index of its first row in the file (the first's: ``first``), counted
    on the reading thread."""
    for batch in batches:
        yield first, batch
        first += batch.num_rows


STRICT_ROWS_NAMED = 5


def _check_strict(table: pa.Table, first_row: int, source: str) -> None:
    codes = arrays.to_numpy(table.column(layout.output_name("status", table.schema)).combine_chunks().indices)
    bad = np.flatnonzero(codes != 0)
    if bad.size:
        named = ", ".join(
            f"row {first_row + int(k) + 1} ({status.STATUSES[codes[k]]})" for k in bad[:STRICT_ROWS_NAMED]
        )
        more = f" and {bad.size - STRICT_ROWS_NAMED} more in this batch" if bad.size > STRICT_ROWS_NAMED else ""
        raise StrictError(
            f"{source}: {option('strict', True)}, and {named}{more} {'is' if bad.size == 1 else 'are'} not ok; "
            "nothing was written "
            f"(drop {option('strict', True)} to keep every row with its status)"
        )
