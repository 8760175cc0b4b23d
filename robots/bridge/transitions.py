"""The outgoing transitions of a mode, their records in its parameter array, and its joint
outcomes; the functions they take their guards and resets from are ``events``' and ``joint``'s.

* a spring leg: ``touchdown_<leg>`` in flight, ``liftoff_<leg>`` in stance;
* an active rigid contact: ``liftoff_<point>`` or ``release_<stop>`` on its normal force;
* an inactive rigid contact strikes (after dropping the contacts it ``releases``): with c = 0,
  ``touchdown_<point>`` / ``impact_<stop>`` into the mode with it active and ``graze_<name>``
  into the mode without it; with c > 0, ``bounce_<name>`` back into the mode without it,
  continued by ``rest_<name>`` (a plastic impact into the mode with it active) when its bounces
  accumulate (``legsim.relaxed.zeno``).

When some contact has Coulomb friction, every event may lead to any mode its contacts can take
(``friction``): one transition per possible target, named as above when the other contacts stay
as they are (``touchdown_<c>``, ``graze_<c>``, ``bounce_<c>``) and ``<that name>@<target>``
otherwise; a stuck contact with friction also has ``slip_<c>>`` / ``slip_<c><`` (its force
reaching the cone's edge) and a slipping one ``stick_<c>`` (its slip velocity back through 0),
with the same several outcomes. On a terrain with corners a sliding point also has
``corner_<c>``: it passed a corner, and strikes the new face or leaves it.

Rigid contacts that strike in the same landing step are resolved together (``joint``): the
outcomes ``joint_<strikers>`` and ``rest_<strikers>`` (their continuation) into each mode they
may lead to, declared with the mode (``ModeFunctions.joint_outcomes``).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from legsim.errors import ModelError
from legsim.hybrid import Continuation, Transition

from .contacts import SLIP_SUFFIX, JointStop, SpringLeg
from .layout import (
    E_CORNER,
    E_FORCE,
    E_GAP,
    E_SLIP,
    E_STICK,
    K_BOUNCE,
    K_LEG_LIFT,
    K_LEG_TOUCH,
    K_OUTCOME,
    K_PLASTIC,
    K_RELEASE,
    TR_COEFF,
    TR_CONTACT,
    TR_EVENT,
    TR_IMPACT,
    TR_KIND,
    TR_MAP,
    TR_NIMPACT,
    TR_NMAP,
    TR_NSTICK,
    TR_REST,
    TR_ROW,
    TR_SIDE,
    TR_STICK,
    TR_STRIKE,
    TR_TARGET,
    TRANSITION_SIZE,
)
from .model import BridgeModel
from .modes import ModeCatalog, ModeSpec
from .params import Builder, blocks, code_of

#: Most modes one event may lead to; most joint outcomes of one mode (``_joint_outcomes``).
MAX_OUTCOMES = 256
MAX_JOINT_OUTCOMES = 1024


@dataclass
class Outgoing:
    """A mode's transitions with their records (``TRANSITION_SIZE`` values each), its events'
    records (Coulomb friction) and its joint outcomes ((name, target) with their records)."""

    transitions: list[Transition]
    records: list[list[float]]
    events: list[list[float]]
    joint_outcomes: list[tuple[str, str]]
    joint_records: list[list[float]]


def record(kind: float, contact: int = -1, strike: int = -1, **fields: float) -> list[float]:
    """A transition record (``layout.TR_*``): its kind, contact and struck contact, and the named
    fields (``side``, ``impact``, ``nimpact``, ``coeff``, ``rest``, ``stick``, ``nstick``, ``row``,
    ``map``, ``nmap``, ``event``, ``target``; 0 when not given)."""
    out = [0.0] * TRANSITION_SIZE
    out[TR_KIND], out[TR_CONTACT], out[TR_STRIKE] = kind, contact, strike
    slots = {"side": TR_SIDE, "impact": TR_IMPACT, "nimpact": TR_NIMPACT, "coeff": TR_COEFF, "rest": TR_REST,
             "stick": TR_STICK, "nstick": TR_NSTICK, "row": TR_ROW, "map": TR_MAP, "nmap": TR_NMAP,
             "event": TR_EVENT, "target": TR_TARGET}  # fmt: skip
    for name, value in fields.items():
        out[slots[name]] = float(value)
    return out


def outgoing(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, b: Builder) -> Outgoing:
    """The transitions out of mode ``spec``, contact by contact in declared order, with their
    records (their sections appended to ``b``), and the mode's joint outcomes."""
    out = Outgoing([], [], [], [], [])
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            _leg(model, modes, spec, cname, b, out)
        elif model.coulomb and cname in spec.active:
            _settled_changes(model, modes, spec, cname, out)
        elif cname in spec.active:
            _release(model, modes, spec, cname, out)
        elif model.coulomb:
            _coulomb_strike(model, modes, spec, cname, out)
        else:
            _strike(model, modes, spec, cname, b, out)
    _joint_outcomes(model, modes, spec, out)
    return out


def _add(
    out: Outgoing, spec: ModeSpec, target: str, name: str, rec: list[float], rest: str = "", rest_to: str = ""
) -> None:
    continuation = Continuation(rest_to, name=rest) if rest else None
    out.transitions.append(Transition(spec.name, target, name=name, continuation=continuation))
    out.records.append(rec)


def _leg(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, leg: str, b: Builder, out: Outgoing) -> None:
    """A spring leg's touchdown or liftoff, with the map of the target's footholds (their index
    in this mode's, -1 for the touching leg's)."""
    stance = leg in spec.active
    dst = modes.spec(modes.name_of(set(spec.active) ^ {leg}))
    index = {lg.leg.name: i for i, lg in enumerate(spec.springs)}
    at = b.append(index.get(lg.leg.name, -1) for lg in dst.springs)
    kind = K_LEG_LIFT if stance else K_LEG_TOUCH
    rec = record(kind, list(model.legs).index(leg), map=at, nmap=len(dst.springs))
    _add(out, spec, dst.name, f"{'liftoff' if stance else 'touchdown'}_{leg}", rec)


def _release(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, contact: str, out: Outgoing) -> None:
    dst = modes.name_of(set(spec.active) - {contact})
    kind = "release" if isinstance(model.contacts[contact], JointStop) else "liftoff"
    rec = record(K_RELEASE, model.index(contact), row=spec.normal_row(contact))
    _add(out, spec, dst, f"{kind}_{contact}", rec)


def _strike(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, contact: str, b: Builder, out: Outgoing) -> None:
    """The impact transitions of an inactive rigid contact of a robot without friction (module
    docstring); the contacts staying active are held plastically through the impact."""
    r = model.rigid[contact]
    c = r.contact
    staying = set(spec.active) - set(getattr(c, "releases", ()))
    kept = [model.rigid[k] for k in model.contacts if k in staying and k in model.rigid]
    impact = b.append(blocks((k, 0.0) for k in [*kept, r]))
    stick = modes.spec(modes.name_of(staying | {contact}))
    free = modes.name_of(staying)
    index = model.index(contact)
    common = {"impact": impact, "nimpact": len(kept) + 1}
    if c.restitution > 0.0:
        coeff = b.append([0.0] * len(kept) + [c.restitution])
        rest = b.append([0.0] * (len(kept) + 1))
        rec = record(K_BOUNCE, index, index, coeff=coeff, rest=rest, **common)
        _add(out, spec, free, f"bounce_{contact}", rec, rest=f"rest_{contact}", rest_to=stick.name)
        return
    coeff = b.append([0.0] * (len(kept) + 1))
    stick_at = b.append(blocks(zip(stick.rigid, stick.slips, strict=True)))
    plastic = {
        **common,
        "coeff": coeff,
        "stick": stick_at,
        "nstick": len(stick.rigid),
        "row": stick.normal_row(contact),
    }
    kind = "impact" if isinstance(c, JointStop) else "touchdown"
    _add(out, spec, stick.name, f"{kind}_{contact}", record(K_PLASTIC, index, index, side=1.0, **plastic))
    _add(out, spec, free, f"graze_{contact}", record(K_PLASTIC, index, index, side=-1.0, **plastic))


# -- robots with Coulomb friction -----------------------------------------------------------


def candidate_targets(
    model: BridgeModel,
    modes: ModeCatalog,
    spec: ModeSpec,
    involved: Sequence[str],
    bouncing: Sequence[str] = (),
    dropped: Sequence[str] = (),
    limit: int = MAX_OUTCOMES,
) -> list[str]:
    """Every mode an event of the ``involved`` rigid contacts in mode ``spec`` may lead to: each
    involved contact absent, stuck or (with friction) slipping either way; a ``bouncing`` one
    only absent; the ``dropped`` ones (released) absent; the other entries unchanged."""
    fixed = [e for e, c in zip(spec.entries, spec.active, strict=True) if c not in involved and c not in dropped]
    options: list[list[float | None]] = []  # per involved contact: absent (None) or its slip
    for c in involved:
        if c in bouncing:
            options.append([None])
        elif model.rigid[c].mu is not None:
            options.append([None, 0.0, 1.0, -1.0])
        else:
            options.append([None, 0.0])
    count = 1
    for o in options:
        count *= len(o)
    if count > limit:
        raise ModelError(
            f"{model.name}: an event in mode '{spec.name}' involves {list(involved)}, which could lead "
            f"to {count} modes (at most {limit} are supported): declare fewer contacts with "
            f"friction, or frictionless ones"
        )
    targets: list[str] = []
    for choice in itertools.product(*options):
        entries = fixed + [
            c + SLIP_SUFFIX[s] if s else c for c, s in zip(involved, choice, strict=True) if s is not None
        ]
        name = modes.name_of(entries)
        if name not in targets:
            targets.append(name)
    return targets


def _event(
    model: BridgeModel,
    modes: ModeCatalog,
    spec: ModeSpec,
    out: Outgoing,
    kind: float,
    contact: str,
    targets: list[str],
    label: Callable[[str], str],
    slip: float = 0.0,
    rest_to: str = "",
    rest_of: str = "",
) -> None:
    """An event's record and its transitions, one per target; the transition into ``rest_of``
    (a bounce's into the mode without the contact) is continued by its rest into ``rest_to``."""
    index = model.index(contact)
    strike = index if kind == E_GAP else -1
    first = len(out.transitions)
    row = spec.normal_row(contact) if contact in spec.active else 0
    out.events.append([kind, index, slip, row, first, len(targets)])
    for target in targets:
        rec = record(K_OUTCOME, index, strike, event=len(out.events) - 1, target=code_of(modes.spec(target).status))
        rest = f"rest_{contact}" if rest_to and target == rest_of else ""
        _add(out, spec, target, label(target), rec, rest=rest, rest_to=rest_to)


def _replaced(modes: ModeCatalog, spec: ModeSpec, contact: str, new_entry: str) -> str:
    """The mode of ``spec`` with ``contact``'s entry replaced by ``new_entry``."""
    return modes.name_of([new_entry if c == contact else e for e, c in zip(spec.entries, spec.active, strict=True)])


def _labels(name: str, canonical: str) -> Callable[[str], str]:
    return lambda target: name if target == canonical else f"{name}@{target}"


def _settled_changes(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, contact: str, out: Outgoing) -> None:
    """The events of an active rigid contact of a robot with friction, each leading to the mode
    whose forces are consistent: ``liftoff_<c>`` / ``release_<c>`` (its normal force through 0);
    for a stuck contact with friction ``slip_<c>>`` and ``slip_<c><`` (its force at the cone's
    edge); for a slipping one ``stick_<c>`` (its slip velocity back through 0); for a sliding
    point, or a round contact rolling or sliding, on a terrain with corners ``corner_<c>``
    (``events.corner_base``)."""
    involved = [r.contact.name for r in spec.rigid]
    targets = candidate_targets(model, modes, spec, involved)
    kind = "release" if isinstance(model.contacts[contact], JointStop) else "liftoff"
    without = modes.name_of([e for e, c in zip(spec.entries, spec.active, strict=True) if c != contact])
    _event(model, modes, spec, out, E_FORCE, contact, targets, _labels(f"{kind}_{contact}", without))
    # a stuck point stays on its face; a stuck ball rolls, its centre moving past corners
    moving = model.rigid[contact].mu is None or spec.slip_of(contact) or model.rigid[contact].radius > 0.0
    if model.cornered and moving and not isinstance(model.contacts[contact], JointStop):
        _event(model, modes, spec, out, E_CORNER, contact, targets, _labels(f"corner_{contact}", spec.name))
    if model.rigid[contact].mu is None:
        return
    slip = spec.slip_of(contact)
    if not slip:
        for s, suffix in SLIP_SUFFIX.items():
            name = f"slip_{contact}{suffix}"
            canonical = _replaced(modes, spec, contact, contact + suffix)
            _event(model, modes, spec, out, E_SLIP, contact, targets, _labels(name, canonical), slip=s)
        return
    canonical = _replaced(modes, spec, contact, contact)
    _event(model, modes, spec, out, E_STICK, contact, targets, _labels(f"stick_{contact}", canonical), slip=slip)


def _coulomb_strike(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, contact: str, out: Outgoing) -> None:
    """The strike of ``contact`` in a robot with friction: one transition per possible target
    (module docstring); a bouncing contact's canonical bounce is continued by its rest."""
    c = model.rigid[contact].contact
    released = [r for r in getattr(c, "releases", ()) if r in spec.active]
    kept = [r.contact.name for r in spec.rigid if r.contact.name not in released]
    bouncing = [contact] if c.restitution > 0.0 else []
    targets = candidate_targets(model, modes, spec, [*kept, contact], bouncing, released)
    staying = [e for e, a in zip(spec.entries, spec.active, strict=True) if a not in released]
    free, stuck = modes.name_of(staying), modes.name_of([*staying, contact])
    kind = "bounce" if bouncing else ("impact" if isinstance(c, JointStop) else "touchdown")

    def label(target: str) -> str:
        if target in (free, stuck):
            return f"{kind if target == stuck or bouncing else 'graze'}_{contact}"
        landed = contact in modes.active_contacts(target)
        return f"{kind if landed or bouncing else 'graze'}_{contact}@{target}"

    rest_to = stuck if bouncing else ""
    _event(model, modes, spec, out, E_GAP, contact, targets, label, rest_to=rest_to, rest_of=free)


# -- simultaneous strikes -----------------------------------------------------------------------


def _joint_outcomes(model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, out: Outgoing) -> None:
    """The outcomes of every set of two or more strikes of the mode (``joint``), each with its
    record (strikers' mask, rest, target code): sets by increasing size while their outcomes stay
    within ``MAX_JOINT_OUTCOMES`` (a robot with many contacts resolves pairs together, and larger
    sets one contact after the other)."""
    strikable = [c for c in model.rigid if c not in spec.active]
    for size in range(2, len(strikable) + 1):
        sets = list(itertools.combinations(strikable, size))
        count = sum(_joint_count(model, spec, strikers, rest) for strikers in sets for rest in (False, True))
        if len(out.joint_outcomes) + count > MAX_JOINT_OUTCOMES:
            return
        for strikers in sets:
            mask = sum(1 << model.index(c) for c in strikers)
            for rest in (0, 1):
                name = f"{'rest' if rest else 'joint'}_{'+'.join(strikers)}"
                for target in _joint_targets(model, modes, spec, strikers, bool(rest)):
                    out.joint_outcomes.append((name, target))
                    out.joint_records.append([mask, rest, code_of(modes.spec(target).status)])


def _joint_count(model: BridgeModel, spec: ModeSpec, strikers: Sequence[str], rest: bool) -> int:
    """At most how many modes ``_joint_targets`` gives (without building them)."""
    released = {o for c in strikers for o in getattr(model.contacts[c], "releases", ()) if o in spec.active}
    count = 1
    if model.coulomb:
        kept = [r.contact.name for r in spec.rigid if r.contact.name not in released]
        for c in [*kept, *strikers]:
            bouncing = not rest and c in strikers and model.rigid[c].contact.restitution > 0.0
            count *= 1 if bouncing else 4 if model.rigid[c].mu is not None else 2
        return count
    for c in strikers:
        count *= 2 if rest or model.rigid[c].contact.restitution == 0.0 else 1
    return count


def _joint_targets(
    model: BridgeModel, modes: ModeCatalog, spec: ModeSpec, strikers: Sequence[str], rest: bool
) -> list[str]:
    """The modes the joint impact of ``strikers`` may lead to: the staying contacts (not
    released) and, without friction, any of the plastic strikers; with friction as
    ``candidate_targets`` of the held and striking contacts."""
    released = {o for c in strikers for o in getattr(model.contacts[c], "releases", ()) if o in spec.active}
    if model.coulomb:
        kept = [r.contact.name for r in spec.rigid if r.contact.name not in released]
        bouncing = [] if rest else [c for c in strikers if model.rigid[c].contact.restitution > 0.0]
        return candidate_targets(model, modes, spec, [*kept, *strikers], bouncing, sorted(released), MAX_JOINT_OUTCOMES)
    staying = [e for e, c in zip(spec.entries, spec.active, strict=True) if c not in released]
    plastic = [c for c in strikers if rest or model.rigid[c].contact.restitution == 0.0]
    targets = []
    for size in range(len(plastic) + 1):
        for landed in itertools.combinations(plastic, size):
            name = modes.name_of([*staying, *landed])
            if name not in targets:
                targets.append(name)
    return targets
