"""Why a spring-legged robot's run left its model's range, at the last state before it: the
run's message then names the leg (``legsim.model.ModeFunctions.range_note``). The model
functions answer nan where a hip goes below the ground, or where a leg's foot, swung to its
flight angle, lies below the ground moving down (``events.leg_touchdown``, ``events.leg_liftoff``);
the note measures both.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .contacts import LegFrames
from .model import BridgeModel
from .modes import ModeSpec

#: A stance leg this share of its rest length short of it counts as lifting off (its foot then
#: swings to the flight angle).
LIFTING_SHARE = 1e-3


class LegsNote:
    """``note(x) -> str``: ``head``, then the lowest hip and every foot below the ground moving
    down that the model reads (a flight leg's, or a stance leg's at its liftoff), with heights
    (m) and vertical velocities (m/s), at the mode's state x."""

    def __init__(self, model: BridgeModel, data: pin.Data, spec: ModeSpec, head: str) -> None:
        self.model, self.data, self.spec, self.head = model, data, spec, head

    def __call__(self, x: np.ndarray) -> str:
        x = np.asarray(x, dtype=float)
        n = self.model.n
        pin.forwardKinematics(self.model.pin_model, self.data, x[:n], x[n : 2 * n])
        legs = self.spec.springs + self.spec.flight_legs
        hips = {lg.leg.name: self._height(lg.hip_id, lg.leg.ground) for lg in legs}
        lowest = min(hips, key=lambda name: hips[name][0])
        found = [f"lowest hip: leg '{lowest}', {_moving(*hips[lowest], 'above')}"]
        footholds = {lg.leg.name: x[2 * n + i] for i, lg in enumerate(self.spec.springs)}
        for lg in legs:
            z, vz = self._height(lg.foot_id, lg.leg.ground)
            foothold = footholds.get(lg.leg.name)
            if z < 0.0 and vz < 0.0 and (foothold is None or self._lifting(lg, foothold)):
                when = "in flight" if foothold is None else "swung to its flight angle at liftoff"
                found.append(f"leg '{lg.leg.name}': its foot {when}, {_moving(-z, vz, 'below')}")
        return f"{self.head}; at the last state before it, {'; '.join(found)}"

    def _height(self, frame: int, ground: float) -> tuple[float, float]:
        """Frame ``frame``'s height above ``ground`` (m) and vertical velocity (m/s)."""
        pm, pd = self.model.pin_model, self.data
        z = pin.updateFramePlacement(pm, pd, frame).translation[2]
        vz = pin.getFrameVelocity(pm, pd, frame, pin.LOCAL_WORLD_ALIGNED).linear[2]
        return float(z - ground), float(vz)

    def _lifting(self, lg: LegFrames, foothold: float) -> bool:
        """Whether stance leg lg (its foot at x = foothold) is within LIFTING_SHARE of its rest length."""
        hip = self.data.oMf[lg.hip_id].translation
        length = math.hypot(hip[0] - foothold, hip[2] - lg.leg.ground)
        return length >= (1.0 - LIFTING_SHARE) * lg.leg.rest_length


def _moving(distance: float, velocity: float, side: str) -> str:
    return f"{distance:.3g} m {side} the ground, vertical velocity {velocity:.3g} m/s"
