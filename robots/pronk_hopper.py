"""The pronk hopper: the pronking runner of paper 000 (``robots/pronk.py``) with actuated legs,
so that a controller can place its feet and servo its pitch (Raibert's pronk, ``raibert_pronk``).

A planar rigid body (mass m, pitch inertia I) has two massless spring legs (stiffness k, rest
length l) hinged d/2 behind (``left``) and d/2 ahead (``right``) of its centre of mass. Every
mode's state is the body's ``(x, z, theta, xd, zd, thetad)`` (m, rad, m/s, rad/s; theta about
+y, positive nose down, as the pronk's), then the angle ``psi_<leg>`` of each leg in flight (rad,
from the body's downward normal, forward), then the foothold ``<leg>_foot_x`` of each leg in
stance (m). Modes ``aerial``, ``left``, ``right``, ``both`` (the legs in stance), 8 coordinates
each.

The control ``u = (swing_left, swing_right, torque_left, torque_right)``: a leg in flight swings
at its rate (rad/s; massless, so swinging moves nothing else); a leg in stance applies its hip
torque to the body (N m, about +y). The massless leg balances that torque with a force
``torque / r`` across it at the hip, r its length, so the ground's force still passes through
the foot: the angular momentum about a single stance foot changes by gravity alone. Without
control (u = None) the legs keep their angles, and the flow is the pronk's at fixed psi.

Guards (m), as the pronk's: touchdown ``max(foot height, foot vertical velocity)`` (the foot's
velocity carried by the body, the leg's swing not included); liftoff ``max(l - r, -dr/dt)``.
Resets: a touchdown pins the foot where it is, a liftoff leaves the leg at its stance angle.
Energy (kinetic, gravity, springs) is conserved by the uncontrolled flow and by every reset.
The stance foot is pinned (no slip, and the liftoff is the spring's, as the pronk's): the
ground's normal force ``k (l - r) n_z + (torque / r) n_x`` (n the unit vector foot -> hip) is a
controller's to keep positive (``raibert_pronk`` limits its torque so). A touchdown whose foot
is below the ground (a flying leg swung down while the body rose, which the guard's rate does
not see) is a ModelBreakdown, not a foothold pinned with its spring compressed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Builder, Model
from legsim.errors import ModelBreakdown
from legsim.hybrid import HybridSystem, Mode, Transition

from .pronk import PARAMETERS as PRONK_PARAMETERS

LEGS = ("left", "right")
BODY_NAMES = ("x", "z", "theta", "xd", "zd", "thetad")
MODES = {"aerial": (), "left": ("left",), "right": ("right",), "both": ("left", "right")}
INITIAL_STATE = {
    "x": 0.0,
    "z": 1.1,
    "theta": 0.0,
    "xd": 3.4,
    "zd": 0.0,
    "thetad": 0.0,
    "psi_left": math.pi / 5,
    "psi_right": math.pi / 5,
}
PARAMETERS = {name: PRONK_PARAMETERS[name] for name in ("m", "I", "k", "l", "d", "g")}
#: A landing foot lower than this (m) went through the ground before its guard saw it.
BELOW_GROUND = 1e-6


def state_names(stance: tuple[str, ...]) -> tuple[str, ...]:
    """A mode's coordinate names: the body's, the flying legs' angles, the stance feet."""
    flying = tuple(f"psi_{leg}" for leg in LEGS if leg not in stance)
    return BODY_NAMES + flying + tuple(f"{leg}_foot_x" for leg in stance)


def state_units(stance: tuple[str, ...]) -> tuple[str, ...]:
    """The units of ``state_names(stance)``."""
    body = ("m", "m", "rad", "m/s", "m/s", "rad/s")
    return body + ("rad",) * (len(LEGS) - len(stance)) + ("m",) * len(stance)


def controls(u: Any) -> np.ndarray:
    """The control as (swing_left, swing_right, torque_left, torque_right); None: zeros."""
    if u is None:
        return np.zeros(4)
    values = np.asarray(u, dtype=float).reshape(-1)
    if values.shape != (4,):
        raise ValueError(
            f"the pronk hopper's control has 4 entries (2 swing rates, 2 hip torques), got {values.shape[0]}"
        )
    return values


class PronkHopper:
    """The body and legs' geometry and forces for parameters m, I (kg, kg m^2), k (N/m), l, d (m),
    g (m/s^2); the hybrid system is ``system()``."""

    def __init__(self, m: float, I: float, k: float, l: float, d: float, g: float) -> None:  # noqa: E741 -- the paper's symbols, also the scene's parameter names
        self.m, self.I, self.k, self.l, self.d, self.g = m, I, k, l, d, g

    def hip_arm(self, leg: str, theta: float) -> np.ndarray:
        """The hip's position relative to the centre of mass (m), shape (2,), at pitch theta."""
        side = 0.5 * self.d * (-1.0 if leg == "left" else 1.0)
        return np.array([side * math.cos(theta), -side * math.sin(theta)])

    def hip(self, leg: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The hip's position (m) and velocity (m/s), each shape (2,), of state x."""
        arm = self.hip_arm(leg, x[2])
        return x[:2] + arm, x[3:5] + x[5] * np.array([arm[1], -arm[0]])

    def leg_in_stance(self, leg: str, x: np.ndarray, foot_x: float) -> tuple[np.ndarray, float, float]:
        """Unit vector foot -> hip, the leg's length r (m) and its extension rate dr/dt (m/s)."""
        position, velocity = self.hip(leg, x)
        along = position - np.array([foot_x, 0.0])
        # sqrt of the sum and a written-out dot: the compiled twin does the same operations
        # (math.hypot and a BLAS dot round differently in numba), so both paths agree to the bit
        r = math.sqrt(along[0] * along[0] + along[1] * along[1])
        n = along / r
        return n, r, float(n[0] * velocity[0] + n[1] * velocity[1])

    def foot_in_flight(self, leg: str, x: np.ndarray, psi: float) -> tuple[np.ndarray, float]:
        """The foot's position (m), shape (2,), and its vertical velocity carried by the body (m/s)."""
        position, velocity = self.hip(leg, x)
        angle = psi - x[2]  # from the downward vertical, forward
        foot = position + self.l * np.array([math.sin(angle), -math.cos(angle)])
        return foot, velocity[1] - self.l * math.sin(angle) * x[5]

    def field(self, stance: tuple[str, ...]) -> Any:
        """The mode's vector field f(t, x, u), shape (8,)."""
        flying = [leg for leg in LEGS if leg not in stance]
        n_fly = len(flying)

        def f(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            control = controls(u)
            force, torque = np.array([0.0, -self.m * self.g]), 0.0
            for i, leg in enumerate(stance):
                hip_torque = control[2 + LEGS.index(leg)]
                n, r, _ = self.leg_in_stance(leg, x, x[6 + n_fly + i])
                across = np.array([n[1], -n[0]])
                on_body = self.k * (self.l - r) * n - hip_torque / r * across
                arm = self.hip_arm(leg, x[2])
                force += on_body
                torque += hip_torque + arm[1] * on_body[0] - arm[0] * on_body[1]
            dx = np.zeros(8)
            dx[:3] = x[3:6]
            dx[3:5] = force / self.m
            dx[5] = torque / self.I
            for i, leg in enumerate(flying):
                dx[6 + i] = control[LEGS.index(leg)]
            return dx

        return f

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Kinetic, gravitational and spring energy (J)."""
        stance = MODES[mode]
        springs = 0.0
        for i, leg in enumerate(stance):
            _, r, _ = self.leg_in_stance(leg, x, x[8 - len(stance) + i])
            springs += 0.5 * self.k * (self.l - r) ** 2
        return 0.5 * self.m * (x[3] ** 2 + x[4] ** 2) + 0.5 * self.I * x[5] ** 2 + self.m * self.g * x[1] + springs

    def touchdown(self, source: str, leg: str) -> Transition:
        """``source -> source + leg``: the foot pinned where it lands."""
        before = MODES[source]
        after = tuple(name for name in LEGS if name in before or name == leg)
        target = next(name for name, legs in MODES.items() if legs == after)
        names_before, names_after = state_names(before), state_names(after)
        psi_index = names_before.index(f"psi_{leg}")

        def guard(x: np.ndarray) -> float:
            foot, rate = self.foot_in_flight(leg, x, x[psi_index])
            return max(foot[1], rate)

        def reset(x: np.ndarray) -> np.ndarray:
            foot = self.foot_in_flight(leg, x, x[psi_index])[0]
            if foot[1] < -BELOW_GROUND:
                raise ModelBreakdown(f"the {leg} foot is {-foot[1]:.3g} m below the ground at its touchdown")
            values = dict(zip(names_before, x, strict=True))
            values[f"{leg}_foot_x"] = foot[0]
            return np.array([values[name] for name in names_after])

        return Transition(source, target, guard, reset, name=f"touchdown_{leg}")

    def liftoff(self, source: str, leg: str) -> Transition:
        """``source -> source - leg``: the leg leaves at its stance angle."""
        before = MODES[source]
        after = tuple(name for name in before if name != leg)
        target = next(name for name, legs in MODES.items() if legs == after)
        names_before, names_after = state_names(before), state_names(after)
        foot_index = names_before.index(f"{leg}_foot_x")

        def guard(x: np.ndarray) -> float:
            _, r, rate = self.leg_in_stance(leg, x, x[foot_index])
            return max(self.l - r, -rate)

        def reset(x: np.ndarray) -> np.ndarray:
            values = dict(zip(names_before, x, strict=True))
            hip = self.hip(leg, x)[0]
            values[f"psi_{leg}"] = math.atan2(x[foot_index] - hip[0], hip[1]) + x[2]
            return np.array([values[name] for name in names_after])

        return Transition(source, target, guard, reset, name=f"liftoff_{leg}")

    def system(self) -> HybridSystem:
        """The hybrid system: four modes, a touchdown and a liftoff per leg from each; each mode
        carries its compiled twin (``robots/pronk_hopper_twin.py``)."""
        from .pronk_hopper_twin import pronk_hopper_twin  # the twins compile the controller, built on this model

        modes = {
            name: Mode(
                8,
                self.field(stance),
                state_names(stance),
                units=state_units(stance),
                compiled=pronk_hopper_twin(self, name),
            )
            for name, stance in MODES.items()
        }
        transitions = [
            self.touchdown(mode, leg) if leg not in stance else self.liftoff(mode, leg)
            for mode, stance in MODES.items()
            for leg in LEGS
        ]
        initial = np.array([INITIAL_STATE[name] for name in state_names(())])
        return HybridSystem(modes, transitions, name="pronk_hopper", energy=self.energy, initial=("aerial", initial))


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback."""
    hopper = PronkHopper(*(params[name] for name in ("m", "I", "k", "l", "d", "g")))

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        """Polylines (m) of the body, the legs (hip -> foot) and the feet, for pictures."""
        x = np.asarray(x, dtype=float)
        stance = MODES[mode]
        names = state_names(stance)
        hips = {leg: hopper.hip(leg, x)[0] for leg in LEGS}
        parts = {"body": np.array([hips["left"], hips["right"]]), "com": x[None, :2].copy()}
        for leg in LEGS:
            if leg in stance:
                foot = np.array([x[names.index(f"{leg}_foot_x")], 0.0])
            else:
                foot = hopper.foot_in_flight(leg, x, x[names.index(f"psi_{leg}")])[0]
            parts[f"leg_{leg}"] = np.array([hips[leg], foot])
            parts[f"foot_{leg}"] = foot[None, :]
        return parts

    info = {
        "guard_units": {f"touchdown_{leg}": "m (foot height)" for leg in LEGS}
        | {f"liftoff_{leg}": "m (rest length minus leg length)" for leg in LEGS},
        "parameters": dict(params),
        "effects": dict(effects),
        "pronk_hopper": hopper,
    }
    return Model(
        system=hopper.system(),
        initial_mode="aerial",
        initial_state=dict(INITIAL_STATE),
        geometry=geometry,
        scenery={"ground": np.array([[-2.0, 0.0], [400.0, 0.0]])},
        info=info,
    )


BUILDER = Builder(
    name="pronk_hopper",
    description="the pronk with actuated legs (each flying leg's swing rate, each standing leg's hip torque)",
    parameters=PARAMETERS,
    effects={},
    build=build,
)
