"""A URDF reached through a scene is held to the scene's rules (robots/urdf_checks.py): physical
data checked before Pinocchio reads it, urdfdom's warnings made errors, a bounded size, and
meshes only from the scene's own folder. Every error names the file, the element and the value."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pinocchio as pin
import pytest
from legsim.robots import urdf
from legsim.robots.urdf_checks import MAX_JOINTS, check_urdf, parser_messages

from helpers.reliability import run_cli
from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene

QUADRUPED = urdf.bundled("quadruped.urdf").read_text()
STAND = urdf.bundled("quadruped_stand.toml").read_text()
#: The bundled quadruped's mass (kg): a 5 kg body and two legs of 0.4 + 0.15 kg.
MASS = 6.1


def scene_folder(root: Path, urdf_text: str, scene_text: str = STAND) -> Path:
    """``root/scene/`` holding the standing quadruped's scene (0.05 s) and ``urdf_text`` as its URDF."""
    folder = root / "scene"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "quadruped.urdf").write_text(urdf_text)
    path = folder / "stand.toml"
    path.write_text(scene_text.replace("t_final = 2.0", "t_final = 0.05"))
    return path


@pytest.mark.parametrize(
    "value, message",
    [
        ("nan", r"link 'body': <mass value='nan'> is not a finite number"),
        ("inf", r"link 'body': <mass value='inf'> is not a finite number"),
        ("heavy", r"link 'body': <mass value='heavy'> is not a finite number"),
        ("1e400", r"link 'body': <mass value='1e400'> is not a finite number"),
        ("-5.0", r"link 'body': <mass value='-5.0'> must be > 0"),
        ("0", r"link 'body': <mass value='0'> must be > 0"),
    ],
)
def test_a_mass_that_is_no_mass_is_refused_naming_file_link_and_value(tmp_path, value, message):
    # urdfdom reports nan and text on stderr and keeps the body massless: the robot weighed 1.1 kg.
    file = tmp_path / "q.urdf"
    file.write_text(QUADRUPED.replace('<mass value="5.0"/>', f'<mass value="{value}"/>'))
    with pytest.raises(ModelError, match=rf"^{file}: {message}"):
        urdf.load_model(file)


@pytest.mark.parametrize(
    "old, new, message",
    [
        ('iyy="0.45"', 'iyy="-0.45"', r"<inertia ixx=0.02 .* iyy=-0.45 .*> is not positive definite"),
        ('ixy="0"', 'ixy="0.5"', r"<inertia ixx=0.02 ixy=0.5 .*> is not positive definite"),
        (
            'izz="0.45"',
            'izz="0.9"',
            r"<inertia ixx=0.02 .* izz=0.9> has principal moments 0.02, 0.45 and 0.9 kg m\^2: the largest exceeds",
        ),
        ('<inertia ixx="0.02" ', "<inertia ", r"<inertia> has no ixx"),
        ('<mass value="5.0"/>', "", r"<inertial> has no <mass>"),
    ],
)
def test_an_inertia_that_no_rigid_body_has_is_refused(tmp_path, old, new, message):
    file = tmp_path / "q.urdf"
    file.write_text(QUADRUPED.replace(old, new, 1))
    with pytest.raises(ModelError, match=rf"^{file}: link 'body': {message}"):
        urdf.load_model(file)


@pytest.mark.parametrize("izz", ["0.47", "0.4704"])
def test_a_flat_body_meets_the_triangle_inequality_with_equality_and_is_kept(tmp_path, izz):
    # A flat plate in the (x, y) plane has izz = ixx + iyy exactly (0.47 here); 0.4704 is that sum
    # rounded up in its fourth digit, within TRIANGLE_SLACK.
    file = tmp_path / "q.urdf"
    file.write_text(QUADRUPED.replace('izz="0.45"', f'izz="{izz}"', 1))
    model, _ = urdf.load_model(file)
    assert model.inertias[1].inertia[2, 2] == pytest.approx(float(izz))


def test_a_scene_with_a_massless_body_is_refused_before_the_run(tmp_path):
    scene = scene_folder(tmp_path, QUADRUPED.replace('<mass value="5.0"/>', '<mass value="nan"/>'))
    code, out, err = run_cli("run", scene, "--rrd", tmp_path / "scene" / "out.rrd")
    assert code == 2 and out == ""
    assert err.startswith(f"legsim: error: {scene}: robot 'urdf' could not be built: ")
    assert "quadruped.urdf: link 'body': <mass value='nan'> is not a finite number" in err
    assert not (tmp_path / "scene" / "out.rrd").exists()
    # The unchanged URDF weighs what its masses add up to.
    model = load_scene(scene_folder(tmp_path / "good", QUADRUPED)).model.info["bridge"].model
    assert pin.computeTotalMass(model) == pytest.approx(MASS, rel=1e-12)


def test_what_urdfdom_warns_about_is_an_error_not_stderr_noise(tmp_path, capfd):
    # An unknown geometry made urdfdom drop the body's whole link, inertia included: 1.1 kg.
    file = tmp_path / "q.urdf"
    file.write_text(QUADRUPED.replace('<box size="0.8 0.2 0.1"/>', '<blob size="1"/>'))
    with pytest.raises(ModelError, match=rf"^{file}: the URDF parser reported: Error: +Unknown geometry type 'blob'"):
        urdf.load_model(file)
    assert capfd.readouterr().err == ""


def test_parser_messages_keeps_what_is_written_to_file_descriptor_2(tmp_path, capfd):
    with (
        pytest.raises(ModelError, match=r"^robot.urdf: the URDF parser reported: Warning: odd / more$"),
        parser_messages("robot.urdf"),
    ):
        os.write(2, b"Warning: odd\n   at line 3 in parser.cpp\nmore\n")
    with parser_messages("robot.urdf"):
        pass
    assert capfd.readouterr().err == ""


def chain(links: int) -> str:
    """A planar chain of ``links`` links joined by revolute joints about y."""
    inertial = '<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>'
    parts = ['<?xml version="1.0"?>', '<robot name="chain">', f'<link name="l0">{inertial}</link>']
    for i in range(1, links):
        parts.append(
            f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/>'
            f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        )
        parts.append(f'<link name="l{i}">{inertial}</link>')
    return "\n".join([*parts, "</robot>"])


def test_a_5000_link_urdf_is_refused_cleanly_where_pinocchio_crashed(tmp_path):
    # Pinocchio's parser crashed on it (exit 139): a fresh process, so that a crash fails this test only.
    file = tmp_path / "chain.urdf"
    file.write_text(chain(5000))
    script = textwrap.dedent(f"""
        from legsim.robots import urdf
        from legsim.errors import ModelError
        try:
            urdf.load_model({str(file)!r})
        except ModelError as exc:
            print(exc)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == (
        f"{file}: 5000 links and 4999 joints; legsim builds planar robots of at most "
        f"{MAX_JOINTS + 1} links and {MAX_JOINTS} joints\n"
    )


def test_no_model_is_built_past_the_joint_bound(tmp_path, monkeypatch):
    at_bound, past = tmp_path / "at.urdf", tmp_path / "past.urdf"
    at_bound.write_text(chain(MAX_JOINTS + 1))
    past.write_text(chain(MAX_JOINTS + 2))
    model, names = urdf.load_model(at_bound, root="fixed")
    assert model.njoints == MAX_JOINTS + 1 and len(names) == MAX_JOINTS

    def never(*args):
        raise AssertionError("Pinocchio asked to build a model past the bound")

    monkeypatch.setattr(pin, "buildModelFromUrdf", never)
    with pytest.raises(ModelError, match=r"66 links and 65 joints; legsim builds planar robots of at most 65 links"):
        urdf.load_model(past, root="fixed")


SECRET = b"solid secret\n" + b"a user's own mesh, outside the scene" * 20


def stl(path: Path, payload: bytes = b"") -> Path:
    """A one-triangle binary STL (with ``payload`` in its 80-byte header's place when given)."""
    import struct

    header = (payload or b"legsim test mesh").ljust(80, b" ")[:80]
    triangle = struct.pack("<12f", 0, 1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 0.1)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(header + struct.pack("<I", 1) + triangle + b"\0\0" + payload)
    return path


@pytest.mark.parametrize("kind", ["parent", "absolute", "file_url", "package", "link_out", "http"])
def test_a_mesh_outside_the_scenes_folder_never_reaches_an_output(tmp_path, kind):
    secret = stl(tmp_path / "outside" / "secret.stl", SECRET)
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "link.stl").symlink_to(secret)
    name = {
        "parent": "../outside/secret.stl",
        "absolute": str(secret),
        "file_url": f"file://{secret}",
        "package": "package://outside/secret.stl",
        "link_out": "link.stl",
        "http": "https://example.com/secret.stl",
    }[kind]
    scene = scene_folder(tmp_path, QUADRUPED.replace('<box size="0.8 0.2 0.1"/>', f'<mesh filename="{name}"/>'))
    code, _, err = run_cli("run", scene, "--rrd", folder / "out.rrd", "--html", folder / "out.html")
    assert code == 2, err
    assert "quadruped.urdf: link 'body': <mesh filename=" in err and name in err
    assert sorted(p.name for p in folder.iterdir()) == ["link.stl", "quadruped.urdf", "stand.toml"]


def test_a_mesh_inside_the_scenes_folder_is_drawn(tmp_path):
    folder = tmp_path / "scene"
    stl(folder / "meshes" / "torso.stl")
    scene = scene_folder(
        tmp_path, QUADRUPED.replace('<box size="0.8 0.2 0.1"/>', '<mesh filename="meshes/torso.stl"/>')
    )
    code, _, err = run_cli("run", scene, "--rrd", folder / "out.rrd", "--quiet")
    assert code == 0, err
    assert b"legsim test mesh" in (folder / "out.rrd").read_bytes()


def test_an_obj_mesh_may_not_name_a_material_library_outside(tmp_path):
    folder = tmp_path / "scene"
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.mtl").write_text("newmtl m\n")
    folder.mkdir()
    (folder / "torso.obj").write_text("mtllib ../outside/secret.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    file = folder / "quadruped.urdf"
    file.write_text(QUADRUPED.replace('<box size="0.8 0.2 0.1"/>', '<mesh filename="torso.obj"/>'))
    with pytest.raises(ModelError, match=r"torso.obj names '../outside/secret.mtl', which lies outside"):
        check_urdf(file)


def test_a_urdf_that_is_a_folder_fifo_or_device_is_named_as_such(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    os.mkfifo(folder / "pipe.urdf")
    (folder / "dir.urdf").mkdir()
    for name, kind in (("pipe.urdf", "a FIFO"), ("dir.urdf", "a directory")):
        path = folder / "stand.toml"
        path.write_text(STAND.replace('file = "quadruped.urdf"', f'file = "{name}"'))
        with pytest.raises(SceneError, match=rf"robot.parameters.file: '{name}' is not a file: it is {kind}$"):
            load_scene(path)
    with pytest.raises(ModelError, match=r"pipe.urdf: not a URDF file \(it is a FIFO\)$"):
        urdf.load_model(folder / "pipe.urdf")
    with pytest.raises(ModelError, match=r"^/dev/null: not a URDF file \(it is a character device\)$"):
        urdf.load_model("/dev/null")


def test_a_urdf_outside_the_scenes_folder_is_refused(tmp_path):
    outside = tmp_path / "outside" / "q.urdf"
    outside.parent.mkdir()
    outside.write_text(QUADRUPED)
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "link.urdf").symlink_to(outside)
    for value in ("../outside/q.urdf", str(outside), "link.urdf"):
        path = folder / "stand.toml"
        path.write_text(STAND.replace('file = "quadruped.urdf"', f'file = "{value}"'))
        with pytest.raises(SceneError, match=r"robot.parameters.file: '.*' lies outside the scene's folder"):
            load_scene(path)


@pytest.mark.parametrize(
    "text, message",
    [
        ("not xml at all", r"not a URDF file: XML syntax error"),
        ('<?xml version="1.0"?><scene/>', r"not a URDF file: the root element is <scene>, not <robot>"),
        ('<!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="r"/>', r"the URDF declares a DOCTYPE or entities"),
        ("<robot>" + "<a>" * 40 + "</a>" * 40 + "</robot>", r"XML elements nested more than 32 deep"),
    ],
)
def test_a_file_that_is_no_urdf_is_named(tmp_path, text, message):
    file = tmp_path / "q.urdf"
    file.write_text(text)
    with pytest.raises(ModelError, match=rf"^{file}: {message}"):
        check_urdf(file)


def test_a_urdf_larger_than_the_bound_is_refused_unread(tmp_path):
    file = tmp_path / "q.urdf"
    file.write_text(QUADRUPED + "<!--" + "x" * (4 << 20) + "-->")
    with pytest.raises(ModelError, match=rf"^{file}: larger than 4194304 bytes, the most a URDF file may hold$"):
        check_urdf(file)
