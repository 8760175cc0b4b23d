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
``CONTROL_KINDS``): the record travels in p, written at every entry, and the torques are added
after the springs and damping, as ``dynamics.applied_forces`` adds them. A guard's control is
the one at its state, as the Python guards take it (a plastic impact's post-impact force too).
A controller without a record runs on the Python path.

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
from legsim._native.calls import lsn_aba, lsn_constrained, lsn_frame_jacobian, lsn_frames, lsn_gravity, lsn_impact
from legsim.compiled import CompiledMode

from ..control_laws import pd_torque
from .contacts import JointStop, PointContact, RigidContact, SpringLeg
from .joint import striking_contacts
from .model import BridgeModel
from .modes import ModeCatalog, ModeSpec

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

#: Control records (at p[P_CTRL]): the kind, then its values. ``CTRL_NONE``: no control (a run
#: without one; no torque). ``CTRL_JOINT_PD``: ``(kind, kp, kd, gravity, target of each
#: actuated joint)``, u = kp (target - q) - kd dq/dt (+ the actuated joints' generalised gravity
#: g(q) when gravity is 1) on the actuated joints (N m or N; kp in N m/rad, kd in N m s/rad).
#: ``CTRL_RUNNER``: Raibert's runner for articulated legs (``robots.runner_twin``).
CONTROL_KINDS = ("none", "joint_pd", "raibert_runner")
CTRL_NONE, CTRL_JOINT_PD, CTRL_RUNNER = range(len(CONTROL_KINDS))
CONTROL_HEAD = 4  # kind and three values before the per-joint entries

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
    an empty array when the run has none (``CONTROL_KINDS``)."""
    nact = int(p[P_NACT])
    at = int(p[P_CTRL])
    if nact == 0 or int(p[at]) == CTRL_NONE:
        return np.empty(0)
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
def bridge_guards(x, p):
    """The mode's guards in the order of its outgoing transitions, shape (n_guards,)."""
    n = int(p[P_N])
    n_guards = int(p[P_NGUARD])
    out = np.empty(n_guards)
    nframe = int(p[P_NFRAME])
    kin = np.empty(4 * max(1, nframe))
    if nframe > 0:
        count(p, C_KINEMATICS)
        lsn_frames(
            np.int64(p[P_HANDLE]), x.ctypes.data, ptr(x, n), np.int64(nframe), ptr(p, int(p[P_FRAME])), kin.ctypes.data
        )
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


# -- building a mode's parameter array ---------------------------------------------------------


class Params:
    """p under construction: the header, then sections appended as they are described."""

    def __init__(self) -> None:
        self.p: list[float] = [0.0] * HEADER
        self.frames: list[int] = []

    def append(self, values: Sequence[float]) -> int:
        at = len(self.p)
        self.p.extend(float(v) for v in values)
        return at

    def slot(self, frame: int) -> int:
        """Index of a frame in the kinematics list (added on first use)."""
        if frame not in self.frames:
            self.frames.append(frame)
        return self.frames.index(frame)


def _rigid_blocks(blocks: Sequence[RigidContact]) -> list[float]:
    """The native library's rigid blocks (pinlegsim.cpp, ``Rigid``): (kind, dof or frame, sign or
    a slipping point's s mu, rows)."""
    out: list[float] = []
    for r in blocks:
        if r.kind == "stop":
            out += [0.0, r.dof, r.sign, r.rows]
        elif r.slip:
            out += [2.0, r.frame_id, r.slip_mu, r.rows]
        else:
            out += [1.0, r.frame_id, r.sign, r.rows]
    return out


def gap_fields(r: RigidContact, pp: Params) -> list[float]:
    """Fields G_GAP_KIND, G_A, G_B, G_C of a stop's or point's gap."""
    c = r.contact
    if isinstance(c, JointStop):
        return [0.0, r.dof, r.sign, c.position]
    return [1.0, pp.slot(r.frame_id), c.ground, 0.0]


def _strike_records(
    model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, cname: str, pp: Params
) -> list[tuple[str, list[float]]] | None:
    """(transition name, guard record) of the impacts of the inactive rigid contact ``cname``
    (as transitions._strike_transitions builds them), or None when the twin cannot follow."""
    c = model.rigid[cname].contact
    if getattr(c, "armed", None) is not None:
        return None
    staying = set(spec.active) - set(getattr(c, "releases", ()))
    kept = [r for r in model.contacts if r in staying and r in model.rigid]
    rows = [model.rigid[r] for r in [*kept, cname]]
    impact_at = pp.append(_rigid_blocks(rows))
    gap = gap_fields(model.rigid[cname], pp)
    if c.restitution > 0.0:
        coeff_at = pp.append([0.0] * len(kept) + [c.restitution])
        rest_at = pp.append([0.0] * len(rows))  # the continuation's: the same impact, plastic
        return [(f"bounce_{cname}", [K_GAP, *gap, impact_at, len(rows), coeff_at, 0.0, 0.0, 0.0, rest_at])]
    coeff_at = pp.append([0.0] * len(rows))
    stick = modes.spec(modes.name_of(staying | {cname}))
    stick_at = pp.append(_rigid_blocks(stick.rigid))
    kind = "impact" if isinstance(c, JointStop) else "touchdown"
    common = [impact_at, len(rows), coeff_at]
    tail = [stick_at, len(stick.rigid), stick.normal_row(cname)]
    return [
        (f"{kind}_{cname}", [K_PLASTIC, *gap, *common, 1.0, *tail]),
        (f"graze_{cname}", [K_PLASTIC, *gap, *common, -1.0, *tail]),
    ]


def _foothold_map(src: ModeSpec, dst: ModeSpec) -> list[float]:
    """Where each foothold of ``dst`` comes from (modes.map_state): its index in ``src``'s
    footholds, or -1 for a leg touching down (its foot's x)."""
    index = {lg.leg.name: i for i, lg in enumerate(src.springs)}
    return [float(index.get(lg.leg.name, -1)) for lg in dst.springs]


def _records(
    model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, pp: Params
) -> list[tuple[str, list[float]]] | None:
    """The guard records of the mode's outgoing transitions, in transitions.outgoing's order."""
    out: list[tuple[str, list[float]]] = []
    stance = {lg.leg.name: i for i, lg in enumerate(spec.springs)}
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            lg = model.legs[cname]
            foot, hip = pp.slot(lg.foot_id), pp.slot(lg.hip_id)
            dst = modes.spec(modes.name_of(set(spec.active) ^ {cname}))
            at = pp.append(_foothold_map(spec, dst))
            if cname in stance:
                out.append(
                    (
                        f"liftoff_{cname}",
                        [
                            K_LEG_LIFT,
                            0.0,
                            foot,
                            hip,
                            c.ground,
                            c.rest_length,
                            0.0,
                            0.0,
                            0.0,
                            at,
                            len(dst.springs),
                            stance[cname],
                        ],
                    )
                )
            else:
                out.append(
                    (
                        f"touchdown_{cname}",
                        [K_LEG_TOUCH, 0.0, foot, hip, c.ground, 0.0, 0.0, 0.0, 0.0, at, len(dst.springs), 0.0],
                    )
                )
        elif cname in spec.active:
            kind = "release" if isinstance(c, JointStop) else "liftoff"
            out.append((f"{kind}_{cname}", [K_RELEASE, 0.0, spec.normal_row(cname)] + [0.0] * 9))
        elif isinstance(c, (JointStop, PointContact)):
            strikes = _strike_records(model, modes, spec, cname, pp)
            if strikes is None:
                return None
            out += strikes
    return out


def bridge_twin(
    model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, transitions: Sequence[Any]
) -> CompiledMode | None:
    """The compiled twin of mode ``spec`` whose outgoing transitions are ``transitions``, or
    None when the native library is unavailable or the mode has something the twin does not
    compute (then the mode runs in Python)."""
    if not native_ready():
        return None
    handle = handle_for(model.pin_model)
    if handle is None:
        return None
    pp = Params()
    records = _records(model, modes, spec, pp)
    if records is None or [name for name, _ in records] != [tr.name for tr in transitions]:
        return None
    guards_at = pp.append([v for _, record in records for v in record])
    p = mode_params(model, spec, pp, handle, len(records), guards_at)
    return CompiledMode(
        bridge_field,
        bridge_guards,
        len(records),
        p,
        bridge_resets,
        fallback=True,
        continued=True,
        joint_groups=tuple(_joint_group(model, name) for name, _ in records),
        controls=controls_of(model, int(p[P_CTRL])) if model.actuated_idx.size else None,
    )


def mode_params(
    model: BridgeModel, spec: ModeSpec, pp: Params, handle: int, n_guards: int, guards_at: int
) -> np.ndarray:
    """The twin's p: the header and the mode's sections (rigid blocks, springs, damping, frames,
    actuated joints, control record, counters) after the guard records already in ``pp``
    (``n_guards`` transitions, their records at ``guards_at``)."""
    header = pp.p
    header[P_HANDLE], header[P_N], header[P_DIM] = handle, model.n, spec.dim
    header[P_NRIGID], header[P_ROWS] = len(spec.rigid), sum(r.rows for r in spec.rigid)
    header[P_RIGID] = pp.append(_rigid_blocks(spec.rigid))
    header[P_NSPRING] = len(spec.springs)
    header[P_SPRING] = pp.append(
        [
            v
            for lg in spec.springs
            for v in (lg.hip_id, lg.leg.stiffness, lg.leg.rest_length, lg.leg.damping, lg.leg.ground)
        ]
    )
    header[P_NDAMP] = len(model.damping_idx)
    header[P_DAMP] = pp.append([v for k, b in zip(model.damping_idx, model.damping_b, strict=True) for v in (k, b)])
    header[P_NGUARD], header[P_GUARD] = n_guards, guards_at
    header[P_NFRAME] = len(pp.frames)
    header[P_FRAME] = pp.append(pp.frames)
    nact = len(model.actuated_idx)
    header[P_NACT], header[P_ACT] = nact, pp.append(model.actuated_idx.tolist())
    header[P_CTRL] = pp.append([0.0] * (CONTROL_HEAD + nact))
    pp.append([0.0] * len(COUNTED))
    return np.array(pp.p)


def controls_of(model: BridgeModel, at: int) -> Any:
    """``CompiledMode.controls`` of an actuated robot's twin whose control record is at p[at:]:
    a run without control writes ``CTRL_NONE``; a controller writes its
    ``compiled_record(pin_model)`` of kind ``joint_pd`` (None, or a record of another kind or
    size: it has none for this robot, the run takes Python)."""
    size = CONTROL_HEAD + len(model.actuated_idx)

    def controls(controller: Any) -> Any:
        if controller is None:
            return lambda p: _write_record(p, at, size, [float(CTRL_NONE)])
        make = getattr(controller, "compiled_record", None)
        if make is None:
            return None
        record = make(model.pin_model)
        if record is None or len(record) != size or record[0] != CTRL_JOINT_PD:
            return None
        return lambda p: _write_record(p, at, size, make(model.pin_model))

    return controls


def _write_record(p: np.ndarray, at: int, size: int, record: Sequence[float]) -> None:
    """The control record ``record`` into p[at : at + size] (zeros past its end)."""
    p[at : at + size] = 0.0
    p[at : at + len(record)] = record


def _joint_group(model: BridgeModel, name: str) -> int:
    """The joint group of transition ``name``: the index of the rigid contact it strikes, which
    joint.resolve resolves with the strikes of other contacts, or -1 (not a strike)."""
    struck = striking_contacts(model, (name,))
    return -1 if not struck else list(model.rigid).index(struck[0])
