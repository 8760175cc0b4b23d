"""Raibert's running controllers (Raibert, *Legged Robots That Balance*, 1986): forward speed by
foot placement, hopping height by thrust, body attitude by hip torque in stance.

Each leg is controlled on its own, from the mode the run is in (the controller is told it) and
the state:

* **flight**: the foot is placed ahead of the hip by ``x_f = xd T_s / 2 + k_x (xd - xd*) + b``
  (m): half the distance the body travels during the last stance of that leg (the neutral
  point, which keeps the speed) plus a correction proportional to the speed error, plus a bias
  ``b`` that integrates the error: at each touchdown it grows by ``k_i`` times the error of the
  body's mean speed over the stride since the leg's last touchdown (the proportional term
  alone leaves a steady error); the leg is held at its touchdown length;
* **stance**: the leg pushes along itself like a spring of stiffness k and rest length l, with
  a thrust that lengthens the spring during extension by ``delta`` (m), adapted hop by hop to
  the apex height error; the hip adds ``k_p (theta - theta*) + k_d dtheta/dt`` (N m) to keep
  the body level (the body gets the opposite torque);
* **bound** (``gait = "bound"``): the pitch is left free and each leg pair hops as a hopper on
  its own hip (height, thrust and foot placement from its hip's motion); a rising leg retracts
  holding its liftoff angle and swings only once its hip falls; a phase term moves each pair's
  apex target by how far its touchdown is off half a stride after the other pair's.

``RunnerRaibert`` drives articulated legs (a hip and a knee per leg, a point foot): the flight
posture by a joint PD with gravity compensation on the inverse kinematics of the foot placement,
the stance spring through the leg Jacobian (tau = J^T f). ``raibert_slip`` (``slip_law``, a
``ControlLaw`` written once as compiled functions) drives the SLIP hopper
(``robots/slip_hopper.py``): its input is the massless leg's swing rate in flight, a servo to the
foot placement's leg angle; its spring is passive and the SLIP conserves energy, so its hopping
height needs no thrust (it trades with the speed).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Model, Param
from legsim.compiled import model_function
from legsim.control import ControlLaw, Controller, ControllerSpec, keeps_law
from legsim.errors import SceneError

from . import runner_laws as laws
from .controllers import bridge_of
from .hopper_laws import swing_rate_compiled
from .runner_laws import touchdown_angle
from .runner_twin import pack_record


@dataclass
class Leg:
    """An articulated leg: hip and knee velocity indices and positions in u, segment lengths
    (m), the knee's bending sign (+1: positive knee angles), the hip's x in the body frame (m),
    the foot's contact name, and what
    the controller remembers of it (touchdown time, last stance duration (s), thrust (m))."""

    contact: str
    hip: int
    knee: int
    u_hip: int
    u_knee: int
    thigh: float
    shank: float
    bend: float
    offset: float = 0.0
    touchdown: float = 0.0
    stance_time: float = 0.12
    thrust: float = 0.0
    in_stance: bool = False
    apex: float = field(default=float("nan"))
    touchdown_x: float = field(default=float("nan"))
    bias: float = 0.0
    liftoff_angle: float = 0.0
    liftoff_time: float = -math.inf
    phase_height: float = 0.0


def leg_point(leg: Leg, q_hip: float, q_knee: float) -> np.ndarray:
    """Foot relative to the hip in the body frame (x, z) (m)."""
    return np.array(laws.foot_terms(leg.thigh, leg.shank, q_hip, q_knee)[:2])


def leg_jacobian(leg: Leg, q_hip: float, q_knee: float) -> np.ndarray:
    """d(foot - hip)/d(q_hip, q_knee) in the body frame (2, 2)."""
    return np.array(laws.foot_terms(leg.thigh, leg.shank, q_hip, q_knee)[2:]).reshape(2, 2)


def leg_angles(leg: Leg, length: float, angle: float) -> tuple[float, float]:
    """(q_hip, q_knee) putting the foot at ``length`` (m) from the hip, ``angle`` (rad) from the
    body's -z axis towards +x (the knee bent by its sign)."""
    return laws.joint_angles(leg.thigh, leg.shank, leg.bend, length, angle)


def find_legs(bridge: Any) -> list[Leg]:
    """The articulated legs of a bridge robot: each point contact whose frame hangs below two
    actuated revolute joints (hip, then knee)."""
    model = bridge.model
    dofs = list(bridge.actuated_dofs)
    legs = []
    for contact in bridge.contacts:
        frame = getattr(contact, "frame", None)
        if frame is None or not hasattr(contact, "tangential"):
            continue
        fid = model.getFrameId(frame)
        knee = model.frames[fid].parentJoint
        hip = model.parents[knee]
        kv, hv = model.joints[knee].idx_v, model.joints[hip].idx_v
        if kv not in dofs or hv not in dofs:
            continue
        thigh = float(np.linalg.norm(model.jointPlacements[knee].translation))
        shank = float(np.linalg.norm(model.frames[fid].placement.translation))
        knee_q = model.joints[knee].idx_q
        bend = 1.0 if model.upperPositionLimit[knee_q] > -model.lowerPositionLimit[knee_q] else -1.0
        offset = float(model.jointPlacements[hip].translation[0])
        legs.append(Leg(contact.name, hv, kv, dofs.index(hv), dofs.index(kv), thigh, shank, bend, offset))
    return legs


#: The laws' constants (``UNLOAD``, ``ATTITUDE_SHARE``, ``THRUST_RATE``, ``SWING_SHARE``,
#: ``RETRACT_STIFFNESS``, ``RETRACT_DAMPING``) are in ``robots.runner_laws``.
#: How long (s) after its liftoff a bound's leg that touches the ground again pulls its foot up
#: (at most ``UNLOAD``) instead of pushing: it lifted off where its contact force passed 0, so
#: at once after the liftoff that force's sign is a matter of rounding, and a foot put back in
#: stance by it would lift off again and again (an accumulation).
REFRACTORY = 0.01


@dataclass
class Gains:
    """The Raibert controller's settings (units in ``RUNNER_PARAMETERS``)."""

    speed: float
    height: float
    k_x: float
    k_i: float
    leg_length: float
    stiffness: float
    damping: float
    k_height: float
    kp_attitude: float
    kd_attitude: float
    kp_joint: float
    kd_joint: float
    max_thrust: float
    k_phase: float


#: The methods that compute ``RunnerRaibert``'s torques, which its compiled twin computes from
#: the record (a subclass may change the others: ``reset``'s values reach the twin through it).
RUNNER_LAW = ("__call__", "_active", "_height", "_joints", "_stance", "_flight")


class RunnerRaibert(Controller):
    """Raibert's controller for articulated legs (module docstring); ``attitude``: the stance
    hips servo the pitch (a pronk), or leave it free (a bound, where each leg pair hops on its
    own: with the body's pitch inertia near m (d/2)^2 the hips move as two separate hoppers, so
    each leg's thrust and swing follow its own hip's height, and a phase term keeps the two
    hoppers half a stride apart)."""

    def __init__(self, bridge: Any, legs: list[Leg], gains: Gains, attitude: bool) -> None:
        self.bridge, self.legs, self.gains, self.attitude = bridge, legs, gains, attitude
        self.n = bridge.n
        self.count = len(bridge.actuated_dofs)
        self._data = bridge.model.createData()
        self._modes: dict[str, frozenset[str]] = {}
        bridge.attach_control(self.preview)

    def preview(self, mode: str, t: float, x: np.ndarray) -> np.ndarray:
        """The control on entering ``mode`` at (t, x), the controller's own state left as it is
        (the bridge chooses the mode after an impact with it)."""
        clone = copy.copy(self)
        clone.legs = [dataclasses.replace(leg) for leg in self.legs]
        clone.reset(mode, t, x)
        return clone(mode, t, x)

    def reset(self, mode: str, t: float, x: np.ndarray) -> None:
        active = set(self.bridge.active_contacts(mode))
        for leg in self.legs:
            stance = leg.contact in active
            if stance and not leg.in_stance:
                if not self.attitude:
                    self._adapt_phase(leg, t)
                self._adapt_placement(leg, t, x)
                leg.touchdown = t
            elif leg.in_stance and not stance:
                leg.stance_time = min(max(t - leg.touchdown, 0.02), 0.5)
                self._adapt_thrust(leg, x)
                if not self.attitude:
                    leg.liftoff_angle = self._world_angle(leg, x)
                    leg.liftoff_time = t
            leg.in_stance = stance

    def compiled_record(self, pin_model: Any) -> list[float] | None:
        """The control record of the robot's compiled twin (``robots.runner_twin``, kind
        ``CTRL_RUNNER``) when this controller drives ``pin_model``, with each leg's memory as
        the last ``reset`` left it; None for the bound gait (its refractory term reads the
        time, which a twin's guards do not take), for another robot's model, and for a
        subclass that changes the law (``RUNNER_LAW``), which the twin would not follow."""
        if not self.attitude or pin_model is not self.bridge.model or not keeps_law(self, RunnerRaibert, RUNNER_LAW):
            return None
        frames = {contact.name: contact.frame for contact in self.bridge.contacts if hasattr(contact, "frame")}
        return pack_record(self.gains, self.legs, [pin_model.getFrameId(frames[leg.contact]) for leg in self.legs])

    @property
    def memory_names(self) -> tuple[str, ...] | None:  # type: ignore[override]
        """Each leg's thrust (m) and last stance duration T_s (s), by the leg's contact name.
        Undeclared (None) with the integral term (k_i > 0): its bias and the stride it measures
        from the last touchdown's time and place would be memory too, which ``restore`` cannot
        set without the section's time and state; likewise in a bound, whose phase term measures
        from both legs' last touchdowns."""
        if self.gains.k_i > 0.0 or not self.attitude:
            return None
        return tuple(f"{kind}_{leg.contact}" for leg in self.legs for kind in ("thrust", "T_s"))

    @property
    def memory_units(self) -> tuple[str, ...]:  # type: ignore[override]
        return ("m", "s") * len(self.legs)

    def memory(self) -> np.ndarray:
        """(thrust (m), T_s (s)) of each leg in turn, shape (2 * legs,): what the next hops use.
        The touchdown times are written at each touchdown and the apex at each liftoff before
        they are read, so they are not memory."""
        return np.array([value for leg in self.legs for value in (leg.thrust, leg.stance_time)])

    def restore(self, mode: str, memory: np.ndarray) -> None:
        """Set each leg's thrust and T_s; a leg in stance in ``mode`` counts its stance from the
        start of the run (a section in stance must be the one right after the touchdown)."""
        values = np.asarray(memory, dtype=float).reshape(len(self.legs), 2)
        for leg, (thrust, stance_time) in zip(self.legs, values, strict=True):
            leg.thrust, leg.stance_time, leg.in_stance = float(thrust), float(stance_time), False

    def _adapt_placement(self, leg: Leg, t: float, x: np.ndarray) -> None:
        """At touchdown: the body's mean speed over the stride since the leg's last touchdown
        (Raibert's measure) moves the foot placement by ``k_i`` times its error, so that the
        placement's bias integrates the speed error away."""
        if t > leg.touchdown and math.isfinite(leg.touchdown_x):
            stride_speed = (x[0] - leg.touchdown_x) / (t - leg.touchdown)
            leg.bias += self.gains.k_i * (stride_speed - self.gains.speed)
        leg.touchdown_x = x[0]

    def _adapt_thrust(self, leg: Leg, x: np.ndarray) -> None:
        """At liftoff: the apex the body's centre will reach, against the commanded height."""
        g = self.gains
        z, zd = self._height(leg, x)
        leg.apex = z + max(zd, 0.0) ** 2 / (2 * 9.81)
        target = g.height + leg.phase_height
        leg.thrust = min(max(leg.thrust + g.k_height * (target - leg.apex), 0.0), g.max_thrust)

    def _adapt_phase(self, leg: Leg, t: float) -> None:
        """Bound, at the leg's touchdown: its lag behind the other pair's last touchdown as a
        share of its own period, against the half period of antiphase, moves its apex target
        (a late leg hops lower, so that its next flight is shorter)."""
        other = next(o for o in self.legs if o is not leg)
        if not (math.isfinite(leg.touchdown_x) and math.isfinite(other.touchdown_x)) or t <= leg.touchdown:
            return
        share = ((t - other.touchdown) / (t - leg.touchdown)) % 1.0
        leg.phase_height = -self.gains.k_phase * (share - 0.5)

    def _world_angle(self, leg: Leg, x: np.ndarray) -> float:
        """The leg's angle (rad) from the world's -z axis towards +x."""
        px, pz = laws.foot_terms(leg.thigh, leg.shank, float(x[leg.hip]), float(x[leg.knee]))[:2]
        return math.atan2(px, -pz) - float(x[2])

    def _height(self, leg: Leg, x: np.ndarray) -> tuple[float, float]:
        """Height (m) and vertical speed (m/s) the leg hops: the body's centre in a pronk; in a
        bound, where each leg pair hops on its own, the leg's hip (``offset sin(pitch)`` below
        the centre)."""
        n = self.n
        if self.attitude:
            return float(x[1]), float(x[n + 1])
        pitch, rate = x[2], x[n + 2]
        return float(x[1] - leg.offset * math.sin(pitch)), float(x[n + 1] - leg.offset * math.cos(pitch) * rate)

    def _active(self, mode: str) -> frozenset[str]:
        """The contacts active in ``mode`` (cached: the controller is called at every guard
        evaluation, and parsing the mode's name would cost more than the control law)."""
        active = self._modes.get(mode)
        if active is None:
            active = self._modes[mode] = frozenset(self.bridge.active_contacts(mode))
        return active

    def _joints(self, leg: Leg, s: list[float]) -> tuple[float, float, float, float]:
        """The leg's hip and knee angles (rad) and rates (rad/s) in the state s (a list)."""
        n = self.n
        return s[leg.hip], s[leg.knee], s[n + leg.hip], s[n + leg.knee]

    def __call__(self, mode: str, t: float, x: np.ndarray) -> np.ndarray:
        n, g = self.n, self.gains
        # floats, not numpy scalars: the law runs at every guard evaluation (the same values)
        s = x.tolist()
        active = self._active(mode)
        u = np.zeros(self.count)
        stance_count = sum(leg.contact in active for leg in self.legs)
        attitude = g.kp_attitude * s[2] + g.kd_attitude * s[n + 2] if self.attitude else 0.0
        # A pronk lifts off together: once a leg has left, the others unload while they extend.
        together = self.attitude and stance_count < len(self.legs)
        gravity = None
        for leg in self.legs:
            if leg.contact in active:
                refractory = not self.attitude and t - leg.liftoff_time < REFRACTORY
                hip, knee = self._stance(leg, s, attitude / stance_count, together or refractory)
            else:
                if gravity is None:
                    gravity = pin.computeGeneralizedGravity(self.bridge.model, self._data, x[:n]).tolist()
                hip, knee = self._flight(leg, s, self._height(leg, x)[1] < 0.0, gravity)
            u[leg.u_hip] += hip
            u[leg.u_knee] += knee
        return u

    def _stance(self, leg: Leg, s: list[float], attitude: float, unload: bool = False) -> tuple[float, float]:
        """Hip and knee torques (N m) of the leg's spring along itself, with thrust while
        extending, and the hip's share of the attitude torque (``runner_laws.stance_torques``)."""
        g = self.gains
        return laws.stance_torques(
            leg.thigh,
            leg.shank,
            *self._joints(leg, s),
            g.leg_length,
            leg.thrust,
            g.stiffness,
            g.damping,
            attitude,
            unload,
        )

    def _flight(self, leg: Leg, s: list[float], falling: bool, gravity: list[float]) -> tuple[float, float]:
        """Hip and knee torques (N m) servoing the foot to its touchdown placement, with the
        generalized ``gravity`` (N m, one per velocity) compensated
        (``runner_laws.pronk_flight_torques``; a bound's: ``_bound_flight``)."""
        g = self.gains
        if not self.attitude:
            return self._bound_flight(leg, s, falling, gravity)
        return laws.pronk_flight_torques(
            leg.thigh,
            leg.shank,
            leg.bend,
            leg.offset,
            *self._joints(leg, s),
            s[2],
            s[self.n],
            falling,
            leg.stance_time,
            leg.bias,
            g.speed,
            g.k_x,
            g.leg_length,
            g.kp_joint,
            g.kd_joint,
            gravity[leg.hip],
            gravity[leg.knee],
        )

    def _bound_flight(self, leg: Leg, s: list[float], falling: bool, gravity: list[float]) -> tuple[float, float]:
        """Bound: once the leg's hip falls the leg swings to the placement of its own hip's
        horizontal speed at full length (joint PD); while the hip rises the leg retracts
        holding its liftoff angle (``runner_laws.retract_torques``)."""
        g, n = self.gains, self.n
        q_hip, q_knee, v_hip, v_knee = self._joints(leg, s)
        g_hip, g_knee = gravity[leg.hip], gravity[leg.knee]
        if not falling:
            return laws.retract_torques(
                leg.thigh,
                leg.shank,
                q_hip,
                q_knee,
                v_hip,
                v_knee,
                s[2],
                s[n + 2],
                leg.liftoff_angle,
                g.leg_length,
                g.kp_joint,
                g.kd_joint,
                g_hip,
                g_knee,
            )
        hip_speed = s[n] - leg.offset * math.sin(s[2]) * s[n + 2]
        world = touchdown_angle(hip_speed, leg.stance_time, g.k_x, g.speed, g.leg_length, leg.bias)
        return laws.servo_torques(
            leg.thigh,
            leg.shank,
            leg.bend,
            q_hip,
            q_knee,
            v_hip,
            v_knee,
            g.leg_length,
            world + s[2],
            g.kp_joint,
            g.kd_joint,
            g_hip,
            g_knee,
        )


RUNNER_PARAMETERS = {
    "gait": Param(
        "pronk", "pronk: the stance hips keep the body level; bound: the pitch is left free", choices=("pronk", "bound")
    ),
    "speed": Param(1.0, "commanded forward speed xd*", "m/s"),
    "height": Param(0.55, "commanded apex height of the body's centre", "m", low=0.0, low_open=True),
    "k_x": Param(0.05, "foot placement gain (m per m/s of speed error)", "s", low=0.0),
    "k_i": Param(
        0.0, "foot placement's integral gain: its bias grows by k_i per m/s of each stride's speed error", "s", low=0.0
    ),
    "leg_length": Param(
        0.42, "leg length at touchdown, and the stance spring's rest length", "m", low=0.0, low_open=True
    ),
    "stiffness": Param(2000.0, "stance spring stiffness along the leg", "N/m", low=0.0, low_open=True),
    "damping": Param(10.0, "stance damping along the leg", "N s/m", low=0.0),
    "thrust": Param(
        0.02, "initial thrust: the stance spring's rest-length extension while the leg extends", "m", low=0.0
    ),
    "k_height": Param(0.2, "thrust adaptation per metre of apex height error", "", low=0.0),
    "max_thrust": Param(0.1, "largest thrust", "m", low=0.0),
    "kp_attitude": Param(60.0, "stance hip torque per radian of pitch", "N m/rad", low=0.0),
    "kd_attitude": Param(6.0, "stance hip torque per rad/s of pitch rate", "N m s/rad", low=0.0),
    "k_phase": Param(
        0.1, "bound: apex target change (m) per share of a period a leg pair's touchdown is off antiphase", "m", low=0.0
    ),
    "kp_joint": Param(60.0, "flight joint stiffness", "N m/rad", low=0.0),
    "kd_joint": Param(2.0, "flight joint damping", "N m s/rad", low=0.0),
}


def _make_runner(model: Model, params: dict[str, Any]) -> RunnerRaibert:
    bridge = bridge_of(model, "raibert_runner")
    legs = find_legs(bridge)
    if not legs:
        raise SceneError(
            "controller 'raibert_runner' found no articulated leg: a point contact on a frame below "
            "two actuated revolute joints (hip, knee)"
        )
    if params["gait"] == "bound" and len(legs) != 2:
        raise SceneError(
            f"controller.parameters.gait = 'bound' needs two leg pairs (hind and front), the robot has "
            f"{len(legs)} articulated leg(s): {', '.join(leg.contact for leg in legs)}"
        )
    gains = Gains(**{k: params[k] for k in Gains.__dataclass_fields__})
    for leg in legs:
        leg.thrust = params["thrust"]
    return RunnerRaibert(bridge, legs, gains, attitude=params["gait"] == "pronk")


RUNNER = ControllerSpec(
    "raibert_runner",
    "Raibert's controller for articulated legs: foot placement, thrust, attitude by the stance hips",
    RUNNER_PARAMETERS,
    _make_runner,
)


#: ``raibert_slip``'s memory: the last stance's duration T_s (s), which the flight law reads;
#: in stance the time of its touchdown (s), from which the next T_s is measured (0 in flight: a
#: gait's memory at a flight section is then periodic whatever the time the return starts at);
#: and 1 while the hopper stands (0 in flight), so that a run's first entry into flight keeps the
#: T_s it starts with (an entry function is told the mode entered, not the one left).
SLIP_MEMORY = ("T_s", "t_touchdown", "stance")
SLIP_MEMORY_UNITS = ("s", "s", "")
M_STANCE_TIME, M_TOUCHDOWN, M_STANCE = range(len(SLIP_MEMORY))
#: ``raibert_slip``'s parameters in each mode: swing gain (1/s), placement gain (s), commanded
#: speed (m/s), the leg length its placement uses (m), and 1 in stance (0 in flight).
C_K_SWING, C_K_X, C_SPEED, C_LENGTH, C_STANCE = range(5)


@model_function
def slip_placement(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, u: np.ndarray) -> None:
    """``raibert_slip``'s input: in flight the swing rate ``k_swing (psi* - psi)`` (rad/s) to
    ``psi* = asin((xd T_s / 2 + k_x (xd - xd*)) / l)`` (``runner_laws.touchdown_angle``), T_s the
    memory's last stance duration; 0 in stance (the stance takes no input)."""
    if p[C_STANCE] != 0.0:
        u[0] = 0.0
        return
    target = touchdown_angle(x[3], m[M_STANCE_TIME], p[C_K_X], p[C_SPEED], p[C_LENGTH])
    u[0] = swing_rate_compiled(p[C_K_SWING], target, x[2])


@model_function
def slip_stance_clock(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, m_new: np.ndarray) -> None:
    """``raibert_slip`` entering a mode at t (s): a touchdown notes its time, a liftoff sets T_s to
    the stance's duration and the touchdown time to 0 (``SLIP_MEMORY``)."""
    landing = p[C_STANCE] != 0.0
    standing = m[M_STANCE] > 0.5
    m_new[M_STANCE_TIME] = t - m[M_TOUCHDOWN] if standing and not landing else m[M_STANCE_TIME]
    m_new[M_TOUCHDOWN] = (t if not standing else m[M_TOUCHDOWN]) if landing else 0.0
    m_new[M_STANCE] = 1.0 if landing else 0.0


def slip_law(length: float, speed: float, k_x: float, k_swing: float, stance_time: float) -> ControlLaw:
    """Raibert's foot placement for the SLIP hopper (``slip_placement``, ``slip_stance_clock``):
    its leg of ``length`` (m), commanded ``speed`` (m/s), gains ``k_x`` (s) and ``k_swing`` (1/s),
    and the stance duration ``stance_time`` (s) assumed before the first liftoff."""
    gains = [k_swing, k_x, speed, length]
    params = {"flight": np.array([*gains, 0.0]), "stance": np.array([*gains, 1.0])}
    return ControlLaw(
        "raibert_slip",
        slip_placement,
        1,
        params.__getitem__,
        slip_stance_clock,
        SLIP_MEMORY,
        SLIP_MEMORY_UNITS,
        (stance_time, 0.0, 0.0),
    )


def _make_slip(model: Model, params: dict[str, Any]) -> ControlLaw:
    hopper = model.info.get("slip_hopper") if isinstance(model.info, dict) else None
    if hopper is None:
        raise SceneError(
            f"controller 'raibert_slip' drives the SLIP hopper (robot 'slip_hopper'); {model.system.name} is not one"
        )
    stance_time = params["stance_time"] or math.pi * math.sqrt(hopper["m"] / hopper["k"])
    return slip_law(hopper["l"], params["speed"], params["k_x"], params["k_swing"], stance_time)


SLIP = ControllerSpec(
    "raibert_slip",
    "Raibert's foot placement for the SLIP hopper (its leg's swing rate in flight)",
    {
        "speed": Param(3.0, "commanded forward speed xd*", "m/s"),
        "k_x": Param(0.05, "foot placement gain (m per m/s of speed error)", "s", low=0.0),
        "k_swing": Param(20.0, "leg swing servo gain", "1/s", low=0.0, low_open=True),
        "stance_time": Param(
            0.0,
            "stance duration assumed before the first liftoff; 0: half the spring-mass period, pi sqrt(m/k)",
            "s",
            low=0.0,
        ),
    },
    _make_slip,
)
