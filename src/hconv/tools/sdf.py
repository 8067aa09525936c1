"""SDF's inertials: each ``<link>``'s ``<inertial>`` in every ``<model>`` (nested ones too, named
``outer::link``), its ``<pose>`` placed in the link's frame through the model's frames, read into
:class:`hconv.tools.inertial.ReadBody` for :mod:`hconv.tools.models`.

Conventions: those of :mod:`hconv.tools.inertial`. ``<pose>``'s roll, pitch, yaw are in
radians, unless SDF says ``degrees="true"``; ``rotation_format="quat_xyzw"`` gives
x y z qx qy qz qw.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hconv.tools.inertial import ReadBody, rotation, rpy, tensor, unit_vector
from hconv.tools.modelxml import Budget, Node, clip, error, flag, quote, required_name, walk

_Pose = tuple[np.ndarray, np.ndarray]  # (p, R): v_parent = R·v + p


def _compose(a: _Pose, b: _Pose) -> _Pose:
    return a[0] + a[1] @ b[0], a[1] @ b[1]


def _invert(a: _Pose) -> _Pose:
    return -(a[1].T @ a[0]), a[1].T


def _pose(owner: Node) -> tuple[_Pose, str | None]:
    """``owner``'s ``<pose>`` and the frame it is relative to (None: the default)."""
    pose = owner.find("pose")
    if pose is None:
        return (np.zeros(3), np.eye(3)), None
    ref = (pose.attrib.get("relative_to") or pose.attrib.get("frame") or "").strip() or None
    kind = pose.attrib.get("rotation_format", "euler_rpy").strip()
    if kind == "euler_rpy":
        v = pose.numbers("", (6,), "0 0 0 0 0 0") or [0.0] * 6
        angles = [math.radians(a) for a in v[3:]] if flag(pose, "degrees") else v[3:]
        return (np.asarray(v[:3]), rpy(*angles)), ref
    if kind == "quat_xyzw":
        v = pose.numbers("", (7,), "0 0 0 0 0 0 1") or [0.0] * 6 + [1.0]
        q = unit_vector([v[6], v[3], v[4], v[5]], pose, "quaternion")
        return (np.asarray(v[:3]), rotation(q)), ref
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
                pose, ref = _pose(node)
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


def bodies(root: Node, path: Path, shown: str, budget: Budget) -> tuple[list[ReadBody], list[str]]:
    """The links of SDF model ``root`` (read from ``path``, shown as ``shown``), depth first in the
    file's order, and notes on what hconv did not follow."""
    notes = []
    tops = root.findall("model") + [m for w in root.findall("world") for m in w.findall("model")]
    for n in walk(root):
        if n.tag == "include":
            uri = n.find("uri")
            notes.append(
                f"{n.where}: hconv does not follow SDF includes "
                f"({quote(uri.text.strip()) if uri is not None else 'no uri'}); "
                "run hconv bodies on the included model's file"
            )
    frames = _Frames()
    # depth first, in the file's order; a stack, not a queue: popping a list's front is quadratic
    work = [(m, "" if len(tops) == 1 else required_name(m, "model") + "::") for m in reversed(tops)]
    raws = []
    while work:
        model, prefix = work.pop()
        for link in model.findall("link"):
            name = budget.name(prefix + required_name(link, "link"), link)
            raws.append(_link(model, link, name, shown, frames))
        work.extend((sub, prefix + required_name(sub, "model") + "::") for sub in reversed(model.findall("model")))
    return raws, notes


def _link(model: Node, link: Node, name: str, shown: str, frames: _Frames) -> ReadBody:
    inertial = link.find("inertial")
    if inertial is None:
        return ReadBody(
            name,
            f"{shown}, line {link.line}",
            status="no_inertial",
            notes=["no <inertial>: SDF's defaults apply, m = 1 kg and I = diag(1, 1, 1) kg·m², a placeholder"],
        )
    source = f"{shown}, line {inertial.line}"
    if flag(inertial, "auto"):
        return ReadBody(
            name,
            source,
            status="no_inertial",
            notes=['<inertial auto="true">: the simulator computes it from the collisions; hconv does not'],
        )
    pose, ref = _pose(inertial)
    if ref is not None and ref != link.attrib.get("name", "").strip():
        try:
            link_in_model = frames.place(model, (link.attrib["name"].strip(),))
            pose = _compose(_compose(_invert(link_in_model), frames.place(model, tuple(ref.split("::")))), pose)
        except _UnresolvedError as exc:
            why = f"the inertial's pose is relative to {quote(ref)}: {exc}"
            return ReadBody(name, source, status="unresolved_frame", notes=[why])
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
    return ReadBody(name, source, m, pose[0], pose[1], tensor(*values), notes=notes)
