"""A URDF file checked before Pinocchio reads it, and the parser's own complaints made errors.

Pinocchio's URDF parser (urdfdom) trusts what it reads: a mass of ``nan``, ``inf`` or text is
reported on stderr and the link kept without mass (the robot then weighs what its other links
weigh, and runs); a negative mass or an inertia that is no inertia runs until it breaks down;
a tree of 5,000 links crashes the process; and a mesh named by an absolute path, ``../``,
``file://`` or ``package://`` is read wherever it is (Rerun's URDF loader then copies it into the
recording). ``check_urdf`` reads the XML itself first and refuses, with a ``ModelError`` naming
the file, the element and the value:

* a file that is no regular file (a folder, a FIFO, a device), or larger than
  ``MAX_URDF_BYTES``; XML that does not parse, declares a DOCTYPE (entities) or nests deeper
  than ``MAX_DEPTH``; a root element other than ``<robot>``;
* more than ``MAX_JOINTS`` joints or ``MAX_LINKS`` links: a planar robot has a handful, and
  the mass matrix and the model data grow with the cube of the count;
* a number that is not one finite decimal (``nan``, ``inf``, ``1e400``, text, a missing value)
  in the elements the model is built from: origins, masses, inertias, axes, limits, dynamics,
  geometry sizes, mesh scales; a mass that is not positive; an inertia matrix that is not
  symmetric positive definite, or whose largest principal moment exceeds the sum of the two
  others (no rigid body has it); a zero axis;
* a file named by a ``filename`` attribute (meshes, textures) that does not lie inside the
  scene's folder (``legsim.builders.input_folder``; outside a scene, the URDF's own folder),
  links resolved, or that is no regular file or larger than ``MAX_MESH_BYTES``. ``package://``
  is refused, since Rerun resolves it through ``ROS_PACKAGE_PATH``, outside any folder legsim
  can check; meshes must be STL or OBJ (whose ``mtllib`` and texture maps are held to the same
  rule), the formats whose references legsim can follow.

``parser_messages`` turns what the parser writes to stderr while it builds the model into a
``ModelError``, so that a warning is never left as noise beside a run that goes on.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import sys
import tempfile
import threading
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

import numpy as np

from legsim.builders import input_folder
from legsim.errors import ModelError
from legsim.output.files import file_kind
from legsim.output.untrusted import printable
from legsim.scene.files import inside_folder, read_input_file

#: Largest URDF file read (bytes): a planar robot of ``MAX_JOINTS`` joints with visuals is some 100 kB.
MAX_URDF_BYTES = 4 << 20
#: Largest mesh or texture file a URDF may name (bytes).
MAX_MESH_BYTES = 64 << 20
#: Most joints (of any type, fixed ones included) of a URDF robot: a planar robot has a handful.
MAX_JOINTS = 64
#: Most links: a tree of ``MAX_JOINTS`` joints has one more.
MAX_LINKS = MAX_JOINTS + 1
#: Deepest nesting of XML elements: a URDF's model nests five (robot, link, visual, geometry, mesh).
MAX_DEPTH = 32
#: Relative slack of the triangle inequality of principal moments (a flat body meets it with
#: equality, which decimals rounded to a few digits may miss by a little).
TRIANGLE_SLACK = 1e-3
#: Mesh formats whose references to other files legsim follows.
MESH_SUFFIXES = (".stl", ".obj")

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: Numeric attributes of the elements the model is built from: element -> attribute -> (count,
#: what the value must be: "any", "positive" or "nonnegative").
NUMBERS: dict[str, dict[str, tuple[int, str]]] = {
    "origin": {"xyz": (3, "any"), "rpy": (3, "any")},
    "mass": {"value": (1, "positive")},
    "inertia": {name: (1, "any") for name in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")},
    "axis": {"xyz": (3, "any")},
    "limit": {"lower": (1, "any"), "upper": (1, "any"), "effort": (1, "nonnegative"), "velocity": (1, "nonnegative")},
    "dynamics": {"damping": (1, "nonnegative"), "friction": (1, "nonnegative")},
    "box": {"size": (3, "positive")},
    "cylinder": {"radius": (1, "positive"), "length": (1, "positive")},
    "capsule": {"radius": (1, "positive"), "length": (1, "positive")},
    "sphere": {"radius": (1, "positive")},
    "mesh": {"scale": (3, "any")},
    "color": {"rgba": (4, "any")},
    "mimic": {"multiplier": (1, "any"), "offset": (1, "any")},
    "calibration": {"rising": (1, "any"), "falling": (1, "any")},
    "safety_controller": {
        name: (1, "any") for name in ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity")
    },
}
#: Attributes a URDF element cannot do without (urdfdom keeps a massless link otherwise).
REQUIRED = {"mass": ("value",), "inertia": ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
#: Top-level elements whose content is the model (``<gazebo>`` and ``<transmission>`` hold other
#: tools' settings, which Pinocchio does not read).
MODEL_ELEMENTS = ("link", "joint", "material")


def check_urdf(file: str | os.PathLike[str], folder: Path | None = None) -> None:
    """``ModelError`` naming the file, element and value for anything in the URDF ``file`` that
    legsim will not build a model from (module docstring). Files it names must lie inside
    ``folder`` (default: the scene's folder while a scene is built, else the URDF's own)."""
    path = Path(file)
    raw = read_input_file(path, MAX_URDF_BYTES, "URDF file", ModelError)
    root = _parse(path, raw)
    links = [e for e in root if e.tag == "link"]
    joints = [e for e in root if e.tag == "joint"]
    if len(joints) > MAX_JOINTS or len(links) > MAX_LINKS:
        raise ModelError(
            f"{path}: {len(links)} links and {len(joints)} joints; legsim builds planar robots of at most "
            f"{MAX_LINKS} links and {MAX_JOINTS} joints"
        )
    for element in root:
        if element.tag in MODEL_ELEMENTS:
            where = f"{element.tag} {element.get('name')!r}"
            for child in element.iter():
                _check_numbers(path, where, child)
    for link in links:
        for inertial in link.findall("inertial"):
            _check_inertial(path, f"link {link.get('name')!r}", inertial)
    for joint in joints:
        for axis in joint.findall("axis"):
            if "xyz" in axis.attrib and not np.any(_numbers(axis.get("xyz", ""))):
                raise ModelError(f"{path}: joint {joint.get('name')!r}: <axis xyz={axis.get('xyz')!r}> is zero")
    scene = input_folder()
    allowed = folder or scene or path.parent
    where = "the URDF's folder" if folder is None and scene is None else "the scene's folder"
    for top in root:
        owner = f"{top.tag} {top.get('name')!r}"
        for element in top.iter():
            name = element.get("filename")
            if name is not None:
                _check_file_reference(path, owner, element.tag, name, allowed, where)


def _parse(path: Path, raw: bytes) -> ET.Element:
    """The XML's root element, checked to be a ``<robot>`` nested at most ``MAX_DEPTH`` deep."""
    if b"<!DOCTYPE" in raw or b"<!ENTITY" in raw:
        raise ModelError(f"{path}: the URDF declares a DOCTYPE or entities, which legsim does not read")
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise ModelError(f"{path}: not a URDF file: XML syntax error: {exc}") from None
    level, depth = [root], 1
    while level:
        level = [child for node in level for child in node]
        depth += bool(level)
        if depth > MAX_DEPTH:
            raise ModelError(f"{path}: XML elements nested more than {MAX_DEPTH} deep")
    if root.tag != "robot":
        raise ModelError(f"{path}: not a URDF file: the root element is <{printable(root.tag):.40}>, not <robot>")
    return root


def _numbers(text: str) -> list[float]:
    """The finite decimals of a URDF attribute, or [] when any part is not one."""
    parts = text.split()
    if not parts or not all(_NUMBER.fullmatch(p) for p in parts):
        return []
    values = [float(p) for p in parts]
    return values if all(np.isfinite(values)) else []


def _check_numbers(path: Path, where: str, element: ET.Element) -> None:
    """The numeric attributes of ``element`` (``NUMBERS``): each one or three finite decimals."""
    rules = NUMBERS.get(element.tag, {})
    for key in REQUIRED.get(element.tag, ()):
        if key not in element.attrib:
            raise ModelError(f"{path}: {where}: <{element.tag}> has no {key}")
    for key, (count, sign) in rules.items():
        text = element.get(key)
        if text is None:
            continue
        values = _numbers(text)
        shown = f"<{element.tag} {key}={printable(text, newlines=False)[:60]!r}>"
        if len(values) != count:
            expected = "a finite number" if count == 1 else f"{count} finite numbers"
            raise ModelError(f"{path}: {where}: {shown} is not {expected}")
        if sign == "positive" and min(values) <= 0:
            raise ModelError(f"{path}: {where}: {shown} must be > 0")
        if sign == "nonnegative" and min(values) < 0:
            raise ModelError(f"{path}: {where}: {shown} must be >= 0")


def _check_inertial(path: Path, where: str, inertial: ET.Element) -> None:
    """A link's ``<inertial>``: a mass and an inertia (kg m^2) symmetric positive definite."""
    mass, inertia = inertial.find("mass"), inertial.find("inertia")
    if mass is None or inertia is None:
        missing = "mass" if mass is None else "inertia"
        raise ModelError(f"{path}: {where}: <inertial> has no <{missing}> (urdfdom would keep the link massless)")
    i = {key: _numbers(inertia.get(key, ""))[0] for key in REQUIRED["inertia"]}
    matrix = np.array(
        [[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]], dtype=float
    )
    moments = np.linalg.eigvalsh(matrix)  # ascending principal moments (kg m^2)
    shown = " ".join(f"{k}={inertia.get(k)}" for k in REQUIRED["inertia"])
    if not moments[0] > 0.0:
        raise ModelError(
            f"{path}: {where}: <inertia {shown}> is not positive definite (smallest principal moment "
            f"{moments[0]:.3g} kg m^2): no rigid body has this inertia"
        )
    # Each principal moment is an integral of the squared distance to its axis, so no moment
    # exceeds the sum of the two others; equality is a flat body, reached by rounded decimals
    # of a thin plate or rod, hence the relative slack.
    if moments[0] + moments[1] < moments[2] * (1.0 - TRIANGLE_SLACK):
        raise ModelError(
            f"{path}: {where}: <inertia {shown}> has principal moments {moments[0]:.4g}, {moments[1]:.4g} and "
            f"{moments[2]:.4g} kg m^2: the largest exceeds the sum of the two others, which no rigid body has"
        )


def _check_file_reference(path: Path, owner: str, tag: str, name: str, folder: Path, where: str) -> None:
    """A file the URDF names (``<mesh filename>``, ``<texture filename>``) in its top-level
    element ``owner`` (``link 'body'``) lies inside ``folder``, is a regular file of at most
    ``MAX_MESH_BYTES``, and a mesh is of a format in ``MESH_SUFFIXES``."""
    shown = f"{owner}: <{tag} filename={printable(name, newlines=False)[:200]!r}>"
    parts = urlsplit(name)
    if parts.scheme == "package":
        raise ModelError(
            f"{path}: {shown}: package:// is resolved through ROS_PACKAGE_PATH, outside the scene's folder; "
            f"name the file by a path relative to the URDF"
        )
    if parts.scheme == "file":
        local = unquote(parts.path)
    elif parts.scheme and len(parts.scheme) > 1:  # a one-letter scheme is a Windows drive
        raise ModelError(f"{path}: {shown}: legsim reads only files (a path, or file://), not {parts.scheme}://")
    else:
        local = name
    if "\x00" in local:
        raise ModelError(f"{path}: {shown}: the name contains a NUL character")
    file = inside_folder(folder, os.path.join(os.path.abspath(path.parent), local))
    if file is None:
        raise ModelError(
            f"{path}: {shown} lies outside {where} {folder}; a URDF's meshes and textures must lie in it (links "
            f"resolved)"
        )
    _check_regular(path, shown, file)
    if tag == "mesh":
        if file.suffix.lower() not in MESH_SUFFIXES:
            raise ModelError(
                f"{path}: {shown}: a {file.suffix or 'suffix-less'} mesh; legsim reads {list(MESH_SUFFIXES)} meshes, "
                f"whose references to other files it can check"
            )
        if file.suffix.lower() == ".obj":
            _check_obj_references(path, shown, file, folder, where)


def _check_regular(path: Path, shown: str, file: Path) -> None:
    try:
        info = os.stat(file)
    except FileNotFoundError:
        raise ModelError(f"{path}: {shown}: no such file {file}") from None
    except OSError as exc:
        raise ModelError(f"{path}: {shown}: cannot read {file}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ModelError(f"{path}: {shown}: {file} is not a file (it is {file_kind(info.st_mode)})")
    if info.st_size > MAX_MESH_BYTES:
        raise ModelError(f"{path}: {shown}: {file} is larger than {MAX_MESH_BYTES} bytes, the most a mesh may hold")


#: OBJ and MTL statements that name other files: material libraries and texture maps.
_OBJ_REFERENCES = re.compile(rb"^\s*(mtllib|map_\w+|bump|disp|decal|refl)\s+(.+?)\s*$", re.MULTILINE)


def _check_obj_references(path: Path, shown: str, file: Path, folder: Path, where: str, depth: int = 0) -> None:
    """The files an OBJ mesh names (``mtllib``, and the texture maps of those libraries) lie
    inside ``folder`` too."""
    for match in _OBJ_REFERENCES.finditer(file.read_bytes()):
        # Options of a texture map (``-bm 1 file.png``) come first: the file is the last word.
        name = match.group(2).split()[-1].decode("utf-8", "replace")
        target = inside_folder(folder, os.path.join(file.parent, name))
        if target is None:
            raise ModelError(f"{path}: {shown}: {file.name} names {name!r}, which lies outside {where} {folder}")
        _check_regular(path, f"{shown}: {file.name} names {name!r}", target)
        if match.group(1) == b"mtllib" and depth == 0:
            _check_obj_references(path, shown, target, folder, where, depth + 1)


_capture_lock = threading.Lock()


@contextlib.contextmanager
def parser_messages(file: str | os.PathLike[str]) -> Iterator[None]:
    """Within the block, what is written to the process's stderr (file descriptor 2: urdfdom and
    the mesh loaders print there) is kept; a ``ModelError`` quoting it, naming ``file``, when
    there was any (also in place of an error the block raised: what the parser said is the
    reason). A URDF that draws a warning is refused, not run with what the parser made of it."""
    with _capture_lock, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(sink.fileno(), 2)
        failure: Exception | None = None
        try:
            yield
        except Exception as exc:
            failure = exc
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        sink.seek(0)
        said = sink.read(4096).decode("utf-8", "replace").strip()
    if said:
        # urdfdom follows each message with the line of its own source that printed it.
        lines = " / ".join(
            line.strip() for line in said.splitlines() if line.strip() and not line.strip().startswith("at line ")
        )
        raise ModelError(f"{file}: the URDF parser reported: {printable(lines, newlines=False)}") from failure
    if failure is not None:
        raise failure


def read_geometry(model: Any, file: str | os.PathLike[str], kind: str) -> Any:
    """The ``kind`` ("visual" or "collision") geometry of the URDF ``file`` for its Pinocchio
    ``model`` (a ``pinocchio.GeometryModel``), meshes looked up beside the file; ``ModelError``
    naming the file with what the parser said or raised."""
    import pinocchio as pin

    path = Path(file)
    geometry_type = pin.GeometryType.VISUAL if kind == "visual" else pin.GeometryType.COLLISION
    try:
        with parser_messages(path):
            return pin.buildGeomFromUrdf(model, str(path), geometry_type, package_dirs=[str(path.parent)])
    except ModelError:
        raise
    except Exception as exc:  # Pinocchio's parser raises RuntimeError or ValueError with its reason
        raise ModelError(f"{path}: the {kind} geometry could not be read: {type(exc).__name__}: {exc}") from exc
