"""Streaming summaries of non-negative per-row figures (errors, angles), in bounded memory.

A :class:`Summary` takes batches of values and keeps: the count, the rows with no value (NaN), the
share at or below a tolerance, the minimum, the maximum and its row, and a histogram in log10 with
100 bins per decade. Exact zeros are counted apart. The median is exact (``numpy.median`` of the
values) while the answered values number at most :data:`EXACT_VALUES`, which are kept for it;
past that it is read from the histogram, to within ±1.2 % (half a bin), and clamped to the
minimum and maximum, so that it never lies outside the values (one row's median is its value).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

_LO, _HI, _PER_DECADE = -40.0, 40.0, 100
_EDGES = np.linspace(_LO, _HI, int((_HI - _LO) * _PER_DECADE) + 1)
#: The most answered values a :class:`Summary` keeps for an exact median: 2 MB of float64 (compare
#: keeps four figures for each of its methods).
EXACT_VALUES = 1 << 18


@dataclass
class Summary:
    tol: float = 0.0  #: values <= tol count as "within"
    rows: int = 0  #: values seen, NaN included
    missing: int = 0  #: NaN values (no answer on that row)
    within: int = 0
    zeros: int = 0
    maximum: float = float("nan")
    max_row: int | None = None  #: 0-based row of the maximum
    minimum: float = float("nan")
    _hist: np.ndarray = field(default_factory=lambda: np.zeros(len(_EDGES) + 1, dtype=np.int64))
    #: the answered values so far, for an exact median; None once more than EXACT_VALUES came
    _kept: list[np.ndarray] | None = field(default_factory=list)

    def add(self, values: np.ndarray, first_row: int = 0) -> None:
        """Take a batch of values ``(n,)``; ``first_row`` is the row number of its first value."""
        v = np.asarray(values, dtype=np.float64)
        self.rows += v.size
        nan = np.isnan(v)
        self.missing += int(nan.sum())
        v_ok = v[~nan]
        if not v_ok.size:
            return
        if self._kept is not None and self.answered <= EXACT_VALUES:
            self._kept.append(v_ok)  # a copy already: boolean indexing copies
        else:
            self._kept = None  # the histogram's median from now on: memory stays bounded
        low = float(v_ok.min())
        if not low >= self.minimum:  # also when the minimum is still NaN
            self.minimum = low
        self.within += int((v_ok <= self.tol).sum())
        zero = v_ok == 0
        self.zeros += int(zero.sum())
        with np.errstate(divide="ignore"):
            logs = np.log10(v_ok[~zero])
        self._hist += np.bincount(np.searchsorted(_EDGES, logs), minlength=len(self._hist))
        k = int(np.nanargmax(np.where(nan, -np.inf, v)))
        if not v[k] <= self.maximum:  # also when the maximum is still NaN
            self.maximum, self.max_row = float(v[k]), first_row + k

    @property
    def answered(self) -> int:
        return self.rows - self.missing

    @property
    def share_within(self) -> float:
        """Share of all rows (NaN rows count as not within) at or below ``tol``."""
        return self.within / self.rows if self.rows else float("nan")

    @property
    def median(self) -> float:
        """The median of the answered rows: exact up to :data:`EXACT_VALUES` of them, else to half
        a bin (±1.2 %) within the minimum and maximum; NaN if there were none."""
        n = self.answered
        if not n:
            return float("nan")
        if self._kept is not None:
            return float(np.median(np.concatenate(self._kept)))
        return min(max(self._binned_median(n), self.minimum), self.maximum)

    def _binned_median(self, n: int) -> float:
        """The median of ``n`` answered rows read from the histogram, to half a bin."""
        half = (n - 1) / 2
        if half < self.zeros:
            return 0.0
        cum = self.zeros + np.cumsum(self._hist)
        k = int(np.searchsorted(cum, half, side="right"))
        if k == 0:
            return float(10.0**_LO)
        if k >= len(_EDGES):
            return float(10.0**_HI) if np.isfinite(self.maximum) else float("inf")
        return float(10.0 ** (0.5 * (_EDGES[k - 1] + _EDGES[k])))
