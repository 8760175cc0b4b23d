"""Guards (``>= 0`` inside the domain), their units, and the initial-state check.

* touchdown of a point contact: ``max(z - ground, dz/dt)`` (m): the gap, past only when it is
  closing (with ``armed``, also ``-armed(q, v)``); of a spring-leg foot: ``z - ground`` while
  descending, ``max(z - ground, dz/dt)`` while rising (m);
* impact on a joint stop: ``max(s (q_j - position), s dq_j/dt)`` (rad, or m for a prismatic
  joint), ``s = +1`` for a lower stop and ``-1`` for an upper one;
* release of a point contact: the normal constraint force (N); of a joint stop: the stop's
  generalised force (N m or N);
* liftoff of a spring leg: ``max(l - r, -dr/dt)`` (m), past once the leg has extended back
  through its rest length.

The models have no body-ground contact: a hip below the ground, or a liftoff that would swing a
foot into the ground while it moves down, raises ``ModelBreakdown``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.errors import ModelBreakdown

from .contacts import SLIP_SUFFIX, JointStop, LegFrames, PointContact, RigidContact, SpringLeg, joint_id
from .dynamics import dynamics
from .model import LWA, BridgeData, BridgeModel
from .modes import ModeSpec


def kinematic_guards(model: BridgeModel, data: BridgeData, spec: ModeSpec, x: np.ndarray) -> dict[str, float]:
    """Values of every position-level guard of the mode at x, by contact name, from one
    kinematics pass (cached for the last state)."""
    key = x.tobytes()
    scratch = data.scratch(spec.name)
    if key == scratch.kin_key:
        return scratch.kin_val
    n = model.n
    q, v = x[:n], x[n : 2 * n]
    if spec.need_fk:
        pin.forwardKinematics(model.pin_model, data.pin_data, q, v)
        data.counts["kinematics"] += 1
    out: dict[str, float] = {}
    for r in model.rigid.values():
        if r.contact.name not in spec.active:
            out[r.contact.name] = _touch_guard(model, data, r, q, v)
    for lg in spec.flight_legs:
        z, vz = _frame_height_and_rise(model, data, lg.foot_id, lg.leg.ground)
        # "at the ground moving down". A foot below the ground while rising is in flight: near
        # a periodic gait the leg swung forward at liftoff scuffs the ground. One that turns
        # down while still below it is past by its depth, not by its velocity: the guard
        # jumps there, no step can land in the strip, and the run ends (halving_exhausted)
        # instead of pinning a foot that never came out of the ground.
        out[lg.leg.name] = z if vz <= 0.0 else max(z, vz)
        hip_z = pin.updateFramePlacement(model.pin_model, data.pin_data, lg.hip_id).translation[2] - lg.leg.ground
        if hip_z < 0.0:
            raise _fell(model, lg.leg, hip_z)
    for i, lg in enumerate(spec.springs):
        out[lg.leg.name] = _liftoff_guard(model, data, lg, x, i)
    scratch.kin_key, scratch.kin_val = key, out
    return out


def _touch_guard(model: BridgeModel, data: BridgeData, r: RigidContact, q: np.ndarray, v: np.ndarray) -> float:
    """Touchdown or impact guard of an inactive rigid contact (frame kinematics already computed)."""
    c = r.contact
    if isinstance(c, JointStop):
        return max(r.sign * (q[r.dof] - c.position), r.sign * v[r.dof])
    z, vz = _frame_height_and_rise(model, data, r.frame_id, c.ground)
    g = max(z, vz)
    if c.armed is not None:
        g = max(g, -float(c.armed(q, v)))
    return g


def _frame_height_and_rise(model: BridgeModel, data: BridgeData, frame: int, ground: float) -> tuple[float, float]:
    """(height above the ground (m), vertical velocity (m/s)) of a frame's origin."""
    p = pin.updateFramePlacement(model.pin_model, data.pin_data, frame).translation
    vz = pin.getFrameVelocity(model.pin_model, data.pin_data, frame, LWA).linear[2]
    return p[2] - ground, vz


def _liftoff_guard(model: BridgeModel, data: BridgeData, lg: LegFrames, x: np.ndarray, i: int) -> float:
    """``max(l - r, -dr/dt)`` of the stance leg whose foothold is ``x[2 nv + i]``."""
    n = model.n
    pm, pd = model.pin_model, data.pin_data
    p = pin.updateFramePlacement(pm, pd, lg.hip_id).translation
    vel = pin.getFrameVelocity(pm, pd, lg.hip_id, LWA).linear
    dx = p[0] - x[2 * n + i]
    dz = p[2] - lg.leg.ground
    if dz < 0.0:
        raise _fell(model, lg.leg, dz)
    r = math.hypot(dx, dz)
    rdot = (dx * vel[0] + dz * vel[2]) / r
    g = max(lg.leg.rest_length - r, -rdot)
    if g < 0.0:
        # Past liftoff: the leg swings to its flight angle. A foot that would then be below
        # the ground *and* moving down swung into it: the runner fell. (Below the ground but
        # rising is a scuff, which every symmetric running gait grazes, within rounding.)
        foot, foot_vz = _frame_height_and_rise(model, data, lg.foot_id, lg.leg.ground)
        if foot < 0.0 and foot_vz < 0.0:
            raise ModelBreakdown(
                f"{model.name}: at liftoff of leg '{lg.leg.name}' its foot, swung to the flight angle, "
                f"would be {-foot:.3g} m below the ground moving down ({foot_vz:.3g} m/s): "
                f"the runner fell"
            )
    return g


def _fell(model: BridgeModel, leg: SpringLeg, hip_height: float) -> ModelBreakdown:
    """The breakdown of a runner whose hip went below the ground (``hip_height`` < 0, m)."""
    return ModelBreakdown(
        f"{model.name}: the hip of leg '{leg.name}' is {-hip_height:.3g} m below the "
        f"ground: the runner fell (the model has no body-ground contact)"
    )


def kinematic_guard(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str
) -> Callable[[np.ndarray], float]:
    """The position-level guard ``g(x)`` of contact ``contact`` in mode ``spec``."""

    def g(x: np.ndarray) -> float:
        return kinematic_guards(model, data, spec, x)[contact]

    return g


def state_guard(model: BridgeModel, value: Callable[[np.ndarray, Any], float]) -> tuple[Callable[..., float], str]:
    """``value(x, u)`` as a guard and its ``guard_args``: on (t, x, u) when the robot is actuated
    (the value then depends on the control), else on x with ``u = None``."""
    if model.timed:
        return (lambda t, x, u: value(x, u)), model.guard_args
    return (lambda x: value(x, None)), model.guard_args


def release_guard(model: BridgeModel, data: BridgeData, spec: ModeSpec, row: int) -> tuple[Callable[..., float], str]:
    """The normal force ``lambda[row]`` (N or N m) of mode ``spec`` as a guard, and its ``guard_args``."""
    return state_guard(model, lambda x, u: float(dynamics(model, data, spec, x, u)[1][row]))


def initial_check(
    model: BridgeModel, data: BridgeData, active_contacts: Callable[[str], tuple[str, ...]]
) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x, eps)``
    names the first inactive joint stop or point contact whose position lies past it by more
    than eps (rad or m), else None. The guards are "and" conditions (past the stop AND moving
    into it), so they count a state deep past a stop but moving away as inside; no execution
    reaches such a state, and a run started there would not be the model's."""

    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        active = active_contacts(mode)
        q = np.asarray(x, dtype=float)[: model.n]
        for r in model.rigid.values():
            if r.contact.name in active:
                continue
            if r.kind == "stop":
                message = _past_stop(model, r, q, eps, mode)
            else:
                message = _below_ground(model, data, r, q, eps, mode)
            if message is not None:
                return message
        return None

    return check


def _past_stop(model: BridgeModel, r: RigidContact, q: np.ndarray, eps: float, mode: str) -> str | None:
    """A message if q lies past the inactive stop by more than eps (rad or m), else None."""
    c = r.stop
    depth = -r.sign * (q[r.dof] - c.position)
    if depth > eps:
        name = model.coordinate_names[r.dof]
        bound = ">=" if c.side == "lower" else "<="
        return (
            f"{name} = {q[r.dof]:g} lies past the {c.side} stop '{c.name}' ({name} {bound} "
            f"{c.position:g}) by {depth:.3g} > eps = {eps:g} in mode '{mode}' where the "
            f"stop is inactive"
        )
    return None


def _below_ground(
    model: BridgeModel, data: BridgeData, r: RigidContact, q: np.ndarray, eps: float, mode: str
) -> str | None:
    """A message if the inactive contact point lies below the ground at q by more than eps (m), else None."""
    c = r.point
    pin.forwardKinematics(model.pin_model, data.pin_data, q)
    z = pin.updateFramePlacement(model.pin_model, data.pin_data, r.frame_id).translation[2]
    depth = c.ground - z
    if depth > eps:
        return (
            f"contact point '{c.name}' (frame '{c.frame}') at height {z:g} m lies below the "
            f"ground {c.ground:g} m by {depth:.3g} > eps = {eps:g} in mode '{mode}' where "
            f"the contact is inactive"
        )
    return None


def guard_units(model: BridgeModel) -> dict[str, str]:
    """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
    units = {}
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            units[f"touchdown_{cname}"] = "m (foot height, while descending)"
            units[f"liftoff_{cname}"] = "m (rest length minus leg length, while extending)"
        elif isinstance(c, PointContact):
            kind = "touchdown" if c.restitution == 0.0 else "bounce"
            units[f"{kind}_{cname}"] = "m (height of the point, while descending)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"liftoff_{cname}"] = "N (normal contact force)"
            if c.friction is not None:
                units[f"liftoff_{cname}"] = "N (normal contact force)"
                for suffix in SLIP_SUFFIX.values():
                    units[f"slip_{cname}{suffix}"] = (
                        "N (mu f_n -+ f_t: the force's distance to the friction cone's edge)"
                    )
                units[f"stick_{cname}"] = "m/s (slip velocity, while the friction decelerates it)"
        else:
            joint = model.pin_model.joints[joint_id(model.pin_model, c.joint, "stop", model.name)]
            rot = joint.shortname().startswith(("JointModelR",))
            kind = "impact" if c.restitution == 0.0 else "bounce"
            units[f"{kind}_{cname}"] = f"{'rad' if rot else 'm'} (distance to the stop, while approaching)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"release_{cname}"] = f"{'N m' if rot else 'N'} (stop force)"
    return units
