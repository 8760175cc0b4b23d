"""Controllers bundled with legsim, found by scenes through the ``legsim.controllers`` entry points.

* ``joint_pd``: a joint-space PD with feed-forward gravity compensation on the actuated joints of
  any bridge robot, ``u = kp (q* - q) - kd dq/dt + g(q)`` (N m or N), g the generalised gravity
  of the actuated joints (``pinocchio.computeGeneralizedGravity``: exact for a fixed base, the
  legs' own weight for a floating one).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Model, Param
from legsim.control import Controller, ControllerSpec, keeps_law
from legsim.errors import SceneError

from .bridge.control_records import CTRL_JOINT_PD
from .control_laws import pd_torque


def bridge_of(model: Model, controller: str) -> Any:
    """The ``ContactBridge`` of a model (``Model.info["bridge"]``), or SceneError."""
    bridge = model.info.get("bridge") if isinstance(model.info, dict) else None
    if bridge is None:
        raise SceneError(
            f"controller '{controller}' drives Pinocchio robots (a model with info['bridge']); "
            f"{model.system.name} is not one"
        )
    return bridge


class JointPD(Controller):
    """``u = kp (q* - q) - kd dq/dt + g(q)`` on the actuated joints (module docstring)."""

    memory_names = ()  # stateless: the orbit search runs it as it is

    def __init__(self, bridge: Any, kp: float, kd: float, targets: np.ndarray, gravity: bool) -> None:
        self.bridge = bridge
        self.dofs = bridge.actuated_dofs
        self.kp, self.kd, self.targets, self.gravity = kp, kd, targets, gravity
        self._data = bridge.model.createData()
        bridge.attach_control(self)

    def __call__(self, mode: str, t: float, x: np.ndarray) -> np.ndarray:
        n = self.bridge.n
        q, v = x[:n], x[n : 2 * n]
        u = np.array([pd_torque(self.kp, self.kd, r, q[k], v[k]) for r, k in zip(self.targets, self.dofs, strict=True)])
        if self.gravity:
            u += pin.computeGeneralizedGravity(self.bridge.model, self._data, q)[self.dofs]
        return u

    def compiled_record(self, pin_model: Any) -> list[float] | None:
        """The control record of the robot's compiled twin (``robots.bridge.control_records.CONTROL_KINDS``:
        ``joint_pd``) when this controller drives ``pin_model``, else None (also for a subclass
        that changes the law, ``__call__``, which the twin would not follow)."""
        if (
            pin_model is not self.bridge.model
            or not keeps_law(self, JointPD, ("__call__",))
            or not np.array_equal(self.dofs, self.bridge.actuated_dofs)  # the twin's joint order
        ):
            return None
        return [float(CTRL_JOINT_PD), self.kp, self.kd, float(self.gravity), *map(float, self.targets)]


class PlainControl:
    """A stateless controller as a plain control ``u(t, x)`` (a robot effect's ``Model.control``)
    that keeps its compiled record (``compiled_record``), so the robot's twin still computes it."""

    def __init__(self, controller: JointPD) -> None:
        self.controller = controller

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        return self.controller("", t, x)

    def compiled_record(self, pin_model: Any) -> list[float] | None:
        """The controller's record (``JointPD.compiled_record``)."""
        return self.controller.compiled_record(pin_model)


def _make_joint_pd(model: Model, params: dict[str, Any]) -> JointPD:
    bridge = bridge_of(model, "joint_pd")
    count = len(bridge.actuated_dofs)
    if not count:
        raise SceneError("controller 'joint_pd': the robot has no actuated joint (robot.parameters.actuated)")
    targets = np.asarray(params["targets"] or [0.0] * count, dtype=float)
    if targets.shape != (count,):
        raise SceneError(
            f"controller.parameters.targets: expected {count} numbers (one per actuated joint), "
            f"got {params['targets']!r}"
        )
    return JointPD(bridge, params["kp"], params["kd"], targets, params["gravity"])


JOINT_PD = ControllerSpec(
    "joint_pd",
    "joint-space PD with feed-forward gravity compensation on the actuated joints",
    {
        "kp": Param(50.0, "stiffness", "N m/rad", low=0.0),
        "kd": Param(2.0, "damping", "N m s/rad", low=0.0),
        "targets": Param([], "target of each actuated joint (rad or m); empty: all 0"),
        "gravity": Param(True, "add the actuated joints' generalised gravity g(q)"),
    },
    _make_joint_pd,
)
