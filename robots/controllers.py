"""Controllers bundled with legsim, found by scenes through the ``legsim.controllers`` entry points.

* ``joint_pd``: a joint-space PD with feed-forward gravity compensation on the actuated joints of
  any bridge robot, ``u = kp (q* - q) - kd dq/dt + g(q)`` (N m or N), g the generalised gravity
  of the actuated joints (Pinocchio's, through the native library: exact for a fixed base, the
  legs' own weight for a floating one). Written once, as a ``legsim.control.ControlLaw`` that the
  Python loop and the compiled kernel both evaluate; it keeps no memory.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from legsim.robots._native.calls import lsn_gravity

from legsim.builders import Model, Param
from legsim.compiled.functions import model_function, scratch
from legsim.control import ControlLaw, ControllerSpec
from legsim.errors import SceneError

from .control_laws import pd_torque

#: The joint PD's parameter array: the robot's native handle, nv, whether g(q) is added (1.0),
#: kp (N m/rad), kd (N m s/rad), the number of actuated joints, then per joint (in the input's
#: order) its velocity index and its target (rad or m).
PD_HANDLE, PD_N, PD_GRAVITY, PD_KP, PD_KD, PD_COUNT = range(6)
PD_HEAD = 6


@model_function
def joint_pd_control(t, x, m, p, u):
    """The joint PD's input into u (one entry per actuated joint) at the plant's state x
    (module docstring)."""
    n = int(p[PD_N])
    gravity = scratch(n)
    gravity[:] = 0.0
    if p[PD_GRAVITY] != 0.0:
        lsn_gravity(np.int64(p[PD_HANDLE]), x.ctypes.data, gravity.ctypes.data)
    for i in range(int(p[PD_COUNT])):
        k = int(p[PD_HEAD + 2 * i])
        u[i] = pd_torque(p[PD_KP], p[PD_KD], p[PD_HEAD + 2 * i + 1], x[k], x[n + k]) + gravity[k]


def bridge_of(model: Model, controller: str) -> Any:
    """The ``ContactBridge`` of a model (``Model.info["bridge"]``), or SceneError."""
    bridge = model.info.get("bridge") if isinstance(model.info, dict) else None
    if bridge is None:
        raise SceneError(
            f"controller '{controller}' drives Pinocchio robots (a model with info['bridge']); "
            f"{model.system.name} is not one"
        )
    return bridge


def joint_pd(bridge: Any, kp: float, kd: float, targets: Any, gravity: bool, hold: bool = False) -> ControlLaw:
    """The joint PD on ``bridge``'s actuated joints (module docstring): gains kp (N m/rad) and kd
    (N m s/rad), one target per actuated joint (rad or m), g(q) added with ``gravity``."""
    dofs = bridge.actuated_dofs
    targets = np.asarray(targets, dtype=float).reshape(-1)
    if targets.shape != dofs.shape:
        raise SceneError(f"joint_pd: {dofs.size} actuated joints but {targets.size} targets")
    params = np.array(
        [bridge.handle, bridge.n, float(gravity), kp, kd, dofs.size]
        + [v for k, target in zip(dofs, targets, strict=True) for v in (k, target)],
        dtype=float,
    )
    return ControlLaw("joint_pd", joint_pd_control, int(dofs.size), SameParams(params), hold=hold)


class SameParams:
    """A controller's ``params(mode)`` that is the same array in every mode."""

    def __init__(self, params: np.ndarray) -> None:
        self.params = params

    def __call__(self, mode: str) -> np.ndarray:
        return self.params


def _make_joint_pd(model: Model, params: dict[str, Any]) -> ControlLaw:
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
    return joint_pd(bridge, params["kp"], params["kd"], targets, params["gravity"])


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
