"""Fuzzing URDF files reached through a scene: the standing quadruped's URDF mutated, run with
``legsim run`` in-process (0.02 s of simulated time, a watchdog for hangs).

Each input is the bundled quadruped.urdf with one to four edits: an attribute's value replaced
(nan, inf, text, empty, negative, zero, huge, several numbers), an element removed, duplicated
or renamed, a visual's geometry replaced by a mesh named by any path (inside the scene's folder,
``../``, absolute, ``file://``, ``package://``, a link out of the folder, a folder, a FIFO, a
missing file), its text edited character by character, a chain of 1 to 5,000 links, or elements
nested hundreds deep. It runs in a fresh folder::

    root/scene/     the scene, its URDF, meshes/ok.stl, a FIFO, a link to the secret mesh
    root/outside/   secret.stl, a user's mesh whose bytes must reach no output

Allowed: exit 0, 2 or 3 with no traceback (a crash ends the test run: that is the point);
nothing outside ``root/scene`` created, changed or removed; no temporary file; the secret
mesh's bytes in no output ("files outside read"); and a run that went ahead (exit 0 or 3) built
a robot whose mass is the sum of the URDF's link masses as the test reads them itself (urdfdom
kept a link whose mass it could not read massless: a "silent wrong result"), every inertia one a
rigid body can have (positive definite, no principal moment above the sum of the two others).

The short form runs in CI; the ``slow``-marked long form draws new inputs (``-m slow`` or
``LEGSIM_FULL=1``). Run without xdist to print the outcome counts (docs/reliability.md).
"""

from __future__ import annotations

import json
import os
import struct
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.reliability import FULL, Hang, record, run_cli, snapshot, temporaries, watchdog
from legsim.scene import bundled_dir, load_scene

QUADRUPED = (bundled_dir() / "quadruped.urdf").read_text()
SCENE = (bundled_dir() / "quadruped_stand.toml").read_text().replace("t_final = 2.0", "t_final = 0.02")
SECRET = b"SECRET-MESH-BYTES-legsim-fuzz" * 4
HANG_SECONDS = 120
FUZZER = "URDF files (legsim run)"


def fuzz_settings(examples: int, long: bool) -> settings:
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=not long,
        # a failure of the random long form prints the blob that replays it (@reproduce_failure)
        print_blob=long,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


def stl(payload: bytes) -> bytes:
    """A one-triangle binary STL carrying ``payload`` after its triangle."""
    triangle = struct.pack("<12f", 0, 1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 0.1)
    return b"fuzz mesh".ljust(80, b" ") + struct.pack("<I", 1) + triangle + b"\0\0" + payload


# -- mutations ------------------------------------------------------------------------------------
NUMBER_TEXTS = ["nan", "inf", "-inf", "1e400", "", "heavy", "-1", "0", "-0.0", "1 2", "1 2 3 4", "1e-300", "1e300",
                "0x10", "1_000", " 5 ", "NaN", "+.5", "5.", "-5.0", "1e-12", "2 0 0"]  # fmt: skip
MESHES = ["meshes/ok.stl", "../outside/secret.stl", "{root}/outside/secret.stl", "file://{root}/outside/secret.stl",
          "package://outside/secret.stl", "link.stl", "meshes", "fifo.stl", "meshes/missing.stl",
          "https://example.com/m.stl", "meshes/../meshes/ok.stl", "meshes/ok.STL", "meshes/ok.dae", ""]  # fmt: skip


def elements(root: ET.Element) -> list[tuple[ET.Element, ET.Element]]:
    """(parent, child) of every element below the root."""
    return [(parent, child) for parent in root.iter() for child in parent]


def edit_attribute(draw, root: ET.Element) -> None:
    with_attributes = [e for e in root.iter() if e.attrib]
    element = draw(st.sampled_from(with_attributes))
    key = draw(st.sampled_from(sorted(element.attrib)))
    element.set(key, draw(st.one_of(st.sampled_from(NUMBER_TEXTS), st.text(max_size=8))))


def edit_element(draw, root: ET.Element) -> None:
    parent, child = draw(st.sampled_from(elements(root)))
    action = draw(st.sampled_from(["remove", "duplicate", "rename"]))
    if action == "remove":
        parent.remove(child)
    elif action == "duplicate":
        parent.append(ET.fromstring(ET.tostring(child)))
    else:
        child.tag = draw(st.sampled_from(["link", "joint", "mesh", "blob", "inertial", "visual", "robot"]))


def add_mesh(draw, root: ET.Element) -> None:
    geometries = [g for g in root.iter("geometry")]
    geometry = draw(st.sampled_from(geometries))
    for child in list(geometry):
        geometry.remove(child)
    mesh = ET.SubElement(geometry, "mesh", filename=draw(st.sampled_from(MESHES)))
    if draw(st.booleans()):
        mesh.set("scale", draw(st.sampled_from(["1 1 1", "0.1 0.1 0.1", "nan 1 1", "1 1"])))


def chain(links: int) -> str:
    inertial = '<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>'
    parts = ['<robot name="chain">', f'<link name="body">{inertial}</link>']
    for i in range(1, links):
        parent = "body" if i == 1 else f"l{i - 1}"
        parts.append(
            f'<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        )
        parts.append(f'<link name="l{i}">{inertial}</link>')
    return "".join([*parts, "</robot>"])


@st.composite
def urdf_inputs(draw) -> str:
    """A mutated URDF's text."""
    how = draw(st.sampled_from(["attribute", "attribute", "element", "mesh", "mesh", "text", "chain", "nest"]))
    if how == "chain":
        return chain(draw(st.sampled_from([1, 2, 30, 64, 65, 66, 200, 5000])))
    if how == "nest":
        depth = draw(st.integers(20, 2000))
        return QUADRUPED.replace("</robot>", "<gazebo>" + "<a>" * depth + "</a>" * depth + "</gazebo></robot>")
    if how == "text":
        text = QUADRUPED
        for _ in range(draw(st.integers(1, 4))):
            at = draw(st.integers(0, len(text)))
            action = draw(st.sampled_from(["insert", "delete", "truncate"]))
            if action == "insert":
                text = text[:at] + draw(st.text(min_size=1, max_size=4)) + text[at:]
            elif action == "delete":
                text = text[:at] + text[at + draw(st.integers(1, 30)) :]
            else:
                text = text[:at]
        return text
    root = ET.fromstring(QUADRUPED)
    for _ in range(draw(st.integers(1, 3))):
        {"attribute": edit_attribute, "element": edit_element, "mesh": add_mesh}[how](draw, root)
    return ET.tostring(root, encoding="unicode")


# -- one input ------------------------------------------------------------------------------------
def make_world(root: Path, text: str) -> Path:
    scene, outside = root / "scene", root / "outside"
    (scene / "meshes").mkdir(parents=True)
    outside.mkdir()
    (outside / "secret.stl").write_bytes(stl(SECRET))
    (scene / "meshes" / "ok.stl").write_bytes(stl(b""))
    (scene / "meshes" / "ok.dae").write_text("<COLLADA/>")
    os.mkfifo(scene / "fifo.stl")
    os.symlink(outside / "secret.stl", scene / "link.stl")
    (scene / "quadruped.urdf").write_text(text.replace("{root}", str(root)), encoding="utf-8", errors="surrogatepass")
    path = scene / "stand.toml"
    path.write_text(SCENE)
    return path


def urdf_mass(path: Path) -> float | None:
    """The sum of the URDF's link masses, read by this test (None when it is no such sum)."""
    try:
        root = ET.parse(path).getroot()
        return sum(float(m.get("value")) for link in root.iter("link") for m in link.iterfind("inertial/mass"))
    except (ET.ParseError, TypeError, ValueError):
        return None


def unphysical_inertia(path: Path) -> str | None:
    """The first link whose inertia no rigid body has (not symmetric positive definite, or a
    principal moment above the sum of the two others beyond 1e-3), read by this test."""
    root = ET.parse(path).getroot()
    for link in root.iter("link"):
        for inertia in link.iterfind("inertial/inertia"):
            i = {key: float(inertia.get(key)) for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
            matrix = [[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]]
            moments = np.linalg.eigvalsh(np.array(matrix))
            if not moments[0] > 0.0 or moments[0] + moments[1] < moments[2] * (1.0 - 1e-3):
                return f"link {link.get('name')!r}: principal moments {moments.tolist()} kg m^2"
    return None


def outcome_of(root: Path, scene: Path) -> tuple[str, str]:
    guarded = {k: v for k, v in snapshot(root).items() if not k.startswith("scene")}
    out_rrd, out_html = scene.parent / "out.rrd", scene.parent / "out.html"
    try:
        with watchdog(HANG_SECONDS):
            code, out, err = run_cli("run", scene, "--json", "--rrd", out_rrd, "--html", out_html)
    except Hang as exc:
        return "hangs", str(exc)
    if code not in (0, 2, 3) or "Traceback" in err or "internal error" in err:
        return "tracebacks", f"exit {code}: {err[-2000:]}"
    if code == 2 and not err.startswith("legsim: error: "):
        return "tracebacks", err
    if {k: v for k, v in snapshot(root).items() if not k.startswith("scene")} != guarded:
        return "files lost or changed", err
    if temporaries(root):
        return "temporaries left", str(temporaries(root))
    for output in (out_rrd, out_html):
        if output.exists() and SECRET[:24] in output.read_bytes():
            return "files outside read", f"{output.name} holds the secret mesh"
    if code == 2:
        return "clear errors (exit 2)", err
    import pinocchio as pin

    mass = pin.computeTotalMass(load_scene(scene).model.info["bridge"].model)
    expected = urdf_mass(scene.parent / "quadruped.urdf")
    if expected is None or abs(mass - expected) > 1e-9 * max(1.0, expected):
        return "silent wrong results", f"the robot weighs {mass} kg, its URDF's links {expected} kg"
    unphysical = unphysical_inertia(scene.parent / "quadruped.urdf")
    if unphysical is not None:
        return "silent wrong results", f"the run went ahead with {unphysical}"
    if json.loads(out)["status"] == "finished" and code != 0:
        return "silent wrong results", f"exit {code} for a finished run"
    return "ran (exit 0 or 3)", ""


def check(text: str) -> None:
    with tempfile.TemporaryDirectory(prefix="legsim-fuzz-urdf-") as folder:
        root = Path(folder)
        outcome, detail = outcome_of(root, make_world(root, text))
    record(FUZZER, outcome)
    assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), f"{outcome}: {detail}\n--- URDF:\n{text[:3000]}"


@pytest.mark.skipif(FULL, reason="the long form runs instead")
@fuzz_settings(40, long=False)
@given(urdf_inputs())
def test_fuzzed_urdfs_end_cleanly(text):
    check(text)


@pytest.mark.slow
@fuzz_settings(600, long=True)
@given(urdf_inputs())
def test_fuzzed_urdfs_end_cleanly_long(text):
    check(text)
