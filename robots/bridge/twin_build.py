"""Building a bridge mode's compiled twin (``twins``: the functions it runs): its parameter
array p (header, rigid blocks, springs, damping, guard records, frames, actuated joints, control
record, counters) and the ``CompiledMode`` around it, or None where the twin cannot follow the
mode (then it runs in Python)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from legsim.compiled import CompiledMode

from ..runner_twin import record_size
from .contacts import JointStop, PointContact, RigidContact, SpringLeg
from .control_records import CONTROL_HEAD, CTRL_JOINT_PD, CTRL_NONE, CTRL_RUNNER
from .joint import striking_contacts
from .model import BridgeModel
from .modes import ModeCatalog, ModeSpec
from .twins import (
    COUNTED,
    HEADER,
    K_GAP,
    K_LEG_LIFT,
    K_LEG_TOUCH,
    K_PLASTIC,
    K_RELEASE,
    P_ACT,
    P_CTRL,
    P_DAMP,
    P_DIM,
    P_FRAME,
    P_GUARD,
    P_HANDLE,
    P_N,
    P_NACT,
    P_NDAMP,
    P_NFRAME,
    P_NGUARD,
    P_NRIGID,
    P_NSPRING,
    P_RIGID,
    P_ROWS,
    P_SPRING,
    bridge_field,
    bridge_guards,
    bridge_resets,
    native_handle,
)


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
    handle = native_handle(model.pin_model)
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
    header[P_CTRL] = pp.append([0.0] * control_size(nact))
    pp.append([0.0] * len(COUNTED))
    return np.array(pp.p)


def control_size(nact: int) -> int:
    """Room for the control record of a robot with ``nact`` actuated joints: a joint PD's, or a
    runner's with a hip and a knee per leg."""
    return max(CONTROL_HEAD + nact, record_size(nact // 2))


def _fits(record: Sequence[float] | None, nact: int) -> bool:
    """Whether ``record`` is one the twin computes for a robot with ``nact`` actuated joints."""
    if record is None or not len(record):
        return False
    if record[0] == CTRL_JOINT_PD:
        return len(record) == CONTROL_HEAD + nact
    return record[0] == CTRL_RUNNER and len(record) <= control_size(nact)


def controls_of(model: BridgeModel, at: int) -> Any:
    """``CompiledMode.controls`` of an actuated robot's twin whose control record is at p[at:]:
    a run without control writes ``CTRL_NONE``; a controller writes its
    ``compiled_record(pin_model)`` of kind ``joint_pd`` or ``raibert_runner`` (None, or a record
    of another kind or size: it has none for this robot, the run takes Python)."""
    nact = len(model.actuated_idx)
    size = control_size(nact)

    def controls(controller: Any) -> Any:
        if controller is None:
            return lambda p: _write_record(p, at, size, [float(CTRL_NONE)])
        make = getattr(controller, "compiled_record", None)
        if make is None or not _fits(make(model.pin_model), nact):
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
