"""MJCF's inertials: each ``<body>``'s ``<inertial>`` under ``<worldbody>`` (through ``<frame>``
and ``<replicate>``; an unnamed body is named by its path, ``parent/body[k]``), with MuJoCo's
``<include>`` resolved, read into :class:`hconv.tools.inertial.ReadBody` for
:mod:`hconv.tools.models`.

Conventions (those of :mod:`hconv.tools.inertial`, and MJCF's own, stated here):

* ``quat`` is (w, x, y, z). ``axisangle`` and ``euler`` are in ``<compiler angle>``'s unit,
  which is **degrees unless angle="radian"**. ``euler`` follows ``<compiler eulerseq>`` (default
  ``xyz``): a lower-case letter turns about the moving frame's axis (intrinsic), an upper-case one
  about the parent's fixed axis (extrinsic). ``xyaxes`` gives I's x and y axes (y is made
  orthogonal to x); ``zaxis`` the z axis, reached by the smallest rotation from (0, 0, 1).
* ``fullinertia`` is (ixx, iyy, izz, ixy, ixz, iyz) in B, with no orientation.
* Where several ``<compiler>`` elements set an attribute, the last counts for the whole model, as
  in MuJoCo.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hconv.tools.inertial import ReadBody, rotation, tensor, unit_vector
from hconv.tools.modelxml import Budget, Node, error, expand_includes, flag, quote, walk

_ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")


@dataclass(frozen=True)
class _Compiler:
    degrees: bool = True  # MuJoCo's default angle is degree
    eulerseq: str = "xyz"
    inertiafromgeom: str = "auto"
    settotalmass: float = -1.0  # MuJoCo's default; a positive value rescales the model
    settotalmass_at: str = ""  # the <compiler> that sets it, for the note
    bounded: bool = False  # boundmass or boundinertia raise values before settotalmass scales them


def _compiler(root: Node) -> tuple[_Compiler, list[str]]:
    """The compiler settings that decide angles, for the whole model (the last of each counts)."""
    degrees, seq, fromgeom, notes = True, "xyz", "auto", []
    total, total_at, bounded = -1.0, "", False
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
        if flag(c, "balanceinertia"):
            notes.append(
                f'{c.where}: balanceinertia="true": MuJoCo raises the moments of bodies that break the '
                "triangle inequality; hconv lists the file's values"
            )
        for bound in ("boundmass", "boundinertia"):
            if bound in a and c.numbers(bound, (1,)) != [0.0]:
                bounded = True
                notes.append(f"{c.where}: {bound}: MuJoCo raises smaller values to it; hconv lists the file's values")
        if "settotalmass" in a:
            total, total_at = c.required("settotalmass", (1,), "")[0], c.where
    if fromgeom == "true":
        notes.append(
            'compiler inertiafromgeom="true": MuJoCo ignores every <inertial> and computes the inertia '
            "from the geoms; hconv lists the file's values"
        )
    return _Compiler(degrees, seq, fromgeom, total, total_at, bounded), notes


def bodies(
    root: Node, path: Path, shown: str, budget: Budget, include_root: Path | None = None
) -> tuple[list[ReadBody], list[str]]:
    """The bodies of MJCF model ``root`` (read from ``path``, shown as ``shown``), depth first in the
    file's order, and notes on what hconv did not follow. ``include_root``: the folder within which
    includes may go (:func:`hconv.tools.modelxml.expand_includes`)."""
    expand_includes(root, path, shown, budget, include_root)
    comp, notes = _compiler(root)
    for n in walk(root):
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
        raws.append(_body(body, name, comp, shown))
        stack.extend(reversed([(c, name, j) for j, c in enumerate(_child_bodies(body), 1)]))
    notes += _misplaced_bodies(root, listed)
    if comp.settotalmass > 0:
        notes.append(_total_mass_note(comp, raws))
    return raws, notes


def _total_mass_note(comp: _Compiler, raws: list[ReadBody]) -> str:
    """What ``settotalmass`` makes MuJoCo do, with the factor when the file alone decides it.

    MuJoCo (checked with 4.0) scales every body's mass and inertia by one factor, after
    ``boundmass`` and ``boundinertia``, so that the masses of all bodies, those it infers from
    geoms among them, add up to the value. hconv, which infers no mass from geoms, lists the
    file's values, as it does under ``boundmass``; it gives the factor when no body's mass comes
    from elsewhere than its <inertial>."""
    target = comp.settotalmass
    said = f"{comp.settotalmass_at}: settotalmass={target:g}: MuJoCo scales every mass and inertia"
    own = all(r.status is None for r in raws) and not comp.bounded and comp.inertiafromgeom != "true"
    total = math.fsum(r.m for r in raws) if own else math.nan
    if own and total > 0:
        return (
            f"{said} by {target:g} / {total:.6g} = {target / total:.6g} (the file's masses add up to "
            f"{total:.6g} kg); hconv lists and checks the file's values"
        )
    return (
        f"{said} so that the masses, with those it infers from geoms or raises to a bound, add up to "
        f"{target:g} kg; hconv lists and checks the file's values"
    )


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


def _body(body: Node, name: str, comp: _Compiler, shown: str) -> ReadBody:
    inertial = body.find("inertial")
    if inertial is None:
        why = {
            "auto": "MuJoCo infers the mass and inertia from the body's geoms; hconv does not",
            "true": "MuJoCo infers the mass and inertia from the body's geoms; hconv does not",
            "false": 'with inertiafromgeom="false" MuJoCo gives it m = 0 and I = 0',
        }[comp.inertiafromgeom]
        return ReadBody(name, f"{shown}, line {body.line}", status="no_inertial", notes=[f"no <inertial>: {why}"])
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
        I_C_I = tensor(*full)
    elif diag is not None:
        I_C_I = np.diag(diag)
    else:
        I_C_I = np.zeros((3, 3))
        notes.append("no diaginertia or fullinertia: MuJoCo takes I = 0")
    R = _rotation(inertial, given[0] if given else None, comp)
    return ReadBody(name, f"{shown}, line {inertial.line}", m, np.asarray(pos), R, I_C_I, notes=notes)


def _rotation(node: Node, kind: str | None, comp: _Compiler) -> np.ndarray:
    """R_BI from MJCF's orientation attribute ``kind`` (see the module's conventions)."""
    scale = math.pi / 180 if comp.degrees else 1.0
    if kind is None:
        return np.eye(3)
    if kind == "quat":
        return rotation(unit_vector(node.required("quat", (4,), ""), node, "quat"))
    if kind == "axisangle":
        v = node.required(kind, (4,), "")
        axis = unit_vector(v[:3], node, "axisangle's axis")
        half = v[3] * scale / 2
        return rotation([math.cos(half), *(math.sin(half) * axis)])
    if kind == "euler":
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for ch, a in zip(comp.eulerseq, node.required(kind, (3,), "")):
            r = np.zeros(4)
            r[0], r["xyz".index(ch.lower()) + 1] = math.cos(a * scale / 2), math.sin(a * scale / 2)
            q = _qmul(q, r) if ch.islower() else _qmul(r, q)  # moving axes: right; fixed axes: left
        return rotation(q)
    if kind == "xyaxes":
        v = node.required(kind, (6,), "")
        x = unit_vector(v[:3], node, "xyaxes' x axis")
        y = np.asarray(v[3:]) - x * float(np.dot(x, v[3:]))
        y = unit_vector(list(y), node, "xyaxes' y axis, less its part along x,")
        return np.column_stack([x, y, np.cross(x, y)])
    z = unit_vector(node.required("zaxis", (3,), ""), node, "zaxis")
    axis = np.cross([0.0, 0.0, 1.0], z)
    s = float(np.linalg.norm(axis))
    half = math.atan2(s, z[2]) / 2
    if s < 1e-10:  # z along ±(0, 0, 1): the turn (none, or half a turn) is about x, as MuJoCo's
        axis, s = np.array([1.0, 0.0, 0.0]), 1.0
    return rotation([math.cos(half), *(math.sin(half) * axis / s)])


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
