"""Compiled twins of the bridge's modes (``legsim.compiled.CompiledMode``), calling Pinocchio's
C++ algorithms through the native library (``legsim._native``).

A twin computes what the Python mode computes, in the same order: the field of
``dynamics.dynamics`` (applied forces of stance spring legs and joint damping, then ABA, or the
KKT solve when rigid contacts are active), the guards of ``transitions.outgoing`` (gaps of
inactive stops and points, plastic-impact pairs, release forces, spring-leg touchdown and
liftoff) and the resets of those transitions and of their Zeno continuations (impacts,
releases, footholds mapped; a bounce's continuation is its impact made plastic), so the compiled
kernel crosses a gait's mode changes itself. The Python bridge stays the reference: the relaxed
loop checks each twin against it at the first visit of its mode, and a mode whose structure the
twin does not know (armed contacts, a transition it does not recognise) gets no twin and runs in
Python.

An actuated robot's twin computes its controller's torques itself (``CompiledMode.controls``)
when the controller gives a *control record* (``compiled_record(pin_model)``, see
``control_records``): the record travels in p, written at every entry, and the torques are added
after the springs and damping, as ``dynamics.applied_forces`` adds them. A guard's control is
the one at its state, as the Python guards take it (a plastic impact's post-impact force too).
A controller without a record runs on the Python path.

The functions of every bridge twin (friction modes' too: ``coulomb_guards``) are in this one
file, as numba's disk cache checks only the file of the function it loads: a function calling a
changed function of another file would load stale. ``twin_build`` builds the parameter arrays.

Everything a twin needs travels in its parameter array p (float64; layout: the ``P_*`` header
positions and the ``G_*`` fields of each guard record). A state past the model's range (a hip
below the ground: ``ModelBreakdown`` in Python) gives nan guards, and the twin is declared with
``fallback=True`` so that the Python loop takes that step and says what happened.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numba
import numpy as np

from legsim import _native
from legsim._native.calls import (
    lsn_aba,
    lsn_constrained,
    lsn_frame_jacobian,
    lsn_frame_motion,
    lsn_frames,
    lsn_gravity,
    lsn_impact,
)
from legsim.compiled import CompiledMode

from ..control_laws import pd_torque
from ..runner_twin import L_FRAME, RUNNER_HEAD, RUNNER_LEG, runner_control
from .control_records import CONTROL_HEAD, CTRL_NONE, CTRL_RUNNER

#: Whether the native library is loaded (it must be, before any twin function compiles).
AVAILABLE = _native.load()

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
_F8 = 8  # bytes per float64, for pointer offsets

# Header of p.
(
    P_HANDLE,
    P_N,
    P_DIM,
    P_NRIGID,
    P_RIGID,
    P_NSPRING,
    P_SPRING,
    P_NDAMP,
    P_DAMP,
    P_NGUARD,
    P_GUARD,
    P_NFRAME,
    P_FRAME,
    P_ROWS,
    P_NACT,
    P_ACT,
    P_CTRL,
) = range(17)
HEADER = 17
SPRING_SIZE = 5  # hip frame, stiffness (N/m), rest length (m), damping (N s/m), ground (m)
# Guard kinds.
K_GAP, K_PLASTIC, K_RELEASE, K_LEG_TOUCH, K_LEG_LIFT = range(5)
# Fields of a guard record: kind; the gap (stop: dof, sign, position; point: frame slot, ground);
# the impact (rows offset, count, restitution offset); a plastic pair's side (+1 stick, -1 graze),
# the stick mode's rigid blocks (offset, count) and the contact's normal row there. Legs: foot
# slot, hip slot, ground, rest length, foothold index.
G_KIND, G_GAP_KIND, G_A, G_B, G_C, G_IMPACT, G_NIMPACT, G_COEFF, G_SIDE, G_STICK, G_NSTICK, G_ROW = range(12)
GUARD_SIZE = 12


#: Model counters (``BridgeData.counts`` names) a twin keeps in the last len(COUNTED) entries of
#: its p, so that a robot's counters stay true on the compiled path (``add_counts``).
COUNTED = ("aba", "kkt", "jacobians", "kinematics", "spring_forces", "damping_evals", "impacts", "actuation_evals")
C_ABA, C_KKT, C_JACOBIANS, C_KINEMATICS, C_SPRINGS, C_DAMPING, C_IMPACTS, C_ACTUATION = range(len(COUNTED))

_HANDLES: dict[int, tuple[Any, int]] = {}
_JOINT_CODES = {
    "JointModelRX": 0,
    "JointModelRY": 1,
    "JointModelRZ": 2,
    "JointModelPX": 3,
    "JointModelPY": 4,
    "JointModelPZ": 5,
}
COMPOSITE = 6


def describe(model: Any) -> np.ndarray | None:
    """The flat description of a Pinocchio model for ``lsn_create`` (pinlegsim.cpp), or None
    when it has a joint the library does not take or a gravity with an angular part."""
    out: list[float] = [model.njoints - 1]
    for j in range(1, model.njoints):
        joint = _joint_description(model.joints[j])
        if joint is None:
            return None
        placement, inertia = model.jointPlacements[j], model.inertias[j]
        out += [*joint, model.parents[j], *placement.rotation.reshape(-1), *placement.translation]
        out += [inertia.mass, *inertia.lever, *inertia.inertia.reshape(-1)]
    out.append(len(model.frames) - 1)
    for frame in list(model.frames)[1:]:
        out += [frame.parentJoint, *frame.placement.rotation.reshape(-1), *frame.placement.translation]
    if np.any(model.gravity.angular != 0.0):
        return None
    out += list(model.gravity.linear)
    return np.array(out, dtype=float)


def _joint_description(joint: Any) -> list[float] | None:
    """A joint's code, and for a composite (the planar root: PX, PZ, RY) its parts' codes and
    placements; None for a joint the library does not take."""
    kind = joint.shortname()
    if kind != "JointModelComposite":
        code = _JOINT_CODES.get(kind)
        return None if code is None else [code]
    composite = joint.extract()
    out: list[float] = [COMPOSITE, len(composite.joints)]
    for part, placement in zip(composite.joints, composite.jointPlacements, strict=True):
        code = _JOINT_CODES.get(part.shortname())
        if code is None:
            return None
        out += [code, *placement.rotation.reshape(-1), *placement.translation]
    return out


def native_ready() -> bool:
    """Whether twins can be built; says once per process why not (``legsim._native``)."""
    if not AVAILABLE:
        _native.warn_unavailable()
    return AVAILABLE


def with_counters(values: Sequence[float]) -> np.ndarray:
    """A twin's p: ``values`` followed by its zeroed counters."""
    return np.array(list(values) + [0.0] * len(COUNTED), dtype=float)


def add_counts(counts: dict[str, int], twin: CompiledMode | None, reset: bool = False) -> None:
    """Add the twin's counters to ``counts`` (a robot's model counters), or zero them with ``reset``."""
    if twin is None:
        return
    tail = twin.params[twin.params.shape[0] - len(COUNTED) :]
    if reset:
        tail[:] = 0.0
        return
    for name, value in zip(COUNTED, tail, strict=True):
        counts[name] = counts.get(name, 0) + int(value)


def native_handle(model: Any) -> int | None:
    """The native handle of a Pinocchio model when twins can be built (``native_ready``), else
    None."""
    return handle_for(model) if native_ready() else None


def handle_for(model: Any) -> int | None:
    """The native handle of a Pinocchio model (created once per model object), or None."""
    found = _HANDLES.get(id(model))
    if found is not None and found[0] is model:
        return found[1]
    desc = describe(model)
    if desc is None or not AVAILABLE:
        return None
    handle = _native.create_model(desc)
    _HANDLES[id(model)] = (model, handle)  # holding the model keeps its id from being reused
    return handle


# -- the twin's functions ---------------------------------------------------------------------


@_jit
def ptr(a, i):
    """Address of a[i] of a contiguous float64 array."""
    return a.ctypes.data + _F8 * i


@_jit
def count(p, counter, amount=1.0):
    """Add to one of the twin's counters (the tail of p)."""
    p[p.shape[0] - len(COUNTED) + counter] += amount


_pd_torque = _jit(pd_torque)


@_jit
def control_input(x, p, n):
    """The control u (one entry per actuated joint) of the record at p[P_CTRL] at state x, or
    an empty array when the run has none (``control_records``)."""
    nact = int(p[P_NACT])
    at = int(p[P_CTRL])
    if nact == 0 or int(p[at]) == CTRL_NONE:
        return np.empty(0)
    if int(p[at]) == CTRL_RUNNER:
        return _runner_input(x, p, n, at, nact)
    kp, kd = p[at + 1], p[at + 2]
    u = np.empty(nact)
    for i in range(nact):
        k = int(p[int(p[P_ACT]) + i])
        u[i] = _pd_torque(kp, kd, p[at + CONTROL_HEAD + i], x[k], x[n + k])
    if p[at + 3] != 0.0:
        gravity = np.empty(n)
        lsn_gravity(np.int64(p[P_HANDLE]), x.ctypes.data, gravity.ctypes.data)
        for i in range(nact):
            u[i] += gravity[int(p[int(p[P_ACT]) + i])]
    return u


@_jit
def _in_mode(p, frame):
    """Whether the contact at Pinocchio frame ``frame`` is active in the twin's mode (one of its
    rigid point blocks)."""
    at = int(p[P_RIGID])
    for b in range(int(p[P_NRIGID])):  # noqa: SIM110 -- a loop numba compiles, not a generator
        if p[at + 4 * b] != 0.0 and p[at + 4 * b + 1] == frame:
            return True
    return False


@_jit
def _runner_input(x, p, n, at, nact):
    """u of Raibert's runner (``robots.runner_twin``) whose record is at p[at:]: a leg is in
    stance where its foot's contact is active in the mode."""
    legs = int(p[at + 1])
    stance = np.empty(legs)
    flying = False
    for i in range(legs):
        stance[i] = 1.0 if _in_mode(p, p[at + RUNNER_HEAD + RUNNER_LEG * i + L_FRAME]) else 0.0
        flying = flying or stance[i] == 0.0
    gravity = np.zeros(n)
    if flying:
        lsn_gravity(np.int64(p[P_HANDLE]), x.ctypes.data, gravity.ctypes.data)
    u = np.empty(nact)
    runner_control(x, n, p, at, stance, gravity, u)
    return u


@_jit
def _applied_forces(x, p, n, u):
    """tau (n,) of dynamics.applied_forces: stance springs (with damping), joint damping, the
    actuated joints' control u (none when u is empty)."""
    tau = np.zeros(n)
    h = np.int64(p[P_HANDLE])
    jac = np.empty(2 + 2 * n)
    base = int(p[P_SPRING])
    for i in range(int(p[P_NSPRING])):
        s = base + SPRING_SIZE * i
        lsn_frame_jacobian(h, x.ctypes.data, np.int64(p[s]), jac.ctypes.data)
        count(p, C_JACOBIANS)
        count(p, C_SPRINGS)
        d0 = jac[0] - x[2 * n + i]
        d1 = jac[1] - p[s + 4]
        r = math.hypot(d0, d1)
        d0 /= r
        d1 /= r
        f = p[s + 1] * (p[s + 2] - r)
        if p[s + 3] > 0.0:
            count(p, C_DAMPING)
            jv0 = 0.0
            jv1 = 0.0
            for j in range(n):
                jv0 += jac[2 + j] * x[n + j]
                jv1 += jac[2 + n + j] * x[n + j]
            f -= p[s + 3] * (d0 * jv0 + d1 * jv1)
        w0 = f * d0
        w1 = f * d1
        for j in range(n):
            tau[j] += w0 * jac[2 + j] + w1 * jac[2 + n + j]
    base = int(p[P_DAMP])
    if int(p[P_NDAMP]) > 0:
        count(p, C_DAMPING)
    for i in range(int(p[P_NDAMP])):
        k = int(p[base + 2 * i])
        tau[k] -= p[base + 2 * i + 1] * x[n + k]
    if u.shape[0] > 0:
        count(p, C_ACTUATION)
        for i in range(u.shape[0]):
            k = int(p[int(p[P_ACT]) + i])
            tau[k] += u[i]
    return tau


@_jit
def accelerate(x, p, n, nrigid, rigid_at, rows, a, lam, u):
    """The acceleration into a (n,) and the constraint forces into lam (rows,) of
    dynamics.dynamics under control u for the rigid blocks at p[rigid_at:] (ABA when there
    are none)."""
    tau = _applied_forces(x, p, n, u)
    h = np.int64(p[P_HANDLE])
    count(p, C_ABA)
    if nrigid == 0:
        lsn_aba(h, x.ctypes.data, ptr(x, n), tau.ctypes.data, a.ctypes.data)
    else:
        count(p, C_KKT)
        lsn_constrained(
            h,
            x.ctypes.data,
            ptr(x, n),
            tau.ctypes.data,
            np.int64(nrigid),
            ptr(p, rigid_at),
            a.ctypes.data,
            lam.ctypes.data,
        )


@_jit
def bridge_field(t, x, p):
    """f(t, x) = (v, a, 0 for the footholds), shape (dim,)."""
    n = int(p[P_N])
    out = np.zeros(int(p[P_DIM]))
    a = np.empty(n)
    lam = np.empty(max(1, int(p[P_ROWS])))
    accelerate(x, p, n, int(p[P_NRIGID]), int(p[P_RIGID]), int(p[P_ROWS]), a, lam, control_input(x, p, n))
    for j in range(n):
        out[j] = x[n + j]
        out[n + j] = a[j]
    return out


@_jit
def gap_value(x, p, g, kin, n):
    """Gap guard of an inactive stop or point (guards._touch_guard), from record g."""
    if p[g + G_GAP_KIND] == 0.0:
        dof, sign = int(p[g + G_A]), p[g + G_B]
        a = sign * (x[dof] - p[g + G_C])
        b = sign * x[n + dof]
        return a if a > b else b
    slot = 4 * int(p[g + G_A])
    z = kin[slot + 1] - p[g + G_B]
    vz = kin[slot + 3]
    return z if z > vz else vz


@_jit
def _post_impact_force(x, p, g, n, u):
    """lambda+ of a plastic impact (impacts.plastic_guard): the contact's normal force in the
    stick mode right after the impact, under the control u at the state before it."""
    h = np.int64(p[P_HANDLE])
    after = x.copy()
    count(p, C_IMPACTS)
    lsn_impact(
        h,
        x.ctypes.data,
        ptr(x, n),
        np.int64(p[g + G_NIMPACT]),
        ptr(p, int(p[g + G_IMPACT])),
        ptr(p, int(p[g + G_COEFF])),
        ptr(after, n),
    )
    nstick = int(p[g + G_NSTICK])
    a = np.empty(n)
    lam = np.empty(int(p[g + G_ROW]) + 1 + 2 * nstick)
    accelerate(after, p, n, nstick, int(p[g + G_STICK]), 0, a, lam, u)
    return lam[int(p[g + G_ROW])]


@_jit
def _leg_touch(p, g, kin):
    """Touchdown guard of a flight leg's foot (guards.kinematic_guards); nan past the model's
    range (its hip below the ground)."""
    foot, hip = 4 * int(p[g + G_A]), 4 * int(p[g + G_B])
    if kin[hip + 1] - p[g + G_C] < 0.0:
        return math.nan
    z = kin[foot + 1] - p[g + G_C]
    vz = kin[foot + 3]
    return z if vz <= 0.0 else (z if z > vz else vz)


@_jit
def _leg_lift(x, p, g, kin, n):
    """Liftoff guard max(l - r, -dr/dt) of a stance leg (guards._liftoff_guard); nan past the
    model's range (hip below the ground, or a foot swung into the ground)."""
    foot, hip = 4 * int(p[g + G_A]), 4 * int(p[g + G_B])
    ground = p[g + G_C]
    dx = kin[hip] - x[2 * n + int(p[g + G_ROW])]
    dz = kin[hip + 1] - ground
    if dz < 0.0:
        return math.nan
    r = math.hypot(dx, dz)
    rdot = (dx * kin[hip + 2] + dz * kin[hip + 3]) / r
    a = p[g + G_IMPACT] - r
    value = a if a > -rdot else -rdot
    if value < 0.0 and kin[foot + 1] - ground < 0.0 and kin[foot + 3] < 0.0:
        return math.nan
    return value


@_jit
def _frame_kinematics(x, p, n):
    """(x, z, vx, vz) of each frame of the twin's kinematics list at (q, v), shape (4 frames,)
    (at least 4 entries)."""
    nframe = int(p[P_NFRAME])
    kin = np.empty(4 * max(1, nframe))
    if nframe > 0:
        count(p, C_KINEMATICS)
        lsn_frames(
            np.int64(p[P_HANDLE]), x.ctypes.data, ptr(x, n), np.int64(nframe), ptr(p, int(p[P_FRAME])), kin.ctypes.data
        )
    return kin


@_jit
def bridge_guards(x, p):
    """The mode's guards in the order of its outgoing transitions, shape (n_guards,)."""
    n = int(p[P_N])
    n_guards = int(p[P_NGUARD])
    out = np.empty(n_guards)
    kin = _frame_kinematics(x, p, n)
    lam = np.empty(max(1, int(p[P_ROWS])))
    solved = False
    u = control_input(x, p, n)
    for e in range(n_guards):
        g = int(p[P_GUARD]) + GUARD_SIZE * e
        kind = int(p[g + G_KIND])
        if kind == K_GAP:
            out[e] = gap_value(x, p, g, kin, n)
        elif kind == K_PLASTIC:
            base = gap_value(x, p, g, kin, n)
            if base >= 0.0:
                out[e] = base
            else:
                lam_plus = _post_impact_force(x, p, g, n, u)
                other = -p[g + G_SIDE] * lam_plus
                out[e] = base if base > other else other
        elif kind == K_RELEASE:
            if not solved:
                a = np.empty(n)
                accelerate(x, p, n, int(p[P_NRIGID]), int(p[P_RIGID]), int(p[P_ROWS]), a, lam, u)
                solved = True
            out[e] = lam[int(p[g + G_A])]
        elif kind == K_LEG_TOUCH:
            out[e] = _leg_touch(p, g, kin)
        else:
            out[e] = _leg_lift(x, p, g, kin, n)
    for e in range(n_guards):  # one guard past the model's range: every guard says so
        if out[e] != out[e]:
            out[:] = math.nan
    return out


@_jit
def bridge_resets(x, p, e):
    """The reset of transition e into its target's state (impacts.impact_reset,
    impacts.plain_reset; for e >= the guard count, the continuation of transition e - count):
    an impact (bounce, plastic stick or graze) replaces v by the
    generalised Newton impact's; a release keeps x; a spring leg's touchdown or liftoff keeps q
    and v and maps the footholds (modes.map_state: kept, dropped, or the touching foot's x)."""
    n = int(p[P_N])
    n_guards = int(p[P_NGUARD])
    g = int(p[P_GUARD]) + GUARD_SIZE * (e % n_guards)
    kind = int(p[g + G_KIND])
    continued = e >= n_guards
    if continued or kind in (K_GAP, K_PLASTIC):
        # An impact; the continuation of a bounce is the same impact made plastic (its
        # restitution row of zeros), into the resting mode.
        coefficients = G_ROW if continued else G_COEFF
        out = x.copy()
        count(p, C_IMPACTS)
        lsn_impact(
            np.int64(p[P_HANDLE]),
            x.ctypes.data,
            ptr(x, n),
            np.int64(p[g + G_NIMPACT]),
            ptr(p, int(p[g + G_IMPACT])),
            ptr(p, int(p[g + coefficients])),
            ptr(out, n),
        )
        return out
    if kind == K_RELEASE:
        return x.copy()
    footholds = int(p[g + G_NSTICK])
    out = np.empty(2 * n + footholds)
    for d in range(2 * n):
        out[d] = x[d]
    at = int(p[g + G_STICK])
    for i in range(footholds):
        j = int(p[at + i])
        if j >= 0:
            out[2 * n + i] = x[2 * n + j]
        else:  # the touching foot's x at q (modes.flight_foot_x)
            kin = np.empty(4)
            frame = np.empty(1)
            frame[0] = p[int(p[P_FRAME]) + int(p[g + G_A])]
            lsn_frames(np.int64(p[P_HANDLE]), x.ctypes.data, ptr(x, n), np.int64(1), frame.ctypes.data, kin.ctypes.data)
            out[2 * n + i] = kin[0]
    return out


# -- modes with Coulomb friction (friction_twins builds their p) -----------------------------

# Event kinds: a strike's gap, a contact's normal force (liftoff, release), a stuck contact's
# distance to the cone's edge towards s, a slipping contact's slip rate against s.
E_GAP, E_FORCE, E_SLIP, E_STICK = range(4)
# Fields of an event record: kind; the gap's fields at twins' G_GAP_KIND, G_A, G_B, G_C (so
# that ``gap_value`` reads them), which the other kinds use as (normal row, mu, s) for E_FORCE
# and E_SLIP and (frame id, s) for E_STICK; how many transitions (outcomes) the event has.
E_KIND, E_GAP_KIND, E_A, E_B, E_C, E_COPIES = range(6)
EVENT_SIZE = 6


@_jit
def _base(x, p, e, kin, n, a, lam):
    """The base guard of the event record at p[e:], with the mode's acceleration a (n,) and
    constraint forces lam already solved."""
    kind = int(p[e + E_KIND])
    if kind == E_GAP:
        return gap_value(x, p, e, kin, n)
    row = int(p[e + E_A])
    if kind == E_FORCE:
        return lam[row]
    if kind == E_SLIP:
        return p[e + E_B] * lam[row] + p[e + E_C] * lam[row - 1]
    motion = np.empty(4)
    lsn_frame_motion(np.int64(p[P_HANDLE]), x.ctypes.data, ptr(x, n), a.ctypes.data, np.int64(row), motion.ctypes.data)
    s = p[e + E_B]
    return max(s * motion[0], s * motion[2])


@_jit
def coulomb_guards(x, p):
    """Every outcome transition's guard, in the mode's transition order, shape (n_guards,): the
    event's base where it is >= 0; all nan once one event's base is < 0 (module docstring)."""
    n = int(p[P_N])
    events_at = int(p[P_GUARD])
    n_events = int(p[events_at])
    kin = _frame_kinematics(x, p, n)
    a = np.empty(n)
    lam = np.empty(max(1, int(p[P_ROWS])))
    dynamic = False  # some event reads the mode's forces or accelerations (flight's strikes do not)
    for k in range(n_events):
        dynamic = dynamic or int(p[events_at + 1 + EVENT_SIZE * k + E_KIND]) != E_GAP
    if dynamic:
        accelerate(x, p, n, int(p[P_NRIGID]), int(p[P_RIGID]), int(p[P_ROWS]), a, lam, control_input(x, p, n))
    out = np.empty(int(p[P_NGUARD]))
    filled = 0
    for k in range(n_events):
        e = events_at + 1 + EVENT_SIZE * k
        value = _base(x, p, e, kin, n, a, lam)
        if not value >= 0.0:  # the event happens in this step (or the state is past the model's range)
            out[:] = math.nan
            return out
        for _ in range(int(p[e + E_COPIES])):
            out[filled] = value
            filled += 1
    return out
