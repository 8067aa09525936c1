"""Whole-file conversion: read batches, convert each, write atomically, tally the statuses.

The CLI's ``convert`` is a thin wrapper over :func:`convert_file`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
import pyarrow as pa

from hconv import methods, status
from hconv.arrow import convert_table
from hconv.errors import UsageError
from hconv.tableio import Output, format_of, open_input


@dataclass
class Tally:
    """What a run did: rows, rows per status, the worst residual and where it was."""

    method: str
    unit: str
    rows: int = 0
    per_status: np.ndarray = field(default_factory=lambda: np.zeros(len(status.STATUSES), dtype=np.int64))
    worst_residual: float = float("nan")
    worst_row: Optional[int] = None  #: 1-based data row of the worst residual
    seconds: float = 0.0

    def add(self, table: pa.Table) -> None:
        st = table.column("status").combine_chunks()
        self.per_status += np.bincount(st.indices.to_numpy(zero_copy_only=False), minlength=len(status.STATUSES))
        if "residual" in table.column_names:
            res = table.column("residual").to_numpy()
            if res.size and not np.isnan(res).all():
                k = int(np.nanargmax(res))
                if not res[k] <= self.worst_residual:  # also true while worst is NaN
                    self.worst_residual, self.worst_row = float(res[k]), self.rows + k + 1
        self.rows += table.num_rows

    def counts(self) -> dict[str, int]:
        return {status.STATUSES[k]: int(c) for k, c in enumerate(self.per_status) if c}


def convert_file(src: str, dst: str, *, method: str = "exact", precision: int = 64,
                 src_format: Optional[str] = None, dst_format: Optional[str] = None,
                 force: bool = False, diagnostics: bool = True,
                 progress: Optional[Callable[[int, Optional[int]], None]] = None) -> Tally:
    """Convert the table in ``src`` into ``dst`` ("-" for stdin/stdout); returns the tally.

    ``progress(done, total)`` is called after each batch with rows or bytes read so far.
    Raises :class:`hconv.errors.HconvError` subclasses with one-line messages.
    """
    try:
        m = methods.get(method)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    fin = format_of(src, src_format, "--from")
    fout = format_of(dst, dst_format, "--to")
    out = Output(dst, fout, force=force, input_path=src)  # refuses early, before reading
    tally = Tally(m.name, m.unit)
    t0 = time.perf_counter()
    with open_input(src, fin, method) as inp, out:
        for batch in inp.batches:
            table = convert_table(batch, method, precision, diagnostics, source=inp.name)
            out.write(table)
            tally.add(table)
            if progress is not None:
                progress(inp.position(), inp.total)
        if tally.rows == 0:  # a header and no rows is a valid empty table
            out.write(convert_table(inp.schema.empty_table(), method, precision, diagnostics, source=inp.name))
    tally.seconds = time.perf_counter() - t0
    return tally
