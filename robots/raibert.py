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

``raibert_runner`` (``RunnerLaw``, written once in ``robots.runner_laws``) drives articulated legs
(a hip and a knee per leg, a point foot): the flight posture by a joint PD with gravity compensation
on the inverse kinematics of the foot placement, the stance spring through the leg Jacobian (tau =
J^T f); what it carries from hop to hop (each leg's stance times, thrust, the placement's integral)
is its declared memory. ``raibert_slip`` (``slip_law``, a ``ControlLaw`` written once as compiled
functions) drives the SLIP hopper (``robots/slip_hopper.py``): its input is the massless leg's swing
rate in flight, a servo to the foot placement's leg angle; its spring is passive and the SLIP
conserves energy, so its hopping height needs no thrust (it trades with the speed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from legsim.builders import Model, Param
from legsim.compiled.functions import model_function
from legsim.control import ControlLaw, ControllerSpec
from legsim.errors import SceneError

from . import runner_laws as laws
from . import stand_laws
from .controllers import bridge_of
from .gait_changes import (
    CHANGE_PARAMETERS,
    STAND_PARAMETERS,
    TRANSITION_PARAMETERS,
    changes_bound_to_pronk,
    changes_pronk_to_bound,
    check_reach,
    declare_memory,
)
from .hopper_laws import swing_rate_compiled
from .leg_laws import foot_terms, joint_angles, touchdown_angle


@dataclass(frozen=True)
class Leg:
    """An articulated leg: hip and knee velocity indices and positions in u, segment lengths
    (m), the knee's bending sign (+1: positive knee angles), the hip's x in the body frame (m) and
    the foot's contact name."""

    contact: str
    hip: int
    knee: int
    u_hip: int
    u_knee: int
    thigh: float
    shank: float
    bend: float
    offset: float = 0.0


def leg_point(leg: Leg, q_hip: float, q_knee: float) -> np.ndarray:
    """Foot relative to the hip in the body frame (x, z) (m)."""
    return np.array(foot_terms(leg.thigh, leg.shank, q_hip, q_knee)[:2])


def leg_jacobian(leg: Leg, q_hip: float, q_knee: float) -> np.ndarray:
    """d(foot - hip)/d(q_hip, q_knee) in the body frame (2, 2)."""
    return np.array(foot_terms(leg.thigh, leg.shank, q_hip, q_knee)[2:]).reshape(2, 2)


def leg_angles(leg: Leg, length: float, angle: float) -> tuple[float, float]:
    """(q_hip, q_knee) putting the foot at ``length`` (m) from the hip, ``angle`` (rad) from the
    body's -z axis towards +x (the knee bent by its sign)."""
    return joint_angles(leg.thigh, leg.shank, leg.bend, length, angle)


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
        if model.joints[knee].idx_v in dofs and model.joints[hip].idx_v in dofs:
            legs.append(leg_of(bridge, contact.name, fid, hip, knee))
    return legs


def leg_of(bridge: Any, contact: str, fid: int, hip: int, knee: int) -> Leg:
    """The leg of ``contact`` (its foot frame fid) on the joints hip and knee (Pinocchio joint
    ids, the knee the frame's parent and the hip the knee's): its segments from the model's
    placements, its knee's bending sign from the knee's limits (+1 where they allow more
    positive than negative bending)."""
    model = bridge.model
    dofs = list(bridge.actuated_dofs)
    kv, hv = model.joints[knee].idx_v, model.joints[hip].idx_v
    thigh = float(np.linalg.norm(model.jointPlacements[knee].translation))
    shank = float(np.linalg.norm(model.frames[fid].placement.translation))
    knee_q = model.joints[knee].idx_q
    bend = 1.0 if model.upperPositionLimit[knee_q] > -model.lowerPositionLimit[knee_q] else -1.0
    offset = float(model.jointPlacements[hip].translation[0])
    return Leg(contact, hv, kv, dofs.index(hv), dofs.index(kv), thigh, shank, bend, offset)


#: A declared leg's keys (``controller.parameters.legs``).
LEG_KEYS = ("contact", "hip", "knee")


def declared_legs(bridge: Any, entries: list[Any]) -> list[Leg]:
    """The legs a scene declares (``controller.parameters.legs``: tables of a point contact's
    name and its leg's hip and knee joint names), or SceneError naming the entry and field: the
    contact must be a declared point contact, the joints actuated joints of the model, the knee
    the parent joint of the contact's frame, the hip the knee's parent and hung from the trunk
    (the leg's kinematics are the two-link chain of ``leg_laws.foot_terms`` from the trunk)."""
    model = bridge.model
    contacts = {c.name: c for c in bridge.contacts if getattr(c, "frame", None) and hasattr(c, "tangential")}
    dofs = list(bridge.actuated_dofs)
    legs = []
    for k, entry in enumerate(entries):
        where = f"controller.parameters.legs[{k}]"
        if not isinstance(entry, dict) or set(entry) != set(LEG_KEYS):
            raise SceneError(
                f"{where}: expected a table {{contact = <name>, hip = <joint>, knee = <joint>}}, got {entry!r:.200}"
            )
        for key in LEG_KEYS:
            if not isinstance(entry[key], str):
                raise SceneError(f"{where}.{key}: expected a name, got {entry[key]!r}")
        contact = contacts.get(entry["contact"])
        if contact is None:
            known = sorted(contacts)
            raise SceneError(f"{where}.contact: {entry['contact']!r} is not a point contact of the robot: {known}")
        joints = {}
        for key in ("hip", "knee"):
            name = entry[key]
            jid = model.getJointId(name) if model.existJointName(name) else model.njoints
            if jid >= model.njoints or model.joints[jid].idx_v not in dofs:
                raise SceneError(
                    f"{where}.{key}: {name!r} is not an actuated joint of the robot (robot.parameters.actuated)"
                )
            joints[key] = jid
        fid = model.getFrameId(contact.frame)
        if model.frames[fid].parentJoint != joints["knee"]:
            raise SceneError(f"{where}.knee: {entry['knee']!r} does not carry the contact's frame {contact.frame!r}")
        if model.parents[joints["knee"]] != joints["hip"]:
            raise SceneError(f"{where}.hip: {entry['hip']!r} is not the parent joint of the knee {entry['knee']!r}")
        if model.joints[model.parents[joints["hip"]]].idx_v in dofs:
            raise SceneError(f"{where}.hip: {entry['hip']!r} hangs below another actuated joint, not from the trunk")
        legs.append(leg_of(bridge, contact.name, fid, joints["hip"], joints["knee"]))
    return legs


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
    late_rest: bool
    gallop_phase: float
    bound_phase: float
    transition_hops: int
    transition_height: float
    transition_reach: float
    transition_hold: float
    transition_hind_thrust: float
    transition_front_thrust: float
    transition_pitch_rate: float
    stand_damping: float
    stand_time: float
    stand_thrust: float
    stand_reach: float
    stand_speed: float
    stand_kp: float
    stand_kd: float
    stand_accel: float


@dataclass(frozen=True)
class RunnerLaw(ControlLaw):
    """Raibert's controller for articulated legs (module docstring), a ``ControlLaw`` whose
    functions are ``runner_laws.runner_control`` and ``runner_enter``; ``legs`` and ``gains``
    are what its parameters were made from. ``pronk``: the stance hips servo the pitch (a pronk),
    or leave it free (a bound or a gallop, where each leg pair hops on its own: with the body's
    pitch inertia near m (d/2)^2 the hips move as two separate hoppers, so each leg's thrust and
    swing follow its own hip's height, and a phase term keeps the front pair ``bound_phase`` of a
    stride after the hind pair in a bound, ``gallop_phase`` in a gallop)."""

    legs: tuple[Leg, ...] = ()
    gains: Gains | None = None
    pronk: bool = True


def leg_entries(legs: tuple[Leg, ...], active: Sequence[str]) -> list[float]:
    """Each leg's ``runner_laws.RL_*`` entries of the controller's parameter array, in stance
    (1.0) where its foot's contact is ``active``."""
    values: list[float] = []
    for leg in legs:
        values += [leg.hip, leg.knee, leg.u_hip, leg.u_knee, leg.thigh, leg.shank, leg.bend, leg.offset]
        values.append(1.0 if leg.contact in active else 0.0)
    return values


class RunnerParams:
    """``RunnerLaw.params``: the controller's parameter array in a mode (``runner_layout.R_*``,
    ``RL_*``), each leg in stance where its foot's contact is active, ``memory`` the offsets of the
    gait changes' memory (``R_TRANSITION_MEMORY``, ``R_STAND_MEMORY``: -1 where not declared);
    built once per mode."""

    def __init__(
        self,
        bridge: Any,
        legs: tuple[Leg, ...],
        gains: Gains,
        gait: str,
        schedule: tuple[tuple[float, float, float], ...],
        memory: tuple[int, int] = (-1, -1),
    ) -> None:
        self.bridge = bridge
        head = [bridge.handle, bridge.n, len(legs), GAIT_CODES[gait]]
        head += [getattr(gains, name) for name in GAIN_ORDER]
        head += [*memory, len(schedule)]
        self.head = [float(v) for v in head]
        self.legs = legs
        self.schedule = [float(v) for entry in schedule for v in entry]
        self._made: dict[str, np.ndarray] = {}

    def __call__(self, mode: str) -> np.ndarray:
        made = self._made.get(mode)
        if made is None:
            values = self.head + leg_entries(self.legs, self.bridge.active_contacts(mode)) + self.schedule
            made = self._made[mode] = np.array(values, dtype=float)
        return made


#: The gains in the order of the parameter array's head after ``R_GAIT`` (``runner_layout``).
GAIN_ORDER = (
    "speed",
    "height",
    "k_x",
    "k_i",
    "leg_length",
    "stiffness",
    "damping",
    "k_height",
    "kp_attitude",
    "kd_attitude",
    "kp_joint",
    "kd_joint",
    "max_thrust",
    "k_phase",
    "late_rest",
    "gallop_phase",
    "bound_phase",
    *TRANSITION_PARAMETERS,
    *STAND_PARAMETERS,
)


def runner_law(
    bridge: Any,
    legs: list[Leg],
    gains: Gains,
    gait: str,
    thrust: float,
    schedule: tuple[tuple[float, float, float], ...] = (),
) -> RunnerLaw:
    """Raibert's runner for ``bridge``'s articulated ``legs``, each starting with ``thrust`` (m),
    a stance time of 0.12 s and no touchdown yet, in ``gait`` (``GAITS``); its memory is
    ``runner_laws.MEMORY_FIELDS`` of each leg in turn, named ``<field>_<contact>``, then, where
    the schedule changes the pronk into the bound, its ``TRANSITION_FIELDS`` likewise, and where it
    changes another gait into the pronk, ``stand_laws.STAND_FIELDS`` likewise. ``schedule``:
    (t (s), speed (m/s), gait code ``GAIT_CODES``) in increasing time, each commanding its speed
    and gait from its t on (``gains.speed`` and ``gait`` before the first)."""
    names = tuple(f"{field}_{leg.contact}" for leg in legs for field, _ in laws.MEMORY_FIELDS)
    units = tuple(unit for _ in legs for _, unit in laws.MEMORY_FIELDS)
    initial = {"T_s": 0.12, "thrust": thrust, "liftoff": laws.LONG_AGO, "apex": laws.LONG_AGO}
    memory = tuple(initial.get(field, 0.0) for _ in legs for field, _ in laws.MEMORY_FIELDS)
    frames = tuple(laws.MEMORY_FRAMES.get(field, "") for _ in legs for field, _ in laws.MEMORY_FIELDS)
    contacts = [leg.contact for leg in legs]
    offsets = [-1, -1]
    changes = (
        (changes_pronk_to_bound, laws.TRANSITION_FIELDS, (0.0, 0.0), ("", "")),
        (changes_bound_to_pronk, stand_laws.STAND_FIELDS, stand_laws.STAND_INITIAL, stand_laws.STAND_FRAMES),
    )
    for k, (scheduled, fields, values, field_frames) in enumerate(changes):
        if scheduled(schedule, GAIT_CODES[gait]):
            offsets[k] = len(memory)
            more = declare_memory(contacts, fields, values, field_frames)
            names, units, memory, frames = names + more[0], units + more[1], memory + more[2], frames + more[3]
    return RunnerLaw(
        "raibert_runner",
        laws.runner_control,
        len(bridge.actuated_dofs),
        RunnerParams(bridge, tuple(legs), gains, gait, schedule, (offsets[0], offsets[1])),
        laws.runner_enter,
        names,
        units,
        memory,
        memory_frames=frames,
        legs=tuple(legs),
        gains=gains,
        pronk=gait == "pronk",
    )


RUNNER_PARAMETERS = {
    "gait": Param(
        "pronk",
        "pronk: the stance hips keep the body level; bound: the pitch is left free, the front pair bound_phase of "
        "a stride after the hind pair; gallop: as a bound, the front pair gallop_phase of a stride after the hind",
        choices=("pronk", "bound", "gallop"),
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
    "gallop_phase": Param(
        0.45,
        "gallop: share of a stride from a hind touchdown to the next front touchdown that the phase term holds",
        "",
        low=0.0,
        low_open=True,
        high=1.0,
        high_open=True,
    ),
    "bound_phase": Param(
        0.5,
        "bound: share of a stride from a hind touchdown to the next front touchdown that the phase term holds "
        "(below the hind pair's share of the stride in stance: one flight a stride)",
        "",
        low=0.0,
        low_open=True,
        high=1.0,
        high_open=True,
    ),
    "legs": Param(
        [],
        "the legs: tables {contact = <point contact>, hip = <joint>, knee = <joint>}, the foot's contact and its "
        "leg's actuated hip and knee; empty: every point contact whose frame hangs below two actuated revolute joints",
    ),
    "schedule": Param(
        [],
        "speed and gait changes during the run: tables {t = s, speed = m/s, gait = 'pronk', 'bound' or 'gallop'} in "
        "increasing t, each commanding its speed and gait from its t on (one left out: the one before; before the "
        "first entry: speed and gait)",
    ),
    "late_rest": Param(
        False,
        "a leg landing while another stands keeps its touchdown length as its stance spring's rest length where "
        "that is longer (else it pulls its foot up at once: the forward pronk at 1 m/s lands its feet apart)",
    ),
    "kp_joint": Param(60.0, "flight joint stiffness", "N m/rad", low=0.0),
    "kd_joint": Param(2.0, "flight joint damping", "N m s/rad", low=0.0),
    **CHANGE_PARAMETERS,
}


def _make_runner(model: Model, params: dict[str, Any]) -> RunnerLaw:
    bridge = bridge_of(model, "raibert_runner")
    legs = declared_legs(bridge, params["legs"]) if params["legs"] else find_legs(bridge)
    if not legs:
        raise SceneError(
            "controller 'raibert_runner' found no articulated leg: a point contact on a frame below "
            "two actuated revolute joints (hip, knee)"
        )
    schedule = command_schedule(params["schedule"], params["speed"], params["gait"])
    pairs = params["gait"] != "pronk" or any(entry[2] != GAIT_CODES["pronk"] for entry in schedule)
    if pairs and len(legs) != 2:
        raise SceneError(
            f"controller.parameters.gait = {params['gait']!r} (or a schedule's) needs two leg pairs (hind and "
            f"front), the robot has {len(legs)} articulated leg(s): {', '.join(leg.contact for leg in legs)}"
        )
    if changes_pronk_to_bound(schedule, GAIT_CODES[params["gait"]]):
        check_reach(legs, params["transition_reach"], "transition_reach")
    if changes_bound_to_pronk(schedule, GAIT_CODES[params["gait"]]):
        check_reach(legs, params["stand_reach"], "stand_reach")
    gains = Gains(**{k: params[k] for k in Gains.__dataclass_fields__})
    return runner_law(bridge, legs, gains, params["gait"], params["thrust"], schedule)


#: A schedule entry's keys: its time, and the speed or the gait (or both) it commands from then on.
SCHEDULE_KEYS = ("t", "speed", "gait")
GAITS = ("pronk", "bound", "gallop")
#: Each gait's code in the parameter array (``runner_laws.GAIT_*``).
GAIT_CODES = {"pronk": laws.GAIT_PRONK, "bound": laws.GAIT_BOUND, "gallop": laws.GAIT_GALLOP}


def command_schedule(entries: list[Any], speed: float, gait: str) -> tuple[tuple[float, float, float], ...]:
    """``controller.parameters.schedule`` as (t (s), speed (m/s), gait code ``GAIT_CODES``)
    triples, an entry without a speed or gait keeping the one before it (the scene's ``speed``
    and ``gait`` before the first); or SceneError naming the entry: each a table of a
    time t >= 0 and a speed (a number) or a gait (``GAITS``) or both, the times increasing."""
    schedule: list[tuple[float, float, float]] = []
    code = GAIT_CODES[gait]
    for k, entry in enumerate(entries):
        where = f"controller.parameters.schedule[{k}]"
        if not isinstance(entry, dict) or "t" not in entry or len(entry) < 2 or not set(entry) <= set(SCHEDULE_KEYS):
            raise SceneError(
                f"{where}: expected a table {{t = <s>, speed = <m/s>, gait = 'pronk', 'bound' or 'gallop'}} with a "
                f"speed or a gait or both, got {entry!r:.200}"
            )
        for key in ("t", "speed"):
            value = entry.get(key, 0.0)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SceneError(f"{where}.{key}: expected a number, got {value!r}")
        if "gait" in entry and entry["gait"] not in GAITS:
            raise SceneError(f"{where}.gait: {entry['gait']!r} is not allowed, choose one of {list(GAITS)}")
        t = entry["t"]
        if t < 0.0 or (schedule and t <= schedule[-1][0]):
            after = f" after the previous entry's {schedule[-1][0]:g} s" if schedule else ""
            raise SceneError(f"{where}.t: {t!r} s must be >= 0 and increasing{after}")
        speed = float(entry.get("speed", speed))
        code = GAIT_CODES[entry["gait"]] if "gait" in entry else code
        schedule.append((float(t), speed, code))
    return tuple(schedule)


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
    ``psi* = asin((xd T_s / 2 + k_x (xd - xd*)) / l)`` (``leg_laws.touchdown_angle``), T_s the
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
