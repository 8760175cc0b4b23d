"""Scalar laws of an articulated leg of Raibert's runners (``robots.runner_laws``,
``robots.biped_laws``): its kinematics, its touchdown angle and its stance and flight torques.

They take and return floats only (``register_jitable``: numba compiles them into the
controllers' functions). A leg is a hip and a knee joint (angles q in rad, rates v in rad/s), a
thigh and a shank (m) and a knee bending sign (+1: positive knee angles); angles of the foot are
from the body's -z axis towards +x.
"""

from __future__ import annotations

import math

from numba.extending import register_jitable

from .control_laws import pd_torque

#: Most force (N) a stance leg past its rest length pulls its foot up with, and the largest
#: share of the leg's force times its length the stance hip's attitude torque may take.
UNLOAD = 5.0
ATTITUDE_SHARE = 0.5
#: Extension rate (m/s) at which the stance thrust is fully on; the swing's leg length (share of
#: the touchdown length) while the body rises, so that the foot clears the ground.
THRUST_RATE = 0.2
SWING_SHARE = 0.75
#: How long (s) a flight leg takes to turn from its rising law to its falling law after its hop's
#: apex (``fall_share``): short against a flight of about 0.15 s (a bound turning over 10 ms
#: instead keeps its antiphase less well and its front foot's slips accumulate at 1 m/s), long
#: against the clock's rounding.
FALL_TURN = 0.001
#: Stiffness (N/m) and damping (N s/m) along a bound's rising leg retracting after liftoff.
RETRACT_STIFFNESS = 500.0
RETRACT_DAMPING = 20.0


@register_jitable
def foot_terms(
    thigh: float, shank: float, q_hip: float, q_knee: float
) -> tuple[float, float, float, float, float, float]:
    """The foot relative to the hip in the body frame, (x, z) (m), and its Jacobian's entries
    d(x, z)/d(q_hip, q_knee) row by row (m/rad) (the stance law runs at every guard
    evaluation, where small numpy arrays would cost more than the arithmetic)."""
    a, b = q_hip, q_hip + q_knee
    sa, ca, sb, cb = math.sin(a), math.cos(a), math.sin(b), math.cos(b)
    l1, l2 = thigh, shank
    return -l1 * sa - l2 * sb, -l1 * ca - l2 * cb, -l1 * ca - l2 * cb, -l2 * cb, l1 * sa + l2 * sb, l2 * sb


@register_jitable
def joint_angles(thigh: float, shank: float, bend: float, length: float, angle: float) -> tuple[float, float]:
    """(q_hip, q_knee) (rad) putting the foot at ``length`` (m) from the hip, ``angle`` (rad)
    from the body's -z axis towards +x, the knee bent by its sign ``bend``."""
    l1, l2 = thigh, shank
    c = (length * length - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    knee = bend * math.acos(max(-1.0, min(1.0, c)))
    # the foot's direction is u(q_hip + phi) with phi the angle the shank adds to the thigh's
    phi = math.atan2(l2 * math.sin(knee), l1 + l2 * math.cos(knee))
    return -angle - phi, knee


@register_jitable
def touchdown_angle(xd: float, stance_time: float, k_x: float, speed: float, length: float, bias: float = 0.0) -> float:
    """Raibert's foot placement as a leg angle (rad, from the vertical, forward): the foot
    ``xd T_s / 2 + k_x (xd - xd*) + bias`` (m) ahead of the hip, the neutral point plus the speed
    correction, for forward speed xd and commanded speed (m/s), stance time T_s (s), gain k_x (s)
    and a leg of ``length`` (m); the reach is capped at 0.9 of the length."""
    ahead = xd * stance_time / 2 + k_x * (xd - speed) + bias
    return math.asin(max(-0.9, min(0.9, ahead / length)))


@register_jitable
def stance_torques(
    thigh: float,
    shank: float,
    q_hip: float,
    q_knee: float,
    v_hip: float,
    v_knee: float,
    leg_length: float,
    thrust: float,
    stiffness: float,
    damping: float,
    attitude: float,
    unload: bool,
) -> tuple[float, float]:
    """Hip and knee torques (N m) of a stance leg's spring along itself (stiffness N/m, damping
    N s/m, rest length ``leg_length`` m lengthened by ``thrust`` m while the leg extends), plus
    the hip's ``attitude`` torque (N m). Past its rest length the leg pulls its foot up (at most
    ``UNLOAD`` N; at once while extending when ``unload``), so that it lifts off rather than
    dragging; the attitude torque is kept below ``ATTITUDE_SHARE`` of the leg force times its
    length, so that the foot's force stays well inside the friction cone."""
    px, pz, j00, j01, j10, j11 = foot_terms(thigh, shank, q_hip, q_knee)
    r = math.sqrt(px * px + pz * pz)  # not hypot: numba's and Python's differ in the last bit
    rdot = (px * (j00 * v_hip + j01 * v_knee) + pz * (j10 * v_hip + j11 * v_knee)) / r
    # the thrust comes in with the extension rate (not at once at the bottom of the stance, so
    # that the contact forces, and the guards on them, stay continuous)
    rest = leg_length + thrust * min(max(rdot / THRUST_RATE, 0.0), 1.0)
    force = max(stiffness * (rest - r) - damping * rdot, -UNLOAD)
    if unload and rdot > 0.0:
        force = -UNLOAD
    limit = ATTITUDE_SHARE * max(force, 0.0) * r
    fx, fz = force * px / r, force * pz / r
    return j00 * fx + j10 * fz + max(-limit, min(limit, attitude)), j01 * fx + j11 * fz


@register_jitable
def servo_torques(
    thigh: float,
    shank: float,
    bend: float,
    q_hip: float,
    q_knee: float,
    v_hip: float,
    v_knee: float,
    length: float,
    angle: float,
    kp: float,
    kd: float,
    gravity_hip: float,
    gravity_knee: float,
) -> tuple[float, float]:
    """Hip and knee torques (N m) of the joint PD (kp N m/rad, kd N m s/rad) to the foot at
    ``length`` (m) and ``angle`` (rad, from the body's -z axis), plus the joints' generalized
    gravity (N m)."""
    hip, knee = joint_angles(thigh, shank, bend, length, angle)
    return pd_torque(kp, kd, hip, q_hip, v_hip) + gravity_hip, pd_torque(kp, kd, knee, q_knee, v_knee) + gravity_knee


@register_jitable
def pronk_flight_torques(
    thigh: float,
    shank: float,
    bend: float,
    offset: float,
    q_hip: float,
    q_knee: float,
    v_hip: float,
    v_knee: float,
    pitch: float,
    xd: float,
    fall: float,
    stance_time: float,
    bias: float,
    speed: float,
    k_x: float,
    leg_length: float,
    kp: float,
    kd: float,
    gravity_hip: float,
    gravity_knee: float,
) -> tuple[float, float]:
    """Hip and knee torques (N m) of a pronk's flight leg (hip ``offset`` m ahead of the body's
    centre along its x axis): the joint PD of ``servo_torques`` to the foot placement of
    ``touchdown_angle`` at the body's forward speed xd (m/s), the leg at ``SWING_SHARE`` of
    ``leg_length`` (m) while the body rises and at the full length once it falls, ``fall`` (0 to
    1, ``fall_share``) the share of the change made. The legs' lengths make up for the pitch
    (rad), so that the feet hang at one height and land together (the stance hips then level the
    body)."""
    world = touchdown_angle(xd, stance_time, k_x, speed, leg_length, bias)
    length = (SWING_SHARE + (1.0 - SWING_SHARE) * fall) * leg_length
    # the hip is -offset sin(pitch) above the body's centre
    length -= offset * math.sin(pitch) / math.cos(world)
    return servo_torques(
        thigh, shank, bend, q_hip, q_knee, v_hip, v_knee, length, world + pitch, kp, kd, gravity_hip, gravity_knee
    )


@register_jitable
def retract_torques(
    thigh: float,
    shank: float,
    q_hip: float,
    q_knee: float,
    v_hip: float,
    v_knee: float,
    pitch: float,
    pitch_rate: float,
    liftoff_angle: float,
    leg_length: float,
    kp: float,
    kd: float,
    gravity_hip: float,
    gravity_knee: float,
) -> tuple[float, float]:
    """Hip and knee torques (N m) shortening a bound's rising leg to ``SWING_SHARE`` of
    ``leg_length`` (m) by a spring along itself (through J^T, as the stance spring), plus the
    joints' generalized gravity (N m), the hip holding the leg's ``liftoff_angle`` (rad, from
    the world's -z axis) by a PD (kp N m/rad, kd N m s/rad) on its world angle (a swing towards
    the vertical would lower the foot onto the ground it just left). The joint PD to the same
    posture also bounds, but its gait settles about three times slower (docs/robots.md, "The
    quadruped's bound")."""
    px, pz, j00, j01, j10, j11 = foot_terms(thigh, shank, q_hip, q_knee)
    pxd, pzd = j00 * v_hip + j01 * v_knee, j10 * v_hip + j11 * v_knee
    r = math.sqrt(px * px + pz * pz)  # not hypot: numba's and Python's differ in the last bit
    rdot = (px * pxd + pz * pzd) / r
    force = RETRACT_STIFFNESS * (SWING_SHARE * leg_length - r) - RETRACT_DAMPING * rdot
    fx, fz = force * px / r, force * pz / r
    world = math.atan2(px, -pz) - pitch
    world_rate = (-pz * pxd + px * pzd) / (r * r) - pitch_rate
    # the foot's angle from the body's -z axis falls as the hip angle grows
    swing = -(kp * (liftoff_angle - world) - kd * world_rate)
    return j00 * fx + j10 * fz + swing + gravity_hip, j01 * fx + j11 * fz + gravity_knee
