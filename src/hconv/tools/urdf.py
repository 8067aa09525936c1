"""URDF's inertials: each ``<link>``'s ``<inertial>`` (``<origin xyz rpy>``, ``<mass>``,
``<inertia>``), read into :class:`hconv.tools.inertial.ReadBody` for :mod:`hconv.tools.models`.

Conventions: those of :mod:`hconv.tools.inertial`; ``rpy`` is in radians. An xacro file is
refused (xacro makes URDF: run it first), and a link name given twice is listed each time, with
a note, since a parser that keys links by name keeps one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hconv.tools.inertial import ReadBody, rpy, tensor
from hconv.tools.modelxml import Budget, Node, error, quote, required_name, walk


def bodies(root: Node, path: Path, shown: str, budget: Budget) -> tuple[list[ReadBody], list[str]]:
    """The links of URDF model ``root`` (read from ``path``, shown as ``shown``), in the file's order,
    and notes on what hconv did not follow."""
    # Only an unexpanded macro counts: many URDFs made by xacro keep its namespace declaration.
    xacro = next((n for n in walk(root) if n.tag.startswith("xacro:")), None)
    if xacro is not None:
        raise error(
            xacro,
            "is xacro, a macro language that makes URDF",
            "run xacro first (xacro model.urdf.xacro > model.urdf) and give hconv the URDF",
        )
    raws = []
    lines: dict[str, list[int]] = {}  # link name -> the lines it is given at
    for link in root.findall("link"):
        name = budget.name(required_name(link, "link"), link)
        lines.setdefault(name, []).append(link.line)
        inertial = link.find("inertial")
        if inertial is None:
            raws.append(
                ReadBody(
                    name,
                    f"{shown}, line {link.line}",
                    status="no_inertial",
                    notes=["no <inertial>: URDF leaves its mass and inertia undefined, and simulators differ"],
                )
            )
            continue
        origin = inertial.find("origin")
        xyz = origin.numbers("xyz", (3,), "0 0 0") if origin is not None else [0.0] * 3
        roll_pitch_yaw = origin.numbers("rpy", (3,), "0 0 0") if origin is not None else [0.0] * 3
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
            ReadBody(
                name,
                f"{shown}, line {inertial.line}",
                m,
                np.asarray(xyz, dtype=np.float64),
                rpy(*(roll_pitch_yaw or [0.0] * 3)),
                tensor(*six.values()),
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


def _lines(at: list[int]) -> str:
    """``3, 9, 12``; the first five and the count when there are more: a note stays a line."""
    shown = ", ".join(map(str, at[:5]))
    return shown if len(at) <= 5 else f"{shown}, … ({len(at):,} in all)"
