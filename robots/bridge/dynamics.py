"""The flow of a bridge mode, as model functions (``legsim.model``) over the mode's parameter
array p (``layout``), calling Pinocchio's C++ algorithms through the native library.

Applied generalised forces tau: stance spring legs through their hips' Jacobians, joint damping
and the actuated joints' input u. Without active rigid contacts the acceleration is the forward
dynamics ``M(q)^-1 (tau - b(q, v))`` (``lsn_aba``: M and b from the robot's planar bodies, or from
Pinocchio's crba and RNEA for a model out of the plane, and a Cholesky factor of M); with them,
the KKT contact dynamics ``M a + b = tau + W^T lambda, J a + dJ/dt v = 0`` through the Schur
complement of the same factor (``lsn_constrained``; W = J except on a
slipping point's normal row, ``J_n - s mu J_t``). A point's rows are x and z on level ground, the
terrain's tangent t and normal n under it on a terrain (``legsim.terrain``; a sliding point
keeps ``z - h(x) = 0``, whose drift has the curvature term). At a profile's breakpoint a
sliding point's face is the one it slides onto, and a stuck point in a notch (a concave
breakpoint) is held by both faces: its rows are the bisector's tangent and normal
(``legsim.heights.notch``). A round contact on a sine touches at the terrain's point nearest
its centre, which moves with the configuration (``place_rounds``); its rows are the tangent
and normal there, and its normal row's drift has the term K (t . v_centre)^2 of the curve r
from the terrain that its centre keeps to. Where slipping contacts have no unique forces (the
Painleve paradox) the acceleration is nan: a state past the model's range.

The state is ``x = (q, v, footholds)``: q and v of size nv, then the foothold x (m) of each
stance leg in declared order, which the flow keeps.
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots import _native
from legsim.robots._native.calls import (
    lsn_aba,
    lsn_constrained,
    lsn_frame_jacobian,
    lsn_frames,
    lsn_round_place,
    lsn_tally,
)

from legsim.compiled.functions import model_function, scratch
from legsim.heights import PROFILE, curvature, face_slope, nearest, notch, notch_mu

from .layout import (
    B_POINT,
    B_SLIPPING,
    B_STOP,
    BLOCK_SIZE,
    C_CENTER,
    C_ID,
    C_KIND,
    C_MU,
    C_RADIUS,
    C_ROWS,
    C_SIGN,
    CONTACT_SIZE,
    KIND_STOP,
    L_DAMPING,
    L_FOOTHOLD,
    L_GROUND,
    L_HIP_FRAME,
    L_REST,
    L_STIFFNESS,
    LEG_SIZE,
    P_ACT,
    P_CONTACT,
    P_DAMP,
    P_DIM,
    P_FRAME,
    P_HANDLE,
    P_LEG,
    P_N,
    P_NACT,
    P_NCONTACT,
    P_NDAMP,
    P_NFRAME,
    P_NLEG,
    P_NRIGID,
    P_RIGID,
    P_ROUNDS_TURN,
    P_ROWS,
    P_TERRAIN,
    P_TERRAIN_TOP,
    S_ABSENT,
    S_SLIP_POS,
    STATUS_BASE,
)
from .native import C_ACTUATION, C_DAMPING, C_SPRINGS

#: Load the library before any function below is compiled or loaded from its cache: numba
#: resolves the ``lsn_*`` symbols in the process.
_native.load()

_F8 = 8  # bytes per float64, for pointer offsets


@model_function
def ptr(a, i):
    """Address of a[i] of a contiguous float64 array."""
    return a.ctypes.data + _F8 * i


@model_function
def handle(p):
    """The native model handle of p."""
    return np.int64(p[P_HANDLE])


@model_function
def frame_kinematics(x, p, kin):
    """(x, z, vx, vz) (m, m/s) of each frame of p's kinematics list at (q, v) into kin
    (4 per frame, in the list's order; a record's slot s reads kin[4 s : 4 s + 4])."""
    count = int(p[P_NFRAME])
    if count > 0:
        lsn_frames(handle(p), x.ctypes.data, ptr(x, int(p[P_N])), np.int64(count), ptr(p, int(p[P_FRAME])),
                   kin.ctypes.data)  # fmt: skip


@model_function
def spring_force(x, p, n, leg, jac):
    """(f, d_x, d_z) of stance leg record ``leg`` at x: its axial force f (N, > 0 pushing the hip
    away from the foot; k (l - r) - b dr/dt) and the unit vector d from the foothold to the hip;
    the hip frame's position and Jacobian rows x and z are left in jac (2 + 2 nv)."""
    lsn_frame_jacobian(handle(p), x.ctypes.data, np.int64(p[leg + L_HIP_FRAME]), jac.ctypes.data)
    lsn_tally(handle(p), C_SPRINGS, 1.0)
    d0 = jac[0] - x[2 * n + int(p[leg + L_FOOTHOLD])]
    d1 = jac[1] - p[leg + L_GROUND]
    r = math.hypot(d0, d1)
    d0 /= r
    d1 /= r
    f = p[leg + L_STIFFNESS] * (p[leg + L_REST] - r)
    if p[leg + L_DAMPING] > 0.0:
        lsn_tally(handle(p), C_DAMPING, 1.0)
        rate = 0.0
        for j in range(n):
            rate += (d0 * jac[2 + j] + d1 * jac[2 + n + j]) * x[n + j]
        f -= p[leg + L_DAMPING] * rate
    return f, d0, d1


@model_function
def applied_forces(x, u, p, n, tau):
    """tau (nv,): stance spring legs, joint damping, the actuated joints' input u (N m or N),
    each entry saturated at its joint's effort limit (inf: none)."""
    for j in range(n):
        tau[j] = 0.0
    legs = int(p[P_NLEG])
    jac = scratch(2 + 2 * n if legs > 0 else 0)
    for i in range(legs):
        leg = int(p[P_LEG]) + LEG_SIZE * i
        if p[leg + L_FOOTHOLD] < 0.0:
            continue
        f, d0, d1 = spring_force(x, p, n, leg, jac)
        for j in range(n):
            tau[j] += f * d0 * jac[2 + j] + f * d1 * jac[2 + n + j]
    damped = int(p[P_NDAMP])
    if damped > 0:
        lsn_tally(handle(p), C_DAMPING, 1.0)
    for i in range(damped):
        k = int(p[int(p[P_DAMP]) + 2 * i])
        tau[k] -= p[int(p[P_DAMP]) + 2 * i + 1] * x[n + k]
    actuated = min(int(p[P_NACT]), u.shape[0])
    if actuated > 0:
        lsn_tally(handle(p), C_ACTUATION, 1.0)
    act = int(p[P_ACT])
    for i in range(actuated):
        limit = p[act + 2 * i + 1]
        ui = u[i]
        if ui > limit:
            ui = limit
        elif ui < -limit:
            ui = -limit
        tau[int(p[act + 2 * i])] += ui


@model_function
def keep(a):
    """Read a[0]: called after a native call that took a's address, it keeps the array alive
    until then (compiled code frees an array after its last use, which its address is not)."""
    return a[0]


@model_function
def on_terrain(p):
    """Whether the robot's ground is a terrain (``legsim.terrain``) rather than a level one."""
    return p[P_TERRAIN] >= 0.0


@model_function
def turning(p):
    """Whether the robot has round contacts under which the terrain's normal turns (a sine, or a
    profile's corners: ``model.rounds_move``): each one's point nearest the ground then moves on
    it with the configuration (``place_rounds``)."""
    return p[P_ROUNDS_TURN] != 0.0


@model_function
def round_record(p, frame):
    """The record offset of the round contact whose own frame is ``frame``, or -1."""
    for i in range(int(p[P_NCONTACT])):
        c = int(p[P_CONTACT]) + CONTACT_SIZE * i
        if p[c + C_RADIUS] > 0.0 and p[c + C_ID] == frame:
            return c
    return -1


#: Heights of a round contact's centre above the terrain's highest point, in radii, beyond which
#: nothing of the ball is near the ground (``round_centre``).
FAR_RADII = 2.0


@model_function
def round_centre(x, p, c, kin):
    """The centre's (x, z, vx, vz) (m, m/s) of the round contact at record c into kin (4,), and
    the terrain's point nearest it: (s, d, g, k) of ``legsim.heights.nearest``. A centre more
    than ``FAR_RADII`` radii above the terrain's highest point (``P_TERRAIN_TOP``: a sine's crest,
    a profile's highest breakpoint) is far from the ground: then, without the search over the
    terrain under it, (x, its height above that point, 0, 0), the height a lower bound of its
    distance and the normal taken as on level ground."""
    one_frame_kinematics(x, p, int(p[c + C_CENTER]), kin)
    above = kin[1] - p[P_TERRAIN_TOP]
    if above > FAR_RADII * p[c + C_RADIUS]:
        return kin[0], above, 0.0, 0.0
    return nearest(p, int(p[P_TERRAIN]), kin[0], kin[1])


@model_function
def place_rounds(x, p):
    """On a terrain whose normal turns, tell the native library where each round contact's
    point nearest the ground is at q: -r n from its centre, n the normal at the terrain's point
    nearest the centre. Every model function of the bridge calls this first; a native call at a
    q its round frames were not placed at answers nan (a breakdown the run reports)."""
    if not turning(p):
        return
    kin = scratch(4)
    for i in range(int(p[P_NCONTACT])):
        c = int(p[P_CONTACT]) + CONTACT_SIZE * i
        r = p[c + C_RADIUS]
        if r <= 0.0:
            continue
        g = round_centre(x, p, c, kin)[2]
        norm = math.sqrt(1.0 + g * g)
        lsn_round_place(handle(p), x.ctypes.data, np.int64(p[c + C_ID]), r * g / norm, -r / norm)


@model_function
def one_frame_kinematics(x, p, frame, kin):
    """(x, z, vx, vz) (m, m/s) of Pinocchio frame ``frame`` at (q, v) into kin (4,): one frame,
    where ``frame_kinematics`` gives every frame of p's list."""
    ids = scratch(1)
    ids[0] = float(frame)
    lsn_frames(handle(p), x.ctypes.data, ptr(x, int(p[P_N])), np.int64(1), ids.ctypes.data, kin.ctypes.data)


@model_function
def ground_grade(x, p, frame, px, vx):
    """dh/dx of the ground's tangent at the contact of Pinocchio frame ``frame`` at x (m) moving
    at vx (m/s): a round contact's where the terrain turns, the tangent at the point nearest its
    centre (on a profile's convex corner, across the line from the corner to the centre); else
    the face under px it moves onto (``legsim.heights.face_slope``)."""
    if turning(p):
        c = round_record(p, frame)
        if c >= 0:
            return round_centre(x, p, c, scratch(4))[2]
    return face_slope(p, int(p[P_TERRAIN]), px, vx)


@model_function
def point_slope(x, p, frame, kin):
    """(dh/dx, sqrt(1 + (dh/dx)^2)) of the terrain under Pinocchio frame ``frame`` at q
    (``ground_grade``); the frame's (x, z, vx, vz) (m, m/s) into kin (4,)."""
    one_frame_kinematics(x, p, frame, kin)
    grade = ground_grade(x, p, frame, kin[0], kin[2])
    return grade, math.sqrt(1.0 + grade * grade)


#: The rate (1/s) at which a round contact's centre is steered back onto the curve r from the
#: terrain (``terrain_slopes``): its distance d obeys d'' = -2 w d' - w^2 (d - r), critically
#: damped, instead of d'' = 0. On the curve the motion is unchanged; off it (a step that crossed
#: the jump of the acceleration at a corner arc's end leaves a velocity along the normal) the
#: error dies out over 1 / w instead of growing at a constant rate. Slow against the steps
#: (w h = 0.02 at h = 1e-3 s), fast against a gait.
ROUND_RETURN_RATE = 20.0
#: Entries of ``terrain_slopes`` per constraint block: slope, curvature, the round's steering.
SLOPE_ENTRIES = 3


@model_function
def terrain_slopes(x, p, count, src, at, slopes):
    """The terrain's (slope, curvature, steering) (1, 1/m, m/s^2) under each of the ``count``
    constraint blocks src[at:] at q into slopes (``SLOPE_ENTRIES`` per block, at least one
    block's), as the native library takes them: zeros for joint stops and on level ground (whose
    rows stay x and z); the steering is a round contact's (``ROUND_RETURN_RATE``), 0 for points."""
    slopes[: SLOPE_ENTRIES * max(1, count)] = 0.0
    if not on_terrain(p):
        return
    ids = scratch(max(1, count))
    for k in range(count):
        ids[k] = src[at + BLOCK_SIZE * k + 1]
    kin = scratch(4 * max(1, count))
    centre = scratch(4)
    lsn_frames(handle(p), x.ctypes.data, ptr(x, int(p[P_N])), np.int64(count), ids.ctypes.data, kin.ctypes.data)
    terrain = int(p[P_TERRAIN])
    for k in range(count):
        block = at + BLOCK_SIZE * k
        if src[block] == B_STOP:
            continue
        c = round_record(p, src[block + 1]) if turning(p) else -1
        if c >= 0:  # the normal at the point nearest its centre, its offset curve's curvature, the steering
            _, distance, grade, level_curvature = round_centre(x, p, c, centre)
            rate = (centre[3] - grade * centre[2]) / math.sqrt(1.0 + grade * grade)
            w = ROUND_RETURN_RATE
            steering = 2.0 * w * rate + w * w * (distance - p[c + C_RADIUS])
            slopes[SLOPE_ENTRIES * k], slopes[SLOPE_ENTRIES * k + 1] = grade, level_curvature
            slopes[SLOPE_ENTRIES * k + 2] = steering
            continue
        px = kin[4 * k]
        if src[block] == B_SLIPPING:  # the face it slides onto: its direction is its status
            slopes[SLOPE_ENTRIES * k] = face_slope(p, terrain, px, src[block + 2])
        else:
            bisector, half = notch(p, terrain, px)
            slopes[SLOPE_ENTRIES * k] = bisector if half >= 0.0 else face_slope(p, terrain, px, kin[4 * k + 2])
        slopes[SLOPE_ENTRIES * k + 1] = curvature(p, terrain, px)


@model_function
def stuck_mu(x, p, c):
    """The friction coefficient of the stuck point contact at record c of p at q: its own, or
    about the bisector where it sits in a notch (``legsim.heights.notch_mu``; its forces are
    then those of that frame, ``terrain_slopes``)."""
    mu = p[c + C_MU]
    # only a profile has notches, and only a point sits in one (a ball between two faces strikes
    # the second, its corner event)
    if not on_terrain(p) or p[int(p[P_TERRAIN])] != PROFILE or p[c + C_RADIUS] > 0.0:
        return mu
    kin = scratch(4)
    one_frame_kinematics(x, p, int(p[c + C_ID]), kin)
    half = notch(p, int(p[P_TERRAIN]), kin[0])[1]
    return notch_mu(mu, half) if half >= 0.0 else mu


@model_function
def accelerate(x, u, p, blocks, src, at, a, lam):
    """The acceleration (nv,) into a and the constraint forces into lam (one per constraint row,
    each block's normal force last; along the terrain's tangent and normal on a terrain) of the
    ``blocks`` constraint blocks src[at:] (``layout.BLOCK_SIZE`` values each) under the input u;
    the unconstrained forward dynamics without blocks."""
    n = int(p[P_N])
    tau = scratch(n)
    applied_forces(x, u, p, n, tau)
    if blocks == 0:
        lsn_aba(handle(p), x.ctypes.data, ptr(x, n), tau.ctypes.data, a.ctypes.data)
    elif not on_terrain(p):  # level ground: no slopes (a null pointer), and nothing allocated
        lsn_constrained(handle(p), x.ctypes.data, ptr(x, n), tau.ctypes.data, np.int64(blocks), ptr(src, at),
                        np.int64(0), a.ctypes.data, lam.ctypes.data)  # fmt: skip
    else:
        slopes = scratch(SLOPE_ENTRIES * blocks)
        terrain_slopes(x, p, blocks, src, at, slopes)
        lsn_constrained(handle(p), x.ctypes.data, ptr(x, n), tau.ctypes.data, np.int64(blocks), ptr(src, at),
                        slopes.ctypes.data, a.ctypes.data, lam.ctypes.data)  # fmt: skip


@model_function
def mode_accelerate(x, u, p, a, lam):
    """``accelerate`` with the mode's own constraint blocks."""
    accelerate(x, u, p, int(p[P_NRIGID]), p, int(p[P_RIGID]), a, lam)


@model_function
def bridge_field(t, x, u, p, dx):
    """f(t, x, u) = (v, a, 0 for the footholds) of the mode, shape (dim,) (module docstring)."""
    n = int(p[P_N])
    place_rounds(x, p)
    lam = scratch(max(1, int(p[P_ROWS])))
    mode_accelerate(x, u, p, dx[n : 2 * n], lam)  # the acceleration written in place
    for j in range(n):
        dx[j] = x[n + j]
    for j in range(2 * n, int(p[P_DIM])):
        dx[j] = 0.0


@model_function
def bridge_forces(t, x, u, p, lam):
    """The constraint forces of the mode's active rigid contacts at (t, x) under u, one per
    constraint row (N, or N m for a stop), each contact's normal force last: the outputs'
    contact forces, from the same solve as the field."""
    place_rounds(x, p)
    a = scratch(int(p[P_N]))
    mode_accelerate(x, u, p, a, lam)


@model_function
def bridge_spring_forces(t, x, u, p, out):
    """The axial force (N, > 0 pushing the hip away from the foot) of each stance leg, in
    declared order, into out."""
    n = int(p[P_N])
    jac = scratch(2 + 2 * n)
    k = 0
    for i in range(int(p[P_NLEG])):
        leg = int(p[P_LEG]) + LEG_SIZE * i
        if p[leg + L_FOOTHOLD] >= 0.0:
            out[k] = spring_force(x, p, n, leg, jac)[0]
            k += 1


# -- modes as statuses ------------------------------------------------------------------------


@model_function
def status_code(status, count):
    """The code ``sum status_i 4^i`` of the statuses status[:count] (``layout``)."""
    code = 0.0
    scale = 1.0
    for i in range(count):
        code += status[i] * scale
        scale *= STATUS_BASE
    return code


@model_function
def blocks_of(p, status, blocks):
    """The constraint blocks of the rigid contacts active in ``status`` (declared order) into
    blocks; returns (their count, their rows)."""
    count = 0
    rows = 0
    for i in range(int(p[P_NCONTACT])):
        s = status[i]
        if s == S_ABSENT:
            continue
        c = int(p[P_CONTACT]) + CONTACT_SIZE * i
        b = BLOCK_SIZE * count
        blocks[b + 1] = p[c + C_ID]
        if p[c + C_KIND] == KIND_STOP:
            blocks[b], blocks[b + 2], blocks[b + 3] = B_STOP, p[c + C_SIGN], 1.0
        elif s == S_SLIP_POS or s == S_SLIP_POS + 1:
            slip = 1.0 if s == S_SLIP_POS else -1.0
            blocks[b], blocks[b + 2], blocks[b + 3] = B_SLIPPING, slip * p[c + C_MU], 1.0
        else:
            blocks[b], blocks[b + 2], blocks[b + 3] = B_POINT, p[c + C_MU], p[c + C_ROWS]
        rows += int(blocks[b + 3])
        count += 1
    return count, rows
