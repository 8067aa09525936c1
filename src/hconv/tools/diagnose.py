"""``hconv diagnose``: which convention explains the ω that the user's engine produced?

Each hypothesis is a way to get ω from the same row that a real engine or script might have
used. Every one is computed for every row and compared with the observed ω (``w_obs``):

* ``residual`` = |ω_hyp - ω_obs| / |ω_obs|, and ``angle`` between the two vectors [degrees]
  (:mod:`hconv.kernels.metrics`);
* a row is *explained* by a hypothesis when its residual is at most ``tol`` (default 1e-3, loose
  enough for an engine that works in float32 and tight enough to tell the hypotheses apart).

Hypotheses (those that need a column the input lacks, or that coincide with ``exact`` for the
input's form, are left out and listed as such):

=====================  ===========================================================================
exact                  ω = I⁻¹H with hconv's conventions (q turns body into world)
transposed-rotation    q used the other way round (world into body): R and Rᵀ swapped
ignored-rotation       the body-frame tensor used with world-frame H, no rotation at all
flipped-products       the products of inertia with the opposite sign
ordering-urdf          the six numbers read in URDF's order (xx, xy, xz, yy, yz, zz)
ordering-sympy         the six numbers read in SymPy's order (xx, yy, zz, xy, yz, zx)
pivot                  I shifted from the centre of mass to the pivot at -r (needs m, r)
diagonal               ω_i = H_i / I_ii, products ignored
document               the seed's Version 1 (needs r; a number in m²/s)
document-principal     the seed's Version 2 (needs r; a number in m²/s)
=====================  ===========================================================================

hconv's own order (xx, yy, zz, xy, xz, yz) is also MuJoCo's ``fullinertia`` order, so a MuJoCo
ordering is ``exact`` here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hconv.errors import UsageError, option
from hconv.kernels.metrics import angle_deg, relative_error
from hconv.solve import bodies, forms
from hconv.solve.options import Conventions
from hconv.tables.job import Job
from hconv.tools.stats import Summary

#: The six-number orders, as positions in hconv's (xx, yy, zz, xy, xz, yz).
_HCONV = ("xx", "yy", "zz", "xy", "xz", "yz")
ORDERINGS = {
    "urdf": ("xx", "xy", "xz", "yy", "yz", "zz"),
    "sympy": ("xx", "yy", "zz", "xy", "yz", "xz"),  # SymPy's inertia(frame, ixx, iyy, izz, ixy, iyz, izx)
}
DEFAULT_TOL = 1e-3
WORST_ROWS = 10


def reorder(I6: np.ndarray, order: tuple) -> np.ndarray:
    """The tensor an engine builds when it reads hconv's six numbers ``(6, N)`` in ``order``:
    the k-th number lands in entry ``order[k]``. Returns ``(6, N)`` in hconv's order."""
    out = np.empty_like(I6)
    for k, entry in enumerate(order):
        out[_HCONV.index(entry)] = I6[k]
    return out


def _conjugate(q: np.ndarray) -> np.ndarray:
    return np.concatenate([q[:1], -q[1:]])


def _six(sets: dict, form: str) -> np.ndarray | None:
    """The inertia as six numbers ``(6, N)``, for the hypotheses that permute them; None for a
    diagonal form, which has no products to misplace."""
    f = forms.get(form)
    return None if f.diagonal else f.as_six(sets["I"])


#: How a hypothesis predicts ω from a batch's sets and form: ``(3, N)``, or None when it is exact's.
Predict = Callable[[dict, str], np.ndarray | None]


@dataclass(frozen=True)
class Hypothesis:
    name: str
    needs: tuple  #: sets it needs besides H and I
    predict: Callable  #: (sets, form) -> ω (3, N) in rad/s or m²/s, or None when it equals exact
    summary: str


def _solve(sets: dict, form: str, method: str = "exact", **conv: Any) -> np.ndarray:
    res = bodies.solve(sets, form, method, 64, Conventions(**conv), diagnostics=False)
    return res.w.T


def _transposed(sets: dict, form: str) -> np.ndarray | None:
    return _solve({**sets, "q": _conjugate(sets["q"])}, form)


def _ignored(sets: dict, form: str) -> np.ndarray | None:
    return _solve({k: v for k, v in sets.items() if k != "q"}, form)


def _flipped(sets: dict, form: str) -> np.ndarray | None:
    return None if forms.get(form).diagonal else _solve(sets, form, products="positive")


def _ordering(order: tuple) -> Predict:
    def predict(sets: dict, form: str) -> np.ndarray | None:
        six = _six(sets, form)
        if six is None:
            return None
        return _solve({**sets, "I": reorder(six, order)}, "sym6")

    return predict


def _pivot(sets: dict, form: str) -> np.ndarray | None:
    return _solve(sets, form, about="pivot")


def _method(name: str) -> Predict:
    def predict(sets: dict, form: str) -> np.ndarray | None:
        if name == "diagonal" and forms.get(form).diagonal:
            return None  # the tensor is diagonal in the frame it is solved in: the same as exact
        return _solve(sets, form, name)

    return predict


HYPOTHESES = (
    Hypothesis("exact", (), _method("exact"), "ω = I⁻¹H with hconv's conventions"),
    Hypothesis("transposed-rotation", ("q",), _transposed, "q applied the other way (R and Rᵀ swapped)"),
    Hypothesis("ignored-rotation", ("q",), _ignored, "body-frame tensor with world-frame H, not rotated"),
    Hypothesis("flipped-products", (), _flipped, "products of inertia with the opposite sign"),
    *(
        Hypothesis(
            f"ordering-{k}",
            (),
            _ordering(v),
            f"six numbers read in {k.upper() if k == 'urdf' else 'SymPy'}'s order ({', '.join(v)})",
        )
        for k, v in ORDERINGS.items()
    ),
    Hypothesis("pivot", ("m", "r"), _pivot, "I shifted from the centre of mass to the pivot"),
    Hypothesis("diagonal", (), _method("diagonal"), "ω_i = H_i / I_ii, products ignored"),
    Hypothesis("document", ("r",), _method("document"), "the seed's Version 1 (m²/s)"),
    Hypothesis("document-principal", ("r",), _method("document-principal"), "the seed's Version 2 (m²/s)"),
)
NAMES = tuple(h.name for h in HYPOTHESES)


@dataclass
class Score:
    """One hypothesis over the whole input."""

    hypothesis: str
    summary: str
    residual: Summary
    angle: Summary
    applicable: bool = True
    why_not: str = ""


@dataclass
class Diagnosis:
    scores: list
    rows: int = 0
    tol: float = DEFAULT_TOL
    unexplained: int = 0  #: rows no hypothesis explains
    examples: list = field(default_factory=list)  #: (row, best hypothesis, its residual) for some of those

    def ranking(self) -> list:
        """Applicable hypotheses, best first: most rows explained, then smallest median residual."""
        usable = [s for s in self.scores if s.applicable]
        return sorted(usable, key=lambda s: (-s.residual.share_within, _key(s.residual.median)))


def _key(x: float) -> float:
    return x if np.isfinite(x) else np.inf


class Diagnoser:
    """Scores every hypothesis batch by batch; :meth:`result` gives the :class:`Diagnosis`."""

    def __init__(self, present: set, tol: float = DEFAULT_TOL):
        self.tol = tol
        self.scores = []
        for h in HYPOTHESES:
            lacking = [s for s in h.needs if s not in present]
            s = Score(
                h.name,
                h.summary,
                Summary(tol),
                Summary(0.0),
                applicable=not lacking,
                why_not=f"needs {', '.join(lacking)}" if lacking else "",
            )
            self.scores.append(s)
        self.rows = 0
        self.unexplained = 0
        self.examples: list[tuple[int, str, float]] = []

    def add(self, sets: dict, form: str) -> None:
        obs = sets["w_obs"]
        n = obs.shape[1]
        best = np.full(n, np.inf)
        best_name = np.full(n, "", dtype=object)
        for h, s in zip(HYPOTHESES, self.scores):
            if not s.applicable:
                continue
            w = h.predict(sets, form)
            if w is None:
                s.applicable, s.why_not = False, f"same as exact for the {form} form"
                continue
            w = w.astype(np.float64)
            res, ang = relative_error(w, obs), angle_deg(w, obs)
            s.residual.add(res, self.rows)
            s.angle.add(ang, self.rows)
            better = res < best
            best = np.where(better, res, best)
            best_name[better] = h.name
        fail = ~(best <= self.tol)
        self.unexplained += int(fail.sum())
        for k in np.flatnonzero(fail)[: max(0, WORST_ROWS - len(self.examples))]:
            self.examples.append((self.rows + int(k), best_name[k] or "none", float(best[k])))
        self.rows += n

    def result(self) -> Diagnosis:
        return Diagnosis(self.scores, self.rows, self.tol, self.unexplained, self.examples)


def diagnose_file(
    src: str,
    *,
    src_format: str | None = None,
    tol: float = DEFAULT_TOL,
    job: Job | None = None,
    progress: Callable[[int, int | None], None] | None = None,
) -> Diagnosis:
    """Score every hypothesis on the rows of ``src`` (CSV or Parquet, "-" for stdin)."""
    import pyarrow as pa

    from hconv.tables.tableio import format_of, open_input

    if not tol > 0:
        raise UsageError(f"{option('tol')} must be positive, got {tol}")
    job = dataclasses.replace(job or Job(), observed=True)
    job = dataclasses.replace(job, conventions=dataclasses.replace(job.conventions, about="same"))
    fin = format_of(src, src_format, "src_format")
    with open_input(src, fin, job) as inp:
        plan = inp.plan
        d = None
        first = 0
        for batch in inp.batches:
            sets, form = plan.read(pa.Table.from_batches([batch]), first)
            first += batch.num_rows
            if d is None:
                d = Diagnoser(set(sets), tol)
            d.add(sets, form)
            if progress is not None:
                progress(inp.position(), inp.total)
        if d is None:
            d = Diagnoser(set(plan.groups), tol)
    return d.result()
