"""The SLIP hopper: the SLIP (a point mass on a massless spring leg) whose leg angle in flight
is actuated, so that a controller can place the foot (Raibert's hopper, ``raibert_slip``).

Modes and states:

* ``flight``: ``(x, z, psi, xd, zd)``: the mass's position (m), the leg's angle from the
  downward vertical, forward (rad), the mass's velocity (m/s). Field ``(xd, zd, u, 0, -g)``: the
  control u is the leg's swing rate (rad/s; the leg is massless, so swinging it costs nothing
  and does not move the mass); without control u = 0 and the leg keeps its angle.
* ``stance``: ``(x, z, xd, zd, foot_x)``: the foot pinned at ``(foot_x, 0)``, the spring
  pushing the mass along the leg with ``k (l - r)`` (N).

Transitions: ``touchdown`` when the foot ``z - l cos(psi)`` reaches the ground while the mass
descends (guard: the foot's height, or ``max(height, zd)`` while the mass rises, m), reset
``foot_x = x + l sin(psi)``; ``liftoff`` when the leg is back at rest length while extending
(guard ``max(l - r, -dr/dt)``, m), reset ``psi = asin((foot_x - x) / l)`` (the leg leaves at
its stance angle). Energy ``m (xd^2 + zd^2) / 2 + m g z (+ k (l - r)^2 / 2 in stance)`` is
conserved by both modes and both resets.

Both modes carry compiled twins (``robots.slip_hopper_twin``), so a run without control or
under ``raibert_slip`` takes the compiled step loop.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Builder, Model, Param
from legsim.hybrid import HybridSystem, Mode, Transition

from .slip_hopper_twin import hopper_twins

FLIGHT_NAMES = ("x", "z", "psi", "xd", "zd")
STANCE_NAMES = ("x", "z", "xd", "zd", "foot_x")
INITIAL_STATE = {"x": 0.0, "z": 1.1, "psi": math.pi / 5, "xd": 3.4, "zd": 0.0}

PARAMETERS = {
    "m": Param(1.0, "point mass", "kg", low=0.0, low_open=True),
    "k": Param(60.0, "leg stiffness", "N/m", low=0.0, low_open=True),
    "l": Param(1.0, "leg rest length", "m", low=0.0, low_open=True),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
}


def swing_rate(u: Any) -> float:
    """The leg's swing rate (rad/s) from the control: a number or a one-entry array; None: 0."""
    if u is None:
        return 0.0
    return float(np.asarray(u, dtype=float).reshape(-1)[0])


def make_system(m: float, k: float, l: float, g: float) -> HybridSystem:  # noqa: E741 -- the paper's symbols, also the scene's parameter names
    """The SLIP hopper's hybrid system (module docstring) for mass m (kg), stiffness k (N/m),
    rest length l (m) and gravity g (m/s^2)."""

    def flight(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[3], x[4], swing_rate(u), 0.0, -g])

    def stance(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        d = np.array([x[0] - x[4], x[1]])
        r = math.hypot(d[0], d[1])
        acc = k * (l - r) / (m * r) * d
        return np.array([x[2], x[3], acc[0], acc[1] - g, 0.0])

    def touchdown_guard(x: np.ndarray) -> float:
        height = x[1] - l * math.cos(x[2])
        return height if x[4] <= 0.0 else max(height, x[4])

    def liftoff_guard(x: np.ndarray) -> float:
        d = np.array([x[0] - x[4], x[1]])
        r = math.hypot(d[0], d[1])
        return max(l - r, -float(d @ x[2:4]) / r)

    def land(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], x[1], x[3], x[4], x[0] + l * math.sin(x[2])])

    def leave(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], x[1], math.asin(max(-1.0, min(1.0, (x[4] - x[0]) / l))), x[2], x[3]])

    def energy(mode: str, x: np.ndarray) -> float:
        if mode == "flight":
            return m * (0.5 * (x[3] ** 2 + x[4] ** 2) + g * x[1])
        r = math.hypot(x[0] - x[4], x[1])
        return m * (0.5 * (x[2] ** 2 + x[3] ** 2) + g * x[1]) + 0.5 * k * (l - r) ** 2

    twins = hopper_twins(m, k, l, g)
    modes = {
        "flight": Mode(5, flight, FLIGHT_NAMES, compiled=twins["flight"]),
        "stance": Mode(5, stance, STANCE_NAMES, compiled=twins["stance"]),
    }
    transitions = [
        Transition("flight", "stance", touchdown_guard, land, name="touchdown"),
        Transition("stance", "flight", liftoff_guard, leave, name="liftoff"),
    ]
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
