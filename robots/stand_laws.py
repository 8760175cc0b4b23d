"""A change of Raibert's runner (``robots.runner_laws``) from the bound (or the gallop) to the
pronk, a standing hop: the bound slows to a stop, both pairs land and stand, damped, until the
pitch and its rate and the vertical motion have died out, then hop off together, and the pronk's
law takes over in that hop's flight, its speed command coming back from 0 (docs/robots.md,
"From the bound to the pronk"). The bound's pitch rate (about 3.5 rad/s) can be taken out only
with both pairs down, and the pronk tolerates little pitch at its start.

Compiled into the controller's functions (``register_jitable``); each leg's stage and the hop's
time are its memory (``STAND_FIELDS``), declared only where a scene schedules such a change.
"""

from __future__ import annotations

import math

from numba.extending import register_jitable

from .leg_laws import foot_terms, stance_torques
from .runner_layout import (
    GAIT_PRONK,
    LEG_MEMORY,
    M_LANDED,
    M_PHASE,
    M_STANCE,
    M_T_S,
    M_THRUST,
    M_TOUCHDOWN,
    M_TOUCHDOWN_LENGTH,
    R_DAMPING,
    R_KD_ATTITUDE,
    R_KP_ATTITUDE,
    R_LEG_LENGTH,
    R_LEGS,
    R_N,
    R_STAND_ACCEL,
    R_STAND_DAMPING,
    R_STAND_KD,
    R_STAND_KP,
    R_STAND_MEMORY,
    R_STAND_SPEED,
    R_STAND_THRUST,
    R_STAND_TIME,
    R_STIFFNESS,
    RL_SHANK,
    RL_STANCE,
    RL_THIGH,
    change_memory,
    commanded_gait,
    leg_at,
    leg_joints,
    leg_length_at,
)

#: Each leg's memory in a change from the bound to the pronk, by name and unit: its stage
#: (``STAND_*``) and the time (s) the hop off the stance on both pairs starts (``NEVER`` until
#: both pairs stand). It follows the other memory and is declared only where the scene schedules
#: such a change (``R_STAND_MEMORY``: its offset).
STAND_FIELDS = (("to_pronk", ""), ("launch", "s"))
S_STAGE, S_LAUNCH = range(len(STAND_FIELDS))
STAND_MEMORY = len(STAND_FIELDS)
#: A leg's stage in a change from the bound to the pronk: none (the commanded gait's law); in
#: flight under the bound's law until it lands; standing, from its first touchdown after the
#: bound has slowed to its liftoff from the hop; the bound slowing to a stop.
STAND_NONE, STAND_GATHER, STAND_HOLD, STAND_SLOW = 0.0, 1.0, 2.0, 3.0
#: A launch time not yet set (s), and how long (s) the hop's thrust takes to come in (a smooth
#: step, ``launch_share``).
NEVER = 1.0e9
LAUNCH_RAMP = 0.01
#: The memory's values at a run's start and what they are measured from
#: (``ControlLaw.memory_frames``: the hop's time is an epoch on the run's clock).
STAND_INITIAL, STAND_FRAMES = (STAND_NONE, NEVER), ("", "t")


@register_jitable
def stand_memory(p, mem):
    """Offset in m of the bound-to-pronk memory (``STAND_FIELDS``) of the leg whose memory starts at
    ``mem``, or -1 where the run carries none."""
    return change_memory(p, R_STAND_MEMORY, STAND_MEMORY, mem)


@register_jitable
def stand_stage(p, m, mem):
    """The stage (``STAND_*``) of the leg whose memory starts at ``mem`` in m in a change from the
    bound to the pronk (``STAND_NONE`` where the run carries no such memory)."""
    at = stand_memory(p, mem)
    return STAND_NONE if at < 0 else m[at + S_STAGE]


@register_jitable
def bound_to_pronk_pending(p, t, m, mem):
    """Whether the leg whose memory starts at ``mem`` in m has a change from the bound to the pronk
    to begin at time t (s): the run carries its memory, the pronk is commanded at t and the leg's
    last touchdown was made under another gait's command."""
    return (
        stand_memory(p, mem) >= 0
        and m[mem + M_LANDED] != 0.0
        and commanded_gait(p, t)[1] == GAIT_PRONK
        and commanded_gait(p, m[mem + M_TOUCHDOWN])[1] != GAIT_PRONK
    )


@register_jitable
def begin_stand(p, t, x, m):
    """A mode entry at (t, x), m the new memory: a leg with a change to the pronk pending slows its
    bound to a stop (``STAND_SLOW``); once every leg slows, at the first touchdown at a forward speed
    below ``stand_speed`` (m/s) the landing pair stands (``STAND_HOLD``) and the other lands
    under the bound's law (``STAND_GATHER``), or stands too where it is down already."""
    legs = int(p[R_LEGS])
    for i in range(legs):
        mem = LEG_MEMORY * i
        if stand_stage(p, m, mem) == STAND_NONE and bound_to_pronk_pending(p, t, m, mem):
            m[stand_memory(p, mem) + S_STAGE] = STAND_SLOW
    for i in range(legs):
        if stand_stage(p, m, LEG_MEMORY * i) != STAND_SLOW:
            return
    if abs(x[int(p[R_N])]) > p[R_STAND_SPEED]:
        return
    for i in range(legs):
        if p[leg_at(p, i) + RL_STANCE] != 0.0 and m[LEG_MEMORY * i + M_STANCE] == 0.0:
            for j in range(legs):
                down = p[leg_at(p, j) + RL_STANCE] != 0.0
                m[stand_memory(p, LEG_MEMORY * j) + S_STAGE] = STAND_HOLD if down else STAND_GATHER
            set_launch(p, t, m)
            return


@register_jitable
def stopping(p, t, m, mem):
    """Whether the leg whose memory starts at ``mem`` in m is in a change from the bound to the pronk
    at time t (s), pending or begun: the bound then slows to a stop."""
    return stand_stage(p, m, mem) != STAND_NONE or bound_to_pronk_pending(p, t, m, mem)


@register_jitable
def leg_speed(p, t, m, mem):
    """The forward speed (m/s) the leg whose memory starts at ``mem`` in m places its foot for at
    time t (s): 0 in a change from the bound to the pronk (``stopping``), then from the hop off the
    stance the commanded speed reached at ``stand_accel`` (m/s^2); else the commanded speed."""
    if stopping(p, t, m, mem):
        return 0.0
    speed = commanded_gait(p, t)[0]
    at = stand_memory(p, mem)
    if at < 0 or m[at + S_LAUNCH] == NEVER:
        return speed
    ramp = p[R_STAND_ACCEL] * max(t - m[at + S_LAUNCH], 0.0)
    return max(min(speed, ramp), -ramp)


@register_jitable
def set_launch(p, t, m):
    """Once every leg stands (``STAND_HOLD``) at time t (s), the hop starts ``stand_time`` (s) later:
    its time into every leg's memory m (``NEVER`` while a leg is still in flight)."""
    legs = int(p[R_LEGS])
    launch = t + p[R_STAND_TIME]
    for j in range(legs):
        if stand_stage(p, m, LEG_MEMORY * j) != STAND_HOLD:
            launch = NEVER
    for j in range(legs):
        m[stand_memory(p, LEG_MEMORY * j) + S_LAUNCH] = launch


@register_jitable
def launch_share(p, t, m, mem):
    """How far (0 to 1) the hop off the stance on both pairs has come in at time t (s) for the leg
    whose memory starts at ``mem`` in m: a smoothstep over ``LAUNCH_RAMP`` s from its launch time."""
    share = min(max((t - m[stand_memory(p, mem) + S_LAUNCH]) / LAUNCH_RAMP, 0.0), 1.0)
    return share * share * (3.0 - 2.0 * share)


@register_jitable
def standing_torques(t, x, m, p, leg, mem, n, stance_count):
    """Hip and knee torques (N m) of a standing leg (``STAND_HOLD``): its spring at ``leg_length``
    damped by ``stand_damping`` (N s/m) and the pronk's attitude torque, until the hop: then the
    rest length grows by ``stand_thrust`` (m), the damping goes back to ``damping`` and, once
    another leg has left, the leg unloads as a pronk's does."""
    share = launch_share(p, t, m, mem)
    settled = max(1.0 - (t - m[mem + M_TOUCHDOWN]) / p[R_STAND_TIME], 0.0)
    rest = p[R_LEG_LENGTH] + settled * max(m[mem + M_TOUCHDOWN_LENGTH] - p[R_LEG_LENGTH], 0.0)
    rest += share * p[R_STAND_THRUST]
    damping = p[R_STAND_DAMPING] + share * (p[R_DAMPING] - p[R_STAND_DAMPING])
    together = stance_count == int(p[R_LEGS])
    attitude = p[R_KP_ATTITUDE] * x[2] + p[R_KD_ATTITUDE] * x[n + 2] if together else 0.0
    unload = share > 0.0 and not together
    q_hip, q_knee, v_hip, v_knee = leg_joints(p, leg, x, n)
    hip, knee = stance_torques(p[leg + RL_THIGH], p[leg + RL_SHANK], q_hip, q_knee, v_hip, v_knee, rest, 0.0,
                               p[R_STIFFNESS], damping, attitude / stance_count, unload)  # fmt: skip
    return hip + upright_torque(p, leg, x, n), knee


@register_jitable
def upright_torque(p, leg, x, n):
    """Hip torque (N m) of a standing leg turning it towards the vertical (a PD on its angle from
    the world's -z axis, ``stand_kp`` N m/rad and ``stand_kd`` N m s/rad): with both feet stuck it
    holds the body over them (the legs and the body are otherwise a linkage free to sway)."""
    q_hip, q_knee, v_hip, v_knee = leg_joints(p, leg, x, n)
    px, pz, j00, j01, j10, j11 = foot_terms(p[leg + RL_THIGH], p[leg + RL_SHANK], q_hip, q_knee)
    pxd, pzd = j00 * v_hip + j01 * v_knee, j10 * v_hip + j11 * v_knee
    world = math.atan2(px, -pz) - x[2]
    world_rate = (-pz * pxd + px * pzd) / (px * px + pz * pz) - x[n + 2]
    return p[R_STAND_KP] * world + p[R_STAND_KD] * world_rate


@register_jitable
def stand_touchdown(p, t, x, m, mem):
    """A leg landing at time t (s), m the new memory: a landing leg of the change stands, and once
    every leg stands the hop's time is set (``set_launch``)."""
    if stand_stage(p, m, mem) == STAND_GATHER:
        m[stand_memory(p, mem) + S_STAGE] = STAND_HOLD
        m[mem + M_TOUCHDOWN_LENGTH] = leg_length_at(p, leg_at(p, mem // LEG_MEMORY), x)
        set_launch(p, t, m)


@register_jitable
def stand_liftoff(p, t, m, i):
    """Leg i lifting off at time t (s), its memory m: from the hop, the pronk's law takes it over
    (``STAND_NONE``), its stance time that of the hop's extension twice, its phase term's apex
    change 0 and its thrust the mean of the legs'; a leg leaving before the hop lands again under
    the bound's law (``STAND_GATHER``)."""
    mem = LEG_MEMORY * i
    if stand_stage(p, m, mem) != STAND_HOLD:
        return
    at = stand_memory(p, mem)
    launch = m[at + S_LAUNCH]
    if t < launch:
        m[at + S_STAGE] = STAND_GATHER
        set_launch(p, t, m)
        return
    m[at + S_STAGE] = STAND_NONE
    m[mem + M_T_S] = min(max(2.0 * (t - launch), 0.02), 0.5)
    m[mem + M_PHASE] = 0.0
    legs = int(p[R_LEGS])
    thrust = 0.0
    for j in range(legs):
        thrust += m[LEG_MEMORY * j + M_THRUST] / legs
    if stand_stage(p, m, LEG_MEMORY * (1 - i)) == STAND_HOLD:
        for j in range(legs):
            m[LEG_MEMORY * j + M_THRUST] = thrust
