"""hconv bodies (hconv.tools.models, its readers urdf, sdf and mjcf, hconv.tools.inertial,
hconv.tools.modelxml, hconv.modelview): the inertias of URDF, SDF and MJCF models against
hand-written models with known answers, rotations checked against independent parametrisations
(elementary matrices, Rodrigues' formula), every status, untrusted input, the round trip into
hconv convert, and MuJoCo itself where it is installed."""

from __future__ import annotations

import io
import itertools
import math
import os
import shutil
import string
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from helpers import axis_angle, hconv_inprocess, mp_solve, need, quats, rodrigues, run_hconv
from rich.console import Console

from hconv import modelview
from hconv.errors import InputError, UsageError
from hconv.tools import models, modelxml, sdf

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "models"


def model(tmp_path: Path, name: str, text: str) -> models.Model:
    path = tmp_path / name
    path.write_text(text)
    return models.read_model(path)


def by_name(m: models.Model) -> dict[str, models.Body]:
    return {b.name: b for b in m.bodies}


def Rx(a):  # noqa: N802 - elementary rotations, written apart from the code under test
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a):  # noqa: N802
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):  # noqa: N802
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


ELEMENTARY = {"x": Rx, "y": Ry, "z": Rz}


def euler_reference(seq: str, angles) -> np.ndarray:
    """MuJoCo's eulerseq as its documentation defines it, with matrices: a lower-case axis moves
    with the frame (the rotation multiplies on the right), an upper-case one is fixed (on the left)."""
    R = np.eye(3)
    for ch, a in zip(seq, angles):
        turn = ELEMENTARY[ch.lower()](a)
        R = R @ turn if ch.islower() else turn @ R
    return R


def box(m, a, b, c):
    return np.diag([m / 12 * (b * b + c * c), m / 12 * (a * a + c * c), m / 12 * (a * a + b * b)])


def cylinder(m, r, h):
    """About the centre; the axis is z."""
    side = m * (3 * r * r + h * h) / 12
    return np.diag([side, side, m * r * r / 2])


def num(x) -> str:
    return repr(float(x))


def nums(v) -> str:
    return " ".join(num(x) for x in v)


def urdf_link(name, m, I, xyz="0 0 0", rpy="0 0 0"):
    return (
        f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="{rpy}"/><mass value="{num(m)}"/>'
        f'<inertia ixx="{num(I[0, 0])}" ixy="{num(I[0, 1])}" ixz="{num(I[0, 2])}" iyy="{num(I[1, 1])}" '
        f'iyz="{num(I[1, 2])}" izz="{num(I[2, 2])}"/></inertial></link>'
    )


def urdf(*links):
    return '<?xml version="1.0"?>\n<robot name="r">\n' + "\n".join(links) + "\n</robot>\n"


def mjcf(bodies, compiler=""):
    return f"<mujoco>{compiler}<worldbody>{bodies}</worldbody></mujoco>"


def assert_tensor(got, want, rtol=1e-14):
    assert np.abs(got - want).max() <= rtol * np.abs(want).max()


# --- known answers ---------------------------------------------------------------------------


def test_read_urdf_box_gives_the_box_formula_and_its_centre(tmp_path):
    I = box(4.0, 0.2, 0.3, 0.5)
    b = model(tmp_path, "box.urdf", urdf(urdf_link("box", 4.0, I, xyz="0.1 -0.2 0.3"))).bodies[0]
    assert (b.name, b.m, b.status, b.reason) == ("box", 4.0, "ok", "")
    assert b.p_BC_B.tolist() == [0.1, -0.2, 0.3]
    assert_tensor(b.I_C_B, I, 0)
    assert np.allclose(b.moments, np.sort(np.diag(I)), rtol=1e-15, atol=0)


def test_read_urdf_rotated_inertial_matches_elementary_rotations(tmp_path):
    I_C_I = cylinder(1.5, 0.05, 0.4)
    rpy = (0.3, -1.1, 2.5)
    text = urdf(urdf_link("c", 1.5, I_C_I, rpy=" ".join(repr(a) for a in rpy)))
    b = model(tmp_path, "c.urdf", text).bodies[0]
    R = Rz(rpy[2]) @ Ry(rpy[1]) @ Rx(rpy[0])  # fixed axes X, Y, Z
    assert_tensor(b.I_C_B, R @ I_C_I @ R.T)
    # the principal frame puts the moments back: I = R(q)·diag(I1, I2, I3)·R(q)ᵀ, q a unit quaternion, qw >= 0
    w, x, y, z = b.q_B
    Rq = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    assert w >= 0 and abs(np.linalg.norm(b.q_B) - 1) < 1e-15
    assert_tensor(Rq @ np.diag(b.moments) @ Rq.T, b.I_C_B)


def test_read_urdf_defaults_origin_to_the_link_frame(tmp_path):
    text = urdf(
        '<link name="a"><inertial><mass value="2"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
        "</inertial></link>",
        '<link name="b"><inertial><origin xyz="1 2 3"/><mass value="2"/>'
        '<inertia ixx="1" ixy="0.1" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>',
    )
    a, b = model(tmp_path, "d.urdf", text).bodies
    assert a.p_BC_B.tolist() == [0, 0, 0] and b.p_BC_B.tolist() == [1, 2, 3]
    assert b.I_C_B[0, 1] == 0.1 and b.I_C_B[1, 0] == 0.1  # products taken as tensor entries


def test_read_sdf_pose_in_radians_degrees_and_quaternions(tmp_path):
    I = cylinder(1.0, 0.1, 0.05)
    six = "".join(f"<{k}>{num(v)}</{k}>" for k, v in zip(("ixx", "iyy", "izz"), np.diag(I)))

    def sdf_link(name, pose):
        return f"<link name='{name}'><inertial>{pose}<mass>1</mass><inertia>{six}</inertia></inertial></link>"

    u, th = np.array([[0.2, -0.3, 0.9]]) / np.linalg.norm([0.2, -0.3, 0.9]), np.array([0.7])
    qw, qx, qy, qz = quats(u, th)[0]
    text = (
        "<sdf version='1.9'><model name='m'>"
        + sdf_link("rad", "<pose>1 2 3 0.1 0.2 0.3</pose>")
        + sdf_link("deg", "<pose degrees='true'>0 0 0 10 20 30</pose>")
        + sdf_link("quat", f"<pose rotation_format='quat_xyzw'>0 0 0 {nums([qx, qy, qz, qw])}</pose>")
        + sdf_link("none", "")
        + "</model></sdf>"
    )
    got = by_name(model(tmp_path, "p.sdf", text))
    assert got["rad"].p_BC_B.tolist() == [1, 2, 3]
    for name, R in (
        ("rad", Rz(0.3) @ Ry(0.2) @ Rx(0.1)),
        ("deg", Rz(math.radians(30)) @ Ry(math.radians(20)) @ Rx(math.radians(10))),
        ("quat", rodrigues(u, th)[0]),
        ("none", np.eye(3)),
    ):
        assert got[name].status == "ok"
        assert_tensor(got[name].I_C_B, R @ I @ R.T)


#: A 2 kg box, 0.1 × 0.2 × 0.3 m, about its centre: the SDF relative_to tests' inertia.
SDF_BOX = box(2.0, 0.1, 0.2, 0.3)


def sdf_link(name, pose, inertial_pose):
    """An SDF link holding SDF_BOX, with the link's ``pose`` and the inertial's ``inertial_pose``."""
    inertia = "".join(f"<{k}>{num(v)}</{k}>" for k, v in zip(("ixx", "iyy", "izz"), np.diag(SDF_BOX)))
    return (
        f"<link name='{name}'>{pose}<inertial>{inertial_pose}<mass>2</mass>"
        f"<inertia>{inertia}</inertia></inertial></link>"
    )


def test_read_sdf_relative_to_follows_frames_links_and_joints(tmp_path):
    I = SDF_BOX
    text = (
        "<sdf version='1.9'><model name='m'>"
        + sdf_link("base", "<pose>0 0 1 0 0 0.5</pose>", "")
        + sdf_link("a", "<pose relative_to='base'>1 0 0 0 0 0</pose>", "<pose relative_to='hub'>0 0 0.1 0 0 0</pose>")
        + "<frame name='hub' attached_to='a'><pose relative_to='a'>0.2 0 0 0.4 0 0</pose></frame>"
        + sdf_link("b", "<pose>0 0 0 0 0 0</pose>", "<pose relative_to='base'>0 0 0 0 0 0</pose>")
        + sdf_link("c", "", "<pose relative_to='j'>0 0 0 0 0 0</pose>")
        + "<joint name='j' type='revolute'><parent>base</parent><child>c</child>"
        + "<pose>0 0.3 0 0 0.6 0</pose></joint>"
        + sdf_link("d", "", "<pose relative_to='d'>0 0 0 0.7 0 0</pose>")
        + "</model></sdf>"
    )
    got = by_name(model(tmp_path, "f.sdf", text))
    # a: hub is a's frame moved by (0.2, 0, 0) and turned by roll 0.4; the inertial 0.1 up hub's z
    R = Rx(0.4)
    assert np.allclose(got["a"].p_BC_B, [0.2, 0, 0] + R @ [0, 0, 0.1], rtol=0, atol=1e-15)
    assert_tensor(got["a"].I_C_B, R @ I @ R.T)
    # b is at the model's origin, unturned; base is 1 up and turned by yaw 0.5
    assert np.allclose(got["b"].p_BC_B, [0, 0, 1], rtol=0, atol=1e-15)
    assert_tensor(got["b"].I_C_B, Rz(0.5) @ I @ Rz(0.5).T)
    # a joint's pose is relative to its child link
    assert np.allclose(got["c"].p_BC_B, [0, 0.3, 0], rtol=0, atol=1e-15)
    assert_tensor(got["c"].I_C_B, Ry(0.6) @ I @ Ry(0.6).T)
    assert_tensor(got["d"].I_C_B, Rx(0.7) @ I @ Rx(0.7).T)


def test_read_sdf_relative_to_a_nested_models_frame_is_placed(tmp_path):
    """inner::l and inner::f name frames of the nested model inner (SDF's scoping); before, any
    name with :: was unresolved_frame."""
    I = SDF_BOX
    half_pi = num(math.pi / 2)
    text = (
        "<sdf version='1.9'><model name='m'>"
        + sdf_link("a", "<pose>0 0 1 0 0 0</pose>", "<pose relative_to='inner::l'>0.5 0 0 0.3 0 0</pose>")
        + sdf_link("b", "<pose>0 0 1 0 0 0</pose>", "<pose relative_to='inner::f'>0 0 0 0 0 0</pose>")
        + f"<model name='inner'><pose>1 0 0 0 0 {half_pi}</pose>"
        + sdf_link("l", "<pose>0 2 0 0 0 0</pose>", "")
        + "<frame name='f' attached_to='l'><pose relative_to='l'>0 0 0.2 0 0 0</pose></frame>"
        + "</model></model></sdf>"
    )
    got = by_name(model(tmp_path, "n.sdf", text))
    # inner::l in m: (1, 0, 0) + Rz(90°)·(0, 2, 0) = (-1, 0, 0), turned by Rz(90°); a's origin is 1 up
    R = Rz(math.pi / 2) @ Rx(0.3)
    assert got["a"].status == "ok", got["a"].reason
    assert np.allclose(got["a"].p_BC_B, [-1, 0.5, -1], rtol=0, atol=1e-15)
    assert_tensor(got["a"].I_C_B, R @ I @ R.T)
    # inner::f is 0.2 up l's z: (-1, 0, 0.2) in m, (-1, 0, -0.8) in b
    assert np.allclose(got["b"].p_BC_B, [-1, 0, -0.8], rtol=0, atol=1e-15)
    assert_tensor(got["b"].I_C_B, Rz(math.pi / 2) @ I @ Rz(math.pi / 2).T)


@pytest.mark.parametrize(
    "ref, why",
    [
        ("other::frame", "'other', which is not a model nested in model 'm'"),
        ("f3", "there is no frame 'f3' in model 'm'"),
        ("nowhere", "there is no frame 'nowhere'"),
        ("f1", "form a cycle"),
        ("world", "frame 'world'"),
    ],
)
def test_read_sdf_relative_to_an_unplaceable_frame_is_unresolved_frame(tmp_path, ref, why):
    text = (
        "<sdf version='1.9'><model name='m'>"
        "<frame name='f1'><pose relative_to='f2'/></frame><frame name='f2'><pose relative_to='f1'/></frame>"
        f"<link name='a'><inertial><pose relative_to='{ref}'/><mass>1</mass></inertial></link>"
        "<link name='b'><inertial><mass>2</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy><izz>0.1</izz></inertia>"
        "</inertial></link></model></sdf>"
    )
    got = by_name(model(tmp_path, "u.sdf", text))
    assert got["a"].status == "unresolved_frame" and why in got["a"].reason
    assert np.isnan(got["a"].m) and np.isnan(got["a"].I_C_B).all()
    assert got["b"].status == "ok"


def test_read_sdf_defaults_and_scoped_names(tmp_path):
    text = (
        "<sdf version='1.9'><world name='w'>"
        "<model name='m1'><link name='bare'/><link name='auto'><inertial auto='true'/></link>"
        "<link name='nomass'><inertial><inertia><ixx>1</ixx><iyy>1</iyy><izz>1</izz></inertia></inertial></link>"
        "<model name='inner'><link name='l'><inertial><mass>3</mass></inertial></link></model></model>"
        "<model name='m2'><link name='l'><inertial><mass>1</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy>"
        "<izz>0.1</izz></inertia></inertial></link></model>"
        "<include><uri>model://elsewhere</uri></include>"
        "</world></sdf>"
    )
    m = model(tmp_path, "w.sdf", text)
    got = by_name(m)
    assert list(got) == ["m1::bare", "m1::auto", "m1::nomass", "m1::inner::l", "m2::l"]
    assert got["m1::bare"].status == "no_inertial" and "m = 1 kg and I = diag(1, 1, 1)" in got["m1::bare"].reason
    assert got["m1::auto"].status == "no_inertial" and "auto" in got["m1::auto"].reason
    assert got["m1::nomass"].m == 1.0 and "no <mass>: SDF's default, 1 kg" in got["m1::nomass"].reason
    assert np.allclose(got["m1::inner::l"].moments, [1, 1, 1]) and "SDF's default" in got["m1::inner::l"].reason
    assert got["m2::l"].status == "ok"
    assert any("model://elsewhere" in n for n in m.notes)


def test_read_mjcf_euler_is_in_degrees_unless_the_compiler_says_radian(tmp_path):
    I_C_I = np.diag([0.1, 0.2, 0.25])
    inertial = '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.2 0.25" euler="{}"/>'
    deg = model(tmp_path, "deg.xml", mjcf(f"<body name='b'>{inertial.format('30 0 0')}</body>")).bodies[0]
    rad = model(
        tmp_path,
        "rad.xml",
        mjcf(f"<body name='b'>{inertial.format('0.5 0 0')}</body>", '<compiler angle="radian"/>'),
    ).bodies[0]
    assert_tensor(deg.I_C_B, Rx(math.radians(30)) @ I_C_I @ Rx(math.radians(30)).T)
    assert_tensor(rad.I_C_B, Rx(0.5) @ I_C_I @ Rx(0.5).T)


def test_read_mjcf_the_last_compiler_setting_counts_for_the_whole_model(tmp_path):
    text = (
        "<mujoco><compiler angle='radian'/><worldbody><body name='b'>"
        "<inertial pos='0 0 0' mass='1' diaginertia='0.1 0.2 0.25' euler='30 0 0'/></body></worldbody>"
        "<compiler angle='degree' eulerseq='XYZ'/></mujoco>"
    )
    b = model(tmp_path, "two.xml", text).bodies[0]
    R = Rx(math.radians(30))
    assert_tensor(b.I_C_B, R @ np.diag([0.1, 0.2, 0.25]) @ R.T)


@pytest.mark.parametrize("seq", ["xyz", "XYZ", "zyx", "ZYX", "zyz", "xYz", "XyZ", "yzx", "YxY"])
@pytest.mark.parametrize("angle", ["degree", "radian"])
def test_read_mjcf_eulerseq_matches_elementary_rotations(tmp_path, seq, angle):
    angles = np.array([0.4, -1.2, 2.2])
    given = np.degrees(angles) if angle == "degree" else angles
    I_C_I = np.diag([0.1, 0.2, 0.25])
    text = mjcf(
        f"<body name='b'><inertial pos='0 0 0' mass='1' diaginertia='0.1 0.2 0.25' "
        f"euler='{' '.join(repr(float(a)) for a in given)}'/></body>",
        f'<compiler angle="{angle}" eulerseq="{seq}"/>',
    )
    R = euler_reference(seq, angles)
    assert_tensor(model(tmp_path, "e.xml", text).bodies[0].I_C_B, R @ I_C_I @ R.T, 1e-13)


def test_read_mjcf_quat_axisangle_xyaxes_and_zaxis_match_rodrigues(tmp_path):
    rng = np.random.default_rng(15)
    u, th = axis_angle(rng, 4)
    Rs, qs = rodrigues(u, th), quats(u, th)
    I_C_I = np.diag([0.3, 0.5, 0.7])
    f = nums
    zaxis = np.array([0.3, -0.4, 0.5])
    zunit = zaxis / np.linalg.norm(zaxis)
    bodies = "".join(
        f"<body name='{n}'><inertial pos='0 0 0' mass='1' diaginertia='0.3 0.5 0.7' {a}/></body>"
        for n, a in (
            ("quat", f"quat='{f(3 * qs[0])}'"),  # not normalised: MuJoCo normalises it
            ("axisangle", f"axisangle='{f(2 * u[1])} {num(math.degrees(th[1]))}'"),
            ("xyaxes", f"xyaxes='{f(2 * Rs[2][:, 0])} {f(Rs[2][:, 1] + 0.5 * Rs[2][:, 0])}'"),
            ("zaxis", f"zaxis='{f(zaxis)}'"),
            ("down", "zaxis='0 0 -2'"),
        )
    )
    got = by_name(model(tmp_path, "o.xml", mjcf(bodies)))
    axis = np.cross([0, 0, 1], zunit)
    Rz_ref = rodrigues((axis / np.linalg.norm(axis))[None], np.array([math.acos(zunit[2])]))[0]
    for name, R in (
        ("quat", Rs[0]),
        ("axisangle", Rs[1]),
        ("xyaxes", Rs[2]),
        ("zaxis", Rz_ref),
        ("down", Rx(math.pi)),
    ):
        assert_tensor(got[name].I_C_B, R @ I_C_I @ R.T, 1e-14)


def test_read_mjcf_fullinertia_is_ixx_iyy_izz_ixy_ixz_iyz_in_the_body_frame(tmp_path):
    text = mjcf("<body name='b'><inertial pos='1 2 3' mass='2' fullinertia='0.4 0.5 0.6 -0.01 0.02 -0.03'/></body>")
    b = model(tmp_path, "full.xml", text).bodies[0]
    assert b.I_C_B.tolist() == [[0.4, -0.01, 0.02], [-0.01, 0.5, -0.03], [0.02, -0.03, 0.6]]
    assert b.p_BC_B.tolist() == [1, 2, 3]


def test_read_mjcf_nested_bodies_are_listed_in_order_with_path_names(tmp_path):
    inertial = "<inertial pos='0 0 0' mass='1' diaginertia='1 1 1'/>"
    text = mjcf(
        f"<body name='a'>{inertial}<body>{inertial}<body name='c'/><frame><body>{inertial}</body></frame></body>"
        f"<body>{inertial}</body></body><body>{inertial}</body>"
    )
    names = [b.name for b in model(tmp_path, "n.xml", text).bodies]
    assert names == ["a", "a/body[1]", "c", "a/body[1]/body[2]", "a/body[2]", "world/body[2]"]


def test_read_mjcf_include_is_relative_to_the_main_model_and_nests(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "main.xml").write_text(
        "<mujoco><worldbody><body name='base'><inertial pos='0 0 0' mass='1' diaginertia='1 1 1'/>"
        "<include file='parts/arm.xml'/></body></worldbody></mujoco>"
    )
    # nested includes are relative to the main model's folder too, as MuJoCo reads them
    (tmp_path / "parts" / "arm.xml").write_text(
        "<mujoco><include file='parts/hand.xml'/><body name='arm'>"
        "<inertial pos='0 0 0' mass='2' diaginertia='1 1 1'/></body></mujoco>"
    )
    (tmp_path / "parts" / "hand.xml").write_text(
        "<mujoco><body name='hand'><inertial pos='0 0 0' mass='3' diaginertia='1 1 1'/></body></mujoco>"
    )
    m = models.read_model(tmp_path / "main.xml")
    assert [(b.name, b.m) for b in m.bodies] == [("base", 1.0), ("hand", 3.0), ("arm", 2.0)]


def test_read_mjcf_compiler_in_an_included_file_counts(tmp_path):
    (tmp_path / "settings.xml").write_text("<mujoco><compiler angle='radian'/></mujoco>")
    (tmp_path / "m.xml").write_text(
        "<mujoco><include file='settings.xml'/><worldbody><body name='b'>"
        "<inertial pos='0 0 0' mass='1' diaginertia='0.1 0.2 0.25' euler='0.5 0 0'/></body></worldbody></mujoco>"
    )
    b = models.read_model(tmp_path / "m.xml").bodies[0]
    assert_tensor(b.I_C_B, Rx(0.5) @ np.diag([0.1, 0.2, 0.25]) @ Rx(0.5).T)


def test_read_mjcf_notes_what_mujoco_does_that_hconv_does_not(tmp_path):
    text = (
        "<mujoco><compiler inertiafromgeom='true' balanceinertia='true'/><worldbody>"
        "<body name='a'><inertial pos='0 0 0' mass='1' diaginertia='1 1 1'/></body>"
        "<body name='b'><geom size='0.1'/></body><replicate count='3'><body name='r'/></replicate>"
        "</worldbody></mujoco>"
    )
    m = model(tmp_path, "g.xml", text)
    notes = " ".join(m.notes)
    assert "inertiafromgeom" in notes and "balanceinertia" in notes and "<replicate>" in notes
    got = by_name(m)
    assert got["b"].status == "no_inertial" and "geoms" in got["b"].reason


# --- statuses --------------------------------------------------------------------------------


def status_of(tmp_path, m, I, name="x.urdf"):
    b = model(tmp_path, name, urdf(urdf_link("l", m, np.asarray(I, dtype=float)))).bodies[0]
    return b.status, b.reason


def test_check_not_physical_gives_the_margin_as_a_share_of_the_trace(tmp_path):
    s, why = status_of(tmp_path, 1.0, np.diag([0.1, 0.1, 0.3]))
    assert s == "not_physical"
    assert "exceeds I1 + I2 = 0.2 kg·m² by 20 % of the trace" in why and "no products, so no sign slip" in why


def test_check_not_physical_says_when_negated_products_would_be_valid(tmp_path):
    # valid with the products -0.003 (moments 0.004, 0.013, 0.013); given +0.003 as CAD reports them
    I = 0.01 * np.ones((3, 3)) * 0.3 + np.diag([0.007] * 3)
    s, why = status_of(tmp_path, 1.2, I)
    assert s == "not_physical" and "with the products negated it would be valid" in why
    s, _ = status_of(tmp_path, 1.2, I * np.where(np.eye(3, dtype=bool), 1, -1), "y.urdf")
    assert s == "ok"


def test_check_not_physical_allows_the_boundary_bodies_within_hconvs_tolerance(tmp_path):
    # a thin plate: I3 = I1 + I2 exactly, and one rounding off it
    assert status_of(tmp_path, 1.0, np.diag([0.1, 0.2, 0.30000000000000004]))[0] == "ok"


@pytest.mark.parametrize(
    "m, I, want, says",
    [
        (1.0, [0, 0, 0], "singular", "I = 0 with m = 1 kg: a point mass"),
        (1.0, [0, 0.1, 0.1], "singular", "1 of them zero, a line mass"),
        (1.0, [-0.1, 0.3, 0.3], "not_positive_definite", "I1 = -0.1 kg·m² < 0"),
        (0.0, [0, 0, 0], "massless", "a frame, not a body"),
        (0.0, [0.1, 0.1, 0.1], "massless_with_inertia", "m = 0 with I ≠ 0"),
        (-1.0, [0.1, 0.1, 0.1], "negative_mass", "m = -1 kg < 0"),
        (0.05, [1, 1, 1], "implausible_density", "far too much inertia for 0.05 kg. A placeholder"),
        (1000.0, [1e-9, 1e-9, 1e-9], "implausible_density", "far too little inertia for 1e+03 kg"),
        (2.0, [0.01, 0.02, 0.025], "ok", ""),
    ],
)
def test_check_status_and_reason(tmp_path, m, I, want, says):
    s, why = status_of(tmp_path, m, np.diag(I))
    assert s == want
    assert says in why if says else why == ""


def test_check_implausible_density_names_both_causes(tmp_path):
    _, why = status_of(tmp_path, 0.05, np.eye(3))
    assert "placeholder" in why and "g·cm²" in why and "3.8e-05 kg/m³" in why
    _, why = status_of(tmp_path, 1000.0, 1e-9 * np.eye(3), "y.urdf")
    assert "placeholder" in why and "the mass in g read as kg" in why


def test_check_reason_names_the_other_statuses_that_apply(tmp_path):
    s, why = status_of(tmp_path, -1.0, np.diag([0.1, 0.1, 0.3]))
    assert s == "negative_mass" and "also not_physical: I3 = 0.3 exceeds" in why


def test_check_massless_with_a_negative_moment_is_not_called_a_rod(tmp_path):
    """Before: m = 0 with only iyz said "also singular: ... a line mass, like an ideal rod", though
    its moments -0.001, 0, 0.001 make it indefinite, which no rod is."""
    I = np.zeros((3, 3))
    I[1, 2] = I[2, 1] = 1e-3
    s, why = status_of(tmp_path, 0.0, I)
    assert s == "massless_with_inertia"
    assert "also not_positive_definite: principal moment I1 = -0.001 kg·m² < 0" in why
    assert "line mass" not in why and "singular" not in why


# iCub's legs as its URDF gives them: a tensor of floating-point dust beside a real mass, and a
# link with a mass and I = 0 (the other numbers of the links are the file's style, not its values)
ICUB_LEGS = urdf(
    '<link name="r_hip_1"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="0.9"/>'
    '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>',
    '<link name="r_hip_2"><inertial><origin xyz="0.0133 0.0 -0.0588" rpy="0 0 0"/><mass value="1.3"/>'
    '<inertia ixx="0.0" ixy="0.0" ixz="2.4e-35" iyy="0.0" iyz="0.0" izz="0.0"/></inertial></link>',
    '<link name="r_upper_leg"><inertial><origin xyz="0.0 0.0 -0.12" rpy="0 0 0"/><mass value="1.5"/>'
    '<inertia ixx="0.0037" ixy="0.0" ixz="0.0" iyy="0.0037" iyz="0.0" izz="0.0009"/></inertial></link>',
)


def test_check_negligible_tensor_is_a_point_mass_as_i_zero_is(tmp_path):
    """Before: r_hip_2 was not_positive_definite, "no mass distribution has it", for rounding
    dust of 2.4e-35 kg·m² beside 1.3 kg; and r_hip_1 (I = 0) had no density check."""
    got = by_name(model(tmp_path, "icub.urdf", ICUB_LEGS))
    dust, zero, leg = got["r_hip_2"], got["r_hip_1"], got["r_upper_leg"]
    assert (dust.status, zero.status, leg.status) == ("singular", "singular", "ok")
    assert dust.reason.startswith("I is negligible beside m·(1 nm)² = 1.3e-18 kg·m² (its largest moment is 2.4e-35")
    assert "no mass distribution" not in dust.reason and "sign slip" not in dust.reason
    assert zero.reason.startswith("I = 0 with m = 0.9 kg: a point mass")
    for b in (dust, zero):
        assert "also implausible_density: a mass of" in b.reason and "an infinite density" in b.reason


@pytest.mark.parametrize(
    "I, want",
    [
        # largest moment just below m·(1 nm)², any signs: dust
        (np.diag([-0.9e-18, 0.0, 0.9e-18]), "singular"),
        (np.diag([0.5e-18, 0.5e-18, 0.9e-18]), "singular"),
        # just above: judged as a tensor, here a body far too dense, with its unit-slip advice
        (np.diag([1.1e-18, 1.1e-18, 1.1e-18]), "implausible_density"),
        (np.diag([-1.1e-18, 1.1e-18, 1.1e-18]), "not_positive_definite"),
    ],
)
def test_check_negligible_threshold_is_m_times_a_nanometre_squared(tmp_path, I, want):
    s, why = status_of(tmp_path, 1.0, I)
    assert s == want
    assert ("negligible" in why) == (want == "singular")


def test_check_density_runs_where_the_trace_is_not_positive(tmp_path):
    """Before: a negative trace with a positive mass went unjudged by the density check."""
    s, why = status_of(tmp_path, 2.0, np.diag([-0.3, -0.2, 0.1]))
    assert s == "not_positive_definite"
    assert "also implausible_density: a mass of 2 kg with a trace of -0.4 kg·m², not positive, has no" in why


def test_read_urdf_duplicate_link_names_are_a_note(tmp_path):
    """Before: the two links named "a" were listed twice with no word."""
    I = np.diag([0.1, 0.2, 0.25])
    m = model(tmp_path, "dup.urdf", urdf(urdf_link("a", 1.0, I), urdf_link("b", 1.0, I), urdf_link("a", 2.0, I)))
    assert [b.name for b in m.bodies] == ["a", "b", "a"]
    assert len(m.notes) == 1
    assert "link 'a' is given 2 times (lines 3, 5); URDF requires unique link names" in m.notes[0]


def test_read_urdf_a_link_name_given_many_times_is_a_note_of_one_line(tmp_path):
    """Before, the note listed every line: a name given a million times, a note of 7 MB."""
    m = model(tmp_path, "dup.urdf", urdf(*['<link name="a"/>'] * 8))
    assert "link 'a' is given 8 times (lines 3, 4, 5, 6, 7, … (8 in all)); URDF requires" in m.notes[0]


def test_check_no_inertial_in_every_format(tmp_path):
    assert by_name(model(tmp_path, "a.urdf", urdf('<link name="l"/>')))["l"].status == "no_inertial"
    assert by_name(model(tmp_path, "a.sdf", "<sdf><model name='m'><link name='l'/></model></sdf>"))["l"].status == (
        "no_inertial"
    )
    b = model(tmp_path, "a.xml", mjcf("<body name='l'><geom size='1'/></body>")).bodies[0]
    assert b.status == "no_inertial" and "MuJoCo infers the mass and inertia from the body's geoms" in b.reason
    assert np.isnan(b.q_B).all() and np.isnan(b.moments).all()


# --- untrusted input -------------------------------------------------------------------------

LAUGHS = (
    '<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
    + "".join(f' <!ENTITY lol{k} "{("&lol" + (str(k - 1) if k > 1 else "") + ";") * 10}">\n' for k in range(1, 10))
    + ']>\n<robot name="&lol9;"/>\n'
)


@pytest.mark.parametrize(
    "name, text, says",
    [
        ("laughs.urdf", LAUGHS, "laughs.urdf, line 3: declares an entity"),
        (
            "xxe.urdf",
            '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n<robot name="&x;"/>',
            "xxe.urdf, line 2: declares an entity",
        ),
        (
            "param.urdf",
            '<!DOCTYPE r [<!ENTITY % p SYSTEM "http://example.invalid/p.dtd"> %p;]><robot/>',
            "declares an entity",
        ),
        ("subset.urdf", "<!DOCTYPE r [<!ATTLIST robot name CDATA 'x'>]><robot/>", "DOCTYPE with declarations"),
        ("dtd.urdf", '<!DOCTYPE robot SYSTEM "http://example.invalid/r.dtd">\n<robot/>', "names an external DTD"),
        ("undefined.urdf", '<robot name="&nope;"/>', "line 1, column 1: not well-formed XML (undefined entity)"),
        (
            "xi.urdf",
            '<robot xmlns:xi="http://www.w3.org/2001/XInclude">\n<xi:include href="/etc/passwd"/></robot>',
            "uses XInclude",
        ),
        ("xacro.urdf", '<robot xmlns:xacro="http://x"><xacro:property name="a" value="1"/></robot>', "run xacro"),
        ("open.urdf", '<robot name="r">\n<link name="a">\n</robot>', "open.urdf, line 3, column 3: not well-formed"),
        ("html.urdf", "<html/>", "<html> is the root element, so this is not a model"),
        ("empty.urdf", "", "empty.urdf: is empty"),
        ("junk.urdf", "\x00\x01PK\x03", "not well-formed XML"),
        ("noname.urdf", urdf("<link/>"), 'name the link: <link name="...">'),
        (
            "nomass.urdf",
            urdf(
                '<link name="a"><inertial>\n<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
                "</inertial></link>"
            ),
            "nomass.urdf, line 3, <inertial> has no <mass>; add <mass",
        ),
        (
            "noiyz.urdf",
            urdf(
                '<link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" izz="1"/>'
                "</inertial></link>"
            ),
            "<inertia> has no attribute iyz; URDF's <inertia> needs all of",
        ),
        ("text.urdf", urdf('<link name="a"><inertial><mass value="heavy"/></inertial></link>'), "holds 'heavy'"),
        ("nan.urdf", urdf('<link name="a"><inertial><mass value="nan"/></inertial></link>'), "holds 'nan'"),
        ("big.urdf", urdf('<link name="a"><inertial><mass value="1e999"/></inertial></link>'), "beyond the range"),
        ("expr.urdf", urdf('<link name="a"><inertial><mass value="${m}"/></inertial></link>'), "run xacro"),
        (
            "rpy.urdf",
            urdf('<link name="a"><inertial><origin rpy="0 0"/><mass value="1"/></inertial></link>'),
            "attribute rpy holds 2 numbers ('0 0'), but takes 3",
        ),
        (
            "two.urdf",
            urdf('<link name="a"><inertial><mass value="1"/></inertial><inertial/></link>'),
            "is the second <inertial> in <link>",
        ),
        ("nopos.xml", mjcf("<body><inertial mass='1' diaginertia='1 1 1'/></body>"), "has no attribute pos"),
        (
            "orient.xml",
            mjcf("<body><inertial pos='0 0 0' mass='1' diaginertia='1 1 1' quat='1 0 0 0' euler='0 0 0'/></body>"),
            "has both quat and euler",
        ),
        (
            "fullq.xml",
            mjcf("<body><inertial pos='0 0 0' mass='1' fullinertia='1 1 1 0 0 0' quat='1 0 0 0'/></body>"),
            "fullinertia is in the body frame and takes no orientation",
        ),
        (
            "both.xml",
            mjcf("<body><inertial pos='0 0 0' mass='1' fullinertia='1 1 1 0 0 0' diaginertia='1 1 1'/></body>"),
            "has both diaginertia and fullinertia",
        ),
        (
            "zeroq.xml",
            mjcf("<body><inertial pos='0 0 0' mass='1' diaginertia='1 1 1' quat='0 0 0 0'/></body>"),
            "quat has zero length",
        ),
        (
            "parallel.xml",
            mjcf("<body><inertial pos='0 0 0' mass='1' diaginertia='1 1 1' xyaxes='1 0 0 2 0 0'/></body>"),
            "xyaxes' y axis, less its part along x, has zero length",
        ),
        ("angle.xml", "<mujoco><compiler angle='grad'/></mujoco>", "has angle='grad'"),
        ("seq.xml", "<mujoco><compiler eulerseq='xyw'/></mujoco>", "has eulerseq='xyw'"),
        ("rot.sdf", "<sdf><model name='m'><link name='l'><inertial><pose rotation_format='q'/>", "not well-formed"),
        (
            "rot2.sdf",
            "<sdf><model name='m'><link name='l'><inertial><pose rotation_format='q'/></inertial></link></model></sdf>",
            "has rotation_format='q'",
        ),
        (
            "deg.sdf",
            "<sdf><model name='m'><link name='l'><inertial><pose degrees='maybe'>0 0 0 0 0 0</pose></inertial>"
            "</link></model></sdf>",
            "has degrees='maybe'",
        ),
    ],
)
def test_read_untrusted_input_is_one_line_naming_file_and_fix(tmp_path, name, text, says):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError) as e:
        models.read_model(path)
    msg = str(e.value)
    assert says in msg and "\n" not in msg and msg.startswith(str(path))


def test_read_xacro_include_says_run_xacro_first(tmp_path):
    """Before: "<xacro:include> uses XInclude, which hconv does not follow; paste the included
    content in", where every other xacro element says to run xacro."""
    path = tmp_path / "arm.urdf.xacro"
    path.write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        '<xacro:include filename="parts.xacro"/>\n<link name="a"/>\n</robot>\n'
    )
    with pytest.raises(InputError) as e:
        models.read_model(path)
    msg = str(e.value)
    assert msg.startswith(f"{path}, line 2, <xacro:include> is xacro") and "run xacro first" in msg
    assert "XInclude" not in msg


def test_read_forgives_what_tinyxml_forgives_and_keeps_line_numbers(tmp_path):
    """Files of a widely used model collection: blank lines before the XML declaration, a NUL
    after the root, and xacro's namespace left on an expanded URDF."""
    text = urdf(urdf_link("a", 1.0, np.eye(3)), '<link name="b">\n<inertial><mass value="x"/></inertial></link>')
    path = tmp_path / "lenient.urdf"
    expanded = text.replace("<robot", '<robot xmlns:xacro="http://ros.org/wiki/xacro"')
    path.write_bytes(b"\n\n" + expanded.encode() + b"\0")
    with pytest.raises(InputError, match=r"lenient.urdf, line 7, <mass> attribute value holds 'x'"):
        models.read_model(path)
    path.write_bytes(b"\n\n" + urdf(urdf_link("a", 1.0, np.eye(3))).encode() + b"\0")
    assert models.read_model(path).bodies[0].status == "ok"


def test_read_refuses_entities_hidden_by_another_encoding(tmp_path):
    path = tmp_path / "laughs16.urdf"
    path.write_bytes(LAUGHS.replace('version="1.0"', 'version="1.0" encoding="UTF-16"').encode("utf-16"))
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="DOCTYPE with declarations"):
        models.read_model(path)
    assert time.perf_counter() - t0 < 1


@pytest.mark.parametrize(
    "files, says",
    [
        ({"m.xml": "<mujoco><include file='m.xml'/></mujoco>"}, "includes 'm.xml' again inside itself"),
        (
            {"m.xml": "<mujoco><include file='a.xml'/></mujoco>", "a.xml": "<mujoco><include file='m.xml'/></mujoco>"},
            "a cycle",
        ),
        (
            {"m.xml": "<mujoco><include file='a.xml'/><include file='a.xml'/></mujoco>", "a.xml": "<mujoco/>"},
            "which 'a.xml' already brought in",
        ),
        ({"m.xml": "<mujoco><include file='gone.xml'/></mujoco>"}, "m.xml, line 1, <include> names 'gone.xml'"),
        ({"m.xml": "<mujoco><include file='../outside.xml'/></mujoco>"}, "outside the model's folder"),
        ({"m.xml": "<mujoco><include file='/etc/hostname'/></mujoco>"}, "outside the model's folder"),
        ({"m.xml": "<mujoco><include file='http://example.invalid/a.xml'/></mujoco>"}, "hconv reads no URLs"),
        ({"m.xml": "<mujoco><include/></mujoco>"}, "has no attribute file"),
        ({"m.xml": "<mujoco><include file='a.xml'/></mujoco>", "a.xml": "<mujoco><body>"}, "a.xml, line 1"),
    ],
)
def test_read_mjcf_include_refusals(tmp_path, files, says):
    (tmp_path / "sub").mkdir()
    for name, text in files.items():
        (tmp_path / "sub" / name).write_text(text)
    (tmp_path / "outside.xml").write_text("<mujoco/>")
    with pytest.raises(InputError) as e:
        models.read_model(tmp_path / "sub" / "m.xml")
    assert says in str(e.value) and "\n" not in str(e.value)


def test_read_mjcf_include_missing_names_the_including_file_and_line(tmp_path):
    """Before, the message named only the missing file: which of the includes to fix was left
    to guess."""
    (tmp_path / "parts").mkdir()
    (tmp_path / "m.xml").write_text("<mujoco><worldbody><include file='parts/arm.xml'/></worldbody></mujoco>")
    (tmp_path / "parts" / "arm.xml").write_text(
        "<mujoco>\n<body name='arm'/>\n<include file='parts/gone.xml'/></mujoco>"
    )
    with pytest.raises(InputError) as e:
        models.read_model(tmp_path / "m.xml")
    msg = str(e.value)
    assert msg.startswith("parts/arm.xml, line 3, <include> names 'parts/gone.xml' (")
    assert os.path.join(str(tmp_path), "parts", "gone.xml") in msg and "check the path" in msg and "\n" not in msg


@pytest.mark.parametrize(
    "text, says",
    [
        (
            "<mujoco><default><body name='lost'/></default><worldbody>{b}</worldbody></mujoco>",
            "line 1, <body> 'lost' is inside <default>, where MuJoCo reads no body",
        ),
        (
            "<mujoco><worldbody>{b}<geom type='sphere' size='1'>\n<body name='lost'/></geom></worldbody></mujoco>",
            "line 2, <body> 'lost' is inside <geom> (",
        ),
        (
            "<mujoco><worldbody>{b}</worldbody><body name='lost'><body/></body></mujoco>",
            "a fragment made for <include>?",
        ),
    ],
)
def test_read_mjcf_body_outside_the_body_tree_is_a_note(tmp_path, text, says):
    """MuJoCo refuses a <body> outside <worldbody>, a <body>, a <frame> or a <replicate>; hconv
    had left it out without a word."""
    b = "<body name='b'><inertial pos='0 0 0' mass='1' diaginertia='1 1 1'/></body>"
    m = model(tmp_path, "x.xml", text.format(b=b))
    assert [x.name for x in m.bodies] == ["b"]
    lost = [n for n in m.notes if "'lost'" in n]
    assert len(lost) == 1 and says in lost[0] and "hconv does not list it" in lost[0], m.notes
    assert len(m.notes) == 1  # a misplaced body's own bodies go with it, unmentioned


def test_read_refuses_a_fifo_without_blocking(tmp_path):
    fifo = tmp_path / "model.urdf"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="is not a regular file"):
        models.read_model(fifo)


def test_read_refuses_a_file_beyond_the_size_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(modelxml, "MAX_BYTES", 100)
    path = tmp_path / "big.urdf"
    path.write_text(urdf(urdf_link("a", 1.0, np.eye(3))))
    with pytest.raises(InputError, match="larger than any model file hconv reads"):
        models.read_model(path)


def test_read_deep_nesting_to_the_limit_needs_no_recursion_and_beyond_it_is_one_line(tmp_path):
    """<mujoco>, <worldbody>, bodies and the last one's <inertial>: MAX_DEPTH elements deep; one more is refused, as
    tinyxml2 (MuJoCo's and libsdformat's parser) refuses it, at the line of the element too deep."""
    inertial = "<inertial pos='0 0 0' mass='1' diaginertia='1 1 1'/>"

    def nested(bodies):
        return mjcf("".join("<body>" + inertial + "\n" for _ in range(bodies)) + "</body>" * bodies)

    depth = modelxml.MAX_DEPTH - 3
    assert len(model(tmp_path, "deep.xml", nested(depth)).bodies) == depth
    with pytest.raises(InputError) as e:
        model(tmp_path, "deeper.xml", nested(depth + 1))
    msg = str(e.value)
    assert f"deeper.xml, line {depth + 1}: nests elements more than {modelxml.MAX_DEPTH} deep" in msg
    assert "\n" not in msg


# --- hostile files: bounded time, memory and output ------------------------------------------

#: The memory bound docs/models.md states for reading a model: 40 bytes per
#: byte of the model, 2 KiB per element, and 1 MiB. Measured here as the peak of Python's
#: allocations while reading (tracemalloc: numpy's arrays included), on the shapes that cost most:
#: the most per byte is an element of many short attributes (` abc=''`, 8 bytes), some 220 bytes
#: each in expat's tables and Python's dict; the most per element an unnamed MJCF body, 1.8 KiB.
MEMORY_PER_BYTE, MEMORY_PER_ELEMENT, MEMORY_BASE = 40, 2048, 1 << 20


def peak_reading(path: Path) -> tuple[int, str]:
    """The peak of Python's allocations while ``read_model(path)`` runs, and its error ("" if none)."""
    import tracemalloc

    tracemalloc.start()
    try:
        try:
            models.read_model(path)
            said = ""
        except InputError as e:
            said = str(e)
        return tracemalloc.get_traced_memory()[1], said
    finally:
        tracemalloc.stop()


def assert_within_memory_bound(path: Path) -> str:
    text = path.read_text()
    elements = text.count("<") - text.count("</")  # a start tag each: generated files have no comments
    bound = MEMORY_PER_BYTE * len(text) + MEMORY_PER_ELEMENT * elements + MEMORY_BASE
    peak, said = peak_reading(path)
    assert peak <= bound, f"{path.name}: {peak / 1e6:.1f} MB > {bound / 1e6:.1f} MB ({said[:200]})"
    return said


def test_read_mjcf_include_symlink_loop_is_one_line_naming_the_link(tmp_path):
    """Before: "internal error: RuntimeError: Symlink loop from ...", exit 1."""
    main = tmp_path / "m.xml"
    main.write_text("<mujoco><worldbody>\n<include file='a.xml'/></worldbody></mujoco>")
    os.symlink("b.xml", tmp_path / "a.xml")
    os.symlink("a.xml", tmp_path / "b.xml")
    proc = run_hconv("bodies", str(main))
    err = proc.stderr.decode()
    assert proc.returncode == 3 and err.count("\n") == 1, err
    assert err.startswith(
        f"hconv: error: {main}, line 2, <include> names 'a.xml' ({tmp_path / 'a.xml'}), a symbolic link that leads "
        "back to itself (a loop); point the link at the file"
    )


@pytest.mark.parametrize("kind", ["directory", "fifo", "device", "unreadable"])
def test_read_mjcf_include_of_what_is_not_a_file_names_the_include_without_blocking(tmp_path, kind, monkeypatch):
    """Before, the message named only the included path ("parts: is a directory"), not the
    include to fix. Unreadable: permission denied, made so for root too (whom it never denies)."""
    target = tmp_path / "parts"
    if kind == "unreadable":
        target.write_text("<mujoco/>")
        os_open = os.open

        def denied(path, *args, **kwargs):
            if os.fspath(path) == str(target):
                raise PermissionError(13, "Permission denied", str(path))
            return os_open(path, *args, **kwargs)

        monkeypatch.setattr(os, "open", denied)
    elif kind == "directory":
        target.mkdir()
    elif kind == "fifo":
        os.mkfifo(target)
    else:
        try:
            os.mknod(target, 0o600 | __import__("stat").S_IFCHR, os.makedev(1, 5))  # as /dev/zero
        except PermissionError:
            pytest.skip("making a device needs root")
    main = tmp_path / "m.xml"
    main.write_text("<mujoco><worldbody>\n\n<include file='parts'/></worldbody></mujoco>")
    with pytest.raises(InputError) as e:
        models.read_model(main)
    msg = str(e.value)
    want = {
        "directory": "which is a directory",
        "unreadable": "which cannot be read: Permission denied; check its permissions",
    }.get(kind, "which is not a regular file (a pipe or a device)")
    assert msg.startswith(f"{main}, line 3, <include> names 'parts'") and want in msg and "\n" not in msg


def test_read_mjcf_include_counts_toward_the_size_limit(tmp_path, monkeypatch):
    """Each file within MAX_BYTES, the model with its includes beyond it: before, read whole."""
    (tmp_path / "m.xml").write_text("<mujoco><worldbody><include file='a.xml'/></worldbody></mujoco>")
    (tmp_path / "a.xml").write_text("<mujoco><body name='b'/><body name='c'/></mujoco>")
    monkeypatch.setattr(modelxml, "MAX_BYTES", 100)
    with pytest.raises(InputError) as e:
        models.read_model(tmp_path / "m.xml")
    assert str(e.value).startswith(f"a.xml: brings the model {tmp_path / 'm.xml'} with its includes to ")
    assert "larger than any model hconv reads" in str(e.value)


def test_read_refuses_more_elements_than_the_limit_with_its_includes(tmp_path, monkeypatch):
    monkeypatch.setattr(modelxml, "MAX_ELEMENTS", 10)
    (tmp_path / "m.xml").write_text("<mujoco><worldbody><include file='a.xml'/></worldbody></mujoco>")
    (tmp_path / "a.xml").write_text("<mujoco>\n" + "<body/>\n" * 8 + "</mujoco>")
    with pytest.raises(InputError) as e:
        models.read_model(tmp_path / "m.xml")
    assert str(e.value) == (
        f"a.xml, line 8: brings the model {tmp_path / 'm.xml'} to more than 10 elements, more than any model "
        "hconv reads; is it a model?"
    )


def test_read_sdf_nested_2000_deep_is_refused_in_bounded_memory(tmp_path):
    """20,000 nested <model>s (2.8 MB) took 1.5 GB: each link's name is the names of all the
    models around it (m0::m1::...::l). Nesting deeper than tinyxml2 reads is refused now."""
    n = 2000
    inertial = "<inertial><mass>1</mass><inertia><ixx>1</ixx><iyy>1</iyy><izz>1</izz></inertia></inertial>"
    path = tmp_path / "nested.sdf"
    path.write_text(
        "<sdf version='1.9'>\n"
        + "".join(f"<model name='m{k}'><link name='l'>{inertial}</link>\n" for k in range(n))
        + "</model>" * n
        + "</sdf>"
    )
    said = assert_within_memory_bound(path)
    assert said == (
        f"{path}, line {modelxml.MAX_DEPTH - 3}: nests elements more than {modelxml.MAX_DEPTH} deep, deeper than any "
        "model (MuJoCo and libsdformat refuse it too); is it a model?"
    )


@pytest.mark.parametrize(
    "name, text",
    [
        (  # names as long as the file allows, nested as deep as it allows: 90 MB of names before
            "scoped.sdf",
            "<sdf>"
            + "".join(f"<model name='{k:04}{'m' * 2000}'><link name='l'/>" for k in range(300))
            + "</model>" * 300
            + "</sdf>",
        ),
        (  # an unnamed body is named by its parent's path: 100 MB of names from 64 kB before
            "unnamed.xml",
            f"<mujoco><worldbody><body name='{'b' * 50_000}'>" + "<body/>" * 2000 + "</body></worldbody></mujoco>",
        ),
    ],
)
def test_read_body_names_made_by_nesting_are_bounded_by_the_file(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    said = assert_within_memory_bound(path)
    assert "which brings the body names hconv makes from the nesting to more than" in said, said
    assert len(said) < 500 and "…" in said and "\n" not in said


def test_read_a_long_value_is_refused_in_bounded_memory_and_quoted_short(tmp_path):
    """A 60 MB attribute of numbers took 1.9 GB and 50 s, and its one-line error repeated the
    whole attribute (63 MB of stderr). Now one more number than it takes is read."""
    path = tmp_path / "long.urdf"
    path.write_text(urdf(f'<link name="a"><inertial><mass value="{"1 " * 1_000_000}"/></inertial></link>'))
    said = assert_within_memory_bound(path)
    assert said.startswith(f"{path}, line 3, <mass> attribute value holds more than 1 numbers ('1 1 1 ")
    assert "…" in said and len(said) < 300, said[:300]


@pytest.mark.parametrize(
    "value, says",
    [
        ("x" * 100_000, "holds 'xxxxxxxx"),  # not a number
        ("1" * 100_000, "holds 11111111"),  # beyond a float
        ("1 2" + " 3" * 100_000, "holds more than 3 numbers"),
    ],
)
def test_read_quotes_at_most_80_characters_of_a_value(tmp_path, value, says):
    path = tmp_path / "q.urdf"
    path.write_text(urdf(f'<link name="a"><inertial><origin xyz="{value}"/><mass value="1"/></inertial></link>'))
    with pytest.raises(InputError) as e:
        models.read_model(path)
    msg = str(e.value)
    assert says in msg and "…" in msg and len(msg) < len(str(path)) + 250, msg[:300]


def test_quote_keeps_the_start_and_the_end_within_80_characters():
    assert modelxml.quote("abc") == "'abc'"
    long = "a" * 100 + "\n" + "z" * 100
    assert modelxml.clip(long) == "a" * 53 + "…" + "z" * 26 and len(modelxml.clip(long)) == modelxml.QUOTED
    assert modelxml.quote(long) == repr("a" * 53 + "…" + "z" * 26)


def test_cli_bodies_strict_names_a_long_body_name_short(tmp_path):
    path = tmp_path / "long.urdf"
    path.write_text(urdf(f'<link name="{"n" * 100_000}"/>'))
    proc = run_hconv("bodies", str(path), "--strict")
    err = proc.stderr.decode()
    assert proc.returncode == 5 and err.count("\n") == 1 and len(err) < 300, err[:300]
    assert "1 of 1 bodies are not ok (--strict): nnnn" in err and "… (no_inertial)" not in err[:50]


def test_read_a_run_of_digits_that_ends_in_a_letter_is_refused_in_linear_time(tmp_path):
    """The number pattern had as many ways to match a run of digits as it has digits: refusing
    100,000 digits and a letter took longer than run_hconv's 120 s timeout (a generous bound,
    that a loaded machine cannot reach: it takes about a second now)."""
    path = tmp_path / "digits.urdf"
    path.write_text(urdf(f'<link name="a"><inertial><mass value="{"1" * 100_000}x"/></inertial></link>'))
    proc = run_hconv("bodies", str(path))
    err = proc.stderr.decode()
    assert proc.returncode == 3 and "which is not a number" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    "shape",
    [
        "<robot name='r'>" + "<a/>" * 20_000 + "</robot>",
        "<robot name='r'>" + "<link name='x'/>" * 3_000 + "</robot>",
        "<mujoco><worldbody>" + "<body/>" * 3_000 + "</worldbody></mujoco>",
        "<mujoco><worldbody>" + "<body><body>" * 240 + "</body></body>" * 240 + "</worldbody></mujoco>",
        "<sdf><model name='m'>" + "<link name='l'><inertial auto='true'/></link>" * 2_000 + "</model></sdf>",
        "<robot " + " ".join(f"{''.join(n)}=''" for n in itertools.product(string.ascii_letters, repeat=3)) + "/>",
    ],
    ids=["elements", "links", "bodies", "nested_bodies", "sdf_links", "attributes"],
)
def test_read_a_model_within_the_limits_stays_within_the_memory_bound(tmp_path, shape):
    """Before, every file read took a 64 MiB buffer, whatever its size."""
    path = tmp_path / ("m.xml" if shape.startswith("<mujoco") else "m.sdf" if shape.startswith("<sdf") else "m.urdf")
    path.write_text(shape)
    assert_within_memory_bound(path)


def test_read_sdf_frames_are_placed_once_each(tmp_path, monkeypatch):
    """Each link placed relative to the head of a chain of frames walked the whole chain, and
    built the model's table of names again: quadratic in the links."""
    n = 200
    frames = "".join(f"<frame name='f{k}' attached_to='f{k + 1}'><pose>0 0 1 0 0 0</pose></frame>" for k in range(n))
    links = "".join(
        f"<link name='l{k}'><inertial><pose relative_to='f0'/><mass>1</mass></inertial></link>" for k in range(n)
    )
    path = tmp_path / "chain.sdf"
    path.write_text(f"<sdf><model name='m'>{frames}<frame name='f{n}'/>{links}</model></sdf>")
    poses = []
    pose_of = sdf._pose
    monkeypatch.setattr(sdf, "_pose", lambda node: poses.append(node) or pose_of(node))
    bodies = models.read_model(path).bodies
    assert len(bodies) == n and all(b.status == "ok" for b in bodies)
    np.testing.assert_allclose(bodies[-1].p_BC_B, [0.0, 0.0, n])
    assert len(poses) <= 3 * (n + 1) + n  # each frame and link once, each inertial once


def test_read_sdf_a_chain_through_many_nested_models_is_unresolved_not_a_crash(tmp_path):
    """Nested model k placed relative to a link of model k + 1, 1,500 times: Python's stack
    overflowed (internal error: RecursionError)."""
    n = 1500
    chain = "".join(f"<model name='m{k}'><pose relative_to='m{k + 1}::l'/><link name='l'/></model>" for k in range(n))
    path = tmp_path / "siblings.sdf"
    path.write_text(
        f"<sdf><model name='top'>{chain}<model name='m{n}'><link name='l'/></model>"
        "<link name='a'><inertial><pose relative_to='m0::l'/><mass>1</mass></inertial></link></model></sdf>"
    )
    a = by_name(models.read_model(path))["a"]
    assert a.status == "unresolved_frame" and "passes through more than 200 frames of nested models" in a.reason


# --- output ----------------------------------------------------------------------------------


def test_table_columns_are_hconvs_input_contract(tmp_path):
    m = models.read_model(EXAMPLES / "arm.urdf")
    t6, tp = m.table("sym6"), m.table("principal")
    common = ["body", "m", "rx", "ry", "rz"]
    assert t6.column_names == common + ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz", "inertia_status", "inertia_reason"]
    assert tp.column_names == common + ["I1", "I2", "I3", "qw", "qx", "qy", "qz", "inertia_status", "inertia_reason"]
    assert t6.schema.field("Ixx").metadata == {b"unit": b"kg*m**2"} and t6.schema.field("rx").metadata[b"unit"] == b"m"
    with pytest.raises(UsageError, match="form must be one of sym6, principal"):
        m.table("full9")


@pytest.mark.parametrize("form, ext", [("sym6", "csv"), ("principal", "parquet")])
def test_roundtrip_bodies_into_convert_gives_inverse_inertia_times_H(tmp_path, form, ext, capsys):
    """Bodies with rotated inertials written by hconv bodies, read by hconv convert with an H per
    row: ω is I⁻¹H for the tensor built here from the same numbers (Rodrigues, 50-digit solve)."""
    rng = np.random.default_rng(7)
    n = 6
    u, th = axis_angle(rng, n)
    Rs, qs = rodrigues(u, th), quats(u, th)
    moments = rng.uniform(0.5, 1.0, (n, 3))
    moments[:, 2] = np.minimum(moments[:, 2], moments[:, 0] + moments[:, 1])
    bodies = "".join(
        f"<body name='b{k}'><inertial pos='{k} 0 0' mass='2' quat='{nums(qs[k])}' "
        f"diaginertia='{nums(moments[k])}'/><freejoint/><geom size='0.1'/></body>"
        for k in range(n)
    )
    (tmp_path / "m.xml").write_text(mjcf(bodies))
    out = tmp_path / f"bodies.{ext}"
    proc = hconv_inprocess("bodies", str(tmp_path / "m.xml"), str(out), "--form", form, capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    t = pacsv.read_csv(out) if ext == "csv" else pq.read_table(out)
    H = rng.normal(size=(n, 3))
    t = t.append_column("Hx", pa.array(H[:, 0])).append_column("Hy", pa.array(H[:, 1]))
    t = t.append_column("Hz", pa.array(H[:, 2]))
    src = tmp_path / f"with-H.{ext}"
    (pacsv.write_csv if ext == "csv" else pq.write_table)(t, src)
    proc = hconv_inprocess("convert", str(src), str(tmp_path / f"omega.{ext}"), "-q", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    res = pacsv.read_csv(tmp_path / f"omega.{ext}") if ext == "csv" else pq.read_table(tmp_path / f"omega.{ext}")
    w = np.column_stack([res.column(c).to_numpy() for c in ("wx", "wy", "wz")])
    I = np.einsum("nij,nj,nkj->nik", Rs, moments, Rs)
    assert np.abs(w - mp_solve(I, H)).max() <= 1e-13 * np.abs(w).max()
    assert set(res.column("status").to_pylist()) == {"ok"}
    assert res.column("body").to_pylist() == [f"b{k}" for k in range(n)]


def test_show_fits_80_columns_without_cutting_a_name_or_a_number():
    for path in sorted(EXAMPLES.glob("*.*")):
        if path.name == "pendulum-arm.xml":
            continue
        m = models.read_model(path)
        buf = io.StringIO()
        modelview.show(m, Console(file=buf, width=80, force_terminal=True, color_system=None))
        lines = buf.getvalue().splitlines()
        assert max(len(line) for line in lines) <= 80
        names = {b.name for b in m.bodies}
        rows: dict[str, str] = {}
        for line in lines:  # the table's row comes first; the reasons below start with the name too
            if line.split() and line.split()[0] in names:
                rows.setdefault(line.split()[0], line)
        for b in m.bodies:
            assert b.name in rows and rows[b.name].split()[-1] == b.status
            for x in (b.m, *b.moments):
                assert ("-" if x != x else f"{x:.4g}") in rows[b.name].split()


def test_show_reasons_and_notes_wrap_without_trailing_spaces():
    """Before: each wrapped reason and note line ended in the space rich wrapped at."""
    m = models.read_model(EXAMPLES / "arm.urdf")
    buf = io.StringIO()
    modelview.show(m, Console(file=buf, width=60, force_terminal=True, color_system=None))
    lines = buf.getvalue().splitlines()
    assert any("sign slip" in ln for ln in lines)
    assert [ln for ln in lines if ln != ln.rstrip()] == []


def test_show_lists_bodies_whose_names_do_not_fit(tmp_path):
    long = "a_link_whose_name_is_far_too_long_for_a_table_row_at_eighty_columns_wide"
    m = model(tmp_path, "l.urdf", urdf(urdf_link(long, 1.0, np.diag([0.1, 0.1, 0.3]))))
    buf = io.StringIO()
    modelview.show(m, Console(file=buf, width=80, force_terminal=True, color_system=None))
    text = buf.getvalue()
    assert max(len(line) for line in text.splitlines()) <= 80
    assert long in text.splitlines() and "not_physical" in text


def test_show_more_bodies_than_a_table_shows_is_tab_separated_on_a_terminal(tmp_path, monkeypatch):
    """rich laid a table out at milliseconds a row: a model of a million bodies took an hour."""
    monkeypatch.setattr(modelview, "MAX_TABLE", 2)
    m = model(tmp_path, "b.xml", mjcf("<body name='a'/><body name='b'/><body name='c'/>"))
    buf = io.StringIO()
    modelview.show(m, Console(file=buf, width=80, force_terminal=True, color_system=None))
    lines = buf.getvalue().splitlines()
    assert lines[2] == "# more bodies than a table shows (2): tab-separated text"
    assert [line.split("\t")[0] for line in lines[3:]] == ["body", "a", "b", "c"]


@pytest.mark.parametrize("terminal", [False, True])
def test_show_escapes_a_tab_or_newline_in_a_name(tmp_path, terminal):
    """A name with &#9; or &#10; split its row into columns or lines of their own."""
    m = model(tmp_path, "n.urdf", urdf('<link name="a&#9;b&#10;c"/>', '<link name="d"/>'))
    buf = io.StringIO()
    modelview.show(m, Console(file=buf, width=120, force_terminal=terminal, color_system=None))
    text = buf.getvalue()
    assert "a\\tb\\nc" in text and "\tb" not in text and "\nc" not in text
    if not terminal:
        assert [line.count("\t") for line in text.splitlines() if not line.startswith("#")] == [6, 6, 6]


# --- the command -----------------------------------------------------------------------------


def test_cli_bodies_in_a_pipe_is_tab_separated(capsys):
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    lines = proc.stdout.decode().splitlines()
    assert lines[0].startswith("# hconv bodies") and lines[2] == "body\tm\tI1\tI2\tI3\tstatus\treason"
    rows = {r.split("\t")[0]: r.split("\t") for r in lines[3:]}
    assert rows["base_link"][1:6] == [
        "4.0",
        "0.016666666666666666",
        "0.016666666666666666",
        "0.02666666666666667",
        "ok",
    ]
    assert rows["forearm_link"][5] == "not_physical" and "sign slip" in rows["forearm_link"][6]


def test_cli_bodies_writes_files_atomically_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "arm.csv"
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), str(out), capsys=capsys)
    assert proc.returncode == 0 and b"7 bodies: 3 ok" in proc.stderr
    assert pacsv.read_csv(out).num_rows == 7
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), str(out), capsys=capsys)
    assert proc.returncode == 4 and b"already exists; pass --force" in proc.stderr
    assert hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), str(out), "--force", "-q", capsys=capsys).stderr == b""
    proc = run_hconv("bodies", str(EXAMPLES / "arm.urdf"), "-", "--to", "csv", "-q")
    assert proc.stdout.startswith(b"body,m,rx,ry,rz,Ixx,")
    proc = hconv_inprocess(
        "bodies", str(EXAMPLES / "arm.urdf"), str(tmp_path / "x.csv"), "--form", "full9", capsys=capsys
    )
    assert proc.returncode == 2 and b"--form must be one of sym6, principal, got 'full9'" in proc.stderr
    assert not (tmp_path / "x.csv").exists()
    proc = hconv_inprocess(
        "bodies", str(EXAMPLES / "arm.urdf"), str(EXAMPLES / "arm.urdf"), "--to", "csv", "--force", capsys=capsys
    )
    assert proc.returncode == 4 and b"is the input file" in proc.stderr


@pytest.mark.parametrize(
    "args, says",
    [
        (("--form", "weird"), "hconv: error: --form must be one of sym6, principal, got 'weird'\n"),
        (
            ("--to", "csv"),
            "hconv: error: --to is for OUT, which is not given; give OUT (- for stdout), or drop it to list the "
            "bodies\n",
        ),
        (("--form", "principal", "--force"), "hconv: error: --form and --force are for OUT, which is not given;"),
    ],
)
def test_cli_bodies_without_out_checks_options_as_with_it(args, says, capsys):
    """Before: without OUT, --form weird and --to csv were ignored, exit 0 and the table."""
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), *args, capsys=capsys)
    assert proc.returncode == 2 and proc.stdout == b""
    assert proc.stderr.decode().startswith(says) and proc.stderr.count(b"\n") == 1


def test_cli_bodies_strict_exits_5_when_a_body_is_not_ok(tmp_path, capsys):
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), "--strict", capsys=capsys)
    assert proc.returncode == 5 and b"4 of 7 bodies are not ok" in proc.stderr and b"forearm_link" in proc.stdout
    proc = hconv_inprocess("bodies", str(EXAMPLES / "arm.urdf"), str(tmp_path / "o.csv"), "--strict", capsys=capsys)
    assert proc.returncode == 5 and b"nothing was written" in proc.stderr and not (tmp_path / "o.csv").exists()
    (tmp_path / "good.urdf").write_text(urdf(urdf_link("a", 1.0, np.diag([0.1, 0.2, 0.25]))))
    assert hconv_inprocess("bodies", str(tmp_path / "good.urdf"), "--strict", capsys=capsys).returncode == 0


def test_cli_bodies_strict_fails_a_model_with_no_bodies(tmp_path, capsys):
    (tmp_path / "empty.xml").write_text("<mujoco><worldbody/></mujoco>")
    proc = hconv_inprocess("bodies", str(tmp_path / "empty.xml"), str(tmp_path / "o.csv"), "--strict", capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 5 and "has no bodies to check (--strict)" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o.csv").exists()
    assert (
        hconv_inprocess("bodies", str(tmp_path / "empty.xml"), capsys=capsys).returncode == 0
    )  # without --strict: listed, 0 bodies


@pytest.mark.parametrize(
    "text", [LAUGHS, "<robot><link name='a'><inertial><mass value='x'/></inertial></link></robot>", "<robot>"]
)
def test_cli_bodies_bad_model_is_one_line_exit_3(tmp_path, text, capsys):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    proc = hconv_inprocess("bodies", str(path), capsys=capsys)
    err = proc.stderr.decode()
    assert proc.returncode == 3 and err.startswith(f"hconv: error: {path}") and err.count("\n") == 1
    assert "Traceback" not in err and proc.stdout == b""


def test_readme_examples_have_the_statuses_the_readme_shows():
    want = {
        "arm.urdf": {
            "base_footprint": "massless",
            "base_link": "ok",
            "shoulder_link": "ok",
            "upper_arm_link": "ok",
            "forearm_link": "not_physical",
            "camera_link": "implausible_density",
            "tool0": "no_inertial",
        },
        "rover.sdf": {
            "chassis": "ok",
            "left_wheel": "ok",
            "right_wheel": "ok",
            "mast": "no_inertial",
            "antenna": "implausible_density",
        },
        "pendulum.xml": {"base": "ok", "upper_link": "ok", "upper_link/body[1]": "ok", "bob": "no_inertial"},
    }
    for name, statuses in want.items():
        got = models.read_model(EXAMPLES / name)
        assert {b.name: b.status for b in got.bodies} == statuses
    rover = by_name(models.read_model(EXAMPLES / "rover.sdf"))
    # both wheels turn the cylinder's axis onto y, one by degrees, one through a frame
    for wheel in ("left_wheel", "right_wheel"):
        assert np.allclose(np.diag(rover[wheel].I_C_B), [0.0027083333333333334, 0.005, 0.0027083333333333334])
    arm = by_name(models.read_model(EXAMPLES / "arm.urdf"))
    assert_tensor(arm["shoulder_link"].I_C_B, np.diag([0.0021875, 0.001875, 0.0021875]), 1e-15)


# --- MuJoCo, the independent reference -------------------------------------------------------


def mujoco_bodies(mujoco, path):
    mj = mujoco.MjModel.from_xml_path(str(path))
    out = {}
    for k in range(1, mj.nbody):
        q = mj.body_iquat[k]
        R = rodrigues_from_quat(q)
        out[k] = (mj.body_mass[k], mj.body_ipos[k].copy(), R @ np.diag(mj.body_inertia[k]) @ R.T, mj.body_inertia[k])
    return out


def rodrigues_from_quat(q):
    q = np.asarray(q) / np.linalg.norm(q)
    th = 2 * math.atan2(np.linalg.norm(q[1:]), q[0])
    axis = q[1:] / np.linalg.norm(q[1:]) if np.linalg.norm(q[1:]) > 0 else np.array([1.0, 0, 0])
    return rodrigues(axis[None], np.array([th]))[0]


@pytest.mark.parametrize("angle, seq", [("degree", "xyz"), ("radian", "XYZ"), ("degree", "zYx"), ("radian", "yzy")])
def test_mujoco_agrees_on_mass_centre_tensor_and_principal_moments(tmp_path, angle, seq):
    mujoco = need("mujoco")
    rng = np.random.default_rng(42)
    scale = 180 / math.pi if angle == "degree" else 1.0
    f = nums
    parts = []
    for k in range(40):
        c = rng.uniform(0.05, 1.0, 3)  # second moments of a random solid: always a valid tensor
        moments = np.array([c[1] + c[2], c[0] + c[2], c[0] + c[1]])
        u, th = axis_angle(rng, 2)
        kind = ["quat", "axisangle", "euler", "xyaxes", "zaxis", "none", "full"][k % 7]
        if kind == "full":
            R = rodrigues(u, th)[0]
            I = R @ np.diag(moments) @ R.T
            spec = f"fullinertia='{f([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}'"
        else:
            spec = (
                f"diaginertia='{f(moments)}'"
                + {
                    "quat": f" quat='{f(quats(u, th)[0])}'",
                    "axisangle": f" axisangle='{f(u[0])} {num(th[0] * scale)}'",
                    "euler": f" euler='{f(rng.uniform(-3, 3, 3) * scale)}'",
                    "xyaxes": f" xyaxes='{f(rng.normal(size=6))}'",
                    "zaxis": f" zaxis='{f(rng.normal(size=3))}'",
                    "none": "",
                }[kind]
            )
        pos = f(rng.normal(size=3))
        parts.append(
            f"<body name='b{k}'><freejoint/><geom size='0.1'/>"
            f"<inertial pos='{pos}' mass='{num(rng.uniform(0.1, 5))}' {spec}/></body>"
        )
    path = tmp_path / "random.xml"
    path.write_text(mjcf("".join(parts), f"<compiler angle='{angle}' eulerseq='{seq}'/>"))
    ours = models.read_model(path).bodies
    theirs = mujoco_bodies(mujoco, path)
    for k, b in enumerate(ours, 1):
        m, ipos, I, moments = theirs[k]
        assert b.status == "ok" and b.m == m
        assert np.allclose(b.p_BC_B, ipos, rtol=0, atol=1e-15)
        assert np.abs(b.I_C_B - I).max() <= 1e-12 * np.trace(I), b.name
        assert np.allclose(b.moments, np.sort(moments), rtol=1e-12, atol=0)


def test_mujoco_agrees_on_the_shipped_example():
    mujoco = need("mujoco")
    ours = [b for b in models.read_model(EXAMPLES / "pendulum.xml").bodies]
    theirs = mujoco_bodies(mujoco, EXAMPLES / "pendulum.xml")
    for k, b in enumerate(ours, 1):
        if b.status == "no_inertial":  # MuJoCo's is inferred from the geom; hconv lists none
            assert theirs[k][0] > 0 and np.isnan(b.m)
            continue
        m, ipos, I, _ = theirs[k]
        assert b.m == m and np.allclose(b.p_BC_B, ipos, rtol=0, atol=1e-15)
        assert np.abs(b.I_C_B - I).max() <= 1e-12 * np.trace(I)


@pytest.mark.parametrize(
    "inertial, ours",
    [
        ("mass='1' diaginertia='0.1 0.1 0.3'", "not_physical"),
        ("mass='1' diaginertia='0 0 0'", "singular"),
        ("mass='1.3' fullinertia='0 0 0 0 2.4e-35 0'", "singular"),
        ("mass='0' diaginertia='0 0 0'", "massless"),
        ("mass='0' diaginertia='0.1 0.1 0.1'", "massless_with_inertia"),
        ("mass='-1' diaginertia='0.1 0.1 0.1'", "negative_mass"),
        ("mass='1' fullinertia='0.1 0.1 0.1 0.2 0 0'", "not_positive_definite"),
        ("mass='1' diaginertia='0.01 0.02 0.025'", "ok"),
        ("mass='0.05' diaginertia='1 1 1'", "implausible_density"),
    ],
)
def test_mujoco_refuses_at_load_what_hconv_flags_but_not_a_placeholder(tmp_path, inertial, ours):
    mujoco = need("mujoco")
    path = tmp_path / "m.xml"
    path.write_text(mjcf(f"<body name='b'><freejoint/><geom size='0.1'/><inertial pos='0 0 0' {inertial}/></body>"))
    assert models.read_model(path).bodies[0].status == ours
    try:
        mujoco.MjModel.from_xml_path(str(path))
        loaded = True
    except ValueError:
        loaded = False
    # MuJoCo checks a moving body's inertia as it loads; a density check is hconv's alone
    assert loaded == (ours in ("ok", "implausible_density"))


def test_readme_bodies_walkthrough_runs_as_written(tmp_path):
    """docs/models.md's sh block and Python block, run from a folder holding examples/."""
    if shutil.which("awk") is None:
        pytest.skip("the walkthrough uses awk")
    section = (EXAMPLES.parent.parent / "docs" / "models.md").read_text()
    sh = section[section.index("```sh\n") + 6 :].split("```", 1)[0]
    py = section[section.index("```python\n") + 10 :].split("```", 1)[0]
    (tmp_path / "examples").symlink_to(EXAMPLES.parent)
    script = f'hconv() {{ "{sys.executable}" -m hconv "$@"; }}\nset -e\n' + sh
    env = dict(os.environ, PYTHONPATH=str(Path(models.__file__).parents[2]))  # this hconv, from any folder
    proc = subprocess.run(["bash", "-c", script], cwd=tmp_path, capture_output=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr.decode()
    t = pacsv.read_csv(tmp_path / "arm-omega.csv")
    got = dict(zip(t.column("body").to_pylist(), t.column("wz").to_pylist()))
    assert got["base_link"] == pytest.approx(0.01 / 0.02666666666666667, rel=1e-15)
    proc = subprocess.run([sys.executable, "-c", py], cwd=tmp_path, capture_output=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr.decode()
    assert pq.read_table(tmp_path / "pendulum-bodies.parquet").column("body").to_pylist()[2] == "upper_link/body[1]"


def test_table_unknown_form_names_the_option(capsys):
    """Before: 'form must be sym6 or principal' on the command line too, not naming --form."""
    from helpers import run_inprocess

    code, _, err = run_inprocess(
        "bodies", str(EXAMPLES / "arm.urdf"), "-", "--to", "csv", "--form", "weird", capsys=capsys
    )
    assert (code, err) == (2, "hconv: error: --form must be one of sym6, principal, got 'weird'\n")
    with pytest.raises(UsageError, match=r"^form must be one of sym6, principal, got 'weird'$"):
        models.read_model(str(EXAMPLES / "arm.urdf")).table(form="weird")
