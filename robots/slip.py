"""SLIP: the spring-loaded inverted pendulum, a point mass on one massless spring leg.

State (``flight``): ``(x, z, xd, zd)`` in m and m/s; ``stance`` appends the foothold
``leg_foot_x`` (m). In flight the leg keeps its rest length l at the angle psi from the downward
vertical, pointing forward; touchdown when the foot reaches the ground moving down (guard
``max(foot height, foot vertical velocity)``, m), liftoff when the leg extends back to l
(guard ``max(l - leg length, -extension rate)``, m).

Defaults (m, k, l, g, psi) = (1 kg, 60 N/m, 1 m, 9.81 m/s^2, pi/5) with initial state
(0, 1.1, 3.4, 0): the symmetric pronk of paper 000 Section V-C with its two parallel legs of
30 N/m merged into one, so that, as the paper notes, this SLIP's motion is the pronking gait's.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Builder, Effect, Model, Param

from .bridge import ContactBridge, SpringLeg, add_point_frame
from .pronk import leg_geometry

COORDINATES = ("x", "z")
VELOCITIES = ("xd", "zd")
STATE_NAMES = COORDINATES + VELOCITIES
INITIAL_STATE = {"x": 0.0, "z": 1.1, "xd": 3.4, "zd": 0.0}

PARAMETERS = {
    "m": Param(1.0, "point mass", "kg", low=0.0, low_open=True),
    "k": Param(60.0, "leg stiffness", "N/m", low=0.0, low_open=True),
    "l": Param(1.0, "leg rest length", "m", low=0.0, low_open=True),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
    "psi": Param(
        math.pi / 5,
        "leg angle in flight, from the downward vertical, forward",
        "rad",
        low=-math.pi / 2,
        high=math.pi / 2,
        low_open=True,
        high_open=True,
    ),
}

EFFECTS = {
    "gravity": Effect("gravity g", default_on=True),
    "damping": Effect(
        "viscous damping along the leg in stance (not conservative)",
        parameters={"b": Param(0.5, "leg damping", "N s/m", low=0.0)},
    ),
}


def pinocchio_model(m: float = 1.0, g: float = 9.81) -> pin.Model:
    """A point mass on PX and PZ joints, with the hip frame ``hip`` at the mass."""
    model = pin.Model()
    jx = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    model.appendBodyToJoint(jz, pin.Inertia(m, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "hip", jz, (0.0, 0.0, 0.0))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -g, 0.0, 0.0, 0.0]))
    return model


def make_bridge(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> ContactBridge:
    """The contact bridge for validated builder parameters and the effects switched on."""
    g = params["g"] if "gravity" in effects else 0.0
    b = effects["damping"]["b"] if "damping" in effects else 0.0
    leg = SpringLeg("leg", "hip", params["k"], params["l"], params["psi"], damping=b)
    return ContactBridge(
        pinocchio_model(params["m"], g),
        [leg],
        coordinate_names=COORDINATES,
        velocity_names=VELOCITIES,
        mode_names={(): "flight", ("leg",): "stance"},
        name="slip",
    )


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback."""
    bridge = make_bridge(params, effects)
    x0 = np.array([INITIAL_STATE[n] for n in STATE_NAMES])
    system = bridge.system("flight", x0)

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        x = np.asarray(x, dtype=float)
        parts = {"body": x[None, :2].copy()}
        parts.update(leg_geometry(bridge, mode, x, {"leg": "hip"}))
        return parts

    info = bridge.model_info(parameters=dict(params), effects=dict(effects))
    return Model(
        system=system,
        initial_mode="flight",
        initial_state=dict(INITIAL_STATE),
        geometry=geometry,
        scenery={"ground": np.array([[-2.0, 0.0], [15.0, 0.0]])},
        counters=bridge.counters,
        info=info,
    )


BUILDER = Builder(
    name="slip",
    description="spring-loaded inverted pendulum: point mass on a massless spring leg (flight, stance)",
    parameters=PARAMETERS,
    effects=EFFECTS,
    build=build,
)


def make(parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters and effects)."""
    return BUILDER.make(parameters, effects)


def state(values: dict[str, float] | None = None) -> np.ndarray:
    """A flight state vector from coordinate values (the rest from ``INITIAL_STATE``)."""
    merged = {**INITIAL_STATE, **(values or {})}
    return np.array([merged[n] for n in STATE_NAMES], dtype=float)
