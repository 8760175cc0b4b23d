"""Building a mode's parameter array p (``layout``): the robot's sections, which every mode
shares (its contacts, legs, damping, actuated joints, kinematics frames), and the mode's own
(its statuses, constraint blocks, stance footholds, then the records of its transitions, events
and joint outcomes, which ``transitions`` appends).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from legsim.terrain import top

from .contacts import RigidContact
from .layout import (
    ARMED_AHEAD,
    ARMED_ALWAYS,
    ARMED_COORDINATE,
    B_POINT,
    B_SLIPPING,
    B_STOP,
    HEADER,
    KIND_POINT,
    KIND_STOP,
    P_ACT,
    P_CODE,
    P_CONTACT,
    P_COULOMB,
    P_DAMP,
    P_DIM,
    P_FRAME,
    P_HANDLE,
    P_KINEMATICS,
    P_LEG,
    P_N,
    P_NACT,
    P_NCONTACT,
    P_NDAMP,
    P_NFRAME,
    P_NLEG,
    P_NRIGID,
    P_NSPRING,
    P_RIGID,
    P_ROUNDS_TURN,
    P_ROWS,
    P_STATUS,
    P_TERRAIN,
    P_TERRAIN_TOP,
    S_ABSENT,
    STATUS_BASE,
)
from .model import BridgeModel, rounds_move
from .modes import ModeSpec


class Builder:
    """p under construction: the header, then sections appended as they are described."""

    def __init__(self) -> None:
        self.values: list[float] = [0.0] * HEADER

    def append(self, values: Iterable[float]) -> int:
        """Append a section; returns its offset in p."""
        at = len(self.values)
        self.values.extend(float(v) for v in values)
        return at

    def set(self, slot: int, value: float) -> None:
        self.values[slot] = float(value)

    def array(self) -> np.ndarray:
        return np.array(self.values, dtype=np.float64)


def code_of(status: Sequence[float]) -> float:
    """The code of a mode's statuses (``layout``: ``sum status_i 4^i``)."""
    return float(sum(s * STATUS_BASE**i for i, s in enumerate(status)))


def block(r: RigidContact, slip: float) -> list[float]:
    """The constraint block (native ``Rigid``) of an active rigid contact, slipping towards slip
    (0: stuck, pinned as declared)."""
    if r.kind == "stop":
        return [B_STOP, r.dof, r.sign, 1.0]
    if slip:
        assert r.mu is not None, "only a contact with friction slips"
        return [B_SLIPPING, r.frame_id, slip * r.mu, 1.0]
    return [B_POINT, r.frame_id, -1.0 if r.mu is None else r.mu, r.rows]


def blocks(pairs: Iterable[tuple[RigidContact, float]]) -> list[float]:
    """The blocks of (contact, slip) pairs, concatenated."""
    return [v for r, slip in pairs for v in block(r, slip)]


def contact_record(model: BridgeModel, r: RigidContact) -> list[float]:
    """A rigid contact's record (``layout.C_*``)."""
    c = r.contact
    point = r.kind == "point"
    names = list(model.rigid)
    releases = sum(1 << names.index(o) for o in getattr(c, "releases", ()) if o in model.rigid)
    armed = getattr(c, "armed", None)
    armed_kind, armed_ref = float(ARMED_ALWAYS), 0.0
    if armed is not None and armed.coordinate:
        armed_kind, armed_ref = ARMED_COORDINATE, model.coordinate_names.index(armed.coordinate)
    elif armed is not None:
        armed_kind, armed_ref = ARMED_AHEAD, model.slot(r.armed_frame)
    return [
        KIND_POINT if point else KIND_STOP,
        r.frame_id if point else r.dof,
        r.sign,
        c.ground if point else c.position,  # type: ignore[union-attr]
        c.restitution,
        -1.0 if r.mu is None else r.mu,
        r.rows,
        model.slot(r.frame_id) if point else -1.0,
        releases,
        armed_kind,
        armed_ref,
        0.0 if armed is None else armed.beyond,
        r.radius,
        r.centre_id,
    ]


def leg_record(model: BridgeModel, spec: ModeSpec, name: str) -> list[float]:
    """A spring leg's record (``layout.L_*``) in mode ``spec``."""
    lg = model.legs[name]
    stance = [s.leg.name for s in spec.springs]
    leg = lg.leg
    return [
        model.slot(lg.hip_id),
        model.slot(lg.foot_id),
        lg.hip_id,
        lg.foot_id,
        leg.stiffness,
        leg.rest_length,
        leg.damping,
        leg.ground,
        stance.index(name) if name in stance else -1.0,
    ]


def start(model: BridgeModel, spec: ModeSpec) -> Builder:
    """A mode's p with its header and every section but the transitions' (``transitions``)."""
    b = Builder()
    b.set(P_HANDLE, model.handle)
    b.set(P_N, model.n)
    b.set(P_DIM, spec.dim)
    b.set(P_NACT, len(model.actuated_idx))
    b.set(P_ACT, b.append(v for k, lim in zip(model.actuated_idx, model.effort_limits, strict=True) for v in (k, lim)))
    b.set(P_NDAMP, len(model.damping_idx))
    b.set(P_DAMP, b.append(v for k, d in zip(model.damping_idx, model.damping_b, strict=True) for v in (k, d)))
    b.set(P_NFRAME, len(model.frames))
    b.set(P_FRAME, b.append(model.frames))
    b.set(P_KINEMATICS, float(_needs_kinematics(model, spec)))
    b.set(P_NCONTACT, len(model.rigid))
    b.set(P_CONTACT, b.append(v for r in model.rigid.values() for v in contact_record(model, r)))
    b.set(P_STATUS, b.append(spec.status))
    b.set(P_CODE, code_of(spec.status))
    b.set(P_NRIGID, len(spec.rigid))
    b.set(P_RIGID, b.append(blocks(zip(spec.rigid, spec.slips, strict=True))))
    b.set(P_ROWS, spec.rows)
    b.set(P_NLEG, len(model.legs))
    b.set(P_LEG, b.append(v for name in model.legs for v in leg_record(model, spec, name)))
    b.set(P_NSPRING, len(spec.springs))
    b.set(P_COULOMB, float(model.coulomb))
    b.set(P_TERRAIN, -1.0 if model.terrain is None else b.append(model.terrain))
    b.set(P_TERRAIN_TOP, top(model.terrain))
    b.set(P_ROUNDS_TURN, float(bool(model.round_offsets) and rounds_move(model.terrain)))
    return b


def _needs_kinematics(model: BridgeModel, spec: ModeSpec) -> bool:
    """Whether the mode's guards read frame kinematics: spring legs, or inactive point contacts."""
    inactive_points = any(
        r.kind == "point" and status == S_ABSENT for r, status in zip(model.rigid.values(), spec.status, strict=True)
    )
    return bool(model.legs) or inactive_points
