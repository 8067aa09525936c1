"""``hconv diagnose``: which convention explains the ω that the user's engine produced?

The scene options (``--frame``, ``--omega-frame``, ``--about``, ``--products``, ``--quat-order``,
``--unit``, ``--map``) say what the user believes the file holds; ``exact`` is ω = I⁻¹H under
exactly that, and every other hypothesis is one mistake away from it: a way to get ω from the
same row that a real engine or script might have used. Every one is computed for every row and
compared with the observed ω (``w_obs``):

* ``residual`` = |ω_hyp - ω_obs| / |ω_obs|, and ``angle`` between the two vectors [degrees]
  (:mod:`hconv.kernels.metrics`);
* a row is *explained* by a hypothesis when its residual is at most ``tol`` (default 1e-3, loose
  enough for an engine that works in float32 and tight enough to tell the hypotheses apart).

Hypotheses; R = R(q) turns body into world, I is the tensor as declared, H its momentum:

=====================  ===========================================================================
exact                  ω = I⁻¹H with the declared conventions
transposed-rotation    q used the other way round (world into body): R and Rᵀ swapped
ignored-rotation       the body-frame tensor used with world-frame H, no rotation at all
omega-body-frame       ω_obs = Rᵀ·ω: the engine's body-frame ω (MuJoCo's free and ball joint
                       ``qvel``, Pinocchio's LOCAL velocity) logged as world
quat-xyzw              q's columns hold (x, y, z, w) (PyBullet, Eigen's ``coeffs()``, ROS): the
                       rotation is that of (qz, qw, qx, qy) as read
flipped-products       the products of inertia with the opposite sign
ordering-urdf          the six numbers read in URDF's order (xx, xy, xz, yy, yz, zz)
ordering-sympy         the six numbers read in SymPy's order (xx, yy, zz, xy, yz, zx)
pivot                  H about a fixed pivot: I shifted from the centre of mass by m(|r|²E - r·rᵀ)
                       (needs m, r); with ``--about pivot`` declared, I not shifted
orbital-momentum       H about the origin, orbital term and all: ω = I⁻¹(H - r × m·v) (needs m, r,
                       v); with ``--about free`` declared, r × m·v left in H and taken for spin
diagonal               ω_i = H_i / I_ii, products ignored
omega-deg-per-s        ω_obs in degrees per second: 180/π times ω in the unit declared for w_obs;
                       with w_obs declared in deg/s, ω_obs in rad/s: ω in the declared unit
document               the seed's Version 1 (needs r; a number in m²/s)
document-principal     the seed's Version 2 (needs r; a number in m²/s)
=====================  ===========================================================================

A hypothesis that needs a column the input lacks, or that the declared conventions make the same
as ``exact`` or meaningless (every one that turns by q, when H and ω are both declared in the
body frame; ``omega-body-frame`` when ω is declared in the body frame; those that permute or flip
products, for a diagonal form), is left out and listed with the reason.

Two hypotheses *tie* when they explain the same rows with the same ω as far as the data can tell:
on each of those rows their ω differ by no more than the row's best residual (how closely any
hypothesis meets ω_obs: the data's own precision, such as an engine's float32), or
:data:`TIE_ULPS` float64 ulps where a hypothesis meets ω_obs exactly. Then the data cannot tell
them apart (a diagonal tensor, a rotation by 180°, the identity), so they share a rank and neither
is called the better. Both within ``tol`` is not enough: a large ``tol`` would tie an exact match
with a hypothesis 10 % off.

hconv's own order (xx, yy, zz, xy, xz, yz) is also MuJoCo's ``fullinertia`` order, so a MuJoCo
ordering is ``exact`` here.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hconv.errors import UsageError, option
from hconv.kernels.metrics import angle_deg, relative_error
from hconv.solve import bodies, forms, methods
from hconv.solve.options import Conventions
from hconv.tables.job import Job, check_job
from hconv.tools.stats import Summary

#: The six-number orders, as positions in hconv's (xx, yy, zz, xy, xz, yz).
_HCONV = ("xx", "yy", "zz", "xy", "xz", "yz")
ORDERINGS = {
    "urdf": ("xx", "xy", "xz", "yy", "yz", "zz"),
    "sympy": ("xx", "yy", "zz", "xy", "yz", "xz"),  # SymPy's inertia(frame, ixx, iyy, izz, ixy, iyz, izx)
}
DEFAULT_TOL = 1e-3
WORST_ROWS = 10
DEG_PER_RAD = 180.0 / np.pi
#: Two ω that differ by at most this many float64 ulps (relative) are the same answer reached by
#: different arithmetic (a division instead of a solve, say), whatever ω_obs is.
TIE_ULPS = 8


def reorder(I6: np.ndarray, order: tuple) -> np.ndarray:
    """The tensor an engine builds when it reads hconv's six numbers ``(6, N)`` in ``order``:
    the k-th number lands in entry ``order[k]``. Returns ``(6, N)`` in hconv's order."""
    out = np.empty_like(I6)
    for k, entry in enumerate(order):
        out[_HCONV.index(entry)] = I6[k]
    return out


def _conjugate(q: np.ndarray) -> np.ndarray:
    return np.concatenate([q[:1], -q[1:]])


@dataclass(frozen=True)
class Scene:
    """What the user declared about the input: the conventions, the inertia form (None before a
    row is read), the order a list column q was read in, and the factor that took each w_obs
    column to rad/s (``--unit``)."""

    conv: Conventions = field(default_factory=Conventions)
    form: str | None = None
    quat_order: str = "wxyz"  #: "xyzw" only for a list column q read with --quat-order xyzw
    w_obs_factors: tuple = (1.0, 1.0, 1.0)
    #: where q is in the input, for the text of the hypotheses about it
    q_where: str = "the qw, qx, qy, qz columns"

    @property
    def uses_q(self) -> bool:
        """q turns something: H (and r, v) into the body frame, or ω out of it."""
        return self.conv.frame == "world" or self.conv.w_frame == "world"

    @property
    def diagonal(self) -> bool:
        return self.form is not None and forms.get(self.form).diagonal


#: How a hypothesis predicts ω ``(3, N)`` [rad/s, or m²/s] from a batch's sets under the scene.
Predict = Callable[[dict, Scene], np.ndarray]
#: Why a hypothesis is not scored under the scene (the same as exact, or meaningless); "" if it is.
Moot = Callable[[Scene], str]


def _scored(scene: Scene) -> str:
    return ""


@dataclass(frozen=True)
class Hypothesis:
    name: str
    needs: tuple  #: sets it needs besides those the declared conventions need
    predict: Predict
    summary: str
    moot: Moot = _scored
    #: the summary when the user declared the convention this hypothesis stands for, so that it
    #: is the reverse mistake (pivot and orbital-momentum: the point of H; omega-deg-per-s: w_obs
    #: in deg/s), and whether the scene declares it
    reverse: str = ""
    declared: Callable[[Scene], bool] = lambda scene: False

    def describe(self, scene: Scene) -> str:
        """The summary for ``scene``: the reverse mistake where it declares this convention, and
        ``{q}`` replaced by where q is in the input (named columns or one list column)."""
        text = self.reverse if self.reverse and self.declared(scene) else self.summary
        return text.replace("{q}", scene.q_where)


def _solve(sets: dict, scene: Scene, method: str = "exact", form: str | None = None, **conv: Any) -> np.ndarray:
    """ω ``(3, N)`` under the scene's conventions with ``conv``'s changes."""
    c = dataclasses.replace(scene.conv, **conv)
    res = bodies.solve(sets, form or scene.form or "scalar", method, 64, c, diagnostics=False)
    return res.w.T.astype(np.float64)


def _exact(sets: dict, scene: Scene) -> np.ndarray:
    return _solve(sets, scene)


def _transposed(sets: dict, scene: Scene) -> np.ndarray:
    return _solve({**sets, "q": _conjugate(sets["q"])}, scene)


def _ignored(sets: dict, scene: Scene) -> np.ndarray:
    # no q at all: the body-frame tensor meets H as given, and ω stays in that frame
    return _solve({k: v for k, v in sets.items() if k != "q"}, scene, omega_frame=None)


def _omega_body(sets: dict, scene: Scene) -> np.ndarray:
    return _solve(sets, scene, omega_frame="body")


def _quat_xyzw(sets: dict, scene: Scene) -> np.ndarray:
    # the columns qw, qx, qy, qz hold x, y, z, w: the rotation's (w, x, y, z) is (qz, qw, qx, qy)
    return _solve({**sets, "q": sets["q"][[3, 0, 1, 2]]}, scene)


def _flipped(sets: dict, scene: Scene) -> np.ndarray:
    return _solve(sets, scene, products="positive" if scene.conv.products == "tensor" else "tensor")


def _ordering(order: tuple) -> Predict:
    def predict(sets: dict, scene: Scene) -> np.ndarray:
        six = forms.get(scene.form or "sym6").as_six(sets["I"])
        return _solve({**sets, "I": reorder(six, order)}, scene, form="sym6")

    return predict


def _about(point: str) -> Predict:
    """H about ``point``; or, when the user declared that point, H about the tensor's own point."""

    def predict(sets: dict, scene: Scene) -> np.ndarray:
        return _solve(sets, scene, about="same" if scene.conv.about == point else point)

    return predict


def _method(name: str) -> Predict:
    # a shortcut divides or projects as it stands: --degenerate is the exact family's, not its
    plain = {} if methods.get(name).exact else {"degenerate": "error", "degenerate_rtol": None}

    def predict(sets: dict, scene: Scene) -> np.ndarray:
        return _solve(sets, scene, name, **plain)

    return predict


def _in_degrees(scene: Scene) -> bool:
    """w_obs is declared in deg/s (every column's factor to rad/s is π/180)."""
    return all(abs(f * DEG_PER_RAD - 1) < 1e-12 for f in scene.w_obs_factors)


def _degrees(sets: dict, scene: Scene) -> np.ndarray:
    # the numbers are degrees per second, read in the declared unit (rad/s unless --unit says);
    # declared deg/s, the reverse slip: the numbers are rad/s, read as deg/s
    per_rad = 1.0 if _in_degrees(scene) else DEG_PER_RAD
    return _solve(sets, scene) * (per_rad * np.asarray(scene.w_obs_factors, dtype=np.float64))[:, None]


def _q_unused(scene: Scene) -> str:
    return "" if scene.uses_q else "H and ω are declared in the body frame, so q turns nothing"


def _moot_ignored(scene: Scene) -> str:
    if scene.conv.frame == "body":
        return "H is declared in the body frame: no rotation of H to leave out; ω not turned is omega-body-frame"
    return ""


def _moot_omega_body(scene: Scene) -> str:
    return "ω is declared in the body frame" if scene.conv.w_frame == "body" else ""


def _moot_xyzw(scene: Scene) -> str:
    if scene.quat_order == "xyzw":
        return "q is read as x, y, z, w already (--quat-order xyzw)"
    return _q_unused(scene)


def _moot_products(scene: Scene) -> str:
    return f"same as exact for the {scene.form} form" if scene.diagonal else ""


def _moot_diagonal(scene: Scene) -> str:
    # a pivot shift gives even a diagonal form products, which the diagonal method then ignores
    return _moot_products(scene) if scene.conv.about != "pivot" else ""


HYPOTHESES = (
    Hypothesis("exact", (), _exact, "ω = I⁻¹H with the declared conventions"),
    Hypothesis("transposed-rotation", ("q",), _transposed, "q applied the other way (R and Rᵀ swapped)", _q_unused),
    Hypothesis(
        "ignored-rotation", ("q",), _ignored, "body-frame tensor with world-frame H, not rotated", _moot_ignored
    ),
    Hypothesis(
        "omega-body-frame",
        ("q",),
        _omega_body,
        "the engine's ω is in the body frame (MuJoCo's free-joint qvel, Pinocchio's LOCAL) but logged as world",
        _moot_omega_body,
    ),
    Hypothesis(
        "quat-xyzw",
        ("q",),
        _quat_xyzw,
        "an x, y, z, w quaternion (PyBullet, Eigen's coeffs(), ROS) in {q}",
        _moot_xyzw,
    ),
    Hypothesis("flipped-products", (), _flipped, "products of inertia with the opposite sign", _moot_products),
    *(
        Hypothesis(
            f"ordering-{k}",
            (),
            _ordering(v),
            f"six numbers read in {k.upper() if k == 'urdf' else 'SymPy'}'s order ({', '.join(v)})",
            _moot_products,
        )
        for k, v in ORDERINGS.items()
    ),
    Hypothesis(
        "pivot",
        ("m", "r"),
        _about("pivot"),
        "H about a fixed pivot: I shifted from the centre of mass to it",
        reverse="I about the pivot already: not shifted from the centre of mass",
        declared=lambda scene: scene.conv.about == "pivot",
    ),
    Hypothesis(
        "orbital-momentum",
        ("m", "r", "v"),
        _about("free"),
        "H about the origin, orbital term r × m·v included (--about free), taken for spin",
        reverse="the orbital term r × m·v left in H and taken for spin",
        declared=lambda scene: scene.conv.about == "free",
    ),
    Hypothesis("diagonal", (), _method("diagonal"), "ω_i = H_i / I_ii, products ignored", _moot_diagonal),
    Hypothesis(
        "omega-deg-per-s",
        (),
        _degrees,
        "ω logged in degrees per second",
        reverse="ω logged in rad/s but declared deg/s (--unit w_obs=deg/s)",
        declared=_in_degrees,
    ),
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
    #: pairs of hypotheses (frozensets of two names) that explain the same rows, at least one, with
    #: the same ω on each of them as far as the data tell (see the module docstring)
    ties: set = field(default_factory=set)

    def groups(self) -> list[list[Score]]:
        """Applicable hypotheses in groups that tie (each member ties with every other), best
        group first: most rows explained, then smallest median residual. A group's members are
        in the order of :data:`HYPOTHESES`, since the data cannot rank them."""
        usable = [s for s in self.scores if s.applicable]
        usable.sort(key=lambda s: (-_key(s.residual.share_within), _key(s.residual.median)))
        out: list[list[Score]] = []
        placed: set = set()
        for s in usable:
            if s.hypothesis in placed:
                continue
            group = [s]
            for t in usable:
                if t.hypothesis not in placed and t is not s and all(self.tied(t, g) for g in group):
                    group.append(t)
            placed.update(g.hypothesis for g in group)
            out.append(sorted(group, key=lambda g: NAMES.index(g.hypothesis)))
        return out

    def ranking(self) -> list:
        """Applicable hypotheses, best first (:meth:`groups`, one after the other)."""
        return [s for g in self.groups() for s in g]

    def ranks(self) -> list[tuple[int, Score, list[str]]]:
        """(rank, score, the names it ties with) in ranking order; tied hypotheses share a rank."""
        out, rank = [], 1
        for g in self.groups():
            for s in g:
                out.append((rank, s, [t.hypothesis for t in g if t is not s]))
            rank += len(g)
        return out

    def tied(self, a: Score, b: Score) -> bool:
        return frozenset((a.hypothesis, b.hypothesis)) in self.ties

    def to_json(self) -> list[dict]:
        """The ranking as ``hconv diagnose --json`` prints it, best first; None (JSON's null)
        where a figure is NaN or infinite, which standard JSON has not."""

        def clean(x: float) -> float | None:
            return x if np.isfinite(x) else None

        return [
            {
                "hypothesis": s.hypothesis,
                "rank": rank,
                "tied_with": tied,
                "median_residual": clean(s.residual.median),
                "share_explained": clean(s.residual.share_within),
                "median_angle_deg": clean(s.angle.median),
            }
            for rank, s, tied in self.ranks()
        ]


def _key(x: float) -> float:
    return x if np.isfinite(x) else np.inf


class Diagnoser:
    """Scores every hypothesis batch by batch; :meth:`result` gives the :class:`Diagnosis`."""

    def __init__(self, present: set, tol: float = DEFAULT_TOL, scene: Scene | None = None):
        self.tol = tol
        self.scene = scene or Scene()
        self.scores = []
        for h in HYPOTHESES:
            lacking = [s for s in h.needs if s not in present]
            why = f"needs {', '.join(lacking)}" if lacking else h.moot(self.scene)
            s = Score(
                h.name,
                h.describe(self.scene),
                Summary(tol),
                Summary(0.0),
                applicable=not why,
                why_not=why,
            )
            self.scores.append(s)
        self.rows = 0
        self.unexplained = 0
        self.examples: list[tuple[int, str, float]] = []
        #: per pair of hypotheses (by position), the rows on which they do not tie
        self._apart = np.zeros((len(HYPOTHESES), len(HYPOTHESES)), dtype=np.int64)

    def add(self, sets: dict, form: str) -> None:
        obs = sets["w_obs"]
        n = obs.shape[1]
        scene = self.scene if self.scene.form == form else dataclasses.replace(self.scene, form=form)
        best = np.full(n, np.inf)
        best_name = np.full(n, "", dtype=object)
        got: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # position -> (ω, explained rows)
        for k, (h, s) in enumerate(zip(HYPOTHESES, self.scores)):
            if not s.applicable:
                continue
            w = h.predict(sets, scene)
            res, ang = relative_error(w, obs), angle_deg(w, obs)
            s.residual.add(res, self.rows)
            s.angle.add(ang, self.rows)
            got[k] = (w, res <= self.tol)
            better = res < best
            best = np.where(better, res, best)
            best_name[better] = h.name
        self._count_apart(got, best)
        fail = ~(best <= self.tol)
        self.unexplained += int(fail.sum())
        for k in np.flatnonzero(fail)[: max(0, WORST_ROWS - len(self.examples))]:
            self.examples.append((self.rows + int(k), best_name[k] or "none", float(best[k])))
        self.rows += n

    def _count_apart(self, got: dict, best: np.ndarray) -> None:
        """Count, per pair, the rows one explains and the other does not, and the rows both
        explain with ω further apart (relative to the second's) than the data can see: the row's
        best residual ``best`` ``(N,)``, or TIE_ULPS ulps."""
        near = np.maximum(best, TIE_ULPS * np.finfo(np.float64).eps)
        for a, b in itertools.combinations(got, 2):
            (wa, ea), (wb, eb) = got[a], got[b]
            if not (ea.any() or eb.any()):
                continue
            both = ea & eb
            apart = int((ea != eb).sum())
            if both.any():
                apart += int((~(relative_error(wa[:, both], wb[:, both]) <= near[both])).sum())
            self._apart[a, b] += apart

    def result(self) -> Diagnosis:
        ties = {
            frozenset((self.scores[a].hypothesis, self.scores[b].hypothesis))
            for a, b in itertools.combinations(range(len(self.scores)), 2)
            if self.scores[a].applicable
            and self.scores[b].applicable
            and self._apart[a, b] == 0
            and self.scores[a].residual.within > 0
        }
        return Diagnosis(self.scores, self.rows, self.tol, self.unexplained, self.examples, ties)


def diagnose_file(
    src: str,
    *,
    src_format: str | None = None,
    tol: float = DEFAULT_TOL,
    job: Job | None = None,
    progress: Callable[[int, int | None], None] | None = None,
) -> Diagnosis:
    """Score every hypothesis on the rows of ``src`` (CSV or Parquet, "-" for stdin), as
    deviations from the conventions, column names and units ``job`` declares."""
    import pyarrow as pa

    from hconv.tables.sniff import format_of
    from hconv.tables.tableio import open_input

    if not (tol > 0 and np.isfinite(tol)):  # an infinite tol explains every row by every hypothesis
        raise UsageError(f"{option('tol')} must be a positive finite number, got {tol}")
    check_job(job)
    job = dataclasses.replace(job or Job(), observed=True)
    fin = format_of(src, src_format, "src_format")
    with open_input(src, fin, job) as inp:
        plan = inp.plan
        q, w_obs = plan.groups.get("q"), plan.groups["w_obs"]
        scene = Scene(
            job.conventions,
            plan.form,
            "xyzw" if q is not None and q.is_list and plan.quat_order == "xyzw" else "wxyz",
            tuple(float(f) for f in np.broadcast_to(np.asarray(w_obs.factors or (1.0,), dtype=np.float64), 3)),
            # a list column is read as w, x, y, z unless --quat-order says otherwise
            f"the list column {q.columns[0]} (read as w, x, y, z)" if q is not None and q.is_list else Scene.q_where,
        )
        d = None
        first = 0
        for batch in inp.batches:
            sets, form = plan.read(pa.Table.from_batches([batch]), first)
            first += batch.num_rows
            if d is None:
                d = Diagnoser(set(sets), tol, dataclasses.replace(scene, form=form))
            d.add(sets, form)
            if progress is not None:
                progress(inp.position(), inp.total)
        if d is None:
            d = Diagnoser(set(plan.groups), tol, scene)
    return d.result()
