"""Where a robot's frames are, and how fast they move, at many stored states, for the checks that scan a whole run (feet
past the ground, links below it, the terrain inside a body): one forward-kinematics pass of the
native library per batch of states serves every check, since each check is handed the very same
arrays (``legsim.relaxed.watches.PointsByMode``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pinocchio as pin

from ..frame_points import frame_motions
from ..kept import KeptWhileAlive
from .model import BridgeModel, native_handle, rounds_move


class Placements:
    """The world (x, z) (m) of a growing set of frames: the bridge model's own (``add_frames``)
    and points fixed in its links (``add_points``). A check keeps the columns it was given and
    reads them from ``at``. The frames are placed on a private copy of the model, so that the
    robot's counters (``native.counts``) count the run's own evaluations, not its checks'."""

    def __init__(self, model: BridgeModel) -> None:
        self.model = model
        self._pin = pin.Model(model.pin_model)  # a copy: the model's handle keeps its own counters
        self._handle: int | None = None  # made at the first batch, once every check has its frames
        self._frames: list[int] = []
        self._kept = KeptWhileAlive()

    def add_frames(self, frames: Iterable[int]) -> np.ndarray:
        """The columns of ``at`` that hold the model's frames ``frames`` (ids), in their order."""
        first = len(self._frames)
        self._frames += [int(f) for f in frames]
        self._kept.clear()
        return np.arange(first, len(self._frames))

    def add_points(self, points: Mapping[str, tuple[int, np.ndarray]]) -> np.ndarray:
        """The columns of ``at`` that hold ``points``: by name, a joint and points (k, 3) (m) in
        its frame, all in their order."""
        marked = pin.Model(self._pin)
        frames = [
            marked.addFrame(pin.Frame(f"point {i} of {name}", joint, pin.SE3(np.eye(3), p), pin.FrameType.OP_FRAME))
            for name, (joint, rows) in points.items()
            for i, p in enumerate(np.asarray(rows, dtype=float))
        ]
        self._pin, self._handle = marked, None
        return self.add_frames(frames)

    def _native(self) -> int:
        """The handle of the private copy: the model's own frames placed as the model's handle
        places them (round contacts' offsets and all), and the added points."""
        if self._handle is None:
            m = self.model
            self._handle = native_handle(self._pin, m.name, m.round_offsets, rounds_move(m.terrain))
        return self._handle

    def at(self, states: np.ndarray) -> np.ndarray:
        """Every frame's world (x, z) (m) at each state, (rows, frames, 2); states (rows, >= 2 n)."""
        return self._motions(states)[:, :, :2]

    def velocities(self, states: np.ndarray) -> np.ndarray:
        """Every frame's world velocity (vx, vz) (m/s) at each state, as ``at``: the same pass."""
        return self._motions(states)[:, :, 2:]

    def _motions(self, states: np.ndarray) -> np.ndarray:
        """(rows, frames, 4): x, z, vx, vz. A batch of several states is kept while the array
        lives: each check is asked about every mode's batch in turn, and reads it again."""
        kept = self._kept.get(states)
        if kept is not None:
            return kept
        rows = np.ascontiguousarray(np.atleast_2d(states), dtype=float)
        out = np.empty((rows.shape[0], len(self._frames), 4))
        if self._frames:
            frame_motions(self._native(), rows, self.model.n, np.array(self._frames, dtype=float), out)
        self._kept.keep(states, out)
        return out
