"""The SLIP hopper: the SLIP (a point mass on a massless spring leg) whose leg angle in flight
is actuated, so that a controller can place the foot (Raibert's hopper, ``raibert_slip``).

Modes and states:

* ``flight``: ``(x, z, psi, xd, zd)``: the mass's position (m), the leg's angle from the
  downward vertical, forward (rad), the mass's velocity (m/s). Field ``(xd, zd, u, 0, -g)``: the
  input u is the leg's swing rate (rad/s; the leg is massless, so swinging it costs nothing and
  does not move the mass); without control u = 0 and the leg keeps its angle.
* ``stance``: ``(x, z, xd, zd, foot_x)``: the foot pinned at ``(foot_x, 0)``, the spring
  pushing the mass along the leg with ``k (l - r)`` (N); it takes no input.

Transitions: ``touchdown`` when the foot ``z - l cos(psi)`` reaches the ground while the mass
descends (guard: the foot's height, or ``max(height, zd)`` while the mass rises, m), reset
``foot_x = x + l sin(psi)``; ``liftoff`` when the leg is back at rest length while extending
(guard ``max(l - r, -dr/dt)``, m), reset ``psi = asin((foot_x - x) / l)`` (the leg leaves at
its stance angle). Energy ``m (xd^2 + zd^2) / 2 + m g z (+ k (l - r)^2 / 2 in stance)`` is
conserved by both modes and both resets.

Written once as compiled model functions (``legsim.model``), parameters ``p = (m (kg), k (N/m),
l (m), g (m/s^2))`` in both modes: a run without control or under ``raibert_slip`` (a compiled
``ControlLaw``) steps in the compiled kernel.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Builder, Model, Param
from legsim.compiled.functions import model_function
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.model import ModeFunctions

FLIGHT_NAMES = ("x", "z", "psi", "xd", "zd")
STANCE_NAMES = ("x", "z", "xd", "zd", "foot_x")
FLIGHT_UNITS = ("m", "m", "rad", "m/s", "m/s")
STANCE_UNITS = ("m", "m", "m/s", "m/s", "m")
INITIAL_STATE = {"x": 0.0, "z": 1.1, "psi": math.pi / 5, "xd": 3.4, "zd": 0.0}
P_M, P_K, P_L, P_G = range(4)

PARAMETERS = {
    "m": Param(1.0, "point mass", "kg", low=0.0, low_open=True),
    "k": Param(60.0, "leg stiffness", "N/m", low=0.0, low_open=True),
    "l": Param(1.0, "leg rest length", "m", low=0.0, low_open=True),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
}


@model_function
def flight_field(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """(xd, zd, u, 0, -g): the leg swings at the input's rate (rad/s)."""
    dx[0] = x[3]
    dx[1] = x[4]
    dx[2] = u[0]
    dx[3] = 0.0
    dx[4] = -p[P_G]


@model_function
def touchdown_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """The foot's height z - l cos(psi), or max(height, zd) while the mass rises (m)."""
    height = x[1] - p[P_L] * math.cos(x[2])
    g[0] = height if x[4] <= 0.0 else (x[4] if x[4] > height else height)


@model_function
def land(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Touchdown: (x, z, xd, zd, foot_x = x + l sin(psi)), the foot pinned where it lands."""
    out[0] = x[0]
    out[1] = x[1]
    out[2] = x[3]
    out[3] = x[4]
    out[4] = x[0] + p[P_L] * math.sin(x[2])


@model_function
def stance_field(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """(xd, zd, k (l - r) / (m r) d - (0, g), 0) with d = (x - foot_x, z), r = |d|."""
    d0 = x[0] - x[4]
    d1 = x[1]
    r = math.hypot(d0, d1)
    scale = p[P_K] * (p[P_L] - r) / (p[P_M] * r)
    dx[0] = x[2]
    dx[1] = x[3]
    dx[2] = scale * d0
    dx[3] = scale * d1 - p[P_G]
    dx[4] = 0.0


@model_function
def liftoff_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """max(l - r, -dr/dt) (m): past only at rest length while the leg extends."""
    d0 = x[0] - x[4]
    d1 = x[1]
    r = math.hypot(d0, d1)
    short = p[P_L] - r
    extending = -(d0 * x[2] + d1 * x[3]) / r
    g[0] = extending if extending > short else short


@model_function
def leave(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Liftoff: (x, z, psi = asin((foot_x - x) / l), xd, zd), the leg at its stance angle."""
    out[0] = x[0]
    out[1] = x[1]
    out[2] = math.asin(max(-1.0, min(1.0, (x[4] - x[0]) / p[P_L])))
    out[3] = x[2]
    out[4] = x[3]


def make_system(m: float, k: float, l: float, g: float) -> HybridSystem:  # noqa: E741 -- the paper's symbols, also the scene's parameter names
    """The SLIP hopper's hybrid system (module docstring) for mass m (kg), stiffness k (N/m),
    rest length l (m) and gravity g (m/s^2)."""
    params = [m, k, l, g]

    def energy(mode: str, x: np.ndarray) -> float:
        if mode == "flight":
            return m * (0.5 * (x[3] ** 2 + x[4] ** 2) + g * x[1])
        r = math.hypot(x[0] - x[4], x[1])
        return m * (0.5 * (x[2] ** 2 + x[3] ** 2) + g * x[1]) + 0.5 * k * (l - r) ** 2

    flight = ModeFunctions(flight_field, touchdown_guard, land, params=params, inputs=1)
    stance = ModeFunctions(stance_field, liftoff_guard, leave, params=params)
    modes = {
        "flight": Mode(5, names=FLIGHT_NAMES, units=FLIGHT_UNITS, functions=flight),
        "stance": Mode(5, names=STANCE_NAMES, units=STANCE_UNITS, functions=stance),
    }
    transitions = [Transition("flight", "stance", name="touchdown"), Transition("stance", "flight", name="liftoff")]
    return HybridSystem(
        modes,
        transitions,
        name="slip_hopper",
        energy=energy,
        initial=("flight", np.array([INITIAL_STATE[n] for n in FLIGHT_NAMES])),
    )


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback."""
    m, k, rest_length, g = (params[n] for n in ("m", "k", "l", "g"))
    system = make_system(m, k, rest_length, g)

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        body = np.array([x[0], x[1]])
        if mode == "flight":
            foot = body + rest_length * np.array([math.sin(x[2]), -math.cos(x[2])])
        else:
            foot = np.array([x[4], 0.0])
        return {"body": body[None, :], "leg": np.vstack([body, foot])}

    info = {
        "guard_units": {"touchdown": "m (foot height)", "liftoff": "m (rest length minus leg length)"},
        "parameters": dict(params),
        "effects": dict(effects),
        "slip_hopper": {"m": m, "k": k, "l": rest_length, "g": g},
    }
    return Model(
        system=system,
        initial_mode="flight",
        initial_state=dict(INITIAL_STATE),
        geometry=geometry,
        scenery={"ground": np.array([[-2.0, 0.0], [400.0, 0.0]])},
        info=info,
    )


BUILDER = Builder(
    name="slip_hopper",
    description="SLIP with an actuated leg angle in flight (u: swing rate, rad/s): Raibert's hopper",
    parameters=PARAMETERS,
    effects={},
    build=build,
)
