"""``hconv compare``: every method on the same rows, measured against the exact answer.

Per row and method: ``diff`` = |ω_m - ω_exact| / |ω_exact| (of the bare numbers, for the m²/s
methods) and ``angle`` between the two vectors [degrees]. The geometry that drives the shortcuts'
failures is measured per row too:

* ``offdiag`` = max over i≠j of |Iij| / √(Iii·Ijj): how far the tensor is from diagonal in the
  axes it is given in (0: diagonal; the diagonal shortcut is then exact);
* ``r_axis`` = min over i of (|r|² - r_i²) / |r|²: 0 when r lies on an axis, where the document
  formula forces two components to zero.

The summary bins the rows by ``offdiag`` and by ``r_axis`` and gives the median difference of the
diagonal and document methods in each bin, and lists the rows where they are furthest off.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hconv.kernels.metrics import angle_deg, relative_error
from hconv.solve import bodies, forms, methods
from hconv.solve.options import Conventions
from hconv.tables.job import Job, check_job
from hconv.tools.stats import Summary

OFFDIAG_BINS = (0.0, 1e-3, 1e-2, 0.1, 0.3, 1.0)
R_AXIS_BINS = (0.0, 1e-6, 1e-3, 1e-2, 0.1, 1.0)
#: The method every other is measured against.
REFERENCE = methods.get("exact")
#: The methods whose worst rows the summary lists: those that read only the diagonal I_ii as
#: given, whose failures offdiag (and, for the document formula, r_axis) explains.
SHORTCUTS = tuple(m.name for m in methods.METHODS.values() if m.ignores_products)
WORST_ROWS = 5


def offdiag_ratio(sets: dict, form: str) -> np.ndarray:
    """max |Iij| / √(Iii·Ijj) per row, ``(N,)``; 0 for the diagonal forms (:meth:`hconv.solve.forms.Form.offdiag`)."""
    return forms.get(form).offdiag(sets["I"])


def r_axis_ratio(r: np.ndarray) -> np.ndarray:
    """min over i of (|r|² - r_i²) / |r|² per row, from ``r`` ``(3, N)``; NaN for r = 0."""
    sq = r * r
    total = sq.sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.min(np.stack([sq[1] + sq[2], sq[0] + sq[2], sq[0] + sq[1]]), axis=0) / np.where(
            total > 0, total, np.nan
        )


@dataclass
class MethodScore:
    method: str
    unit: str
    diff: Summary = field(default_factory=lambda: Summary(1e-6))
    angle: Summary = field(default_factory=Summary)
    by_offdiag: list = field(default_factory=lambda: [Summary() for _ in OFFDIAG_BINS[:-1]])
    by_r_axis: list = field(default_factory=lambda: [Summary() for _ in R_AXIS_BINS[:-1]])
    worst: list = field(default_factory=list)  #: (diff, row, offdiag, |r|, r_axis), largest first


@dataclass
class Comparison:
    scores: list
    rows: int
    skipped: list  #: (method, why) for methods that could not run on this input


def _binned(summaries: list, edges: tuple, key: np.ndarray, values: np.ndarray, first_row: int) -> None:
    idx = np.clip(np.searchsorted(edges, key, side="right") - 1, 0, len(edges) - 2)
    ok = np.isfinite(key)
    for b, s in enumerate(summaries):
        sel = ok & (idx == b)
        if sel.any():
            s.add(values[sel], first_row)


class Comparer:
    """Runs every method batch by batch; :meth:`result` gives the :class:`Comparison`."""

    def __init__(self, present: set, conv: Conventions = Conventions()):
        self.conv = conv
        self.scores, self.skipped = [], []
        for m in methods.METHODS.values():
            if m.needs_r and "r" not in present:
                self.skipped.append((m.name, "needs rx, ry, rz"))
            else:
                self.scores.append(MethodScore(m.name, m.unit))
        self.rows = 0

    def add(self, sets: dict, form: str) -> dict:
        """Score one batch; returns its per-row columns (name -> ``(n,)`` array)."""
        n = sets["H"].shape[1]
        exact = bodies.solve(sets, form, REFERENCE, 64, self.conv, diagnostics=False).w.T
        off = offdiag_ratio(sets, form)
        r = sets.get("r")
        r_axis = r_axis_ratio(r) if r is not None else np.full(n, np.nan)
        r_norm = np.sqrt((r * r).sum(axis=0)) if r is not None else np.full(n, np.nan)
        cols = {"offdiag": off, "r_axis": r_axis}
        for s in self.scores:
            w = (
                exact
                if s.method == REFERENCE.name
                else bodies.solve(sets, form, s.method, 64, self.conv, diagnostics=False).w.T
            )
            w = w.astype(np.float64)
            diff, ang = relative_error(w, exact), angle_deg(w, exact)
            s.diff.add(diff, self.rows)
            s.angle.add(ang, self.rows)
            _binned(s.by_offdiag, OFFDIAG_BINS, off, diff, self.rows)
            _binned(s.by_r_axis, R_AXIS_BINS, r_axis, diff, self.rows)
            if s.method in SHORTCUTS:
                order = np.argsort(np.where(np.isnan(diff), -np.inf, diff))[::-1][:WORST_ROWS]
                s.worst += [
                    (float(diff[k]), self.rows + int(k), float(off[k]), float(r_norm[k]), float(r_axis[k]))
                    for k in order
                    if np.isfinite(diff[k])
                ]
                s.worst = sorted(s.worst, key=lambda t: -t[0])[:WORST_ROWS]
            cols[f"diff_{s.method}"] = diff
            cols[f"angle_{s.method}"] = ang
        self.rows += n
        return cols

    def result(self) -> Comparison:
        return Comparison(self.scores, self.rows, self.skipped)


def compare_file(
    src: str,
    dst: str | None = None,
    *,
    src_format: str | None = None,
    dst_format: str | None = None,
    force: bool = False,
    job: Job | None = None,
) -> Comparison:
    """Compare every method on the rows of ``src``; with ``dst``, also write the per-row figures
    (the input columns, then offdiag, r_axis, diff_<method>, angle_<method>), atomically."""
    import contextlib

    import pyarrow as pa

    from hconv.tables.output import Output
    from hconv.tables.pipeline import BackgroundWriter
    from hconv.tables.sniff import format_of
    from hconv.tables.tableio import open_input

    check_job(job)
    job = job or Job()
    fin = format_of(src, src_format, "src_format")
    out = Output(dst, format_of(dst, dst_format, "dst_format"), force=force, input_path=src) if dst else None
    with open_input(src, fin, job) as inp, contextlib.ExitStack() as stack:
        writer = None
        if out is not None:
            stack.enter_context(out)
            writer = stack.enter_context(BackgroundWriter(out))
        comp = None
        first = 0
        for batch in inp.batches:
            table = pa.Table.from_batches([batch])
            sets, form = inp.plan.read(table, first)
            first += batch.num_rows
            if comp is None:
                comp = Comparer(set(sets), job.conventions)
            cols = comp.add(sets, form)
            if writer is not None:
                clash = [c for c in cols if c in table.column_names]
                if clash:
                    from hconv.errors import InputError

                    raise InputError(
                        f"{inp.name}: already has column {clash[0]!r}; rename it (is this compare's own output?)"
                    )
                for name, values in cols.items():
                    table = table.append_column(
                        pa.field(name, pa.float64(), metadata={"unit": "deg" if name.startswith("angle_") else "1"}),
                        pa.array(values),
                    )
                writer.write(table)
        if comp is None:  # a header and no rows: still a valid (empty) output
            comp = Comparer(set(inp.plan.groups), job.conventions)
            if writer is not None:
                table = inp.schema.empty_table()
                names = ["offdiag", "r_axis"] + [f"{k}_{s.method}" for s in comp.scores for k in ("diff", "angle")]
                for name in names:
                    table = table.append_column(name, pa.array([], pa.float64()))
                writer.write(table)
    return comp.result()
