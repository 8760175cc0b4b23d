"""Raibert's runner for articulated legs (``robots.raibert``), written once: the controller's
functions (``runner_control``, ``runner_enter``: a ``legsim.control.ControlLaw`` that the Python
loop and the compiled kernel both evaluate), over the leg's scalar laws (``robots.leg_laws``).

The controller's parameter array in a mode (``R_*`` head, then ``RL_*`` per leg) holds the gains,
each leg's geometry and whether the leg is in stance in that mode; its memory (``M_*`` per leg,
``MEMORY_FIELDS`` names them) is what it carries from hop to hop (``robots.runner_layout``). A
change from the pronk to the bound runs here in stages; one from the bound to the pronk is
``robots.stand_laws``.
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots import _native
from legsim.robots._native.calls import lsn_gravity
from numba.extending import register_jitable

from legsim.compiled.functions import model_function, scratch

from .leg_laws import (
    FALL_TURN,
    foot_terms,
    pronk_flight_torques,
    retract_torques,
    servo_torques,
    stance_torques,
    touchdown_angle,
)
from .runner_layout import (
    GAIT_BOUND,
    GAIT_GALLOP,
    GAIT_PRONK,
    LEG_MEMORY,
    LONG_AGO,
    M_APEX,
    M_BIAS,
    M_LANDED,
    M_LIFTOFF,
    M_LIFTOFF_ANGLE,
    M_PHASE,
    M_STANCE,
    M_T_S,
    M_THRUST,
    M_TOUCHDOWN,
    M_TOUCHDOWN_LENGTH,
    M_TOUCHDOWN_X,
    R_BOUND_PHASE,
    R_DAMPING,
    R_GAIT,
    R_GALLOP_PHASE,
    R_HANDLE,
    R_HEIGHT,
    R_K_HEIGHT,
    R_K_I,
    R_K_PHASE,
    R_K_X,
    R_KD_ATTITUDE,
    R_KD_JOINT,
    R_KP_ATTITUDE,
    R_KP_JOINT,
    R_LATE_REST,
    R_LEG_LENGTH,
    R_LEGS,
    R_MAX_THRUST,
    R_N,
    R_STAND_REACH,
    R_STIFFNESS,
    R_TRANSITION_FRONT_THRUST,
    R_TRANSITION_HEIGHT,
    R_TRANSITION_HIND_THRUST,
    R_TRANSITION_HOLD,
    R_TRANSITION_HOPS,
    R_TRANSITION_MEMORY,
    R_TRANSITION_PITCH_RATE,
    R_TRANSITION_REACH,
    RL_BEND,
    RL_HIP,
    RL_KNEE,
    RL_OFFSET,
    RL_SHANK,
    RL_STANCE,
    RL_THIGH,
    RL_U_HIP,
    RL_U_KNEE,
    RUNNER_HEAD,
    RUNNER_LEG,
    change_memory,
    commanded_gait,
    leg_at,
    leg_joints,
    leg_length_at,
)
from .runner_layout import MEMORY_FIELDS as MEMORY_FIELDS
from .runner_layout import MEMORY_FRAMES as MEMORY_FRAMES
from .stand_laws import (
    STAND_GATHER,
    STAND_HOLD,
    STAND_NONE,
    begin_stand,
    bound_to_pronk_pending,
    leg_speed,
    stand_liftoff,
    stand_stage,
    stand_touchdown,
    standing_torques,
    stopping,
)

#: The controller's functions call the native library: load it before they compile (numba
#: resolves its symbols in the process).
_native.load()

#: Each leg's memory in a change from the pronk to the bound, by name and unit: its stage
#: (``TRANSITION_*``) and the low hops it has made. It follows every leg's ``MEMORY_FIELDS`` and is
#: declared only where the scene schedules such a change: a run without one carries the state it
#: carries without the law (an adaptive step's error norm is taken over the whole state).
TRANSITION_FIELDS = (("transition", ""), ("low_hops", ""))
T_STAGE, T_LOW_HOPS = range(len(TRANSITION_FIELDS))
TRANSITION_MEMORY = len(TRANSITION_FIELDS)
#: A leg's stage in a change from the pronk to the bound (memory ``transition``): none (the
#: commanded gait's law); the pronk's low hops (``transition_hops`` of them, to
#: ``transition_height``); the hind pair held short and the front pair reaching, from the liftoff
#: where the bound's law takes over to the held pair's touchdown and the reaching pair's liftoff.
TRANSITION_NONE, TRANSITION_LOW_HOPS, TRANSITION_HELD, TRANSITION_REACH = 0.0, 1.0, 2.0, 3.0
#: How long (s) after its liftoff a bound's leg that touches the ground again pulls its foot up
#: (at most ``UNLOAD``) instead of pushing: it lifted off where its contact force passed 0, so at
#: once after the liftoff that force's sign is a matter of rounding, and a foot put back in
#: stance by it would lift off again and again (an accumulation).
REFRACTORY = 0.01
G = 9.81


@register_jitable
def hop_height(p, leg, x, n):
    """``gait_hop_height`` in the scene's gait (``gait``, before any schedule entry)."""
    return gait_hop_height(p[R_GAIT] == GAIT_PRONK, p, leg, x, n)


@register_jitable
def gait_hop_height(pronk, p, leg, x, n):
    """Height (m) and vertical speed (m/s) the leg hops: the body's centre in a pronk; in a bound,
    where each leg pair hops on its own, the leg's hip (``offset sin(pitch)`` below the centre)."""
    if pronk:
        return x[1], x[n + 1]
    offset, pitch, rate = p[leg + RL_OFFSET], x[2], x[n + 2]
    return x[1] - offset * math.sin(pitch), x[n + 1] - offset * math.cos(pitch) * rate


@register_jitable
def fall_share(t, apex):
    """How far (0 to 1) a flight leg has turned from its rising law to its falling law at time t
    (s), its hop's apex at ``apex`` (s): 0 before the apex, 1 from ``FALL_TURN`` s after it, a
    smoothstep between. A turn on time, not on the sign of the vertical speed (a switch on the
    state can hold the flow at the apex, a sliding mode: the swinging legs push the body back
    across it); and a smooth one, as a torque that jumps at a time stops error control there
    (a step across the jump is accurate only once it is shorter than the clock's rounding)."""
    share = min(max((t - apex) / FALL_TURN, 0.0), 1.0)
    return share * share * (3.0 - 2.0 * share)


# -- a change from the pronk to the bound, in stages ----------------------------------------------
# The bound's pitch rate (about 3.6 rad/s nose-up at a hind touchdown) cannot be made from a
# pronk's hop by a stance on both pairs, and a single pair's stance turns the pitch rate only
# with the vertical speed (about 7.8 rad/s per m/s): so the change lowers the hop first, then
# lands the front pair alone near the top of a hop while the hind pair is held clear, and lets
# the hind pair land once the front stance has pitched the body nose-up (docs/robots.md, "From
# the pronk to the bound").


@register_jitable
def transition_memory(p, m, mem):
    """Offset in m of the transition memory (``TRANSITION_FIELDS``) of the leg whose memory starts
    at ``mem``, or -1 where the run carries none (no change from the pronk to the bound scheduled)."""
    return change_memory(p, R_TRANSITION_MEMORY, TRANSITION_MEMORY, mem)


@register_jitable
def transition_stage(p, m, mem):
    """The stage (``TRANSITION_*``) of the leg whose memory starts at ``mem`` in m in a change from
    the pronk to the bound (``TRANSITION_NONE`` where the run carries no transition memory)."""
    at = transition_memory(p, m, mem)
    return TRANSITION_NONE if at < 0 else m[at + T_STAGE]


@register_jitable
def set_transition_stage(p, m, mem, stage):
    """Sets the stage (``TRANSITION_*``) of the leg whose memory starts at ``mem`` in m."""
    m[transition_memory(p, m, mem) + T_STAGE] = stage


@register_jitable
def pronk_to_bound_pending(p, t, m, mem):
    """Whether the leg whose memory starts at ``mem`` in m has a change from the pronk to the bound
    to begin at time t (s): the run carries the transition memory, the bound is commanded at t and
    the leg's last touchdown was made under the pronk's command (a run that starts in the bound,
    or a leg that never landed, has none)."""
    return (
        transition_memory(p, m, mem) >= 0
        and m[mem + M_LANDED] != 0.0
        and commanded_gait(p, t)[1] == GAIT_BOUND
        and commanded_gait(p, m[mem + M_TOUCHDOWN])[1] == GAIT_PRONK
    )


@register_jitable
def runs_pronk(p, t, m, mem):
    """Whether the leg whose memory starts at ``mem`` in m runs the pronk's law at time t (s): the
    pronk commanded, or a change to the bound that is still in its low hops or not yet begun
    (``pronk_to_bound_pending``: the command may come in the middle of a stance), or a leg standing
    in a change to the pronk (``STAND_HOLD``); not in a change to the pronk before its pairs stand
    (``bound_to_pronk_pending``, ``STAND_SLOW``, ``STAND_GATHER``: the bound's law stops it)."""
    stage, stand = transition_stage(p, m, mem), stand_stage(p, m, mem)
    if stage == TRANSITION_LOW_HOPS or stand == STAND_HOLD:
        return True
    if stage != TRANSITION_NONE or stand != STAND_NONE:
        return False
    if commanded_gait(p, t)[1] == GAIT_PRONK:
        return not bound_to_pronk_pending(p, t, m, mem)
    return pronk_to_bound_pending(p, t, m, mem)


@register_jitable
def begin_transition(p, t, m, mem):
    """A mode entry at time t (s): the leg whose memory starts at ``mem`` begins its change from
    the pronk to a commanded bound with the low hops (``TRANSITION_LOW_HOPS``), none made yet."""
    if transition_stage(p, m, mem) == TRANSITION_NONE and pronk_to_bound_pending(p, t, m, mem):
        set_transition_stage(p, m, mem, TRANSITION_LOW_HOPS)
        m[transition_memory(p, m, mem) + T_LOW_HOPS] = 0.0


@register_jitable
def transition_liftoff(p, m, i):
    """Leg i lifting off, its memory m: in the low hops, one more of them, or after
    ``transition_hops`` of them True (the bound's law takes over at this liftoff, ``take_over``);
    a reaching front leg ends its change here, its stance spring back at its own rest length."""
    mem = LEG_MEMORY * i
    stage = transition_stage(p, m, mem)
    if stage == TRANSITION_REACH:
        set_transition_stage(p, m, mem, TRANSITION_NONE)
        m[mem + M_TOUCHDOWN_LENGTH] = 0.0
    if stage != TRANSITION_LOW_HOPS:
        return False
    hops = transition_memory(p, m, mem) + T_LOW_HOPS
    if m[hops] < p[R_TRANSITION_HOPS]:
        m[hops] += 1.0
        return False
    return True


@register_jitable
def take_over(p, m, i):
    """The bound's law takes over leg i at its liftoff, its memory m: the front pair reaches
    (``TRANSITION_REACH``, to land alone near the top of the hop) and the hind pair is held short
    (``TRANSITION_HELD``), each thrust seeded with the bound's own (``transition_front_thrust``,
    ``transition_hind_thrust``, m), so that the first bound strides push as the settled ones."""
    mem = LEG_MEMORY * i
    if is_front(p, i):
        set_transition_stage(p, m, mem, TRANSITION_REACH)
        m[mem + M_THRUST] = p[R_TRANSITION_FRONT_THRUST]
    else:
        set_transition_stage(p, m, mem, TRANSITION_HELD)
        m[mem + M_THRUST] = p[R_TRANSITION_HIND_THRUST]


@register_jitable
def apex_target(p, m, mem):
    """The apex height (m) the thrust of the leg whose memory starts at ``mem`` adapts to: in a
    change's low hops ``transition_height`` (a lower hop brings the vertical speed to the bound's
    scale), else ``height`` plus the bound's phase term's change."""
    if transition_stage(p, m, mem) == TRANSITION_LOW_HOPS:
        return p[R_TRANSITION_HEIGHT]
    return p[R_HEIGHT] + m[mem + M_PHASE]


@register_jitable
def falling_length(p, x, n, m, mem):
    """The length (m) a bound's flight leg swings out to once its hip falls: ``leg_length``; in a
    change from the pronk the front pair's ``transition_reach`` (so that it lands alone near the
    top of the hop), and the hind pair held at ``transition_hold`` of ``leg_length`` until the
    front stance has pitched the body nose-up (a negative pitch rate) past
    ``transition_pitch_rate`` (rad/s), the pitch rate of the bound's hind touchdowns; in a change
    to the pronk the pair landing after the other stands, ``stand_reach``."""
    stage = transition_stage(p, m, mem)
    if stage == TRANSITION_REACH:
        return p[R_TRANSITION_REACH]
    if stand_stage(p, m, mem) == STAND_GATHER:
        return p[R_STAND_REACH]
    if stage == TRANSITION_HELD and -x[n + 2] < p[R_TRANSITION_PITCH_RATE]:
        return p[R_TRANSITION_HOLD] * p[R_LEG_LENGTH]
    return p[R_LEG_LENGTH]


@register_jitable
def taking_over_from_pronk(p, m, mem):
    """Whether the leg whose memory starts at ``mem`` in m is in the flight where the bound's law
    takes over from the pronk's (held or reaching, until its touchdown)."""
    stage = transition_stage(p, m, mem)
    return stage in (TRANSITION_HELD, TRANSITION_REACH)


@register_jitable
def is_front(p, i):
    """Whether leg i is the front pair: its hip ahead of the other leg's (two legs)."""
    return p[leg_at(p, i) + RL_OFFSET] > p[leg_at(p, 1 - i) + RL_OFFSET]


@register_jitable
def flight_torques(t, x, m, p, leg, mem, n, gravity):
    """Hip and knee torques (N m) of a flight leg: a pronk's foot placement servo
    (``pronk_flight_torques``); a bound's leg retracts holding its liftoff angle while its hip
    rises (``retract_torques``; in the flight where the bound takes over from the pronk, the
    pronk's rising law instead) and swings to the placement of its own hip's speed at its falling
    length (``falling_length``) once the hip falls (``servo_torques``). The leg turns from rising
    to falling over ``FALL_TURN`` s after its hop's apex time (memory ``apex``, ``fall_share``). Its
    placement is for the leg's speed command (``leg_speed``)."""
    q_hip, q_knee, v_hip, v_knee = leg_joints(p, leg, x, n)
    g_hip, g_knee = gravity[int(p[leg + RL_HIP])], gravity[int(p[leg + RL_KNEE])]
    thigh, shank, bend, offset = p[leg + RL_THIGH], p[leg + RL_SHANK], p[leg + RL_BEND], p[leg + RL_OFFSET]
    speed = leg_speed(p, t, m, mem)
    fall = fall_share(t, m[mem + M_APEX])
    length, kp, kd = p[R_LEG_LENGTH], p[R_KP_JOINT], p[R_KD_JOINT]
    if runs_pronk(p, t, m, mem):
        return pronk_flight_torques(thigh, shank, bend, offset, q_hip, q_knee, v_hip, v_knee, x[2], x[n], fall,
                                    m[mem + M_T_S], m[mem + M_BIAS], speed, p[R_K_X], length, kp, kd, g_hip,
                                    g_knee)  # fmt: skip
    hip, knee = 0.0, 0.0
    if fall < 1.0 and taking_over_from_pronk(p, m, mem):
        # Both pairs left the ground together, as in a pronk: the pronk's rising law lifts the feet
        # clear (the bound's retraction from that liftoff sets the pairs chattering and falling).
        hip, knee = pronk_flight_torques(thigh, shank, bend, offset, q_hip, q_knee, v_hip, v_knee, x[2], x[n], 0.0,
                                         m[mem + M_T_S], m[mem + M_BIAS], speed, p[R_K_X], length, kp, kd, g_hip,
                                         g_knee)  # fmt: skip
    elif fall < 1.0:
        hip, knee = retract_torques(thigh, shank, q_hip, q_knee, v_hip, v_knee, x[2], x[n + 2],
                                    m[mem + M_LIFTOFF_ANGLE], length, kp, kd, g_hip, g_knee)  # fmt: skip
    if fall > 0.0:
        reach = falling_length(p, x, n, m, mem)
        hip_speed = x[n] - offset * math.sin(x[2]) * x[n + 2]
        world = touchdown_angle(hip_speed, m[mem + M_T_S], p[R_K_X], speed, reach, m[mem + M_BIAS])
        swing = servo_torques(thigh, shank, bend, q_hip, q_knee, v_hip, v_knee, reach, world + x[2], kp, kd, g_hip,
                              g_knee)  # fmt: skip
        hip, knee = (1.0 - fall) * hip + fall * swing[0], (1.0 - fall) * knee + fall * swing[1]
    return hip, knee


@model_function
def runner_control(t, x, m, p, u):
    """The runner's torques into u (N m, one per actuated joint) at (t, x) in the mode of p, from
    the memory m: each stance leg's spring along itself with thrust and, where it runs the pronk's
    law (``runs_pronk``), its share of the attitude torque (a leg standing in a change to the
    pronk: ``standing_torques``); each flight leg's servo (``flight_torques``) with the generalised
    gravity compensated."""
    n, legs = int(p[R_N]), int(p[R_LEGS])
    u[:] = 0.0
    stance_count = 0
    for i in range(legs):
        stance_count += 1 if p[leg_at(p, i) + RL_STANCE] != 0.0 else 0
    gravity = scratch(n)
    gravity[:] = 0.0
    if stance_count < legs:
        lsn_gravity(np.int64(p[R_HANDLE]), x.ctypes.data, gravity.ctypes.data)
    for i in range(legs):
        leg, mem = leg_at(p, i), LEG_MEMORY * i
        if p[leg + RL_STANCE] != 0.0 and stand_stage(p, m, mem) == STAND_HOLD:
            hip, knee = standing_torques(t, x, m, p, leg, mem, n, stance_count)
        elif p[leg + RL_STANCE] != 0.0:
            pronk = runs_pronk(p, t, m, mem)
            attitude = p[R_KP_ATTITUDE] * x[2] + p[R_KD_ATTITUDE] * x[n + 2] if pronk else 0.0
            # A pronk lifts off together: once a leg has left, the others unload while they extend.
            together = pronk and stance_count < legs
            unload = together or (not pronk and t - m[mem + M_LIFTOFF] < REFRACTORY)
            q_hip, q_knee, v_hip, v_knee = leg_joints(p, leg, x, n)
            hip, knee = stance_torques(p[leg + RL_THIGH], p[leg + RL_SHANK], q_hip, q_knee, v_hip, v_knee,
                                       max(p[R_LEG_LENGTH], m[mem + M_TOUCHDOWN_LENGTH]), m[mem + M_THRUST],
                                       p[R_STIFFNESS], p[R_DAMPING],
                                       attitude / stance_count, unload)  # fmt: skip
        else:
            hip, knee = flight_torques(t, x, m, p, leg, mem, n, gravity)
        u[int(p[leg + RL_U_HIP])] += hip
        u[int(p[leg + RL_U_KNEE])] += knee


@model_function
def runner_enter(t, x, m, p, m_new):
    """Entering the mode of p at (t, x): the new memory from m into m_new, leg by leg (a leg reads
    the other's as this entry has already changed it). A leg whose last touchdown was the pronk's
    begins a change to a commanded bound (``begin_transition``), a leg whose last touchdown was
    another gait's one to a commanded pronk (``begin_stand``); a leg touching down notes its
    touchdown (``note_touchdown``), a leg lifting off its liftoff (``note_liftoff``); a leg in
    flight before any liftoff, at a run's start, takes its hop's apex from the state."""
    m_new[:] = m
    n = int(p[R_N])
    begin_stand(p, t, x, m_new)
    for i in range(int(p[R_LEGS])):
        leg, mem = leg_at(p, i), LEG_MEMORY * i
        stance = p[leg + RL_STANCE] != 0.0
        was = m_new[mem + M_STANCE] != 0.0
        begin_transition(p, t, m_new, mem)
        if stance and not was:
            note_touchdown(t, x, m, p, m_new, i, leg_speed(p, t, m_new, mem))
        elif was and not stance:
            note_liftoff(t, x, p, m_new, i, n)
        m_new[mem + M_STANCE] = 1.0 if stance else 0.0
        if not stance and m_new[mem + M_APEX] == LONG_AGO:
            z, zd = gait_hop_height(runs_pronk(p, t, m_new, mem), p, leg, x, n)
            m_new[mem + M_APEX] = ballistic_apex(t, z, zd)[0]


@register_jitable
def note_touchdown(t, x, m, p, m_new, i, speed):
    """Leg i touching down at (t, x) (m: the memory before this entry, m_new the new one, speed
    the leg's speed command, m/s: ``leg_speed``): the integral term's speed error moves its
    placement's bias (not while the bound stops for the pronk, ``stopping``), and in
    a bound the phase term its apex target (not at the touchdowns that end a change from the
    pronk, whose other pair last landed in the pronk); it notes its touchdown's time and place,
    and its stance spring's rest length: a reaching front leg's touchdown length
    (``TRANSITION_REACH``, that its stance pushes from where it landed, near the top of the hop),
    else with ``late_rest`` ``late_landing_length``. A held leg's change ends here; a leg landing
    in a change to the pronk stands (``stand_touchdown``)."""
    leg, mem = leg_at(p, i), LEG_MEMORY * i
    stage = transition_stage(p, m_new, mem)
    if not runs_pronk(p, t, m_new, mem) and stage == TRANSITION_NONE:
        adapt_phase(t, p, m_new, i, phase_target(p, i, commanded_gait(p, t)[1]))
    if t > m_new[mem + M_TOUCHDOWN] and m_new[mem + M_LANDED] != 0.0 and not stopping(p, t, m_new, mem):
        stride_speed = (x[0] - m_new[mem + M_TOUCHDOWN_X]) / (t - m_new[mem + M_TOUCHDOWN])
        m_new[mem + M_BIAS] += p[R_K_I] * (stride_speed - speed)
    m_new[mem + M_TOUCHDOWN_X] = x[0]
    m_new[mem + M_TOUCHDOWN] = t
    if stage == TRANSITION_REACH:
        m_new[mem + M_TOUCHDOWN_LENGTH] = leg_length_at(p, leg, x)
    elif p[R_LATE_REST] != 0.0:
        m_new[mem + M_TOUCHDOWN_LENGTH] = late_landing_length(p, leg, x, m)
    m_new[mem + M_LANDED] = 1.0
    if stage == TRANSITION_HELD:
        set_transition_stage(p, m_new, mem, TRANSITION_NONE)
    stand_touchdown(p, t, x, m_new, mem)


@register_jitable
def note_liftoff(t, x, p, m, i, n):
    """Leg i lifting off at (t, x), its memory m, by the law of the stance it leaves: it notes its
    stance's duration T_s (clipped to [0.02, 0.5] s), adapts its thrust to the apex its hop will
    reach (``apex_target``), notes that apex's time (``note_apex_time``) and, in a bound, its
    liftoff angle and time. A change's low hops counted, the bound's law may take over here
    (``transition_liftoff``, ``take_over``: the thrust seeded); from the standing hop the pronk's
    law takes over (``stand_liftoff``)."""
    leg, mem = leg_at(p, i), LEG_MEMORY * i
    m[mem + M_T_S] = min(max(t - m[mem + M_TOUCHDOWN], 0.02), 0.5)
    taking_over = transition_liftoff(p, m, i)
    stand_liftoff(p, t, m, i)
    pronk = runs_pronk(p, t, m, mem)
    z, zd = gait_hop_height(pronk, p, leg, x, n)
    apex_time, apex = ballistic_apex(t, z, zd)
    thrust = m[mem + M_THRUST] + p[R_K_HEIGHT] * (apex_target(p, m, mem) - apex)
    m[mem + M_THRUST] = min(max(thrust, 0.0), p[R_MAX_THRUST])
    if taking_over:
        take_over(p, m, i)
    note_apex_time(apex_time, pronk, p, m, i)
    if not pronk:
        q_hip, q_knee = x[int(p[leg + RL_HIP])], x[int(p[leg + RL_KNEE])]
        foot = foot_terms(p[leg + RL_THIGH], p[leg + RL_SHANK], q_hip, q_knee)
        m[mem + M_LIFTOFF_ANGLE] = math.atan2(foot[0], -foot[1]) - x[2]
        m[mem + M_LIFTOFF] = t


@register_jitable
def ballistic_apex(t, z, zd):
    """The time (s) and height (m) of the apex that a body at height z (m) rising at zd (m/s) at
    time t (s) reaches in free flight: t and z themselves when it is not rising."""
    rise = max(zd, 0.0)
    return t + rise / G, z + rise * rise / (2 * G)


@register_jitable
def note_apex_time(apex, pronk, p, m, i):
    """Leg i lifting off: the time (s) its hop's apex is predicted at (ballistic, from the
    liftoff's vertical speed) into its memory m; in a pronk the body hops on all legs, so every
    flight leg's apex time follows the latest liftoff's prediction."""
    for j in range(int(p[R_LEGS])):
        if j == i or (pronk and p[leg_at(p, j) + RL_STANCE] == 0.0):
            m[LEG_MEMORY * j + M_APEX] = apex


@register_jitable
def late_landing_length(p, leg, x, m):
    """The length (m) of a leg touching down at x while another leg already stands (its stance
    spring's rest length is then at least this, so that it does not pull its foot up at once: a
    pronk's pitch in flight lands one foot first, the other's leg stretched by its hip's height);
    0 when it lands alone or with the others (m: the memory before this entry)."""
    for j in range(int(p[R_LEGS])):
        if j != (leg - RUNNER_HEAD) // RUNNER_LEG and m[LEG_MEMORY * j + M_STANCE] != 0.0:
            return leg_length_at(p, leg, x)
    return 0.0


@register_jitable
def phase_target(p, i, gait):
    """The share of a stride (0 to 1) by which leg i's touchdowns should follow the other pair's:
    ``bound_phase`` in a bound, ``gallop_phase`` in a gallop, for the front pair (the leg whose
    hip is ahead of the other's), and the rest of the stride for the hind pair."""
    phase = p[R_GALLOP_PHASE] if gait == GAIT_GALLOP else p[R_BOUND_PHASE]
    return phase if is_front(p, i) else 1.0 - phase


@register_jitable
def adapt_phase(t, p, m, i, target):
    """Bound or gallop, at leg i's touchdown: its lag behind the other pair's last touchdown as a
    share of its own stride, against the ``target`` share (``phase_target``), moves its apex
    target (a late leg hops lower, so that its next flight is shorter)."""
    mem, other = LEG_MEMORY * i, LEG_MEMORY * (1 - i)
    if m[mem + M_LANDED] == 0.0 or m[other + M_LANDED] == 0.0 or t <= m[mem + M_TOUCHDOWN]:
        return
    share = ((t - m[other + M_TOUCHDOWN]) / (t - m[mem + M_TOUCHDOWN])) % 1.0
    m[mem + M_PHASE] = -p[R_K_PHASE] * (share - target)
