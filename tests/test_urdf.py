"""URDF links that MuJoCo fuses when it loads the file (hconv.tools.urdf): links joined by fixed
joints become part of the link they are fixed to, changing its mass and inertia; hconv lists the
file's links and notes what MuJoCo makes of them. MuJoCo, loading the same file, is the reference."""

from __future__ import annotations

import math

import numpy as np
from helpers import need

from hconv.tools import models

# One leg of a Unitree A1 as its URDF writes it: the calf (0.166 kg) with a foot (0.06 kg) fixed
# to it, a massless frame fixed to the foot and a pad (0.02 kg) to that; the trunk is the root, and an imu is
# fixed to it. Inertials and joints are rotated, so that the fused tensor needs every frame.
A1_LEG = """<?xml version="1.0"?>
<robot name="a1">{extension}
  <link name="trunk"><inertial><origin xyz="0.0127 0.0018 0.0007" rpy="0 0 0"/><mass value="4.714"/>
    <inertia ixx="0.0168" ixy="-0.00024" ixz="0.00017" iyy="0.0566" iyz="-4.2e-05" izz="0.0649"/></inertial></link>
  <link name="imu_link"><inertial><mass value="0.001"/>
    <inertia ixx="1e-07" ixy="0" ixz="0" iyy="1e-07" iyz="0" izz="1e-07"/></inertial></link>
  <joint name="imu_joint" type="fixed"><parent link="trunk"/><child link="imu_link"/></joint>
  <link name="FR_thigh"><inertial><origin xyz="-0.0033 0.0222 -0.0274"/><mass value="1.013"/>
    <inertia ixx="0.0055" ixy="-1e-05" ixz="0.00034" iyy="0.0051" iyz="-2.2e-05" izz="0.0013"/></inertial></link>
  <joint name="FR_thigh_joint" type="revolute"><parent link="trunk"/><child link="FR_thigh"/>
    <origin xyz="0.183 -0.1311 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="4" effort="33" velocity="21"/></joint>
  <link name="FR_calf"><inertial><origin xyz="0.0067 -0.0004 -0.1415" rpy="0.1 0 0"/><mass value="0.166"/>
    <inertia ixx="0.0029" ixy="0" ixz="-0.00012" iyy="0.0029" iyz="0" izz="3.2e-05"/></inertial></link>
  <joint name="FR_calf_joint" type="revolute"><parent link="FR_thigh"/><child link="FR_calf"/>
    <origin xyz="0 0 -0.2"/><axis xyz="0 1 0"/><limit lower="-2.7" upper="-0.9" effort="33" velocity="21"/></joint>
  <link name="FR_foot"><inertial><origin xyz="0.001 0 0.002" rpy="0 0.3 0.2"/><mass value="0.06"/>
    <inertia ixx="9.6e-06" ixy="0" ixz="0" iyy="9.6e-06" iyz="0" izz="1.2e-05"/></inertial></link>
  <joint name="FR_foot_fixed" type="fixed"><parent link="FR_calf"/><child link="FR_foot"/>
    <origin xyz="0 0 -0.2" rpy="0.2 -0.1 0.4"/></joint>
  <link name="FR_toe_frame"/>
  <joint name="FR_toe_fixed" type="fixed"><parent link="FR_foot"/><child link="FR_toe_frame"/>
    <origin xyz="0 0 -0.02" rpy="0 0.5 0"/></joint>
  <link name="FR_toe_pad"><inertial><origin xyz="0.01 0 0" rpy="0.3 0 0"/><mass value="0.02"/>
    <inertia ixx="2e-06" ixy="0" ixz="0" iyy="3e-06" iyz="0" izz="4e-06"/></inertial></link>
  <joint name="FR_pad_fixed" type="fixed"><parent link="FR_toe_frame"/><child link="FR_toe_pad"/>
    <origin xyz="0.01 0.02 -0.01" rpy="0 0 0.7"/></joint>
</robot>
"""


def mujoco_bodies(path) -> dict[str, tuple[float, np.ndarray]]:
    mujoco = need("mujoco")
    mj = mujoco.MjModel.from_xml_path(str(path))
    return {mj.body(k).name: (float(mj.body_mass[k]), np.sort(mj.body_inertia[k])) for k in range(1, mj.nbody)}


def test_read_urdf_fixed_links_fused_by_mujoco_are_noted_with_the_fused_body(tmp_path):
    """Before: FR_calf was listed at 0.166 kg without a word, and MuJoCo has 0.226 kg."""
    path = tmp_path / "a1.urdf"
    path.write_text(A1_LEG.format(extension=""))
    got = {b.name: b for b in models.read_model(path).bodies}
    assert got["FR_calf"].m == 0.166  # the file's value
    calf = got["FR_calf"].reason
    assert calf.startswith("MuJoCo fuses 'FR_foot', 'FR_toe_frame', 'FR_toe_pad' into it (fixed joints; fusestatic")
    fused_m = float(calf.split("there m = ")[1].split(" kg")[0])
    fused_moments = [float(x) for x in calf.split("I1, I2, I3 = ")[1].split(" kg·m²")[0].split(", ")]
    for name in ("FR_foot", "FR_toe_frame", "FR_toe_pad"):
        assert "MuJoCo fuses it into 'FR_calf' (fixed joint" in got[name].reason
    assert "the root, which no joint moves: MuJoCo fuses it, with 'imu_link', into the world" in got["trunk"].reason
    assert "MuJoCo fuses it, with the root 'trunk', into the world" in got["imu_link"].reason
    assert got["FR_thigh"].reason == ""  # a joint moves it, and nothing is fixed to it
    theirs = mujoco_bodies(path)
    assert sorted(theirs) == ["FR_calf", "FR_thigh"]  # the rest fused: into the calf, or the world
    m, moments = theirs["FR_calf"]
    # the note gives four digits
    assert math.isclose(fused_m, m, rel_tol=5e-4) and round(m, 3) == 0.246  # a1's 0.226, and the pad
    assert np.allclose(fused_moments, moments, rtol=5e-4, atol=0)


def test_read_urdf_fusestatic_false_in_the_file_means_no_fusion_notes(tmp_path):
    path = tmp_path / "a1.urdf"
    path.write_text(A1_LEG.format(extension='\n  <mujoco><compiler fusestatic="false"/></mujoco>'))
    got = models.read_model(path).bodies
    assert all("fuses" not in b.reason for b in got)
    assert sorted(mujoco_bodies(path)) == sorted(b.name for b in got)


def test_read_urdf_fused_link_with_collision_but_no_inertial_gives_no_numbers(tmp_path):
    """MuJoCo infers such a link's mass from its collision geoms, which hconv does not."""
    text = A1_LEG.format(extension="").replace(
        '<link name="FR_toe_frame"/>',
        '<link name="FR_toe_frame"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>',
    )
    path = tmp_path / "a1.urdf"
    path.write_text(text)
    calf = {b.name: b for b in models.read_model(path).bodies}["FR_calf"].reason
    assert "what MuJoCo infers from the collision geoms of links without <inertial>" in calf
    assert "there m =" not in calf
    assert mujoco_bodies(path)["FR_calf"][0] > 0.246 + 0.03  # the sphere's inferred mass
