"""``hconv bodies``: the inertias of a robot model, read from URDF, SDF or MJCF, and checked.

A format's reader (:mod:`hconv.tools.urdf`, :mod:`hconv.tools.sdf`, :mod:`hconv.tools.mjcf`, told
apart by the root element) hands over each body's inertial as the file gives it
(:class:`hconv.tools.inertial.ReadBody`, whose module states the frames every format shares);
here each one is turned into B, reduced to its principal moments and axes, and checked.

Conventions (stated once, here; the input's are in :mod:`hconv.tools.inertial` and the readers,
hconv's own in :mod:`hconv.kernels.inertia`):

* Output: the principal moments ``I1 <= I2 <= I3`` about C, and the unit quaternion
  ``q_B = (qw, qx, qy, qz)``, qw >= 0, that turns principal-axis vectors into B: ``I_C_B =
  R(q_B)·diag(I1, I2, I3)·R(q_B)ᵀ``, which is how ``hconv convert`` reads I1, I2, I3 with q.

The checks are hconv's own (:mod:`hconv.solve.status`): a moment is zero by ``singular_rtol``, the
triangle inequality holds within ``TRIANGLE_RTOL`` of the trace, and the density band is the
unit-slip check's (:func:`hconv.solve.units.implausible`). This module adds one threshold, for
tensors that are nothing beside the mass:

* A body with m > 0 whose largest principal moment, in magnitude, is at most
  ``m·NEGLIGIBLE_LENGTH²`` (1 nm) has a negligible tensor: a point mass, as I = 0 is (``singular``),
  whatever its signs, not ``not_positive_definite``. Model files carry such dust: iCub's links
  have ``ixz = 2.4e-35`` beside m = 1.3 kg, and an indefinite tensor of 1e-35 kg·m² is rounding,
  not a sign slip. Why 1 nm, a radius of gyration of atomic size: it is a thousand times below
  the finest length model files write (positions to six decimals of a metre), so no body a file
  describes comes near it; and it stays below what a unit slip leaves of a real body (the
  largest, g·mm² read as kg·m², shrinks I by 1e9 and a 1 mm body's radius of gyration to some
  30 nm), so that a slip keeps ``implausible_density`` with its advice and is not called dust.
* The density check runs where the trace is not positive too, and on negligible tensors: a
  positive mass with no inertia has a radius of gyration of zero, so the cube has an infinite
  density, above the band (:func:`hconv.solve.units.implausible` leaves such rows unjudged).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hconv.errors import UsageError, option
from hconv.kernels.inertia import Sym3, principal_frame
from hconv.solve import forms, status, units
from hconv.solve.options import check_choice
from hconv.tables.sets import VECTOR_SETS
from hconv.tools import mjcf, sdf, urdf
from hconv.tools.inertial import ReadBody
from hconv.tools.modelxml import Budget, error, read

if TYPE_CHECKING:
    import pyarrow as pa

#: names the others that apply too.
STATUSES: dict[str, str] = {
    "ok": "the inertia is one a solid body can have",
    "no_inertial": "the file gives no inertia (MuJoCo infers it from the geoms; hconv does not)",
    "unresolved_frame": "SDF: the inertial's pose is relative to a frame hconv cannot place",
    "negative_mass": "m < 0",
    "massless_with_inertia": "m = 0 with a non-zero inertia (hconv convert: invalid_input)",
    "massless": "m = 0 and I = 0: a frame, not a body",
    "singular": "a principal moment is zero (all three: a point mass)",
    "not_positive_definite": "a principal moment is negative",
    "not_physical": "the principal moments break the triangle inequality I3 <= I1 + I2",
    "implausible_density": "no solid of this mass has this inertia: a placeholder, or a unit slip",
}
#: The output forms: hconv's six tensor numbers in B, or the principal moments with q_B.
OUTPUT_FORMS = ("sym6", "principal")
#: The radius of gyration below which a body's tensor is negligible beside its mass [m] (the
#: module's docstring says why 1 nm).
NEGLIGIBLE_LENGTH = 1e-9
STATUS_COLUMN = "inertia_status"  # not "status": hconv convert writes that one, and refuses an input with it
REASON_COLUMN = "inertia_reason"


@dataclass(frozen=True, slots=True)
class Body:
    """One body of a model: its inertia about its centre of mass, in its own frame, and its status.

    Without an inertial (status ``no_inertial`` or ``unresolved_frame``) every number is NaN.
    """

    name: str
    source: str  #: where the file describes it: ``arm.urdf, line 12``
    m: float  #: mass [kg]
    p_BC_B: np.ndarray  #: (3,) the centre of mass C from B's origin, in B [m]
    I_C_B: np.ndarray  #: (3, 3) about C, in B [kg·m²], tensor entries
    moments: np.ndarray  #: (3,) principal moments about C, ascending [kg·m²]
    q_B: np.ndarray  #: (4,) (w, x, y, z): principal axes → B
    status: str
    reason: str  #: why the status, and what else applies; "" for ok


@dataclass(frozen=True)
class Model:
    """A model file's bodies, in the file's order, and notes on what hconv did not follow."""

    path: str
    format: str  #: URDF, SDF or MJCF
    bodies: tuple[Body, ...]
    notes: tuple[str, ...] = ()

    def counts(self) -> dict[str, int]:
        """Bodies per status, for the statuses that occur, in precedence order."""
        got = [b.status for b in self.bodies]
        return {s: got.count(s) for s in STATUSES if s in got}

    def table(self, form: str = "sym6") -> pa.Table:
        """One row per body in hconv's input contract: ``body``, ``m``, ``rx, ry, rz`` (C from B's
        origin, in B) and the inertia about C as ``form``: ``sym6`` (Ixx … Iyz in B) or
        ``principal`` (I1, I2, I3 with qw, qx, qy, qz); then the status and its reason."""
        import pyarrow as pa

        from hconv.tables import arrays

        check_choice("form", form, tuple(OUTPUT_FORMS))
        bodies = self.bodies

        def col(values: list[float], unit: str) -> tuple[pa.Array, dict]:
            return arrays.from_numpy(np.array(values, dtype=np.float64)), {"unit": unit}

        cols: dict[str, tuple[pa.Array, dict | None]] = {}
        cols["body"] = (arrays.strings([b.name for b in bodies]), None)
        cols["m"] = col([b.m for b in bodies], units.SI["m"])
        for k, name in enumerate(VECTOR_SETS["r"]):
            cols[name] = col([float(b.p_BC_B[k]) for b in bodies], units.SI["r"])
        if form == "sym6":
            at = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
            for name, (i, j) in zip(forms.get("sym6").columns, at):
                cols[name] = col([float(b.I_C_B[i, j]) for b in bodies], units.SI["I"])
        else:
            for k, name in enumerate(forms.get("principal").columns):
                cols[name] = col([float(b.moments[k]) for b in bodies], units.SI["I"])
            for k, name in enumerate(VECTOR_SETS["q"]):
                cols[name] = col([float(b.q_B[k]) for b in bodies], "1")
        cols[STATUS_COLUMN] = (arrays.strings([b.status for b in bodies]), None)
        cols[REASON_COLUMN] = (arrays.strings([b.reason for b in bodies]), None)
        fields = [pa.field(n, a.type, metadata=meta) for n, (a, meta) in cols.items()]
        return pa.Table.from_arrays([a for a, _ in cols.values()], schema=pa.schema(fields))


def read_model(path: str | os.PathLike, *, root: str | os.PathLike | None = None) -> Model:
    """Read the bodies of a URDF, SDF or MJCF model (told apart by the root element) and check
    each one; InputError (one line: file, line, element and the fix) for a file it cannot read.

    ``root``: a folder holding the model's, within which MJCF includes may go (metaworld's
    models include ``../scene/basic_scene.xml``); by default the model's own folder. UsageError
    for a URDF or SDF model, which hconv reads from its one file: a root would change nothing."""
    shown = os.fspath(path)
    budget = Budget(shown)
    top = read(Path(path), shown, budget)
    if top.tag not in _READERS:
        raise error(
            top,
            "is the root element, so this is not a model hconv reads",
            "give a URDF (<robot>), SDF (<sdf>) or MJCF (<mujoco>) file",
        )
    fmt, reader = _READERS[top.tag]
    if root is not None and fmt != "MJCF":
        why = "has no includes" if fmt == "URDF" else "is read without its includes"
        raise UsageError(f"{shown}: {option('root')} is for MJCF includes; {fmt} {why}: drop {option('root')}")
    include_root = None if root is None else _include_root(Path(root), Path(path))
    if fmt == "MJCF":
        raws, notes = mjcf.bodies(top, Path(path), shown, budget, include_root=include_root)
    else:
        raws, notes = reader(top, Path(path), shown, budget)
    return Model(shown, fmt, tuple(_check(raws)), tuple(notes))


_READERS = {"robot": ("URDF", urdf.bodies), "sdf": ("SDF", sdf.bodies), "mujoco": ("MJCF", mjcf.bodies)}


def _include_root(root: Path, model: Path) -> Path:
    """``root``, checked: a folder that holds the model's; UsageError naming the option otherwise."""
    if not root.is_dir():
        raise UsageError(f"{option('root', os.fspath(root))} is not a folder; name the folder includes may come from")
    folder = model.resolve().parent
    held = root.resolve()
    if held != folder and held not in folder.parents:
        raise UsageError(
            f"{option('root', os.fspath(root))} does not hold the model's folder {str(folder)!r}; "
            "name a folder that holds both the model and what it includes"
        )
    return held


def write_bodies(
    model: Model, dst: str, *, form: str = "sym6", dst_format: str | None = None, force: bool = False
) -> None:
    """Write ``model.table(form)`` to ``dst`` (``-`` for stdout) through hconv's atomic writer."""
    from hconv.tables.output import Output
    from hconv.tables.sniff import format_of

    table = model.table(form)
    with Output(dst, format_of(dst, dst_format, "dst_format"), force=force, input_path=model.path) as out:
        out.write(table)


# --- the checks ----------------------------------------------------------------------------


def _quat(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) with w >= 0 of a proper rotation; Shepperd's branch on the largest of w², x²,
    y², z², so that the square root never takes a difference of nearly equal numbers."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        s = 2 * math.sqrt(1 + t)
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif k == 1:
        s = 2 * math.sqrt(1 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif k == 2:
        s = 2 * math.sqrt(1 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2 * math.sqrt(1 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4]
    v = np.asarray(q) / math.sqrt(sum(x * x for x in q))
    return (-v if v[0] < 0 else v) + 0.0  # + 0.0: no -0.0 in the output


def _g(x: float) -> str:
    return f"{x:.3g}"


def _valid(S: np.ndarray) -> np.ndarray:
    """Moments ``(3, N)`` (ascending) that a solid can have: none zero or negative, and the
    triangle inequality within hconv's tolerance."""
    top = np.abs(S).max(axis=0)
    trace = S.sum(axis=0)
    return (S[0] > status.singular_rtol(np.float64) * top) & (S[2] <= S[0] + S[1] + status.TRIANGLE_RTOL * trace)


def _sym3(I: np.ndarray) -> Sym3:
    return Sym3(I[:, 0, 0], I[:, 1, 1], I[:, 2, 2], I[:, 0, 1], I[:, 0, 2], I[:, 1, 2])


def _check(raws: list[ReadBody]) -> list[Body]:
    """Each body's tensor in B, principal moments and axes, status and reason."""
    n = len(raws)
    have = np.array([r.status is None for r in raws], dtype=bool)
    I_C_B = np.full((n, 3, 3), np.nan)
    for k, r in enumerate(raws):
        if r.I_C_I is not None and r.status is None:
            T = r.R_BI @ r.I_C_I @ r.R_BI.T
            I_C_B[k] = 0.5 * (T + T.T)  # symmetric to the last bit, whatever the rounding of the product
    S = np.full((3, n), np.nan)
    R = np.full((3, 3, n), np.nan)
    if have.any():
        S[:, have], R[:, :, have] = principal_frame(_sym3(I_C_B[have]))
    m = np.array([r.m for r in raws])
    flipped = I_C_B * np.where(np.eye(3, dtype=bool), 1.0, -1.0)
    moments_flipped = np.full((3, n), np.nan)
    if have.any():
        moments_flipped[:, have], _ = principal_frame(_sym3(flipped[have]))
    trace = S.sum(axis=0)
    bodies = []
    with np.errstate(invalid="ignore"):
        zero = have & np.all(I_C_B.reshape(n, 9) == 0, axis=1)
        top = np.abs(S).max(axis=0)
        negligible = have & (m > 0) & (top <= m * NEGLIGIBLE_LENGTH**2)
        # A moment below zero beyond the singular threshold makes the tensor indefinite, whatever
        # else is zero: (-1, 0, 1) is no rod, and its reason must say so, not "a line mass".
        negative = have & ~negligible & (S[0] < -status.singular_rtol(np.float64) * top)
        singular = (
            have
            & ~negative
            & (negligible | (np.abs(S).min(axis=0) <= status.singular_rtol(np.float64) * top))
            & ~(zero & (m == 0))
        )
        # no inertia beside a positive mass: an infinite density, which units.implausible leaves unjudged
        pointlike = have & (m > 0) & (negligible | (trace <= 0))
        flags = {
            "negative_mass": have & (m < 0),
            "massless_with_inertia": have & (m == 0) & ~zero,
            "massless": have & (m == 0) & zero,
            "singular": singular,
            "not_positive_definite": have & ~singular & (S[0] < 0),
            "not_physical": have & ~singular & (S[0] >= 0) & (S[2] > S[0] + S[1] + status.TRIANGLE_RTOL * trace),
            "implausible_density": pointlike
            | (have & units.implausible(np.where(have, trace, 0.0), np.where(have, m, 0.0))),
        }
        flip_ok = _valid(moments_flipped)
    for k, r in enumerate(raws):
        found = [r.status] if r.status else [s for s in STATUSES if s in flags and flags[s][k]] or ["ok"]
        q = np.full(4, np.nan)
        if have[k]:
            P = R[:, :, k].copy()
            if np.linalg.det(P) < 0:
                P[:, 0] = -P[:, 0]  # a right-handed frame, so that it is a rotation
            q = _quat(P)
        parts = [] if found[0] in ("ok", r.status) else [_why(found[0], m[k], S[:, k], I_C_B[k], flip_ok[k])]
        parts += r.notes
        parts += [f"also {s}: {_why(s, m[k], S[:, k], I_C_B[k], flip_ok[k])}" for s in found[1:]]
        bodies.append(
            Body(r.name, r.source, r.m, r.p_BC_B, I_C_B[k], S[:, k].copy(), q, found[0], "; ".join(filter(None, parts)))
        )
    return bodies


def _why(name: str, m: float, S: np.ndarray, I: np.ndarray, flip_ok: bool) -> str:
    """The reason for status ``name``, with the numbers that show it."""
    if name == "negative_mass":
        return f"m = {_g(m)} kg < 0"
    if name == "massless_with_inertia":
        return f"m = 0 with I ≠ 0 (moments {', '.join(_g(s) for s in S)} kg·m²): no inertia without mass"
    if name == "massless":
        return "m = 0 and I = 0: a frame, not a body; engines accept it only fixed to a parent"
    top = float(np.abs(S).max())
    negligible = m > 0 and top <= m * NEGLIGIBLE_LENGTH**2
    if name == "singular":
        if not np.any(I):
            return f"I = 0 with m = {_g(m)} kg: a point mass; engines need positive moments (MuJoCo refuses it)"
        if negligible:
            return (
                f"I is negligible beside m·(1 nm)² = {_g(m * NEGLIGIBLE_LENGTH**2)} kg·m² (its largest moment "
                f"is {_g(top)} kg·m², floating-point dust): a point mass, as if I = 0; engines need positive "
                "moments: give the link's real inertia"
            )
        zeros = int(np.sum(np.abs(S) <= status.singular_rtol(np.float64) * np.abs(S).max()))
        what = "a line mass, like an ideal rod" if zeros == 1 else "a point mass"
        listed = ", ".join(_g(s) for s in S)
        return f"moments {listed} kg·m²: {zeros} of them zero, {what}; engines need positive moments"
    products = bool(I[0, 1] or I[0, 2] or I[1, 2])
    flip = (
        "with the products negated it would be valid: a sign slip (+∫xy dm written where -∫xy dm belongs)?"
        if products and flip_ok
        else ("negating the products does not make it valid" if products else "it has no products, so no sign slip")
    )
    if name == "not_positive_definite":
        return f"principal moment I1 = {_g(S[0])} kg·m² < 0: no mass distribution has it; {flip}"
    if name == "not_physical":
        margin = (S[2] - S[0] - S[1]) / S.sum()
        return (
            f"I3 = {_g(S[2])} exceeds I1 + I2 = {_g(S[0] + S[1])} kg·m² by {_g(100 * margin)} % of the trace: "
            f"no mass distribution has it; {flip}"
        )
    if name == "implausible_density":
        lo, hi = status.UNIT_DENSITY_BAND
        if negligible or S.sum() <= 0:
            what, cause = (
                ("no inertia to speak of", ": the inertia left out or a placeholder")
                if negligible
                else (f"a trace of {_g(S.sum())} kg·m², not positive,", "")
            )
            return (
                f"a mass of {_g(m)} kg with {what} has no radius of gyration, so the cube with it an infinite "
                f"density (hconv accepts {_g(lo)} to {_g(hi)} kg/m³){cause}"
            )
        side = 2.0 * math.sqrt(S.sum() / (2.0 * m))
        rho = m / side**3
        if rho < lo:
            return (
                f"the uniform cube with this mass and radius of gyration has density {_g(rho)} kg/m³ "
                f"(hconv accepts {_g(lo)} to {_g(hi)}): far too much inertia for {_g(m)} kg. A placeholder "
                "(such as I = 1 kg·m²), or the inertia in g·cm², kg·cm² or kg·mm² read as kg·m²"
            )
        return (
            f"the uniform cube with this mass and radius of gyration has density {_g(rho)} kg/m³ "
            f"(hconv accepts {_g(lo)} to {_g(hi)}): far too little inertia for {_g(m)} kg. A placeholder, "
            "or the mass in g read as kg"
        )
    raise ValueError(name)
