"""Raibert's biped runner for two articulated legs (``robots.biped``), written once: the
controller's functions (``biped_control``, ``biped_enter``: a ``legsim.control.ControlLaw`` that
the Python loop and the compiled kernel both evaluate), built on the runner's scalar laws
(``robots.leg_laws``: ``stance_torques``, ``touchdown_angle``).

The biped runs one leg at a time (Raibert, *Legged Robots That Balance*, 1986, ch. 4): the
leg that lands next is the **active** one, the other the **idle** one. At a touchdown the
other leg becomes the active one: it swings forward during the stance, and in the flight after
the liftoff it is placed for the next touchdown while the leg that just left retracts. Angles of
a foot are from the body's -z axis (body frame) or the world's (world frame) towards +x.

The parameter array in a mode (``B_*`` head, then per leg the runner's ``RL_*`` entries) holds
the gains, each leg's geometry and whether the leg is in stance in that mode; the memory
(``MEMORY_FIELDS``) is what the controller carries from step to step.
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots._native.calls import lsn_gravity
from numba.extending import register_jitable

from legsim.compiled.functions import model_function, scratch

from .leg_laws import foot_terms, stance_torques, touchdown_angle
from .runner_laws import RL_HIP, RL_KNEE, RL_SHANK, RL_STANCE, RL_THIGH, RL_U_HIP, RL_U_KNEE, RUNNER_LEG, ballistic_apex

#: The head of the parameter array: the robot's native handle, nv, then the gains
#: (``biped.Gains``, units in ``biped.BIPED_PARAMETERS``).
(
    B_HANDLE,
    B_N,
    B_SPEED,
    B_HEIGHT,
    B_K_X,
    B_K_I,
    B_LEG_LENGTH,
    B_STIFFNESS,
    B_DAMPING,
    B_K_HEIGHT,
    B_MAX_THRUST,
    B_KP_ATTITUDE,
    B_KD_ATTITUDE,
    B_KP_JOINT,
    B_KD_JOINT,
    B_SWING_SHARE,
    B_SWING_STIFFNESS,
    B_SWING_DAMPING,
    B_PRELOAD,
) = range(19)
BIPED_HEAD = 19

#: The memory, by name and unit: the index of the leg that lands next (0 or 1, the legs in the
#: order the scene declares their feet); each leg in stance at the last mode entry (1.0); the
#: last stance's duration T_s (s); the thrust (m); the last step's touchdown time (s) and the
#: body's x there (m); 1.0 once a leg has landed; the foot placement's bias (m); the time (s)
#: of the apex the body reaches after the last liftoff (ballistic estimate at the liftoff); each
#: leg's last liftoff time (s).
MEMORY_FIELDS = (
    ("next", ""),
    ("stance_0", ""),
    ("stance_1", ""),
    ("T_s", "s"),
    ("thrust", "m"),
    ("touchdown", "s"),
    ("touchdown_x", "m"),
    ("landed", ""),
    ("bias", "m"),
    ("apex", "s"),
    ("liftoff_0", "s"),
    ("liftoff_1", "s"),
)
(
    M_NEXT,
    M_STANCE,
    _M_STANCE_1,
    M_T_S,
    M_THRUST,
    M_TOUCHDOWN,
    M_TOUCHDOWN_X,
    M_LANDED,
    M_BIAS,
    M_APEX,
    M_LIFTOFF,
    _M_LIFTOFF_1,
) = range(len(MEMORY_FIELDS))
#: What memory fields are measured from (``ControlLaw.memory_frames``): the touchdown, apex and
#: liftoff times are epochs on the run's clock, the touchdown place a position along x.
MEMORY_FRAMES = {"touchdown": "t", "apex": "t", "liftoff_0": "t", "liftoff_1": "t", "touchdown_x": "x"}
#: Before the first liftoff the apex and the liftoffs were this long ago (s).
LONG_AGO = -1.0e9
#: How long (s) after its liftoff a leg that touches the ground again pulls its foot up instead
#: of pushing: it lifted off where its contact force passed 0, so at once after the liftoff that
#: force's sign is a matter of rounding (the runner's bound has the same rule).
REFRACTORY = 0.01
#: Bounds (s) of a measured stance duration.
SHORTEST_STANCE, LONGEST_STANCE = 0.02, 0.5


@register_jitable
def leg_offset(i):
    """Offset of leg i's entries in the parameter array."""
    return BIPED_HEAD + RUNNER_LEG * i


@register_jitable
def body_angle(p, leg, x, n):
    """The leg's foot angle (rad) from the body's -z axis and its rate (rad/s) at x."""
    hip, knee = int(p[leg + RL_HIP]), int(p[leg + RL_KNEE])
    px, pz, j00, j01, j10, j11 = foot_terms(p[leg + RL_THIGH], p[leg + RL_SHANK], x[hip], x[knee])
    pxd, pzd = j00 * x[n + hip] + j01 * x[n + knee], j10 * x[n + hip] + j11 * x[n + knee]
    return math.atan2(px, -pz), (-pz * pxd + px * pzd) / (px * px + pz * pz)


@register_jitable
def servo_leg(p, leg, x, n, gravity, length, angle, rate):
    """Hip and knee torques (N m) holding the leg's foot at ``length`` (m) by a spring along the
    leg (``swing_stiffness``, ``swing_damping``, through J^T as the stance spring), and at
    ``angle`` (rad, from the body's -z axis) moving at ``rate`` (rad/s) by a hip PD
    (``kp_joint``, ``kd_joint``), with the joints' generalised gravity added: a landing leg
    pushes along itself under the flight's input as under the stance's."""
    hip, knee = int(p[leg + RL_HIP]), int(p[leg + RL_KNEE])
    px, pz, j00, j01, j10, j11 = foot_terms(p[leg + RL_THIGH], p[leg + RL_SHANK], x[hip], x[knee])
    pxd, pzd = j00 * x[n + hip] + j01 * x[n + knee], j10 * x[n + hip] + j11 * x[n + knee]
    r2 = px * px + pz * pz
    r = math.sqrt(r2)  # not hypot: numba's and Python's differ in the last bit
    rdot = (px * pxd + pz * pzd) / r
    force = p[B_SWING_STIFFNESS] * (length - r) - p[B_SWING_DAMPING] * rdot
    fx, fz = force * px / r, force * pz / r
    now, now_rate = math.atan2(px, -pz), (-pz * pxd + px * pzd) / r2
    # the foot's angle from the body's -z axis falls as the hip angle grows
    swing = -(p[B_KP_JOINT] * (angle - now) + p[B_KD_JOINT] * (rate - now_rate))
    return j00 * fx + j10 * fz + swing + gravity[hip], j01 * fx + j11 * fz + gravity[knee]


@register_jitable
def stance_leg(p, leg, x, n, thrust, attitude, unload):
    """Hip and knee torques (N m) of a stance leg: the runner's spring along the leg with
    ``thrust`` (m) and the hip's ``attitude`` torque (N m); ``unload``: it pulls its foot up
    while it extends."""
    hip, knee = int(p[leg + RL_HIP]), int(p[leg + RL_KNEE])
    return stance_torques(p[leg + RL_THIGH], p[leg + RL_SHANK], x[hip], x[knee], x[n + hip], x[n + knee],
                          p[B_LEG_LENGTH], thrust, p[B_STIFFNESS], p[B_DAMPING], attitude, unload)  # fmt: skip


@register_jitable
def flight_leg(t, x, m, p, i, n, gravity, other_stance):
    """Hip and knee torques (N m) of leg i off the ground. The active leg in a flight phase is
    placed by Raibert's ``touchdown_angle`` (the neutral point of the last stance's duration, the
    speed correction and the integral's bias), and lengthens from the swing share of its length
    at the other leg's liftoff to ``leg_length - preload`` at the apex predicted then (a time,
    not the sign of the vertical speed: a switch on a state holds the body at the apex, a
    sliding mode). The preload makes the stance spring push from the touchdown on.
    Otherwise (the idle leg, or the active leg while the other stands) the leg is held short at
    the mirror image of the other leg in the body frame, angle and rate, so that the two swing
    in opposite ways and their reactions on the trunk cancel."""
    leg = leg_offset(i)
    length = p[B_LEG_LENGTH] - p[B_PRELOAD]
    short = p[B_SWING_SHARE] * p[B_LEG_LENGTH]
    if int(m[M_NEXT]) == i and not other_stance:
        world = touchdown_angle(x[n], m[M_T_S], p[B_K_X], p[B_SPEED], length, m[M_BIAS])
        liftoff, apex = m[M_LIFTOFF + 1 - i], m[M_APEX]
        share = min(max((t - liftoff) / (apex - liftoff), 0.0), 1.0) if apex > liftoff else 1.0
        return servo_leg(p, leg, x, n, gravity, short + share * (length - short), world + x[2], 0.0)
    angle, rate = body_angle(p, leg_offset(1 - i), x, n)
    return servo_leg(p, leg, x, n, gravity, short, -angle, -rate)


@model_function
def biped_control(t, x, m, p, u):
    """The biped's torques into u (N m, one per actuated joint) at (t, x) in the mode of p, from
    the memory m (module docstring). A leg alone in stance is the spring with the thrust and the
    whole attitude torque ``kp pitch + kd pitch_rate`` (N m); of two legs in stance the one
    behind pulls its foot up while it extends, so that it lifts off, and the other is the
    spring (which leg is behind is read from the legs' angles, not from the memory). Legs off
    the ground by ``flight_leg``."""
    n = int(p[B_N])
    u[:] = 0.0
    # In a flight phase the whole robot falls freely: its joints feel no gravity to compensate.
    gravity = scratch(n)
    gravity[:] = 0.0
    if p[leg_offset(0) + RL_STANCE] != 0.0 or p[leg_offset(1) + RL_STANCE] != 0.0:
        lsn_gravity(np.int64(p[B_HANDLE]), x.ctypes.data, gravity.ctypes.data)
    attitude = p[B_KP_ATTITUDE] * x[2] + p[B_KD_ATTITUDE] * x[n + 2]
    for i in range(2):
        leg, other = leg_offset(i), leg_offset(1 - i)
        other_stance = p[other + RL_STANCE] != 0.0
        if p[leg + RL_STANCE] == 0.0:
            hip, knee = flight_leg(t, x, m, p, i, n, gravity, other_stance)
        elif other_stance and body_angle(p, leg, x, n)[0] < body_angle(p, other, x, n)[0]:
            hip, knee = stance_leg(p, leg, x, n, 0.0, 0.0, True)
        else:
            unload = t - m[M_LIFTOFF + i] < REFRACTORY
            hip, knee = stance_leg(p, leg, x, n, m[M_THRUST], attitude, unload)
        u[int(p[leg + RL_U_HIP])] += hip
        u[int(p[leg + RL_U_KNEE])] += knee


@model_function
def biped_enter(t, x, m, p, m_new):
    """Entering the mode of p at (t, x): the new memory from m into m_new. The active leg
    touching down ends a step: the stride's mean speed since the last step's touchdown moves the
    placement's bias by ``k_i`` times its error, the touchdown is noted, and the other leg
    becomes the active one. A leg lifting off notes its time, the stance's duration T_s (clipped
    to [0.02, 0.5] s), the apex time the body's vertical speed reaches, and adapts the thrust to
    the apex height error (``k_height``, within [0, max_thrust])."""
    m_new[:] = m
    n = int(p[B_N])
    for i in range(2):
        stance = p[leg_offset(i) + RL_STANCE] != 0.0
        was = m[M_STANCE + i] != 0.0
        if stance and not was and int(m[M_NEXT]) == i:
            if m[M_LANDED] != 0.0 and t > m[M_TOUCHDOWN]:
                stride_speed = (x[0] - m[M_TOUCHDOWN_X]) / (t - m[M_TOUCHDOWN])
                m_new[M_BIAS] += p[B_K_I] * (stride_speed - p[B_SPEED])
            m_new[M_TOUCHDOWN] = t
            m_new[M_TOUCHDOWN_X] = x[0]
            m_new[M_LANDED] = 1.0
            m_new[M_NEXT] = 1.0 - i
        elif was and not stance:
            m_new[M_LIFTOFF + i] = t
            if int(m[M_NEXT]) != i:
                m_new[M_T_S] = min(max(t - m[M_TOUCHDOWN], SHORTEST_STANCE), LONGEST_STANCE)
                m_new[M_APEX], apex = ballistic_apex(t, x[1], x[n + 1])
                thrust = m[M_THRUST] + p[B_K_HEIGHT] * (p[B_HEIGHT] - apex)
                m_new[M_THRUST] = min(max(thrust, 0.0), p[B_MAX_THRUST])
        m_new[M_STANCE + i] = 1.0 if stance else 0.0
