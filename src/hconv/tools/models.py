"""``hconv bodies``: the inertias of a robot model, read from URDF, SDF or MJCF, and checked.

Conventions (stated once, here; hconv's own are in :mod:`hconv.kernels.inertia`):

* B is a body's own frame: the URDF or SDF link frame, the MJCF body frame. Every format gives a
  body's inertia about its centre of mass C, in an inertial frame I placed in B by a pose: C's
  position ``p_BC_B`` [m] and a rotation ``R_BI`` whose columns are I's axes in B
  (``v_B = R_BI·v_I``). The tensor in B is ``I_C_B = R_BI · I_C_I · R_BIᵀ`` [kg·m²].
* Products of inertia are tensor entries, ``Ixy = -∫xy dm``, in URDF (``ixy``), SDF (``<ixy>``)
  and MJCF (``fullinertia``'s fourth number), as in hconv, so they are taken as they stand.
* URDF ``rpy`` and SDF ``<pose>``'s roll, pitch, yaw turn about the fixed axes X, then Y, then Z:
  ``R = Rz(yaw)·Ry(pitch)·Rx(roll)``; radians, unless SDF says ``degrees="true"``. SDF's
  ``rotation_format="quat_xyzw"`` gives x y z qx qy qz qw.
* MJCF: ``quat`` is (w, x, y, z). ``axisangle`` and ``euler`` are in ``<compiler angle>``'s unit,
  which is **degrees unless angle="radian"**. ``euler`` follows ``<compiler eulerseq>`` (default
  ``xyz``): a lower-case letter turns about the moving frame's axis (intrinsic), an upper-case one
  about the parent's fixed axis (extrinsic). ``xyaxes`` gives I's x and y axes (y is made
  orthogonal to x); ``zaxis`` the z axis, reached by the smallest rotation from (0, 0, 1).
  ``fullinertia`` is (ixx, iyy, izz, ixy, ixz, iyz) in B, with no orientation. Where several
  ``<compiler>`` elements set an attribute, the last counts for the whole model, as in MuJoCo.
* Output: the principal moments ``I1 <= I2 <= I3`` about C, and the unit quaternion
  ``q_B = (qw, qx, qy, qz)``, qw >= 0, that turns principal-axis vectors into B: ``I_C_B =
  R(q_B)·diag(I1, I2, I3)·R(q_B)ᵀ``, which is how ``hconv convert`` reads I1, I2, I3 with q.

The checks are hconv's own (:mod:`hconv.solve.status`): a moment is zero by ``singular_rtol``, the
triangle inequality holds within ``TRIANGLE_RTOL`` of the trace, and the density band is the
unit-slip check's (:func:`hconv.solve.units.implausible`). This module adds no threshold.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hconv.kernels.frames import quaternion_matrix
from hconv.kernels.inertia import Sym3, principal_frame
from hconv.solve import forms, status, units
from hconv.solve.options import check_choice
from hconv.tables.sets import VECTOR_SETS
from hconv.tools.modelxml import Budget, Node, clip, error, expand_includes, quote, read

if TYPE_CHECKING:
    import pyarrow as pa

#: A body's status, in order of precedence: the first that applies is the body's, and its reason
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
STATUS_COLUMN = "inertia_status"  # not "status": hconv convert writes that one, and refuses an input with it
REASON_COLUMN = "inertia_reason"
_ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")


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

        check_choice("form", form, tuple(OUTPUT_FORMS))
        bodies = self.bodies

        def col(values: list[float], unit: str) -> tuple[pa.Array, dict]:
            return pa.array(values, type=pa.float64()), {"unit": unit}

        cols: dict[str, tuple[pa.Array, dict | None]] = {}
        cols["body"] = (pa.array([b.name for b in bodies], pa.string()), None)
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
        cols[STATUS_COLUMN] = (pa.array([b.status for b in bodies], pa.string()), None)
        cols[REASON_COLUMN] = (pa.array([b.reason for b in bodies], pa.string()), None)
        fields = [pa.field(n, a.type, metadata=meta) for n, (a, meta) in cols.items()]
        return pa.Table.from_arrays([a for a, _ in cols.values()], schema=pa.schema(fields))


def read_model(path: str | os.PathLike) -> Model:
    """Read the bodies of a URDF, SDF or MJCF model (told apart by the root element) and check
    each one; InputError (one line: file, line, element and the fix) for a file it cannot read."""
    shown = os.fspath(path)
    budget = Budget(shown)
    root = read(Path(path), shown, budget)
    readers = {"robot": ("URDF", _urdf), "sdf": ("SDF", _sdf), "mujoco": ("MJCF", _mjcf)}
    if root.tag not in readers:
        raise error(
            root,
            "is the root element, so this is not a model hconv reads",
            "give a URDF (<robot>), SDF (<sdf>) or MJCF (<mujoco>) file",
        )
    fmt, reader = readers[root.tag]
    raws, notes = reader(root, Path(path), shown, budget)
    return Model(shown, fmt, tuple(_check(raws)), tuple(notes))


def write_bodies(
    model: Model, dst: str, *, form: str = "sym6", dst_format: str | None = None, force: bool = False
) -> None:
    """Write ``model.table(form)`` to ``dst`` (``-`` for stdout) through hconv's atomic writer."""
    from hconv.tables.output import Output
    from hconv.tables.sniff import format_of

    table = model.table(form)
    with Output(dst, format_of(dst, dst_format, "dst_format"), force=force, input_path=model.path) as out:
        out.write(table)


# --- rotations (small, per body) -----------------------------------------------------------


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw)·Ry(pitch)·Rx(roll)``: URDF's and SDF's fixed-axis X, Y, Z."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _matrix(q: list[float] | np.ndarray) -> np.ndarray:
    """The rotation of a quaternion (w, x, y, z), normalised (hconv's kernel)."""
    R, _ = quaternion_matrix(np.asarray(q, dtype=np.float64)[:, None])
    return R[:, :, 0]


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product ``a·b`` of (w, x, y, z) quaternions: first b, then a."""
    return np.array(
        [
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ]
    )


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


def _unit(v: list[float], node: Node, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise error(node, f"{what} has zero length", f"give a non-zero {what}")
    return a / n


# --- what the readers hand over ----------------------------------------------------------


@dataclass(slots=True)
class _Raw:
    """A body as read: the inertial's numbers in its own frame, or why there are none."""

    name: str
    source: str
    m: float = math.nan
    p_BC_B: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    R_BI: np.ndarray = field(default_factory=lambda: np.eye(3))
    I_C_I: np.ndarray | None = None
    status: str | None = None  #: no_inertial or unresolved_frame, with ``notes`` saying why
    notes: list[str] = field(default_factory=list)


def _tensor(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float) -> np.ndarray:
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=np.float64)


def _walk(root: Node) -> list[Node]:
    """Every element under ``root``, in document order, without recursion."""
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(reversed(n.children))
    return out


def _name(node: Node, what: str) -> str:
    name = node.attrib.get("name", "").strip()
    if not name:
        raise error(node, "has no name", f'name the {what}: <{node.tag} name="...">')
    return name


def _lines(at: list[int]) -> str:
    """``3, 9, 12``; the first five and the count when there are more: a note stays a line."""
    shown = ", ".join(map(str, at[:5]))
    return shown if len(at) <= 5 else f"{shown}, … ({len(at):,} in all)"


# --- URDF ----------------------------------------------------------------------------------


def _urdf(root: Node, path: Path, shown: str, budget: Budget) -> tuple[list[_Raw], list[str]]:
    # Only an unexpanded macro counts: many URDFs made by xacro keep its namespace declaration.
    xacro = next((n for n in _walk(root) if n.tag.startswith("xacro:")), None)
    if xacro is not None:
        raise error(
            xacro,
            "is xacro, a macro language that makes URDF",
            "run xacro first (xacro model.urdf.xacro > model.urdf) and give hconv the URDF",
        )
    raws = []
    lines: dict[str, list[int]] = {}  # link name -> the lines it is given at
    for link in root.findall("link"):
        name = budget.name(_name(link, "link"), link)
        lines.setdefault(name, []).append(link.line)
        inertial = link.find("inertial")
        if inertial is None:
            raws.append(
                _Raw(
                    name,
                    f"{shown}, line {link.line}",
                    status="no_inertial",
                    notes=["no <inertial>: URDF leaves its mass and inertia undefined, and simulators differ"],
                )
            )
            continue
        origin = inertial.find("origin")
        xyz = origin.numbers("xyz", (3,), "0 0 0") if origin is not None else [0.0] * 3
        rpy = origin.numbers("rpy", (3,), "0 0 0") if origin is not None else [0.0] * 3
        mass = inertial.find("mass")
        if mass is None:
            raise error(inertial, "has no <mass>", 'add <mass value="..."/> in kg (URDF requires it)')
        m = mass.required("value", (1,), 'give the mass in kg: <mass value="1.5"/>')[0]
        inertia = inertial.find("inertia")
        if inertia is None:
            raise error(
                inertial,
                "has no <inertia>",
                'add <inertia ixx="..." ixy="..." ixz="..." iyy="..." iyz="..." izz="..."/> (URDF requires it)',
            )
        fix = "URDF's <inertia> needs all of ixx, ixy, ixz, iyy, iyz, izz (kg·m²)"
        six = {a: inertia.required(a, (1,), fix)[0] for a in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")}
        raws.append(
            _Raw(
                name,
                f"{shown}, line {inertial.line}",
                m,
                np.asarray(xyz, dtype=np.float64),
                _rpy(*(rpy or [0.0] * 3)),
                _tensor(*six.values()),
            )
        )
    # Both are listed, as the file gives them, but a parser that keys links by name keeps one
    notes = [
        f"{shown}: link {quote(name)} is given {len(at)} times (lines {_lines(at)}); URDF requires "
        "unique link names, and urdfdom refuses the model: rename or remove all but one"
        for name, at in lines.items()
        if len(at) > 1
    ]
    return raws, notes


# --- SDF -----------------------------------------------------------------------------------

_Pose = tuple[np.ndarray, np.ndarray]  # (p, R): v_parent = R·v + p


def _compose(a: _Pose, b: _Pose) -> _Pose:
    return a[0] + a[1] @ b[0], a[1] @ b[1]


def _invert(a: _Pose) -> _Pose:
    return -(a[1].T @ a[0]), a[1].T


def _bool(node: Node, name: str) -> bool:
    v = node.attrib.get(name, "false").strip().lower()
    if v not in ("true", "false", "1", "0"):
        raise error(node, f"has {name}={quote(v)}", f'write {name}="true" or {name}="false"')
    return v in ("true", "1")


def _sdf_pose(owner: Node) -> tuple[_Pose, str | None]:
    """``owner``'s ``<pose>`` and the frame it is relative to (None: the default)."""
    pose = owner.find("pose")
    if pose is None:
        return (np.zeros(3), np.eye(3)), None
    ref = (pose.attrib.get("relative_to") or pose.attrib.get("frame") or "").strip() or None
    kind = pose.attrib.get("rotation_format", "euler_rpy").strip()
    if kind == "euler_rpy":
        v = pose.numbers("", (6,), "0 0 0 0 0 0") or [0.0] * 6
        angles = [math.radians(a) for a in v[3:]] if _bool(pose, "degrees") else v[3:]
        return (np.asarray(v[:3]), _rpy(*angles)), ref
    if kind == "quat_xyzw":
        v = pose.numbers("", (7,), "0 0 0 0 0 0 1") or [0.0] * 6 + [1.0]
        q = _unit([v[6], v[3], v[4], v[5]], pose, "quaternion")
        return (np.asarray(v[:3]), _matrix(q)), ref
    raise error(pose, f"has rotation_format={quote(kind)}", 'write rotation_format="euler_rpy" or "quat_xyzw"')


class _UnresolvedError(Exception):
    """An SDF frame hconv cannot place; the message says which and why."""


class _TooDeepError(_UnresolvedError):
    """Placing a frame passed through more than :data:`_MAX_NESTED` nested models' frames: not
    the frame's own failing, since from a frame further down the chain the rest may be short."""


#: The most frames of nested models that placing one frame may pass through (``a::b::link``, or a
#: nested model placed relative to a frame of another): models nest a few deep, and each is a
#: level of recursion here, which must stay within Python's stack.
_MAX_NESTED = 200
_Path = tuple[str, ...]  # a frame's name split at "::": ("inner", "link") is link in nested model inner
_MODEL: _Path = ("__model__",)


class _Frames:
    """The SDF frames of a file placed in their models' frames, each frame once: a file of many
    links relative to the end of a long chain of frames is placed in time linear in its size."""

    def __init__(self) -> None:
        self._elements: dict[int, dict[str, Node]] = {}
        self._placed: dict[tuple[int, _Path], _Pose | str] = {}  # a pose, or why there is none

    def place(self, model: Node, path: _Path, outer: tuple = ()) -> _Pose:
        """The pose of frame ``path`` (a link, frame, joint or nested model of ``model``, or
        ``__model__``; ``("inner", "name")`` a frame of the nested model ``inner``, as SDF scopes
        names) in ``model``'s frame, following relative_to and attached_to. ``outer``: the
        (model, frame) pairs being placed further up, so that a nested model placed relative to
        its own frame is a cycle."""
        got = self._placed.get((id(model), path))
        if isinstance(got, str):
            raise _UnresolvedError(got)
        return got if got is not None else self._place(model, path, outer)

    def _elements_of(self, model: Node) -> dict[str, Node]:
        if id(model) not in self._elements:
            self._elements[id(model)] = {
                c.attrib.get("name", "").strip(): c
                for c in model.children
                if c.tag in ("link", "frame", "joint", "model")
            }
        return self._elements[id(model)]

    def _place(self, model: Node, path: _Path, outer: tuple) -> _Pose:
        seen: list[_Path] = []  # the frames of model walked, from path on
        try:
            if (id(model), path) in outer:
                raise _UnresolvedError(
                    f"frame {quote('::'.join(path))} is placed relative to itself through a nested model: a cycle"
                )
            if len(outer) >= _MAX_NESTED:
                raise _TooDeepError(
                    f"placing it passes through more than {_MAX_NESTED} frames of nested models; hconv follows "
                    f"{_MAX_NESTED}"
                )
            outer = (*outer, (id(model), path))
            elements = self._elements_of(model)
            scope = model.attrib.get("name", "").strip()
            chain: list[_Pose] = []
            walked: set[_Path] = set()
            base: _Pose = (np.zeros(3), np.eye(3))  # where the chain ends: the model's frame, or another's
            while path != _MODEL:
                got = self._placed.get((id(model), path)) if seen else None
                if got is not None:  # placed before: the chain ends there
                    if isinstance(got, str):
                        raise _UnresolvedError(got)
                    base = got
                    break
                if len(path) > 1:
                    sub = elements.get(path[0])
                    if sub is None or sub.tag != "model":
                        raise _UnresolvedError(
                            f"frame {quote('::'.join(path))} names {quote(path[0])}, which is not a model nested in "
                            f"model {quote(scope)} (SDF names reach only into nested models, never out to an "
                            "enclosing one)"
                        )
                    # the nested model's frame in this one, then the frame in the nested model's
                    base = _compose(self.place(model, path[:1], outer), self.place(sub, path[1:], outer))
                    break
                name = path[0]
                if name == "world":
                    raise _UnresolvedError("frame 'world': hconv reads no model's place in a world")
                if path in walked:
                    cycle = " → ".join(p[0] for p in [*seen, path])
                    raise _UnresolvedError(f"frames {clip(cycle)} form a cycle")
                node = elements.get(name)
                if node is None:
                    raise _UnresolvedError(
                        f"there is no frame {quote(name)} in model {quote(scope)} (SDF resolves a name in the "
                        "model that holds it, and in nested models as inner::name)"
                    )
                seen.append(path)
                walked.add(path)
                pose, ref = _sdf_pose(node)
                chain.append(pose)
                if ref is None:
                    if node.tag == "frame":
                        ref = node.attrib.get("attached_to", "").strip() or None
                    elif node.tag == "joint":
                        child = node.find("child")
                        ref = child.text.strip() if child is not None else None
                path = tuple(ref.split("::")) if ref else _MODEL
        except _UnresolvedError as exc:
            if isinstance(exc, _TooDeepError):
                raise  # kept for no frame: see _TooDeepError
            for p in seen or [path]:  # each frame of the chain fails the same way: walked once
                self._placed[(id(model), p)] = str(exc)
            raise
        out = base
        for p, pose in zip(reversed(seen), reversed(chain)):
            out = _compose(out, pose)
            self._placed[(id(model), p)] = out
        return out


def _sdf(root: Node, path: Path, shown: str, budget: Budget) -> tuple[list[_Raw], list[str]]:
    notes = []
    tops = root.findall("model") + [m for w in root.findall("world") for m in w.findall("model")]
    for n in _walk(root):
        if n.tag == "include":
            uri = n.find("uri")
            notes.append(
                f"{n.where}: hconv does not follow SDF includes "
                f"({quote(uri.text.strip()) if uri is not None else 'no uri'}); "
                "run hconv bodies on the included model's file"
            )
    frames = _Frames()
    # depth first, in the file's order; a stack, not a queue: popping a list's front is quadratic
    work = [(m, "" if len(tops) == 1 else _name(m, "model") + "::") for m in reversed(tops)]
    raws = []
    while work:
        model, prefix = work.pop()
        for link in model.findall("link"):
            name = budget.name(prefix + _name(link, "link"), link)
            raws.append(_sdf_link(model, link, name, shown, frames))
        work.extend((sub, prefix + _name(sub, "model") + "::") for sub in reversed(model.findall("model")))
    return raws, notes


def _sdf_link(model: Node, link: Node, name: str, shown: str, frames: _Frames) -> _Raw:
    inertial = link.find("inertial")
    if inertial is None:
        return _Raw(
            name,
            f"{shown}, line {link.line}",
            status="no_inertial",
            notes=["no <inertial>: SDF's defaults apply, m = 1 kg and I = diag(1, 1, 1) kg·m², a placeholder"],
        )
    source = f"{shown}, line {inertial.line}"
    if _bool(inertial, "auto"):
        return _Raw(
            name,
            source,
            status="no_inertial",
            notes=['<inertial auto="true">: the simulator computes it from the collisions; hconv does not'],
        )
    pose, ref = _sdf_pose(inertial)
    if ref is not None and ref != link.attrib.get("name", "").strip():
        try:
            link_in_model = frames.place(model, (link.attrib["name"].strip(),))
            pose = _compose(_compose(_invert(link_in_model), frames.place(model, tuple(ref.split("::")))), pose)
        except _UnresolvedError as exc:
            why = f"the inertial's pose is relative to {quote(ref)}: {exc}"
            return _Raw(name, source, status="unresolved_frame", notes=[why])
    notes = []
    mass = inertial.find("mass")
    if mass is None:
        m = 1.0
        notes.append("no <mass>: SDF's default, 1 kg")
    else:
        m = (mass.numbers("", (1,)) or [math.nan])[0]
    inertia = inertial.find("inertia")
    values = []
    defaulted = []
    for k, entry in enumerate(("ixx", "iyy", "izz", "ixy", "ixz", "iyz")):
        node = inertia.find(entry) if inertia is not None else None
        if node is None:
            values.append(1.0 if k < 3 else 0.0)
            if k < 3:
                defaulted.append(entry)
        else:
            values.append((node.numbers("", (1,)) or [math.nan])[0])
    if defaulted:
        notes.append(f"no {', '.join(defaulted)}: SDF's default, 1 kg·m², a placeholder")
    return _Raw(name, source, m, pose[0], pose[1], _tensor(*values), notes=notes)


# --- MJCF ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Compiler:
    degrees: bool = True  # MuJoCo's default angle is degree
    eulerseq: str = "xyz"
    inertiafromgeom: str = "auto"


def _compiler(root: Node) -> tuple[_Compiler, list[str]]:
    """The compiler settings that decide angles, for the whole model (the last of each counts)."""
    degrees, seq, fromgeom, notes = True, "xyz", "auto", []
    for c in root.findall("compiler"):
        a = c.attrib
        if "angle" in a:
            if a["angle"] not in ("degree", "radian"):
                raise error(c, f"has angle={quote(a['angle'])}", 'write angle="degree" or angle="radian"')
            degrees = a["angle"] == "degree"
        if "eulerseq" in a:
            seq = a["eulerseq"]
            if len(seq) != 3 or any(ch not in "xyzXYZ" for ch in seq):
                raise error(c, f"has eulerseq={quote(seq)}", "give three of x, y, z, X, Y, Z, such as xyz or XYZ")
        if "inertiafromgeom" in a:
            fromgeom = a["inertiafromgeom"]
            if fromgeom not in ("false", "true", "auto"):
                raise error(c, f"has inertiafromgeom={quote(fromgeom)}", 'write "false", "true" or "auto"')
        if _bool(c, "balanceinertia"):
            notes.append(
                f'{c.where}: balanceinertia="true": MuJoCo raises the moments of bodies that break the '
                "triangle inequality; hconv lists the file's values"
            )
        for bound in ("boundmass", "boundinertia"):
            if bound in a and c.numbers(bound, (1,)) != [0.0]:
                notes.append(f"{c.where}: {bound}: MuJoCo raises smaller values to it; hconv lists the file's values")
    if fromgeom == "true":
        notes.append(
            'compiler inertiafromgeom="true": MuJoCo ignores every <inertial> and computes the inertia '
            "from the geoms; hconv lists the file's values"
        )
    return _Compiler(degrees, seq, fromgeom), notes


def _mjcf(root: Node, path: Path, shown: str, budget: Budget) -> tuple[list[_Raw], list[str]]:
    expand_includes(root, path, shown, budget)
    comp, notes = _compiler(root)
    for n in _walk(root):
        if n.tag in ("replicate", "attach", "composite", "flexcomp"):
            notes.append(
                f"{n.where}: MuJoCo makes bodies from <{n.tag}> that hconv does not list; "
                "save the compiled model (mj_saveLastXML) to check them"
            )
    top = [b for wb in root.findall("worldbody") for b in _child_bodies(wb)]
    stack = [(b, "world", k) for k, b in reversed(list(enumerate(top, 1)))]
    raws = []
    listed: set[int] = set()
    while stack:
        body, parent, k = stack.pop()
        listed.add(id(body))
        name = budget.name(body.attrib.get("name", "").strip() or f"{parent}/body[{k}]", body)
        raws.append(_mjcf_body(body, name, comp, shown))
        stack.extend(reversed([(c, name, j) for j, c in enumerate(_child_bodies(body), 1)]))
    notes += _misplaced_bodies(root, listed)
    return raws, notes


def _misplaced_bodies(root: Node, listed: set[int]) -> list[str]:
    """A note per outermost <body> that the body tree does not reach (``listed``: the ids of
    those it does): MuJoCo's schema refuses a body anywhere but in <worldbody>, a <body>, a
    <frame> or a <replicate>, so leaving it out without a word would hide a model MuJoCo rejects."""
    notes = []
    stack = [(c, root) for c in reversed(root.children)]
    while stack:
        node, parent = stack.pop()
        if node.tag == "body" and id(node) not in listed:
            if parent is root:  # a file made to be included, or a <worldbody> forgotten
                why = (
                    f"is at the top of <{root.tag}>, not in <worldbody>, so hconv does not list it (MuJoCo "
                    "refuses it there); a fragment made for <include>? Run hconv bodies on the model that "
                    "includes it"
                )
            else:
                at = (
                    ""
                    if (parent.file, parent.line) == (node.file, node.line)
                    else f" ({parent.file}, line {parent.line})"
                )
                why = (
                    f"is inside <{parent.tag}>{at}, where MuJoCo reads no body (it refuses the model), so "
                    "hconv does not list it; move it into <worldbody> or a <body>"
                )
            notes.append(f"{node.where}{_named(node)} {why}")
            continue  # its own bodies go with it
        stack.extend((c, node) for c in reversed(node.children))
    return notes


def _named(node: Node) -> str:
    name = node.attrib.get("name", "").strip()
    return f" {quote(name)}" if name else ""


def _child_bodies(node: Node) -> list[Node]:
    """The bodies directly under ``node``, looking through <frame> and <replicate>."""
    out, stack = [], list(reversed(node.children))
    while stack:
        c = stack.pop()
        if c.tag == "body":
            out.append(c)
        elif c.tag in ("frame", "replicate"):
            stack.extend(reversed(c.children))
    return out


def _mjcf_body(body: Node, name: str, comp: _Compiler, shown: str) -> _Raw:
    inertial = body.find("inertial")
    if inertial is None:
        why = {
            "auto": "MuJoCo infers the mass and inertia from the body's geoms; hconv does not",
            "true": "MuJoCo infers the mass and inertia from the body's geoms; hconv does not",
            "false": 'with inertiafromgeom="false" MuJoCo gives it m = 0 and I = 0',
        }[comp.inertiafromgeom]
        return _Raw(name, f"{shown}, line {body.line}", status="no_inertial", notes=[f"no <inertial>: {why}"])
    pos = inertial.required("pos", (3,), 'give the centre of mass: pos="x y z" (MuJoCo requires it)')
    m = inertial.required("mass", (1,), 'give the mass in kg: mass="1.5" (MuJoCo requires it)')[0]
    diag = inertial.numbers("diaginertia", (3,))
    full = inertial.numbers("fullinertia", (6,))
    given = [a for a in _ORIENTATIONS if a in inertial.attrib]
    if len(given) > 1:
        raise error(inertial, f"has both {given[0]} and {given[1]}", "give one orientation (MuJoCo allows one)")
    if diag is not None and full is not None:
        raise error(inertial, "has both diaginertia and fullinertia", "give one of them")
    if full is not None and given:
        raise error(
            inertial,
            f"has fullinertia with {given[0]}",
            "fullinertia is in the body frame and takes no orientation: drop one",
        )
    notes = []
    if full is not None:
        I_C_I = _tensor(*full)
    elif diag is not None:
        I_C_I = np.diag(diag)
    else:
        I_C_I = np.zeros((3, 3))
        notes.append("no diaginertia or fullinertia: MuJoCo takes I = 0")
    R = _mjcf_rotation(inertial, given[0] if given else None, comp)
    return _Raw(name, f"{shown}, line {inertial.line}", m, np.asarray(pos), R, I_C_I, notes=notes)


def _mjcf_rotation(node: Node, kind: str | None, comp: _Compiler) -> np.ndarray:
    """R_BI from MJCF's orientation attribute ``kind`` (see the module's conventions)."""
    scale = math.pi / 180 if comp.degrees else 1.0
    if kind is None:
        return np.eye(3)
    if kind == "quat":
        return _matrix(_unit(node.required("quat", (4,), ""), node, "quat"))
    if kind == "axisangle":
        v = node.required(kind, (4,), "")
        axis = _unit(v[:3], node, "axisangle's axis")
        half = v[3] * scale / 2
        return _matrix([math.cos(half), *(math.sin(half) * axis)])
    if kind == "euler":
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for ch, a in zip(comp.eulerseq, node.required(kind, (3,), "")):
            r = np.zeros(4)
            r[0], r["xyz".index(ch.lower()) + 1] = math.cos(a * scale / 2), math.sin(a * scale / 2)
            q = _qmul(q, r) if ch.islower() else _qmul(r, q)  # moving axes: right; fixed axes: left
        return _matrix(q)
    if kind == "xyaxes":
        v = node.required(kind, (6,), "")
        x = _unit(v[:3], node, "xyaxes' x axis")
        y = np.asarray(v[3:]) - x * float(np.dot(x, v[3:]))
        y = _unit(list(y), node, "xyaxes' y axis, less its part along x,")
        return np.column_stack([x, y, np.cross(x, y)])
    z = _unit(node.required("zaxis", (3,), ""), node, "zaxis")
    axis = np.cross([0.0, 0.0, 1.0], z)
    s = float(np.linalg.norm(axis))
    half = math.atan2(s, z[2]) / 2
    if s < 1e-10:  # z along ±(0, 0, 1): the turn (none, or half a turn) is about x, as MuJoCo's
        axis, s = np.array([1.0, 0.0, 0.0]), 1.0
    return _matrix([math.cos(half), *(math.sin(half) * axis / s)])


# --- the checks ----------------------------------------------------------------------------


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


def _check(raws: list[_Raw]) -> list[Body]:
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
        # A moment below zero beyond the singular threshold makes the tensor indefinite, whatever
        # else is zero: (-1, 0, 1) is no rod, and its reason must say so, not "a line mass".
        negative = have & (S[0] < -status.singular_rtol(np.float64) * top)
        singular = (
            have & ~negative & (np.abs(S).min(axis=0) <= status.singular_rtol(np.float64) * top) & ~(zero & (m == 0))
        )
        flags = {
            "negative_mass": have & (m < 0),
            "massless_with_inertia": have & (m == 0) & ~zero,
            "massless": have & (m == 0) & zero,
            "singular": singular,
            "not_positive_definite": have & ~singular & (S[0] < 0),
            "not_physical": have & ~singular & (S[0] >= 0) & (S[2] > S[0] + S[1] + status.TRIANGLE_RTOL * trace),
            "implausible_density": have & units.implausible(np.where(have, trace, 0.0), np.where(have, m, 0.0)),
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
    if name == "singular":
        if not np.any(I):
            return f"I = 0 with m = {_g(m)} kg: a point mass; engines need positive moments (MuJoCo refuses it)"
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
        side = 2.0 * math.sqrt(S.sum() / (2.0 * m))
        rho = m / side**3
        lo, hi = status.UNIT_DENSITY_BAND
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
