"""Compiled twins of the modes of a robot with Coulomb friction (``friction``): their p.

In such a robot every event (a strike, a liftoff, a stuck contact reaching the cone's edge, a
slipping one coming to rest) has one transition per mode it may lead to, and the frictional
impact law (an active-set iteration) chooses among them. A transition's guard is the event's
*base* guard where the law chooses its target and the base's absolute value elsewhere
(``friction.outcome_transitions``): while the base is >= 0 every one of them equals it.

The twin computes the field (the KKT dynamics of stuck and slipping contacts, the slipping ones'
friction forces along ``W = J_z - s mu J_x``, in the native library) and every event's base.
Where a base is >= 0 it is each of the event's guards; where it is < 0 the event happens in that
step, and the twin returns nan guards: the mode is declared with ``fallback=True``, so the
Python loop takes the rest of the visit from the kernel's last accepted point: the steps the
relaxed rule shortens until one lands in the event's strip, and the event, whose outcome, reset
and next mode the Python law decides; the next mode's visit is compiled again (its functions:
``twins.coulomb_guards``, ``twins.bridge_field``). The twin has no resets: the kernel never
lands in its strips. A slipping mode whose contact forces are not unique (the Painleve paradox,
``dynamics.check_consistent``) gets a nan field, hence nan guards, and Python raises the
ModelBreakdown there.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from legsim.compiled import CompiledMode

from .contacts import SLIP_SUFFIX, JointStop, PointContact
from .model import BridgeModel
from .modes import ModeCatalog, ModeSpec
from .twin_build import Params, controls_of, gap_fields, mode_params
from .twins import E_FORCE, E_GAP, E_SLIP, E_STICK, P_CTRL, bridge_field, coulomb_guards, native_handle

_STRIKES = ("touchdown", "impact", "bounce", "graze")


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
    handle = native_handle(model.pin_model)
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
