"""Compiled twins of the passive walkers' stance modes (``legsim.robots.compass_gait``,
``legsim.robots.rimless_wheel``): Pinocchio's C++ ABA, kinematics and impact law through the
native library, computing what the walkers' Python callables compute, in the same order.

Both walkers have one mode whose transitions return to it (heel strike; the spoke impacts), so
with these twins a whole walk runs in the compiled kernel, strips and resets included.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim._native.calls import lsn_aba, lsn_crba, lsn_frames, lsn_impact, lsn_momentum_about
from legsim.compiled import CompiledMode

from .twins import C_ABA, C_IMPACTS, C_KINEMATICS, _jit, count, handle_for, native_ready, ptr, with_counters

# Compass gait p: stance model handle, impact model handle, leg length l (m), the stance
# model's swing-foot frame, the impact block (point, foot2's frame, sign, 2 rows) and its
# restitution 0.
CG_STANCE, CG_IMPACT, CG_L, CG_FOOT, CG_BLOCK, CG_COEFF = 0, 1, 2, 3, 4, 8


@_jit
def _passive_field(x, p, handle, nv):
    """(v, ABA(q, v, 0), 0 for foot_x) of a passive chain whose state is (q, v, foot_x), shape (2 nv + 1,)."""
    out = np.zeros(2 * nv + 1)
    tau = np.zeros(nv)
    for j in range(nv):
        out[j] = x[nv + j]
    count(p, C_ABA)
    lsn_aba(np.int64(handle), x.ctypes.data, ptr(x, nv), tau.ctypes.data, ptr(out, nv))
    return out


@_jit
def compass_field(t, x, p):
    """(stanced, hipd, ABA accelerations, 0), shape (5,)."""
    return _passive_field(x, p, p[CG_STANCE], 2)


@_jit
def _swing_foot(x, p):
    """(x, z, vx, vz) of the swing foot relative to the stance foot (m, m/s)."""
    kin = np.empty(4)
    count(p, C_KINEMATICS)
    lsn_frames(np.int64(p[CG_STANCE]), x.ctypes.data, ptr(x, 2), np.int64(1), ptr(p, CG_FOOT), kin.ctypes.data)
    return kin


@_jit
def compass_guards(x, p):
    """Heel strike: max(swing foot height, its vertical velocity, -its lead) (m); nan once the
    hip is below the slope (the walker fell: ModelBreakdown in Python)."""
    out = np.empty(1)
    if p[CG_L] * math.cos(x[0]) < 0.0:
        out[0] = math.nan
        return out
    kin = _swing_foot(x, p)
    g = kin[1] if kin[1] > kin[3] else kin[3]
    out[0] = g if g > -kin[0] else -kin[0]
    return out


@_jit
def compass_resets(x, p, e):
    """Heel strike (CompassGait.heel_strike): plastic impact of the swing foot on the
    floating-base model, then the legs exchange roles and foot_x advances by the step."""
    th, phi, thd, phid = x[0], x[1], x[2], x[3]
    leg_length = p[CG_L]
    qf = np.array([leg_length * math.sin(th), leg_length * math.cos(th), th, phi])
    vf = np.array([leg_length * thd * math.cos(th), -leg_length * thd * math.sin(th), thd, phid])
    v_plus = np.empty(4)
    count(p, C_IMPACTS)
    lsn_impact(
        np.int64(p[CG_IMPACT]),
        qf.ctypes.data,
        vf.ctypes.data,
        np.int64(1),
        ptr(p, CG_BLOCK),
        ptr(p, CG_COEFF),
        v_plus.ctypes.data,
    )
    kin = _swing_foot(x, p)
    out = np.empty(5)
    out[0] = th + phi
    out[1] = -phi
    out[2] = v_plus[2] + v_plus[3]
    out[3] = -v_plus[3]
    out[4] = x[4] + kin[0]
    return out


def compass_gait_twin(walker: Any) -> CompiledMode | None:
    """The twin of a ``CompassGait``'s stance mode, or None without the native library."""
    if not native_ready():
        return None
    stance, impact = handle_for(walker.stance_bridge.model), handle_for(walker.impact_bridge.model)
    if stance is None or impact is None:
        return None
    foot2 = walker.impact_bridge.model.getFrameId("foot2")
    p = with_counters(
        [stance, impact, walker.l, walker.stance_bridge.model.getFrameId("swing_foot"), 1.0, foot2, 1.0, 2.0, 0.0]
    )
    twin = CompiledMode(compass_field, compass_guards, 1, p, compass_resets, fallback=True)
    walker.stance_bridge.count_twin(twin)
    return twin


# Rimless wheel p: model handle, alpha (rad), the front and back spoke tips' frames.
RW_HANDLE, RW_ALPHA, RW_FRONT, RW_BACK = 0, 1, 2, 3


@_jit
def rimless_field(t, x, p):
    """(thetad, ABA acceleration, 0), shape (3,)."""
    return _passive_field(x, p, p[RW_HANDLE], 1)


@_jit
def rimless_guards(x, p):
    """(max(alpha - theta, -thetad), max(theta + alpha, thetad)) (rad)."""
    out = np.empty(2)
    a = p[RW_ALPHA] - x[0]
    out[0] = a if a > -x[1] else -x[1]
    b = x[0] + p[RW_ALPHA]
    out[1] = b if b > x[1] else x[1]
    return out


@_jit
def rimless_resets(x, p, e):
    """Plastic impact of the front (e = 0) or back (e = 1) spoke (RimlessWheel._impact): the
    angular momentum about the striking tip, divided by the inertia about it."""
    h = np.int64(p[RW_HANDLE])
    frame = p[RW_FRONT] if e == 0 else p[RW_BACK]
    shift = -2.0 * p[RW_ALPHA] if e == 0 else 2.0 * p[RW_ALPHA]
    momentum = np.empty(3)
    count(p, C_IMPACTS)
    lsn_momentum_about(h, x.ctypes.data, ptr(x, 1), np.int64(frame), momentum.ctypes.data)
    new = np.array([x[0] + shift])
    inertia = np.empty(1)
    lsn_crba(h, new.ctypes.data, inertia.ctypes.data)
    out = np.empty(3)
    out[0] = new[0]
    out[1] = momentum[0] / inertia[0]
    out[2] = x[2] + momentum[1]
    return out


def rimless_wheel_twin(wheel: Any) -> CompiledMode | None:
    """The twin of a ``RimlessWheel``'s stance mode, or None without the native library."""
    handle = handle_for(wheel.stance_bridge.model) if native_ready() else None
    if handle is None:
        return None
    model = wheel.stance_bridge.model
    p = with_counters([handle, wheel.alpha, model.getFrameId("front_tip"), model.getFrameId("back_tip")])
    twin = CompiledMode(rimless_field, rimless_guards, 2, p, rimless_resets)
    wheel.stance_bridge.count_twin(twin)
    return twin
