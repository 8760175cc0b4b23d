"""Compiled twins of the pronk hopper's modes (``legsim.compiled.CompiledMode``), and of Raibert's
controller for it (``raibert_pronk``), so that a controlled pronk's steps run in the kernel.

A twin computes what the Python callables of ``robots/pronk_hopper.py`` compute, in the same
order: the field of ``PronkHopper.field`` (gravity, then each stance leg's spring and hip torque
in ``LEGS`` order), the guards of ``touchdown`` and ``liftoff`` (one per leg, in ``LEGS`` order,
as ``PronkHopper.system`` lists the transitions) and their resets. One set of functions serves
the four modes: which legs stand is data in p.

The control comes from a record at ``p[P_CTRL:]`` (``CONTROL_KINDS``), written by Python at every
entry of the mode after the controller's reset (``CompiledMode.controls``): ``none`` for a run
without control (u = 0, the Python field's u = None), or ``PronkRaibert.compiled_record`` (its
gains, each leg's stance time T_s now, the leg length and stiffness its law uses). The twin then
computes u as ``PronkRaibert.__call__`` does, through the same scalar rules compiled from their
Python source (``touchdown_angle``, ``stance_torque``), not copies of them.

Past the model's range -- a flying foot more than ``BELOW_GROUND`` under the ground while its
touchdown guard turns negative by its rate (the foot swung through the ground unseen), whose
touchdown Python refuses as a ModelBreakdown -- every guard is nan and the twin is declared with
``fallback``, so that the Python loop takes that step and ends the run as the Python path does.
A step's ordinary overshoot (the guard negative by the height, the rate below it) stays with the
kernel; a touchdown reset below the ground is nan, which the kernel hands back to Python's reset.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from legsim.compiled import CompiledMode

from .control_laws import attitude_share, swing_rate
from .pronk_hopper import BELOW_GROUND, LEGS, MODES, PronkHopper
from .raibert import touchdown_angle_compiled
from .raibert_pronk import RECORD_KIND, RECORD_NAMES, stance_torque

_jit = numba.njit(cache=True, fastmath=False, nogil=True)

# p: the hopper's parameters, which legs stand (1.0 or 0.0, in LEGS order), the control record.
P_M, P_I, P_K, P_L, P_D, P_G, P_STANCE = range(7)
P_CTRL = P_STANCE + len(LEGS)
#: Control record kinds: ``none`` (a run without control), ``raibert_pronk`` (``RECORD_NAMES``).
CONTROL_KINDS = {0.0: "none", RECORD_KIND: "raibert_pronk"}
CTRL_NONE = 0.0
R_K_SWING, R_KP, R_KD, R_SPEED, R_K_X, R_L, R_K, R_T_S = (
    RECORD_NAMES.index(name) for name in ("k_swing", "kp_attitude", "kd_attitude", "speed", "k_x", "l", "k", "T_s_left")
)
RECORD_SIZE = len(RECORD_NAMES)

#: The controller's scalar rules, compiled from their Python source (one rule each).
_touchdown_angle = touchdown_angle_compiled
_stance_torque = _jit(stance_torque)
_swing_rate = _jit(swing_rate)
_attitude_share = _jit(attitude_share)


@_jit
def _layout(p, leg):
    """The index of ``leg``'s coordinate in a state of the mode: its angle psi (flying) or its
    foothold (standing); and the number of flying legs."""
    n_fly = 0
    for j in range(2):
        if p[P_STANCE + j] == 0.0:
            n_fly += 1
    at = 6
    standing = p[P_STANCE + leg] != 0.0
    if standing:
        at += n_fly
    for j in range(leg):
        if (p[P_STANCE + j] != 0.0) == standing:
            at += 1
    return at, n_fly


@_jit
def _hip(x, p, leg):
    """The hip's arm from the centre of mass (m), position (m) and velocity (m/s), as
    ``PronkHopper.hip_arm`` and ``hip``: (arm_x, arm_z, px, pz, vx, vz)."""
    side = 0.5 * p[P_D] * (-1.0 if leg == 0 else 1.0)
    arm0 = side * math.cos(x[2])
    arm1 = -side * math.sin(x[2])
    return arm0, arm1, x[0] + arm0, x[1] + arm1, x[3] + x[5] * arm1, x[4] + x[5] * -arm0


@_jit
def _leg_in_stance(x, p, leg, foot_x):
    """``PronkHopper.leg_in_stance``: the unit vector foot -> hip (n_x, n_z), the length r (m)
    and the rate dr/dt (m/s)."""
    _, _, px, pz, vx, vz = _hip(x, p, leg)
    a0 = px - foot_x
    a1 = pz - 0.0
    r = math.sqrt(a0 * a0 + a1 * a1)
    n0 = a0 / r
    n1 = a1 / r
    return n0, n1, r, n0 * vx + n1 * vz


@_jit
def _foot_in_flight(x, p, leg, psi):
    """``PronkHopper.foot_in_flight``: the foot's position (m) and vertical velocity carried by
    the body (m/s)."""
    _, _, px, pz, _, vz = _hip(x, p, leg)
    angle = psi - x[2]
    length = p[P_L]
    return px + length * math.sin(angle), pz + length * -math.cos(angle), vz - length * math.sin(angle) * x[5]


@_jit
def _control(x, p):
    """u = (swing_left, swing_right, torque_left, torque_right) of the record at p[P_CTRL:]
    (``PronkRaibert.__call__``), zeros for a run without control."""
    u = np.zeros(4)
    c = P_CTRL
    if p[c] == CTRL_NONE:
        return u
    n_stance = p[P_STANCE] + p[P_STANCE + 1]
    for leg in range(2):
        at, _ = _layout(p, leg)
        if p[P_STANCE + leg] != 0.0:
            share = _attitude_share(p[c + R_KP], p[c + R_KD], x[2], x[5], n_stance)
            n0, n1, r, _ = _leg_in_stance(x, p, leg, x[at])
            u[2 + leg] = _stance_torque(share, p[c + R_K], p[c + R_L], r, n0, n1)
        else:
            target = _touchdown_angle(x[3], p[c + R_T_S + leg], p[c + R_K_X], p[c + R_SPEED], p[c + R_L]) + x[2]
            u[leg] = _swing_rate(p[c + R_K_SWING], target, x[at])
    return u


@_jit
def pronk_hopper_field(t, x, p):
    """``PronkHopper.field`` under the record's control, shape (8,)."""
    u = _control(x, p)
    k, length = p[P_K], p[P_L]
    force0 = 0.0
    force1 = -p[P_M] * p[P_G]
    torque = 0.0
    dx = np.zeros(8)
    for leg in range(2):
        at, _ = _layout(p, leg)
        if p[P_STANCE + leg] == 0.0:
            dx[at] = u[leg]
            continue
        hip_torque = u[2 + leg]
        n0, n1, r, _ = _leg_in_stance(x, p, leg, x[at])
        spring = k * (length - r)
        across = hip_torque / r
        on0 = spring * n0 - across * n1
        on1 = spring * n1 - across * -n0
        arm0, arm1, _, _, _, _ = _hip(x, p, leg)
        force0 = force0 + on0
        force1 = force1 + on1
        torque = torque + (hip_torque + arm1 * on0 - arm0 * on1)
    dx[0] = x[3]
    dx[1] = x[4]
    dx[2] = x[5]
    dx[3] = force0 / p[P_M]
    dx[4] = force1 / p[P_M]
    dx[5] = torque / p[P_I]
    return dx


@_jit
def pronk_hopper_guards(x, p):
    """Per leg in ``LEGS`` order: touchdown max(foot height, its rate) of a flying leg, liftoff
    max(l - r, -dr/dt) of a standing one (m); all nan past the model's range: a touchdown guard
    negative by its rate, the foot below the ground, where Python's touchdown would be a
    ModelBreakdown (a step's ordinary overshoot is negative by the height, its rate lower)."""
    out = np.empty(2)
    for leg in range(2):
        at, _ = _layout(p, leg)
        if p[P_STANCE + leg] == 0.0:
            _, height, rate = _foot_in_flight(x, p, leg, x[at])
            if height < -BELOW_GROUND and height < rate < 0.0:
                out[:] = math.nan
                return out
            out[leg] = rate if rate > height else height
        else:
            _, _, r, rate = _leg_in_stance(x, p, leg, x[at])
            short = p[P_L] - r
            out[leg] = -rate if -rate > short else short
    return out


@_jit
def pronk_hopper_resets(x, p, e):
    """The reset of leg e's transition into the target mode's state: a touchdown pins the foot
    where it is (nan when it is below the ground: Python's reset decides), a liftoff leaves
    the leg at its stance angle, psi = atan2(foot_x - hip_x, hip_z) + theta."""
    at, _ = _layout(p, e)
    landing = p[P_STANCE + e] == 0.0
    if landing:
        value, height, _ = _foot_in_flight(x, p, e, x[at])
        if height < -BELOW_GROUND:
            value = math.nan
    else:
        _, _, px, pz, _, _ = _hip(x, p, e)
        value = math.atan2(x[at] - px, pz) + x[2]
    after = p[P_STANCE : P_STANCE + 2].copy()
    after[e] = 1.0 if landing else 0.0
    out = np.empty(8)
    out[:6] = x[:6]
    flying = 6
    standing = 6 + int(2.0 - after[0] - after[1])
    for leg in range(2):
        at_before, _ = _layout(p, leg)
        own = value if leg == e else x[at_before]
        if after[leg] == 0.0:
            out[flying] = own
            flying += 1
        else:
            out[standing] = own
            standing += 1
    return out


def pronk_hopper_twin(hopper: PronkHopper, mode: str) -> CompiledMode:
    """The twin of ``mode`` (one of ``MODES``) of ``hopper``'s system."""
    stance = MODES[mode]
    params = [hopper.m, hopper.I, hopper.k, hopper.l, hopper.d, hopper.g]
    params += [1.0 if leg in stance else 0.0 for leg in LEGS]
    params += [CTRL_NONE] + [0.0] * (RECORD_SIZE - 1)
    return CompiledMode(
        pronk_hopper_field,
        pronk_hopper_guards,
        len(LEGS),
        np.array(params),
        pronk_hopper_resets,
        fallback=True,
        controls=_controls(hopper),
    )


def _controls(hopper: PronkHopper) -> Any:
    """``CompiledMode.controls``: a run without control writes the ``none`` record; a controller
    writes its ``compiled_record(hopper)`` when it has one of kind ``raibert_pronk`` for this
    hopper (None: the run takes the Python path)."""

    def controls(controller: Any) -> Any:
        if controller is None:
            return lambda p: _write_record(p, [CTRL_NONE])
        make = getattr(controller, "compiled_record", None)
        if make is None:
            return None
        record = make(hopper)
        if record is None or len(record) != RECORD_SIZE or record[0] != RECORD_KIND:
            return None
        return lambda p: _write_record(p, make(hopper))

    return controls


def _write_record(p: np.ndarray, record: list[float]) -> None:
    """The control record into p[P_CTRL:] (zeros past its end)."""
    p[P_CTRL:] = 0.0
    p[P_CTRL : P_CTRL + len(record)] = record
