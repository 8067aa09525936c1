"""MJCF's compiler settings that change the values MuJoCo simulates with (hconv.tools.mjcf):
``settotalmass``, noted as ``boundmass`` and ``balanceinertia`` are, with the factor MuJoCo
scales by, checked against MuJoCo's own compiled model where it is installed."""

from __future__ import annotations

import math
import re

import numpy as np
from helpers import need

from hconv.tools import models

# A two-link arm on a free base, as MuJoCo's own model files write one: a free joint, hinges,
# rotated inertials, and settotalmass in the compiler.
ARM = """<mujoco model="arm">
  <compiler angle="radian" settotalmass="{total}"{extra}/>
  <worldbody>
    <body name="base" pos="0 0 0.1">
      <freejoint/>
      <inertial pos="0 0 0.02" mass="2.5" diaginertia="0.012 0.011 0.02" quat="0.9 0.1 0 0.4"/>
      <body name="upper" pos="0 0 0.05">
        <joint type="hinge" axis="0 1 0"/>
        <inertial pos="0 0 0.15" mass="1.2" fullinertia="0.0093 0.0093 0.0006 0.0001 0 0.0002"/>
        <body name="fore" pos="0 0 0.3">
          <joint type="hinge" axis="0 1 0"/>
          <inertial pos="0 0 0.12" mass="0.8" diaginertia="0.004 0.004 0.0003"/>
          {geom_body}
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_read_mjcf_settotalmass_is_noted_with_the_factor_mujoco_scales_by(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its deprecation warning to MUJOCO_LOG.TXT here
    path = tmp_path / "arm.xml"
    path.write_text(ARM.format(total=9, extra="", geom_body=""))
    got = models.read_model(path)
    factor = 9 / (2.5 + 1.2 + 0.8)
    assert [b.m for b in got.bodies] == [2.5, 1.2, 0.8]  # the file's values, as under boundmass
    note = [n for n in got.notes if "settotalmass" in n]
    assert len(note) == 1 and "arm.xml, line 2, <compiler>: settotalmass=9: MuJoCo scales" in note[0]
    assert f"= {factor:.6g} (the file's masses add up to 4.5 kg)" in note[0]
    mujoco = need("mujoco")
    mj = mujoco.MjModel.from_xml_path(str(path))
    for k, b in enumerate(got.bodies, 1):
        assert math.isclose(mj.body_mass[k], factor * b.m, rel_tol=1e-14)
        assert np.allclose(np.sort(mj.body_inertia[k]), factor * b.moments, rtol=1e-12, atol=0)


def test_read_mjcf_settotalmass_with_masses_from_geoms_is_noted_without_a_factor(tmp_path, monkeypatch):
    """MuJoCo counts the mass it infers from a geom; hconv cannot, so it gives no factor."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "arm.xml"
    hand = "<body name='hand' pos='0 0 0.25'><joint type='hinge'/><geom type='sphere' size='0.04'/></body>"
    path.write_text(ARM.format(total=9, extra="", geom_body=hand))
    got = models.read_model(path)
    note = " ".join(n for n in got.notes if "settotalmass" in n)
    assert "with those it infers from geoms or raises to a bound, add up to 9 kg" in note
    assert not re.search(r"by 9 / ", note)
    mujoco = need("mujoco")
    mj = mujoco.MjModel.from_xml_path(str(path))
    assert math.isclose(mj.body_mass.sum(), 9, rel_tol=1e-12)


def test_read_mjcf_without_settotalmass_has_no_such_note(tmp_path):
    path = tmp_path / "arm.xml"
    path.write_text(ARM.format(total=-1, extra="", geom_body=""))
    assert not any("settotalmass" in n for n in models.read_model(path).notes)
