"""The pronking runner of paper 000, Section V-C (Figs. 15-17).

A planar rigid body (mass m, pitch inertia I) moves in the sagittal (x, z) plane under gravity g.
Two massless linear spring legs (stiffness k, rest length l) are hinged at the hips, d/2 behind
(``left``) and d/2 ahead (``right``) of the centre of mass along the body axis. In the air a leg
keeps its rest length and the angle psi from the body's downward normal, pointing forward; when
its foot reaches the ground moving down it is pinned there (the foothold joins the state), and it
lifts off when the leg extends back to its rest length.

State (``aerial``): ``(x, z, theta, xd, zd, thetad)`` in m, m, rad, m/s, m/s, rad/s; ``theta``
is the rotation about +y (Pinocchio's RY joint), so ``theta > 0`` pitches the nose (right hip)
down and the paper's ``theta0 = -0.4`` lifts it, so the left foot lands first. Stance modes
append the footholds ``left_foot_x`` / ``right_foot_x`` (m). Modes: ``aerial``, ``left``,
``right``, ``both``; with one leg switched off, two modes.

Guards (eps in metres): touchdown ``max(foot height, foot vertical velocity)``; liftoff
``max(l - leg length, -leg extension rate)``.

Defaults are the paper's: (m, I, k, l, d, g, psi) = (1, 1, 30, 1, 1, 9.81, pi/5), initial
state (0, 1.1, 0, 3.4, 0, 0), h = 1e-3, eps = 1e-2. ``PITCHED_STATE`` is Fig. 17 (right),
theta0 = -0.4; ``PITCH_RATE_STATE`` the Fig. 16 neighbour with a negative pitch rate.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Builder, Effect, Model, Param

from .bridge import ContactBridge, SpringLeg, add_point_frame, planar_floating_base

COORDINATES = ("x", "z", "theta")
VELOCITIES = ("xd", "zd", "thetad")
STATE_NAMES = COORDINATES + VELOCITIES
LEGS = ("left", "right")

INITIAL_STATE = {"x": 0.0, "z": 1.1, "theta": 0.0, "xd": 3.4, "zd": 0.0, "thetad": 0.0}
PITCHED_STATE = {**INITIAL_STATE, "theta": -0.4}
PITCH_RATE_STATE = {**INITIAL_STATE, "thetad": -0.5}

PARAMETERS = {
    "m": Param(1.0, "body mass", "kg", low=0.0, low_open=True),
    "I": Param(1.0, "body pitch moment of inertia", "kg m^2", low=0.0, low_open=True),
    "k": Param(30.0, "leg stiffness", "N/m", low=0.0, low_open=True),
    "l": Param(1.0, "leg rest length", "m", low=0.0, low_open=True),
    "d": Param(1.0, "distance between the hips", "m", low=0.0),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
    "psi": Param(
        math.pi / 5,
        "leg angle in flight, from the body's downward normal, forward",
        "rad",
        low=-math.pi / 2,
        high=math.pi / 2,
        low_open=True,
        high_open=True,
    ),
}

EFFECTS = {
    "gravity": Effect("gravity g", default_on=True),
    "left_leg": Effect("the rear (left) spring leg", default_on=True),
    "right_leg": Effect("the front (right) spring leg", default_on=True),
    "damping": Effect(
        "viscous damping along the legs in stance (not conservative)",
        parameters={"b": Param(0.5, "leg damping", "N s/m", low=0.0)},
    ),
}

_MODE_NAMES = {(): "aerial", ("left",): "left", ("right",): "right", ("left", "right"): "both"}


def pinocchio_model(m: float = 1.0, I: float = 1.0, d: float = 1.0, g: float = 9.81) -> pin.Model:  # noqa: E741 -- the paper's symbols, also the scene's parameter names
    """The body on a planar floating base (PX, PZ, RY) with hip frames ``hip_left`` and
    ``hip_right`` at -d/2 and +d/2 along the body axis."""
    model = pin.Model()
    body = planar_floating_base(model, names=COORDINATES)
    model.appendBodyToJoint(body, pin.Inertia(m, np.zeros(3), np.diag([I, I, I])), pin.SE3.Identity())
    add_point_frame(model, "hip_left", body, (-0.5 * d, 0.0, 0.0))
    add_point_frame(model, "hip_right", body, (0.5 * d, 0.0, 0.0))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -g, 0.0, 0.0, 0.0]))
    return model


def make_bridge(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> ContactBridge:
    """The contact bridge for validated builder parameters and the effects switched on."""
    g = params["g"] if "gravity" in effects else 0.0
    model = pinocchio_model(params["m"], params["I"], params["d"], g)
    b = effects["damping"]["b"] if "damping" in effects else 0.0
    legs = [
        SpringLeg(side, f"hip_{side}", params["k"], params["l"], params["psi"], damping=b)
        for side in LEGS
        if f"{side}_leg" in effects
    ]
    names = {key: name for key, name in _MODE_NAMES.items() if all(f"{s}_leg" in effects for s in key)}
    return ContactBridge(
        model, legs, coordinate_names=COORDINATES, velocity_names=VELOCITIES, mode_names=names, name="pronk"
    )


def leg_geometry(bridge: ContactBridge, mode: str, x: np.ndarray, hips: dict[str, str]) -> dict[str, np.ndarray]:
    """Polylines of the legs (hip -> foot) and feet (one point) of a spring-legged robot."""
    x = np.asarray(x, dtype=float)
    feet = bridge.foot_positions(mode, x)
    pos = bridge.frame_positions(x[: bridge.n], [hips[leg] for leg in feet])
    parts = {}
    for leg, foot in feet.items():
        parts[f"leg_{leg}"] = np.array([pos[hips[leg]], foot])
        parts[f"foot_{leg}"] = foot[None, :]
    return parts


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback: the runner with only the legs and effects named."""
    bridge = make_bridge(params, effects)
    x0 = np.array([INITIAL_STATE[n] for n in STATE_NAMES])
    initial_mode = bridge.mode_name(())
    system = bridge.system(initial_mode, x0)
    hips = {leg: f"hip_{leg}" for leg in LEGS}

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        x = np.asarray(x, dtype=float)
        pos = bridge.frame_positions(x[:3], ("hip_left", "hip_right"))
        parts = {"body": np.array([pos["hip_left"], pos["hip_right"]]), "com": x[None, :2].copy()}
        parts.update(leg_geometry(bridge, mode, x, hips))
        return parts

    info = bridge.model_info(parameters=dict(params), effects=dict(effects))
    return Model(
        system=system,
        initial_mode=initial_mode,
        initial_state=dict(INITIAL_STATE),
        geometry=geometry,
        scenery={"ground": np.array([[-2.0, 0.0], [15.0, 0.0]])},
        counters=bridge.counters,
        info=info,
    )


BUILDER = Builder(
    name="pronk",
    description="planar runner with two spring legs, pronking with simultaneous touchdowns (paper 000 Figs. 15-17)",
    parameters=PARAMETERS,
    effects=EFFECTS,
    build=build,
)


def make(parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters and effects)."""
    return BUILDER.make(parameters, effects)


def state(values: dict[str, float] | None = None) -> np.ndarray:
    """An aerial state vector from coordinate values (the rest from ``INITIAL_STATE``)."""
    merged = {**INITIAL_STATE, **(values or {})}
    return np.array([merged[n] for n in STATE_NAMES], dtype=float)
