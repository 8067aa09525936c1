"""URDF's inertials: each ``<link>``'s ``<inertial>`` (``<origin xyz rpy>``, ``<mass>``,
``<inertia>``), read into :class:`hconv.tools.inertial.ReadBody` for :mod:`hconv.tools.models`.

Conventions: those of :mod:`hconv.tools.inertial`; ``rpy`` is in radians. A ``<joint>``'s
``<origin>`` places the child link's frame in the parent's. An xacro file is refused (xacro makes
URDF: run it first), and a link name given twice is listed each time, with a note, since a parser
that keys links by name keeps one.

MuJoCo, loading a URDF, fuses every link that cannot move into the body it is fixed to
(``fusestatic``, on for URDF unless the file's ``<mujoco><compiler fusestatic="false"/>`` turns
it off; checked with MuJoCo 4.0): a link joined to its parent by a ``fixed`` joint becomes part of
its parent, and the root link, which no joint moves, part of the world, with what is fixed to it.
hconv lists every link as the file gives it, and notes on each link concerned what MuJoCo makes
of it: the fused mass and principal moments of the body that takes links in (MuJoCo's
``body_mass`` and ``body_inertia``), unless a link without an ``<inertial>`` is among them, whose
mass MuJoCo infers from its geoms.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hconv.tools.inertial import ReadBody, rpy, tensor
from hconv.tools.modelxml import Budget, Node, error, flag, quote, required_name, walk


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
    if _fusestatic(root):
        first: dict[str, int] = {}
        for k, r in enumerate(raws):
            first.setdefault(r.name, k)
        # links whose mass MuJoCo infers: no <inertial>, and a <collision> (visuals it discards)
        inferred = {
            n.attrib.get("name", "").strip()
            for n in root.findall("link")
            if n.find("inertial") is None and n.findall("collision")
        }
        _note_fusion(root, raws, first, inferred)
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


def _fusestatic(root: Node) -> bool:
    """Whether MuJoCo fuses static links when it loads this URDF: yes, unless the file's
    ``<mujoco><compiler fusestatic="false"/></mujoco>`` says otherwise (the last one counts)."""
    on = True
    for ext in root.findall("mujoco"):
        for c in ext.findall("compiler"):
            if "fusestatic" in c.attrib:
                on = flag(c, "fusestatic")
    return on


def _note_fusion(root: Node, raws: list[ReadBody], at: dict[str, int], inferred: set[str]) -> None:
    """Add to ``raws`` (``at``: link name -> its first index) the notes on what MuJoCo fuses
    (see the module's docstring); ``inferred``: the links whose mass MuJoCo infers from geoms."""
    # child link -> (parent link, joint type, the child frame's position and rotation in the parent's)
    up: dict[str, tuple[str, str, np.ndarray, np.ndarray]] = {}
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            continue  # not a joint MuJoCo can load either; hconv reads links, not joints
        p_name, c_name = parent.attrib.get("link", "").strip(), child.attrib.get("link", "").strip()
        if c_name in up or p_name not in at or c_name not in at:
            continue
        origin = joint.find("origin")
        xyz = origin.numbers("xyz", (3,), "0 0 0") if origin is not None else [0.0] * 3
        turn = origin.numbers("rpy", (3,), "0 0 0") if origin is not None else [0.0] * 3
        kind = joint.attrib.get("type", "").strip()
        up[c_name] = (p_name, kind, np.asarray(xyz, dtype=np.float64), rpy(*(turn or [0.0] * 3)))
    # each link fixed to another -> the link at the end of its chain of fixed joints, whose body it
    # becomes part of, with its frame's pose in that link's frame. Each chain is walked once, its
    # links resolved on the way back, so that a long chain costs time linear in its length.
    into: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    done: set[str] = set()
    for name in at:
        chain, link, on_chain = [], name, set()
        while link not in done and link in up and up[link][1] == "fixed" and link not in on_chain:
            chain.append(link)
            on_chain.add(link)
            link = up[link][0]
        if link in on_chain:  # a loop of fixed joints: not a tree, MuJoCo refuses it; no note
            done.update(chain)
            continue
        # link ends the chain: a moving link or the root (its own host), or a link already placed
        host, p, R = into[link] if link in into else (link, np.zeros(3), np.eye(3))
        for fixed in reversed(chain):
            _, _, p_pl, R_PL = up[fixed]  # its frame in its parent's
            p, R = p + R @ p_pl, R @ R_PL
            into[fixed] = (host, p, R)
        done.update(chain)
    groups: dict[str, list[str]] = {}
    for name, (host, _, _) in into.items():
        groups.setdefault(host, []).append(name)
    for name, (host, _, _) in into.items():
        if host in up:
            note = f"MuJoCo fuses it into {quote(host)} (fixed joint; fusestatic, on for URDF)"
        else:  # fixed to the root, which no joint moves either
            note = (
                f"MuJoCo fuses it, with the root {quote(host)}, into the world (fixed joint; fusestatic, on for URDF)"
            )
        raws[at[name]].notes.append(note)
    for host, fused in groups.items():
        raws[at[host]].notes.append(_host_note(host, fused, raws, at, into, inferred, host in up))


def _host_note(
    host: str,
    fused: list[str],
    raws: list[ReadBody],
    at: dict[str, int],
    into: dict[str, tuple[str, np.ndarray, np.ndarray]],
    inferred: set[str],
    moves: bool,
) -> str:
    """The note on a link that takes in the links ``fused`` into it: their names, and the mass and
    principal moments MuJoCo then has for it (``moves``: a joint moves it; else it is the root,
    which MuJoCo fuses into the world with them)."""
    shown = ", ".join(quote(n) for n in fused[:5]) + (f" and {len(fused) - 5:,} more" if len(fused) > 5 else "")
    joints = "joint" if len(fused) == 1 else "joints"
    if not moves:
        return (
            f"the root, which no joint moves: MuJoCo fuses it, with {shown}, into the world (fixed {joints}; "
            "fusestatic, on for URDF)"
        )
    said = f"MuJoCo fuses {shown} into it (fixed {joints}; fusestatic, on for URDF)"
    if inferred.intersection([host, *fused]):
        return (
            f"{said}: there its mass and inertia take in what MuJoCo infers from the collision geoms of "
            "links without <inertial>"
        )
    # each part's pose in the host's frame; a link without <inertial> or <collision> adds nothing
    poses = [(host, np.zeros(3), np.eye(3))] + [(n, into[n][1], into[n][2]) for n in fused]
    parts = [(raws[at[n]], p, R) for n, p, R in poses if raws[at[n]].status is None]
    m = math.fsum(r.m for r, _, _ in parts)
    if not m > 0:
        return f"{said}: there m = {m:.4g} kg"
    # each part's centre and tensor in the host's frame H: p_HC = p_HL + R_HL·p_LC, I_H = R_HI·I·R_HIᵀ
    centres = [p + R @ r.p_BC_B for r, p, R in parts]
    c = sum((r.m * x for (r, _, _), x in zip(parts, centres)), np.zeros(3)) / m
    I = np.zeros((3, 3))
    for (r, _, R), x in zip(parts, centres):
        assert r.I_C_I is not None  # every body with an inertial has its tensor
        R_HI = R @ r.R_BI
        d = x - c
        I += R_HI @ r.I_C_I @ R_HI.T + r.m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    moments = np.linalg.eigvalsh(0.5 * (I + I.T))
    listed = ", ".join(f"{x:.4g}" for x in moments)
    return f"{said}: there m = {m:.4g} kg, I1, I2, I3 = {listed} kg·m²"
