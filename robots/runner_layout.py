"""The layout of Raibert's runner's arrays (``robots.runner_laws``, ``robots.stand_laws``): the
controller's parameter array in a mode (``R_*`` head, then ``RL_*`` per leg, then the schedule)
and its memory (``M_*`` per leg, ``MEMORY_FIELDS`` names them), with the few readers of them that
every law of the controller shares.
"""

from __future__ import annotations

import math

from numba.extending import register_jitable

from .leg_laws import foot_terms

#: The gaits' codes in the parameter array: a pronk (the stance hips level the body), a bound and
#: a gallop (the pitch free, each leg pair a hopper on its own hip; the front pair ``bound_phase``
#: of a stride after the hind pair in a bound, ``gallop_phase`` in a gallop).
GAIT_BOUND, GAIT_PRONK, GAIT_GALLOP = 0.0, 1.0, 2.0
#: The head of the controller's parameter array: the robot's native handle, nv, the number of
#: legs, the gait's code, then the gains (``raibert.Gains``, units in
#: ``raibert.RUNNER_PARAMETERS``), then the offsets in the memory of a change from the pronk to the
#: bound (``TRANSITION_FIELDS``) and of one from the bound to the pronk (``STAND_FIELDS``), each -1
#: where none is declared, then the number of the schedule's entries,
#: which follow the legs' entries as (t (s), speed (m/s), gait code) triples.
(
    R_HANDLE,
    R_N,
    R_LEGS,
    R_GAIT,
    R_SPEED,
    R_HEIGHT,
    R_K_X,
    R_K_I,
    R_LEG_LENGTH,
    R_STIFFNESS,
    R_DAMPING,
    R_K_HEIGHT,
    R_KP_ATTITUDE,
    R_KD_ATTITUDE,
    R_KP_JOINT,
    R_KD_JOINT,
    R_MAX_THRUST,
    R_K_PHASE,
    R_LATE_REST,
    R_GALLOP_PHASE,
    R_BOUND_PHASE,
    R_TRANSITION_HOPS,
    R_TRANSITION_HEIGHT,
    R_TRANSITION_REACH,
    R_TRANSITION_HOLD,
    R_TRANSITION_HIND_THRUST,
    R_TRANSITION_FRONT_THRUST,
    R_TRANSITION_PITCH_RATE,
    R_STAND_DAMPING,
    R_STAND_TIME,
    R_STAND_THRUST,
    R_STAND_REACH,
    R_STAND_SPEED,
    R_STAND_KP,
    R_STAND_KD,
    R_STAND_ACCEL,
    R_TRANSITION_MEMORY,
    R_STAND_MEMORY,
    R_SCHEDULE,
) = range(39)
RUNNER_HEAD = 39
#: Each leg's entries: its hip's and knee's velocity indices and positions in u, thigh and shank
#: (m), knee bending sign, the hip's x in the body frame (m), and 1.0 when the leg is in stance
#: in the mode.
RL_HIP, RL_KNEE, RL_U_HIP, RL_U_KNEE, RL_THIGH, RL_SHANK, RL_BEND, RL_OFFSET, RL_STANCE = range(9)
RUNNER_LEG = 9

#: Each leg's memory, by name and unit: in stance at the last mode entry (1.0); its last
#: touchdown's time (s); its last stance's duration T_s (s); its thrust (m); 1.0 once it has
#: landed (its touchdown time and place are then set); the body's x at its last touchdown (m);
#: the foot placement's bias (m); its angle from the world's -z axis at its last liftoff (rad);
#: that liftoff's time (s); a bound's apex target change (m); its length at its last touchdown if
#: another leg stood then (m, else 0: ``late_landing_length``), below which its stance spring's
#: rest length does not go; the time (s) of the apex its hop reaches (``note_apex_time``), at
#: which its flight leg turns from rising to falling.
MEMORY_FIELDS = (
    ("stance", ""),
    ("touchdown", "s"),
    ("T_s", "s"),
    ("thrust", "m"),
    ("landed", ""),
    ("touchdown_x", "m"),
    ("bias", "m"),
    ("liftoff_angle", "rad"),
    ("liftoff", "s"),
    ("phase_height", "m"),
    ("touchdown_length", "m"),
    ("apex", "s"),
)
(
    M_STANCE,
    M_TOUCHDOWN,
    M_T_S,
    M_THRUST,
    M_LANDED,
    M_TOUCHDOWN_X,
    M_BIAS,
    M_LIFTOFF_ANGLE,
    M_LIFTOFF,
    M_PHASE,
    M_TOUCHDOWN_LENGTH,
    M_APEX,
) = range(len(MEMORY_FIELDS))
LEG_MEMORY = len(MEMORY_FIELDS)
#: What memory fields are measured from (``ControlLaw.memory_frames``): the touchdown, liftoff
#: and apex times are epochs on the run's clock, the touchdown place a position along x.
MEMORY_FRAMES = {"touchdown": "t", "liftoff": "t", "touchdown_x": "x", "apex": "t"}
#: Before its first liftoff a leg's liftoff time and its hop's apex are this long ago (s).
LONG_AGO = -1.0e9


@register_jitable
def leg_at(p, i):
    """Offset of leg i's entries in the parameter array p."""
    return RUNNER_HEAD + RUNNER_LEG * i


@register_jitable
def change_memory(p, slot, width, mem):
    """Offset in the memory of a gait change's entries for the leg whose memory starts at ``mem``:
    the change keeps ``width`` entries per leg from the offset ``p[slot]`` (``R_TRANSITION_MEMORY``,
    ``R_STAND_MEMORY``), -1 where the run carries none (no such change scheduled)."""
    start = int(p[slot])
    return -1 if start < 0 else start + width * (mem // LEG_MEMORY)


#: Entries of one schedule entry in the parameter array.
SCHEDULE_ENTRY = 3


@register_jitable
def commanded_gait(p, t):
    """The forward speed (m/s) and gait's code (``GAIT_*``) commanded at time t (s): the
    schedule's last entry at or before t, or the scene's ``speed`` and ``gait`` before its first
    (a schedule's entries are in increasing time)."""
    speed, gait = p[R_SPEED], p[R_GAIT]
    start = RUNNER_HEAD + RUNNER_LEG * int(p[R_LEGS])
    for k in range(int(p[R_SCHEDULE])):
        entry = start + SCHEDULE_ENTRY * k
        if t >= p[entry]:
            speed, gait = p[entry + 1], p[entry + 2]
    return speed, gait


@register_jitable
def leg_joints(p, leg, x, n):
    """The leg's hip and knee angles (rad) and rates (rad/s) at x."""
    hip, knee = int(p[leg + RL_HIP]), int(p[leg + RL_KNEE])
    return x[hip], x[knee], x[n + hip], x[n + knee]


@register_jitable
def leg_length_at(p, leg, x):
    """The length (m) of the leg whose entries start at ``leg`` in p, hip to foot, at x."""
    q_hip, q_knee = x[int(p[leg + RL_HIP])], x[int(p[leg + RL_KNEE])]
    px, pz = foot_terms(p[leg + RL_THIGH], p[leg + RL_SHANK], q_hip, q_knee)[:2]
    return math.sqrt(px * px + pz * pz)
