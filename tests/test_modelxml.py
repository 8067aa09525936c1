"""MJCF includes as real model trees have them (hconv.tools.modelxml, through hconv.tools.models
and ``hconv bodies``): a model that includes files from a neighbouring folder, as 84 of
metaworld's 86 models do, read within a root folder the user names, and a Windows path in an
include. MuJoCo, where it is installed, is the reference for what the tree holds."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from helpers import hconv_inprocess, need

from hconv.errors import InputError, UsageError
from hconv.tools import models


def inertial(m: float, moments: str) -> str:
    return f"<inertial pos='0 0.01 0' mass='{m}' diaginertia='{moments}'/>"


def metaworld_like(top: Path) -> Path:
    """A tree laid out as metaworld's: the model in sawyer_xyz/, including ../scene/ and
    ../objects/; the scene's own include is relative to the model's folder, as MuJoCo reads it."""
    for d in ("sawyer_xyz", "scene", "objects/assets"):
        (top / d).mkdir(parents=True)
    (top / "scene" / "basic_scene.xml").write_text(
        "<mujocoinclude><include file='../objects/assets/table.xml'/>"
        f"<worldbody><body name='RetainingWall'><freejoint/>{inertial(2.5, '0.1 0.2 0.25')}</body></worldbody>"
        "</mujocoinclude>"
    )
    (top / "objects" / "assets" / "table.xml").write_text(
        f"<mujocoinclude><worldbody><body name='tablelink'><freejoint/>{inertial(20, '1 2 2.5')}</body>"
        "</worldbody></mujocoinclude>"
    )
    model = top / "sawyer_xyz" / "sawyer_reach.xml"
    model.write_text(
        "<mujoco>\n<include file='../scene/basic_scene.xml'/>\n<worldbody>"
        f"<body name='obj'><freejoint/>{inertial(0.75, '8.8e-4 8.8e-4 8.8e-4')}</body></worldbody></mujoco>"
    )
    return model


def test_read_mjcf_include_from_a_neighbouring_folder_is_refused_naming_the_root_that_works(tmp_path):
    model = metaworld_like(tmp_path)
    with pytest.raises(InputError) as e:
        models.read_model(model)
    msg = str(e.value)
    assert "line 2, <include> names '../scene/basic_scene.xml', outside the model's folder" in msg
    assert f"root={str(tmp_path)!r}" in msg and "\n" not in msg


def test_read_mjcf_include_within_the_named_root_agrees_with_mujoco(tmp_path):
    model = metaworld_like(tmp_path)
    got = models.read_model(model, root=tmp_path)
    assert [(b.name, b.m, b.status) for b in got.bodies] == [
        ("tablelink", 20.0, "ok"),
        ("RetainingWall", 2.5, "ok"),
        ("obj", 0.75, "ok"),
    ]
    mujoco = need("mujoco")
    mj = mujoco.MjModel.from_xml_path(str(model))
    for b in got.bodies:
        k = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, b.name)
        assert mj.body_mass[k] == b.m
        assert np.array_equal(np.sort(mj.body_inertia[k]), b.moments)


def test_cli_bodies_root_reads_includes_from_within_it(tmp_path, capsys):
    model = metaworld_like(tmp_path)
    refused = hconv_inprocess("bodies", str(model), capsys=capsys)
    assert refused.returncode == 3
    assert f"give --root {tmp_path} to let includes come from within that folder" in refused.stderr.decode()
    read = hconv_inprocess("bodies", str(model), "--root", str(tmp_path), capsys=capsys)
    assert read.returncode == 0
    assert "tablelink" in read.stdout.decode() and "3 bodies: 3 ok" in read.stdout.decode()


def test_read_mjcf_include_beyond_the_root_by_dots_or_a_link_is_refused(tmp_path):
    model = metaworld_like(tmp_path / "tree")
    (tmp_path / "secret.xml").write_text("<mujocoinclude/>")
    text = model.read_text()
    model.write_text(text.replace("../scene/basic_scene.xml", "../../secret.xml"))
    with pytest.raises(InputError) as e:
        models.read_model(model, root=tmp_path / "tree")
    assert f"outside the root folder {str(tmp_path / 'tree')!r} (root)" in str(e.value)
    # a symbolic link inside the root that leads out of it
    os.symlink(tmp_path / "secret.xml", tmp_path / "tree" / "scene" / "link.xml")
    model.write_text(text.replace("basic_scene.xml", "link.xml"))
    with pytest.raises(InputError) as e:
        models.read_model(model, root=tmp_path / "tree")
    assert f"(a symbolic link to {str(tmp_path / 'secret.xml')!r}), outside the root folder" in str(e.value)


def test_read_model_root_must_be_a_folder_holding_the_model(tmp_path):
    model = metaworld_like(tmp_path / "tree")
    (tmp_path / "other").mkdir()
    with pytest.raises(UsageError, match="does not hold the model's folder"):
        models.read_model(model, root=tmp_path / "other")
    with pytest.raises(UsageError, match="is not a folder"):
        models.read_model(model, root=tmp_path / "none")


def test_cli_bodies_root_on_urdf_or_sdf_is_refused_naming_it(tmp_path, capsys):
    """Before: --root was taken and did nothing for URDF and SDF (hconv reads them from their one
    file, SDF's includes noted, not followed), so a user could believe it had found what their
    includes name. Now it is refused in one line that names it and why, exit 2, as in Python."""
    (tmp_path / "m").mkdir()
    urdf = tmp_path / "m" / "arm.urdf"
    urdf.write_text(
        '<robot name="a"><link name="l"><inertial><mass value="1"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>'
    )
    sdf = tmp_path / "m" / "arm.sdf"
    sdf.write_text(
        '<sdf version="1.9"><model name="a"><include><uri>model://base</uri></include>'
        "<link name='l'><inertial><mass>1</mass><inertia><ixx>1</ixx><iyy>1</iyy><izz>1</izz>"
        "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial></link></model></sdf>"
    )
    for model, why in ((urdf, "URDF has no includes"), (sdf, "SDF is read without its includes")):
        assert hconv_inprocess("bodies", str(model), capsys=capsys).returncode == 0  # without it, read
        got = hconv_inprocess("bodies", str(model), "--root", str(tmp_path), capsys=capsys)
        err = got.stderr.decode().strip()
        assert got.returncode == 2 and "\n" not in err
        assert err == f"hconv: error: {model}: --root is for MJCF includes; {why}: drop --root"
        with pytest.raises(UsageError, match=f"root is for MJCF includes; {why}: drop root$"):
            models.read_model(model, root=tmp_path)


def windows_include(tmp_path: Path, written: str) -> Path:
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "table_dependencies.xml").write_text(
        f"<mujocoinclude><body name='table'><freejoint/>{inertial(3, '0.1 0.1 0.1')}</body></mujocoinclude>"
    )
    model = tmp_path / "m.xml"
    model.write_text(f"<mujoco><worldbody><include file='{written}'/></worldbody></mujoco>")
    return model


def test_read_mjcf_include_with_a_backslash_is_a_folder_separator_as_in_mujoco(tmp_path):
    """MuJoCo (4.0, on Linux) opens assets\\x.xml as assets/x.xml; hconv had said "not found"."""
    model = windows_include(tmp_path, "assets\\table_dependencies.xml")
    got = models.read_model(model)
    assert [(b.name, b.m) for b in got.bodies] == [("table", 3.0)]
    mujoco = need("mujoco")
    assert list(mujoco.MjModel.from_xml_path(str(model)).body_mass) == [0.0, 3.0]


def test_read_mjcf_include_with_a_backslash_not_found_says_how_it_was_read(tmp_path):
    model = windows_include(tmp_path, "assets\\gone.xml")
    with pytest.raises(InputError) as e:
        models.read_model(model)
    msg = str(e.value)
    assert "assets/gone.xml, each backslash read as /, as MuJoCo reads it)" in msg and "\n" not in msg


def test_read_mjcf_nested_include_found_beside_the_including_file_as_mujoco_does(tmp_path):
    """MuJoCo 4.0 looks for an included file's include beside the main model, then beside the
    file that includes it; hconv looked beside the main model only, and said "cannot be read"."""
    model = metaworld_like(tmp_path)
    scene = tmp_path / "scene" / "basic_scene.xml"
    scene.write_text(scene.read_text().replace("../objects/assets/table.xml", "table.xml"))
    (tmp_path / "objects" / "assets" / "table.xml").rename(tmp_path / "scene" / "table.xml")
    got = models.read_model(model, root=tmp_path)
    assert [b.name for b in got.bodies] == ["tablelink", "RetainingWall", "obj"]
    # one beside the main model too: that one is read, as MuJoCo reads it
    (tmp_path / "sawyer_xyz" / "table.xml").write_text(
        f"<mujocoinclude><worldbody><body name='near'><freejoint/>{inertial(7, '1 1 1')}</body>"
        "</worldbody></mujocoinclude>"
    )
    got = models.read_model(model, root=tmp_path)
    assert [b.name for b in got.bodies] == ["near", "RetainingWall", "obj"]
    mujoco = need("mujoco")
    mj = mujoco.MjModel.from_xml_path(str(model))
    assert [mj.body(k).name for k in range(1, mj.nbody)] == ["near", "RetainingWall", "obj"]


def test_cli_bodies_root_in_the_refusal_is_quoted_for_the_shell(tmp_path, capsys):
    model = metaworld_like(tmp_path / "my models")
    refused = hconv_inprocess("bodies", str(model), capsys=capsys)
    assert f"give --root '{tmp_path / 'my models'}' to let" in refused.stderr.decode()


@pytest.mark.parametrize(
    "name, says",
    [
        ("real.xlsx", "is an Excel workbook (.xlsx, a zip of spreadsheet parts), not a model file"),
        ("model.zip", "is a zip archive (unzip it and give the model file inside), not a model file"),
        ("model.urdf.gz", "is gzip-compressed (decompress it first: gzip -dc), not a model file"),
    ],
)
def test_cli_bodies_of_a_zip_or_a_spreadsheet_says_what_it_is(name, says, tmp_path, capsys):
    """Before: a workbook (a zip) was "not well-formed XML (invalid token)"."""
    import gzip
    import zipfile

    path = tmp_path / name
    if name.endswith(".gz"):
        path.write_bytes(gzip.compress(b"<robot name='r'/>"))
    else:
        with zipfile.ZipFile(path, "w") as z:
            if name.endswith(".xlsx"):  # the parts every workbook has
                z.writestr("[Content_Types].xml", "<Types/>")
                z.writestr("xl/workbook.xml", "<workbook/>")
            else:
                z.writestr("robot.urdf", "<robot name='r'/>")
    proc = hconv_inprocess("bodies", str(path), capsys=capsys)
    assert (proc.returncode, proc.stderr.decode()) == (
        3,
        f"hconv: error: {path}: {says}; give a URDF, SDF or MJCF model (XML text)\n",
    )
