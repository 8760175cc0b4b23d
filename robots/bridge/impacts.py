"""Resets, and the guards of plastic impacts.

Impact of rigid contacts with restitution c (generalised Newton impact): with ``J`` the Jacobian
rows of the contacts constrained at the impact, ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)``
where ``w = -c J v`` row-wise (c = 0 for the contacts that stay active, the striking contact's
own c on its rows); for a joint stop alone this is paper 003 eq. (30). A plastic impact
(c = 0) after which the contact would pull (normal force lambda+ < 0 at the post-impact state)
separates at once: it is a second transition ``graze_<name>`` into the mode without the contact,
with guard ``max(gap guard, lambda+)`` against ``max(gap guard, -lambda+)`` for the sticking one.
Liftoff and release keep q and v and drop what leaves the state; a spring leg's touchdown
appends its foothold.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from .dynamics import constraint_forces, constraint_rows, control_key, solve_small
from .guards import kinematic_guards, state_guard
from .model import BridgeData, BridgeModel
from .modes import ModeSpec, map_state

Reset = Callable[[np.ndarray], np.ndarray]


def impact_velocity(
    model: BridgeModel, data: BridgeData, rows: Sequence[tuple[str, float]], q: np.ndarray, v: np.ndarray
) -> np.ndarray:
    """Post-impact velocity (nv,) of the generalised Newton impact.

    ``rows``: ``(contact name, restitution)`` of the contacts constrained at the impact;
    each contact's Jacobian rows J_i get ``J_i v+ = -c_i J_i v``.
    ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)``, ``w = -c J v`` row-wise.
    """
    data.counts["impacts"] += 1
    rigid = [model.rigid[name] for name, _ in rows]
    J, _ = constraint_rows(model, data, rigid, q, v, drift=False)
    coeff = np.concatenate([np.full(r.rows, c) for r, (_, c) in zip(rigid, rows, strict=True)])
    Minv = pin.computeMinverse(model.pin_model, data.pin_data, q)
    MJt = Minv @ J.T
    Jv = J @ v
    return v + MJt @ solve_small(J @ MJt, -(1.0 + coeff) * Jv)


def impact_reset(
    model: BridgeModel, data: BridgeData, src: ModeSpec, dst: ModeSpec, rows: Sequence[tuple[str, float]]
) -> Reset:
    """Reset of an impact from mode ``src`` into ``dst`` (``rows`` as in ``impact_velocity``)."""
    n = model.n

    def reset(x: np.ndarray) -> np.ndarray:
        v_new = impact_velocity(model, data, rows, x[:n], x[n : 2 * n])
        return map_state(model, data, src, dst, x, v_new)

    return reset


def plain_reset(model: BridgeModel, data: BridgeData, src: ModeSpec, dst: ModeSpec) -> Reset | None:
    """Reset of a transition that keeps q and v: None (the identity) when both modes have the
    same stance legs, else the map that drops or appends footholds."""
    if src.springs == dst.springs:
        return None
    return lambda x: map_state(model, data, src, dst, x, None)


def plastic_guard(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str, stick: ModeSpec, stick_reset: Reset, sign: float
) -> Callable[..., float]:
    """``max(gap guard, -sign * lambda+)`` of a plastic impact of ``contact`` from mode ``spec``
    (sign +1: the sticking transition into ``stick``; -1: the grazing one). lambda+ is the
    contact's normal force right after the impact, computed only once the gap guard is past
    (then cached per state and control). Declared with ``model.guard_args``."""

    def value(x: np.ndarray, u: Any) -> float:
        base = kinematic_guards(model, data, spec, x)[contact]
        if base >= 0.0:
            return base
        key = x.tobytes() + control_key(u)
        post = data.scratch(spec.name).post
        cached = post.get(contact)
        if cached is not None and cached[0] == key:
            lam = cached[1]
        else:
            lam = float(constraint_forces(model, data, stick, stick_reset(x), u)[contact][-1])
            post[contact] = (key, lam)
        return max(base, -sign * lam)

    return state_guard(model, value)[0]
