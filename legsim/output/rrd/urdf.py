"""URDF robots as Rerun draws them: the file logged once through Rerun's own URDF loader, the
joints and the planar root moved by a Transform3D per sample.

``rec.log_file_from_path(file, entity_path_prefix="world/robot", static=True)`` logs, statically,
each link's visual shapes (Boxes3D, Cylinders3D, Ellipsoids3D, Mesh3D) under
``/world/robot/<robot>/visual_geometries/<link>/<visual>``, each in its link's named frame
(``CoordinateFrame``: the link's name), and on ``/tf_static`` every joint's transform from its
parent link's frame to its child's at joint value 0. The recorder then logs, per sample:

* ``/world/robot/joints/<joint>``: the transform of every movable joint at its coordinate in
  the state (``rerun.urdf.UrdfJoint.compute_transform_columns``: parent and child frames set);
* ``/world/robot/joints/root``: the root link's frame in the world's (``tf#/world``, the frame
  Rerun derives from the ``/world`` entity): translation (x, 0, z) and a rotation by pitch
  about +y, the planar root (x, z, pitch) of ``robots.urdf``; for a fixed root, the identity,
  statically.

Rerun stores transforms in float32: positions composed from them are exact to some 1e-7
relative, which is what the viewer shows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .layout import ROBOT, WORLD, entity

#: The entity under which the joints' and the root's transforms are logged.
JOINTS = f"{ROBOT}/joints"
ROOT = f"{JOINTS}/root"
#: The frame Rerun derives from the ``/world`` entity, which the 3D view shows.
WORLD_FRAME = f"tf#{WORLD}"
#: Joint types whose transform changes with the state.
MOVABLE = ("revolute", "continuous", "prismatic")

Indexes = Callable[[np.ndarray], list]


class UrdfLogger:
    """Logs a URDF robot: the file once (``start``), its joints and root per block of samples
    (``add``)."""

    def __init__(self, rr: Any, rec: Any, indexes: Indexes, file: str | Path, root: str) -> None:
        from rerun.urdf import UrdfTree

        self.rr, self.rec, self.indexes = rr, rec, indexes
        self.file, self.root = Path(file), root
        self.tree = UrdfTree.from_file_path(self.file)
        self.joints = [joint for joint in self.tree.joints() if joint.joint_type in MOVABLE]
        self.root_link = self.tree.root_link().name
        self.low = np.full(2, np.inf)
        self.high = np.full(2, -np.inf)

    def start(self) -> None:
        """The URDF through Rerun's loader (static geometry and joint frames); a fixed root's
        link placed at the world's origin."""
        self.rec.log_file_from_path(self.file, entity_path_prefix=ROBOT.lstrip("/"), static=True)
        if self.root != "planar":
            transform = self.rr.Transform3D(parent_frame=WORLD_FRAME, child_frame=self.root_link)
            self.rec.log(ROOT, transform, static=True)

    def add(self, rows: np.ndarray, names: Sequence[str], states: np.ndarray) -> None:
        """Log the transforms at the sample ``rows`` of the states (len(rows), len(names)),
        whose coordinates are ``names`` (the root's x, z, pitch and the joints' names)."""
        column = {name: i for i, name in enumerate(names)}
        if self.root == "planar":
            x, z, pitch = (states[:, column[name]] for name in ("x", "z", "pitch"))
            self._root(rows, x, z, pitch)
        for joint in self.joints:
            # The scene's stops, not the URDF's limits, bound the motion: record the state as it is.
            columns = joint.compute_transform_columns(states[:, column[joint.name]].tolist(), clamp=False)
            self.rec.send_columns(entity(JOINTS, joint.name), indexes=self.indexes(rows), columns=columns)

    def _root(self, rows: np.ndarray, x: np.ndarray, z: np.ndarray, pitch: np.ndarray) -> None:
        """The root link's frame in the world's: (x, 0, z) m, turned by ``pitch`` rad about +y."""
        n = len(rows)
        translation = np.zeros((n, 3))
        translation[:, 0], translation[:, 2] = x, z
        quaternion = np.zeros((n, 4))
        quaternion[:, 1], quaternion[:, 3] = np.sin(pitch / 2), np.cos(pitch / 2)
        columns = self.rr.Transform3D.columns(
            translation=translation,
            quaternion=quaternion,
            parent_frame=[WORLD_FRAME] * n,
            child_frame=[self.root_link] * n,
        )
        self.rec.send_columns(ROOT, indexes=self.indexes(rows), columns=columns)
        with np.errstate(invalid="ignore"):
            finite = np.isfinite(x) & np.isfinite(z)
        if finite.any():
            self.low = np.minimum(self.low, [x[finite].min(), z[finite].min()])
            self.high = np.maximum(self.high, [x[finite].max(), z[finite].max()])

    def box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The (x, z) corners of the root's path widened by the robot's reach, or None."""
        if not np.all(np.isfinite(self.low)):
            return None
        return self.low - REACH, self.high + REACH

    def entities(self) -> dict[str, Any]:
        """What ``legsim/meta`` says of the robot: the URDF file, its root link and the
        entities of the transforms per joint."""
        return {
            "file": str(self.file),
            "root": self.root,
            "root_link": self.root_link,
            "joints": {joint.name: entity(JOINTS, joint.name) for joint in self.joints},
        }


#: How far (m) around its root the 3D view's camera shows a URDF robot.
REACH = 0.6


def urdf_source(model: Any) -> dict[str, Any] | None:
    """The URDF file and root of a model built by ``robots.urdf`` (its ``info["urdf"]``), or None."""
    info = getattr(model, "info", None) or {}
    source = info.get("urdf")
    return source if isinstance(source, dict) and source.get("file") else None
