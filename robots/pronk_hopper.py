"""The pronk hopper: the pronking runner of paper 000 (``robots/pronk.py``) with actuated legs,
so that a controller can place its feet and servo its pitch (Raibert's pronk, ``raibert_pronk``).

A planar rigid body (mass m, pitch inertia I) has two massless spring legs (stiffness k, rest
length l) hinged d/2 behind (``left``) and d/2 ahead (``right``) of its centre of mass. Every
mode's state is the body's ``(x, z, theta, xd, zd, thetad)`` (m, rad, m/s, rad/s; theta about
+y, positive nose down, as the pronk's), then the angle ``psi_<leg>`` of each leg in flight (rad,
from the body's downward normal, forward), then the foothold ``<leg>_foot_x`` of each leg in
stance (m). Modes ``aerial``, ``left``, ``right``, ``both`` (the legs in stance), 8 coordinates
each.

The input ``u = (swing_left, swing_right, torque_left, torque_right)``: a leg in flight swings
at its rate (rad/s; massless, so swinging moves nothing else); a leg in stance applies its hip
torque to the body (N m, about +y). The massless leg balances that torque with a force
``torque / r`` across it at the hip, r its length, so the ground's force still passes through
the foot: the angular momentum about a single stance foot changes by gravity alone. Without
control u = 0: the legs keep their angles, and the flow is the pronk's at fixed psi.

Guards (m), as the pronk's: touchdown ``max(foot height, foot vertical velocity)`` (the foot's
velocity carried by the body, the leg's swing not included); liftoff ``max(l - r, -dr/dt)``.
Resets: a touchdown pins the foot where it is, a liftoff leaves the leg at its stance angle.
Energy (kinetic, gravity, springs) is conserved by the uncontrolled flow and by every reset.
The stance foot is pinned (no slip, and the liftoff is the spring's, as the pronk's): the
ground's normal force ``k (l - r) n_z + (torque / r) n_x`` (n the unit vector foot -> hip) is a
controller's to keep positive (``raibert_pronk`` limits its torque so). A touchdown whose foot
is below the ground (a flying leg swung down while the body rose, which the guard's rate does
not see) is past the model's range: its image is nan and the run ends in a model breakdown,
rather than pinning a foothold with its spring compressed.

Written once as compiled model functions (``legsim.model``): the four modes share them, with
``p = (m, I, k, l, d, g, left stands, right stands)`` (kg, kg m^2, N/m, m, m, m/s^2, then 1.0 or
0.0); the geometry helpers (``leg_coordinate``, ``hip_motion``, ``leg_in_stance``,
``foot_in_flight``) serve the controller, the energy and the pictures too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Builder, Model
from legsim.compiled.functions import model_function
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.model import ModeFunctions

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
#: What the models' nan means (module docstring), for the run's message.
LANDING_BELOW_GROUND = "a flight leg lands with its foot below the ground (swung down while the body rose)"
P_M, P_I, P_K, P_L, P_D, P_G, P_LEFT, P_RIGHT = range(8)


def state_names(stance: tuple[str, ...]) -> tuple[str, ...]:
    """A mode's coordinate names: the body's, the flying legs' angles, the stance feet."""
    flying = tuple(f"psi_{leg}" for leg in LEGS if leg not in stance)
    return BODY_NAMES + flying + tuple(f"{leg}_foot_x" for leg in stance)


def state_units(stance: tuple[str, ...]) -> tuple[str, ...]:
    """The units of ``state_names(stance)``."""
    body = ("m", "m", "rad", "m/s", "m/s", "rad/s")
    return body + ("rad",) * (len(LEGS) - len(stance)) + ("m",) * len(stance)


@model_function
def leg_coordinate(left_stands: float, right_stands: float, leg: int) -> int:
    """The index of leg ``leg``'s coordinate (0 left, 1 right) in a state of the mode where each
    leg stands when its flag is nonzero: its angle psi if it flies, its foothold if it stands."""
    stands = (left_stands if leg == 0 else right_stands) != 0.0
    flying = int(left_stands == 0.0) + int(right_stands == 0.0)
    at = 6 + flying if stands else 6
    if leg == 1 and (left_stands != 0.0) == stands:
        at += 1
    return at


@model_function
def hip_motion(x: np.ndarray, d: float, leg: int) -> tuple[float, float, float, float, float, float]:
    """Leg ``leg``'s hip for hips ``d`` (m) apart: its arm from the centre of mass (m), position
    (m) and velocity (m/s), as (arm_x, arm_z, px, pz, vx, vz)."""
    side = 0.5 * d * (-1.0 if leg == 0 else 1.0)
    arm0 = side * math.cos(x[2])
    arm1 = -side * math.sin(x[2])
    return arm0, arm1, x[0] + arm0, x[1] + arm1, x[3] + x[5] * arm1, x[4] + x[5] * -arm0


@model_function
def leg_in_stance(x: np.ndarray, d: float, leg: int, foot_x: float) -> tuple[float, float, float, float]:
    """A standing leg with its foot at (foot_x, 0): the unit vector foot -> hip (n_x, n_z), its
    length r (m) and its extension rate dr/dt (m/s)."""
    _, _, px, pz, vx, vz = hip_motion(x, d, leg)
    a0 = px - foot_x
    a1 = pz
    r = math.sqrt(a0 * a0 + a1 * a1)
    n0 = a0 / r
    n1 = a1 / r
    return n0, n1, r, n0 * vx + n1 * vz


@model_function
def foot_in_flight(x: np.ndarray, d: float, length: float, leg: int, psi: float) -> tuple[float, float, float]:
    """A flying leg of ``length`` (m) at angle psi (rad): its foot's position (x, z) (m) and
    vertical velocity carried by the body (m/s)."""
    _, _, px, pz, _, vz = hip_motion(x, d, leg)
    angle = psi - x[2]  # from the downward vertical, forward
    return px + length * math.sin(angle), pz - length * math.cos(angle), vz - length * math.sin(angle) * x[5]


@model_function
def pronk_field(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """The body under gravity and each standing leg's spring and hip torque; each flying leg
    swings at its input's rate; the footholds stay (module docstring), shape (8,)."""
    left, right = p[P_LEFT], p[P_RIGHT]
    force0 = 0.0
    force1 = -p[P_M] * p[P_G]
    torque = 0.0
    for d in range(6, 8):
        dx[d] = 0.0
    for leg in range(2):
        at = leg_coordinate(left, right, leg)
        if (left if leg == 0 else right) == 0.0:
            dx[at] = u[leg]
            continue
        hip_torque = u[2 + leg]
        n0, n1, r, _ = leg_in_stance(x, p[P_D], leg, x[at])
        spring = p[P_K] * (p[P_L] - r)
        across = hip_torque / r
        on0 = spring * n0 - across * n1
        on1 = spring * n1 + across * n0
        arm0, arm1, _, _, _, _ = hip_motion(x, p[P_D], leg)
        force0 += on0
        force1 += on1
        torque += hip_torque + arm1 * on0 - arm0 * on1
    dx[0] = x[3]
    dx[1] = x[4]
    dx[2] = x[5]
    dx[3] = force0 / p[P_M]
    dx[4] = force1 / p[P_M]
    dx[5] = torque / p[P_I]


@model_function
def pronk_guards(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """Per leg in ``LEGS`` order (m): touchdown max(foot height, its rate) of a flying leg,
    liftoff max(l - r, -dr/dt) of a standing one."""
    left, right = p[P_LEFT], p[P_RIGHT]
    for leg in range(2):
        at = leg_coordinate(left, right, leg)
        if (left if leg == 0 else right) == 0.0:
            _, height, rate = foot_in_flight(x, p[P_D], p[P_L], leg, x[at])
            g[leg] = rate if rate > height else height
        else:
            _, _, r, rate = leg_in_stance(x, p[P_D], leg, x[at])
            short = p[P_L] - r
            g[leg] = -rate if -rate > short else short


@model_function
def pronk_reset(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Leg e's transition into the target mode's state: a touchdown pins the foot where it is
    (nan below the ground: past the model's range), a liftoff leaves the leg at its stance angle
    psi = atan2(foot_x - hip_x, hip_z) + theta."""
    left, right = p[P_LEFT], p[P_RIGHT]
    at = leg_coordinate(left, right, e)
    landing = (left if e == 0 else right) == 0.0
    if landing:
        foot_x, foot_z, _ = foot_in_flight(x, p[P_D], p[P_L], e, x[at])
        value = foot_x if foot_z >= -BELOW_GROUND else math.nan
    else:
        _, _, px, pz, _, _ = hip_motion(x, p[P_D], e)
        value = math.atan2(x[at] - px, pz) + x[2]
    stands = 1.0 if landing else 0.0
    new_left = stands if e == 0 else left
    new_right = stands if e == 1 else right
    for d in range(6):
        out[d] = x[d]
    for leg in range(2):
        own = value if leg == e else x[leg_coordinate(left, right, leg)]
        out[leg_coordinate(new_left, new_right, leg)] = own


class PronkHopper:
    """The hopper's parameters m, I (kg, kg m^2), k (N/m), l, d (m), g (m/s^2), its geometry
    (the compiled helpers, from Python) and energy; the hybrid system is ``system()``."""

    def __init__(self, m: float, I: float, k: float, l: float, d: float, g: float) -> None:  # noqa: E741 -- the paper's symbols, also the scene's parameter names
        self.m, self.I, self.k, self.l, self.d, self.g = m, I, k, l, d, g

    def hip(self, leg: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The hip's position (m) and velocity (m/s), each shape (2,), of state x."""
        _, _, px, pz, vx, vz = hip_motion(np.ascontiguousarray(x, dtype=float), self.d, LEGS.index(leg))
        return np.array([px, pz]), np.array([vx, vz])

    def leg_in_stance(self, leg: str, x: np.ndarray, foot_x: float) -> tuple[np.ndarray, float, float]:
        """Unit vector foot -> hip, the leg's length r (m) and its extension rate dr/dt (m/s)."""
        n0, n1, r, rate = leg_in_stance(np.ascontiguousarray(x, dtype=float), self.d, LEGS.index(leg), float(foot_x))
        return np.array([n0, n1]), r, rate

    def foot_in_flight(self, leg: str, x: np.ndarray, psi: float) -> tuple[np.ndarray, float]:
        """The foot's position (m), shape (2,), and its vertical velocity carried by the body (m/s)."""
        state = np.ascontiguousarray(x, dtype=float)
        fx, fz, vz = foot_in_flight(state, self.d, self.l, LEGS.index(leg), float(psi))
        return np.array([fx, fz]), vz

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Kinetic, gravitational and spring energy (J)."""
        stance = MODES[mode]
        springs = 0.0
        for i, leg in enumerate(stance):
            _, r, _ = self.leg_in_stance(leg, x, x[8 - len(stance) + i])
            springs += 0.5 * self.k * (self.l - r) ** 2
        return 0.5 * self.m * (x[3] ** 2 + x[4] ** 2) + 0.5 * self.I * x[5] ** 2 + self.m * self.g * x[1] + springs

    def params(self, mode: str) -> list[float]:
        """The parameter array p of ``mode`` (module docstring)."""
        stance = MODES[mode]
        return [self.m, self.I, self.k, self.l, self.d, self.g, *(float(leg in stance) for leg in LEGS)]

    def system(self) -> HybridSystem:
        """The hybrid system: four modes, a touchdown and a liftoff per leg from each (each mode's
        transitions in ``LEGS`` order, as its guards)."""
        modes = {
            name: Mode(
                8,
                names=state_names(stance),
                units=state_units(stance),
                functions=ModeFunctions(
                    pronk_field,
                    pronk_guards,
                    pronk_reset,
                    params=self.params(name),
                    inputs=4,
                    nan_breaks=True,
                    range_note=LANDING_BELOW_GROUND,
                ),
            )
            for name, stance in MODES.items()
        }
        transitions = [_transition(mode, leg) for mode in MODES for leg in LEGS]
        initial = np.array([INITIAL_STATE[name] for name in state_names(())])
        return HybridSystem(modes, transitions, name="pronk_hopper", energy=self.energy, initial=("aerial", initial))


def _transition(source: str, leg: str) -> Transition:
    """Leg ``leg``'s transition out of ``source``: its liftoff when it stands there, else its
    touchdown."""
    before = MODES[source]
    after = tuple(name for name in LEGS if (name in before) != (name == leg))
    target = next(name for name, legs in MODES.items() if legs == after)
    kind = "liftoff" if leg in before else "touchdown"
    return Transition(source, target, name=f"{kind}_{leg}")


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
