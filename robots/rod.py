"""A rigid rod dropped onto a frictionless floor: the simplest simultaneous impact.

A uniform rod of mass m and length L (inertia m L^2 / 12 about its centre) on a planar floating
base: coordinates ``x``, ``z`` (m, the centre) and ``theta`` (rad, +y: the +x end down), with
rates ``xd``, ``zd``, ``thetad``. Its two ends are point contacts ``a`` (+x end) and ``b`` with
restitution c on a frictionless floor at z = 0 (``legsim.robots.bridge``). Dropped flat, both ends
strike in the same instant: the bridge resolves them under one impact law (``bridge.joint``), so
the rod bounces flat (theta stays 0) and loses the closed-form energy
``(1 - c^2) m v^2 / 2`` per impact, v the vertical speed at impact. Dropped tilted by theta0, the
ends strike one after the other once |theta0| is past what one landing step can cover, and the
outcome is continuous in theta0 in between.

Modes: ``air`` (no contact) and, for c = 0, the resting modes ``a``, ``b``, ``a+b``. With c > 0 the
bounces accumulate and the rod comes to rest in ``a+b`` (Zeno continuation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Builder, Model, Param

from .bridge import ContactBridge, PointContact, add_point_frame, planar_floating_base

PARAMETERS = {
    "mass": Param(1.0, "mass", "kg", low=0.0, low_open=True),
    "length": Param(1.0, "length", "m", low=0.0, low_open=True),
    "restitution": Param(0.5, "coefficient of restitution c of both ends", "", low=0.0, high=1.0),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0, low_open=True),
}
INITIAL_STATE = {"x": 0.0, "z": 1.0, "theta": 0.0, "xd": 0.0, "zd": 0.0, "thetad": 0.0}
COORDINATES = ("x", "z", "theta")
VELOCITIES = ("xd", "zd", "thetad")


def make_bridge(params: dict[str, Any]) -> ContactBridge:
    """The rod as a ``ContactBridge`` with its two ends as frictionless point contacts."""
    m, length = params["mass"], params["length"]
    model = pin.Model()
    body = planar_floating_base(model)
    inertia = m * length * length / 12.0
    model.appendBodyToJoint(body, pin.Inertia(m, np.zeros(3), np.diag([inertia, inertia, inertia])), pin.SE3.Identity())
    add_point_frame(model, "end_a", body, (0.5 * length, 0.0, 0.0))
    add_point_frame(model, "end_b", body, (-0.5 * length, 0.0, 0.0))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -params["g"], 0.0, 0.0, 0.0]))
    c = params["restitution"]
    contacts = [
        PointContact("a", "end_a", restitution=c, tangential=False),
        PointContact("b", "end_b", restitution=c, tangential=False),
    ]
    return ContactBridge(
        model, contacts, coordinate_names=COORDINATES, velocity_names=VELOCITIES, mode_names={(): "air"}, name="rod"
    )


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    bridge = make_bridge(params)
    x0 = np.array([INITIAL_STATE[name] for name in COORDINATES + VELOCITIES])
    system = bridge.system("air", x0)
    half = 0.5 * params["length"]

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        dx, dz = half * math.cos(x[2]), -half * math.sin(x[2])
        return {"rod": np.array([[x[0] - dx, x[1] - dz], [x[0] + dx, x[1] + dz]])}

    info = bridge.model_info()
    return Model(
        system=system,
        initial_mode="air",
        initial_state=dict(INITIAL_STATE),
        geometry=geometry,
        scenery={"floor": np.array([[-1.0, 0.0], [1.0, 0.0]])},
        counters=bridge.counters,
        info=info,
    )


BUILDER = Builder(
    "rod", "a rigid rod dropped on a frictionless floor: simultaneous impacts of its two ends", PARAMETERS, {}, _build
)


def make(parameters: dict[str, Any] | None = None) -> Model:
    """The rod's model with ``parameters`` (defaults: ``PARAMETERS``)."""
    return BUILDER.make(parameters, {})
