"""Compiled twins of the modes of a robot with Coulomb friction (``friction``).

In such a robot every event (a strike, a liftoff, a stuck contact reaching the cone's edge, a
slipping one coming to rest) has one transition per mode it may lead to, and the frictional
impact law (an active-set iteration) chooses among them. A transition's guard is the event's
*base* guard where the law chooses its target and the base's absolute value elsewhere
(``friction.outcome_transitions``): while the base is >= 0 every one of them equals it.

The twin computes the field (the KKT dynamics of stuck and slipping contacts, the slipping ones'
friction forces along ``W = J_z - s mu J_x``, in the native library) and every event's base.
Where a base is >= 0 it is each of the event's guards; where it is < 0 the event happens in that
step, and the twin returns nan guards: the mode is declared with ``fallback=True``, so the
Python loop takes the rest of the visit from the kernel's last accepted point. That is the step
with the event, whose outcome, reset and next mode the Python law decides; the next mode's visit
is compiled again. The twin has no resets: the kernel never lands in its strips. A slipping mode
whose contact forces are not unique (the Painleve paradox, ``dynamics.check_consistent``) gets
a nan field, hence nan guards, and Python raises the ModelBreakdown there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from legsim._native.calls import lsn_frame_motion, lsn_frames
from legsim.compiled import CompiledMode

from .contacts import SLIP_SUFFIX, JointStop, PointContact
from .model import BridgeModel
from .modes import ModeCatalog, ModeSpec
from .twins import (
    C_KINEMATICS,
    P_CTRL,
    P_FRAME,
    P_GUARD,
    P_HANDLE,
    P_N,
    P_NFRAME,
    P_NRIGID,
    P_RIGID,
    P_ROWS,
    Params,
    _jit,
    accelerate,
    bridge_field,
    control_input,
    controls_of,
    count,
    gap_fields,
    gap_value,
    handle_for,
    mode_params,
    native_ready,
    ptr,
)

# Event kinds: a strike's gap, a contact's normal force (liftoff, release), a stuck contact's
# distance to the cone's edge towards s, a slipping contact's slip rate against s.
E_GAP, E_FORCE, E_SLIP, E_STICK = range(4)
# Fields of an event record: kind; the gap's fields at twins' G_GAP_KIND, G_A, G_B, G_C (so
# that ``gap_value`` reads them), which the other kinds use as (normal row, mu, s) for E_FORCE
# and E_SLIP and (frame id, s) for E_STICK; how many transitions (outcomes) the event has.
E_KIND, E_GAP_KIND, E_A, E_B, E_C, E_COPIES = range(6)
EVENT_SIZE = 6
_STRIKES = ("touchdown", "impact", "bounce", "graze")


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
    nframe = int(p[P_NFRAME])
    kin = np.empty(4 * max(1, nframe))
    if nframe > 0:
        count(p, C_KINEMATICS)
        lsn_frames(
            np.int64(p[P_HANDLE]), x.ctypes.data, ptr(x, n), np.int64(nframe), ptr(p, int(p[P_FRAME])), kin.ctypes.data
        )
    a = np.empty(n)
    lam = np.empty(max(1, int(p[P_ROWS])))
    total = 0
    dynamic = False  # some event reads the mode's forces or accelerations (flight's strikes do not)
    for k in range(n_events):
        e = events_at + 1 + EVENT_SIZE * k
        total += int(p[e + E_COPIES])
        dynamic = dynamic or int(p[e + E_KIND]) != E_GAP
    if dynamic:
        accelerate(x, p, n, int(p[P_NRIGID]), int(p[P_RIGID]), int(p[P_ROWS]), a, lam, control_input(x, p, n))
    out = np.empty(total)
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


def _events(model: BridgeModel, spec: ModeSpec, pp: Params) -> list[tuple[tuple[str, ...], list[float]]] | None:
    """(the names their transitions start with, event record without its count) of the mode's
    events, in ``transitions.outgoing``'s order, or None when the twin cannot follow (spring
    legs, armed contacts)."""
    out: list[tuple[tuple[str, ...], list[float]]] = []
    for cname, c in model.contacts.items():
        if not isinstance(c, (JointStop, PointContact)) or getattr(c, "armed", None) is not None:
            return None
        if cname not in spec.active:
            out.append((tuple(f"{kind}_{cname}" for kind in _STRIKES), [E_GAP, *gap_fields(model.rigid[cname], pp)]))
            continue
        row = spec.normal_row(cname)
        kind = "release" if isinstance(c, JointStop) else "liftoff"
        out.append(((f"{kind}_{cname}",), [E_FORCE, 0.0, row, 0.0, 0.0]))
        mu = model.rigid[cname].mu
        if mu is None:
            continue
        slip = spec.rigid_of(cname).slip
        if not slip:
            out += [((f"slip_{cname}{suffix}",), [E_SLIP, 0.0, row, mu, s]) for s, suffix in SLIP_SUFFIX.items()]
        else:
            out.append(((f"stick_{cname}",), [E_STICK, 0.0, model.rigid[cname].frame_id, slip, 0.0]))
    return out


def _outcome_counts(events: Sequence[tuple[tuple[str, ...], list[float]]], names: Sequence[str]) -> list[int] | None:
    """How many of the consecutive transitions ``names`` belong to each event (a transition is
    ``<stem>`` or ``<stem>@<target>``), or None when they do not follow the events exactly."""
    counts, i = [], 0
    for stems, _ in events:
        start = i
        while i < len(names) and any(names[i] == s or names[i].startswith(s + "@") for s in stems):
            i += 1
        if i == start:
            return None
        counts.append(i - start)
    return counts if i == len(names) else None


def coulomb_twin(
    model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, transitions: Sequence[Any]
) -> CompiledMode | None:
    """The compiled twin of mode ``spec`` of a robot with Coulomb friction whose outgoing
    transitions are ``transitions`` (module docstring), or None when the native library is
    unavailable or the mode has something the twin does not compute."""
    if not native_ready():
        return None
    handle = handle_for(model.pin_model)
    if handle is None:
        return None
    pp = Params()
    events = _events(model, spec, pp)
    if events is None:
        return None
    counts = _outcome_counts(events, [tr.name for tr in transitions])
    if counts is None:
        return None
    records = [v for (_, record), copies in zip(events, counts, strict=True) for v in (*record, copies)]
    events_at = pp.append([len(events), *records])
    p = mode_params(model, spec, pp, handle, len(transitions), events_at)
    return CompiledMode(
        bridge_field,
        coulomb_guards,
        len(transitions),
        p,
        fallback=True,
        controls=controls_of(model, int(p[P_CTRL])) if model.actuated_idx.size else None,
    )
