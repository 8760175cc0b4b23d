"""The outgoing transitions of a mode, one or two per contact.

* a spring leg: ``touchdown_<leg>`` in flight, ``liftoff_<leg>`` in stance (position guards);
* an active rigid contact: ``liftoff_<point>`` or ``release_<stop>`` on its normal force;
* an inactive rigid contact strikes (after dropping the contacts it ``releases``):
  with c = 0, ``touchdown_<point>`` / ``impact_<stop>`` into the mode with it active and
  ``graze_<name>`` into the mode without it (plastic guards, ``impacts``); with c > 0,
  ``bounce_<name>`` back into the mode without it, continued by ``rest_<name>`` (a plastic impact
  into the mode with it active) when its bounces accumulate (``legsim.relaxed.zeno``).

When some contact has Coulomb friction (``friction``), every strike is resolved by the impact law
with the friction cone and may lead to any mode its contacts can take: one transition per
possible target (``friction.outcome_transitions``), named as above when the other contacts stay
as they are (``touchdown_<c>``, ``graze_<c>``, ``bounce_<c>``) and ``<that name>@<target>``
otherwise; a stuck contact with friction also has ``slip_<c>>`` / ``slip_<c><`` (its force
reaching the cone's edge) and a slipping one ``stick_<c>`` (its slip velocity back through 0,
with the same several outcomes).
"""

from __future__ import annotations

from legsim.hybrid import Continuation, Transition

from . import friction
from .contacts import SLIP_SUFFIX, JointStop, SpringLeg
from .guards import kinematic_guard, kinematic_guards, release_guard
from .impacts import impact_reset, plain_reset, plastic_guard
from .model import BridgeData, BridgeModel
from .modes import ModeCatalog, ModeSpec, map_state


def outgoing(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec) -> list[Transition]:
    """Transitions out of mode ``spec``, contact by contact in declared order (their targets are
    resolved in ``modes`` on the way)."""
    out: list[Transition] = []
    active = set(spec.active)
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            out.append(_leg_transition(model, data, modes, spec, cname))
        elif cname in active and model.coulomb:
            out.extend(_settled_changes(model, data, modes, spec, cname))
        elif cname in active:
            out.append(_release_transition(model, data, modes, spec, cname))
        elif model.coulomb:
            out.extend(_coulomb_strikes(model, data, modes, spec, cname))
        else:
            out.extend(_strike_transitions(model, data, modes, spec, cname))
    return out


def _leg_transition(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec, leg: str) -> Transition:
    active = set(spec.active)
    if leg in active:
        dst, kind = modes.spec(modes.name_of(active - {leg})), "liftoff"
    else:
        dst, kind = modes.spec(modes.name_of(active | {leg})), "touchdown"
    return Transition(
        spec.name,
        dst.name,
        kinematic_guard(model, data, spec, leg),
        plain_reset(model, data, spec, dst),
        name=f"{kind}_{leg}",
    )


def _release_transition(
    model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec, contact: str
) -> Transition:
    dst = modes.spec(modes.name_of(set(spec.active) - {contact}))
    kind = "release" if isinstance(model.contacts[contact], JointStop) else "liftoff"
    guard, args = release_guard(model, data, spec, spec.normal_row(contact))
    return Transition(
        spec.name, dst.name, guard, plain_reset(model, data, spec, dst), name=f"{kind}_{contact}", guard_args=args
    )


def _strike_transitions(
    model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec, contact: str
) -> list[Transition]:
    """Impact transitions of the inactive rigid contact ``contact``. The contacts staying active
    through the impact are constrained plastically with it (rows of ``impact_velocity``)."""
    c = model.rigid[contact].contact
    staying = set(spec.active) - set(getattr(c, "releases", ()))
    kept = [(r, 0.0) for r in model.contacts if r in staying and r in model.rigid]
    rows = [*kept, (contact, c.restitution)]
    stick = modes.spec(modes.name_of(staying | {contact}))
    free = modes.spec(modes.name_of(staying))
    args = model.guard_args
    if c.restitution == 0.0:
        # A plastic impact sticks only if the contact then pushes (lambda > 0); otherwise
        # the contact separates at once. The two cases are two transitions with the same
        # impact law and complementary guards, so no reset lands outside its target.
        kind = "impact" if isinstance(c, JointStop) else "touchdown"
        stick_reset = impact_reset(model, data, spec, stick, rows)
        return [
            Transition(
                spec.name,
                stick.name,
                plastic_guard(model, data, spec, contact, stick, stick_reset, 1.0),
                stick_reset,
                name=f"{kind}_{contact}",
                guard_args=args,
            ),
            Transition(
                spec.name,
                free.name,
                plastic_guard(model, data, spec, contact, stick, stick_reset, -1.0),
                impact_reset(model, data, spec, free, rows),
                name=f"graze_{contact}",
                guard_args=args,
            ),
        ]
    bounce_reset = impact_reset(model, data, spec, free, rows)
    # When bounces accumulate the contact rests: the plastic impact into the constrained mode,
    # left again by its release guard where the contact force changes sign.
    rest = Continuation(
        stick.name, impact_reset(model, data, spec, stick, [*kept, (contact, 0.0)]), name=f"rest_{contact}"
    )
    return [
        Transition(
            spec.name,
            free.name,
            kinematic_guard(model, data, spec, contact),
            bounce_reset,
            name=f"bounce_{contact}",
            continuation=rest,
        )
    ]


def _replaced(modes: ModeCatalog, spec: ModeSpec, contact: str, new_entry: str) -> str:
    """The mode of ``spec`` with ``contact``'s entry replaced by ``new_entry``."""
    return modes.name_of([new_entry if c == contact else e for e, c in zip(spec.entries, spec.active, strict=True)])


def _settled_changes(
    model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec, contact: str
) -> list[Transition]:
    """The changes of an active rigid contact in a robot with friction, each leading to the mode
    whose forces are consistent under the controller's new control (``friction.mode_change``):
    ``liftoff_<c>`` / ``release_<c>`` (its normal force through 0); for a stuck contact with
    friction ``slip_<c>>`` and ``slip_<c><`` (its force at the cone's edge); for a slipping one
    ``stick_<c>`` (its slip velocity back through 0)."""
    involved = [r.contact.name for r in spec.rigid]
    targets = friction.candidate_targets(model, modes, spec, involved)
    kind = "release" if isinstance(model.contacts[contact], JointStop) else "liftoff"
    guard, _ = release_guard(model, data, spec, spec.normal_row(contact))
    lift = (lambda x, u: guard(0.0, x, u)) if model.timed else (lambda x, u: guard(x))
    out = _changes(model, data, spec, targets, lift, kind, contact, None, modes)
    slip = spec.rigid_of(contact).slip
    if model.rigid[contact].mu is None:
        return out
    if not slip:
        for s, suffix in SLIP_SUFFIX.items():
            base = friction.stick_slip_guard(model, data, spec, contact, s)
            out += _changes(model, data, spec, targets, base, "slip", contact, s, modes, suffix)
        return out

    def solve(x, u):
        return friction.event_outcome(model, data, modes, spec, x, u, (), {}, stopping=(contact,))

    canonical = _replaced(modes, spec, contact, contact)
    return out + friction.outcome_transitions(
        model,
        data,
        spec,
        targets,
        friction.slip_stop_guard(model, data, spec, contact),
        solve,
        lambda target: f"stick_{contact}" if target == canonical else f"stick_{contact}@{target}",
    )


def _changes(
    model: BridgeModel,
    data: BridgeData,
    spec: ModeSpec,
    targets: list[str],
    base,
    kind: str,
    contact: str,
    slip: float | None,
    modes: ModeCatalog,
    suffix: str = "",
) -> list[Transition]:
    """Outcome transitions of a contact lifting off (slip None) or starting to slip."""
    canonical = (
        _replaced(modes, spec, contact, contact + suffix)
        if slip is not None
        else modes.name_of([e for e, c in zip(spec.entries, spec.active, strict=True) if c != contact])
    )

    def solve(x, u):
        return friction.mode_change(model, data, modes, spec, x, u, contact, slip)

    def label(target: str) -> str:
        name = f"{kind}_{contact}{suffix}"
        return name if target == canonical else f"{name}@{target}"

    return friction.outcome_transitions(model, data, spec, targets, base, solve, label)


def _coulomb_strikes(
    model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec, contact: str
) -> list[Transition]:
    """The strike of ``contact`` in a robot with friction: one transition per possible target
    (module docstring); a bouncing contact's canonical bounce is continued by its rest."""
    c = model.rigid[contact].contact
    released = [r for r in getattr(c, "releases", ()) if r in spec.active]
    kept = [r.contact.name for r in spec.rigid if r.contact.name not in released]
    bouncing = [contact] if c.restitution > 0.0 else []
    targets = friction.candidate_targets(model, modes, spec, [*kept, contact], bouncing, released)
    staying = [e for e, a in zip(spec.entries, spec.active, strict=True) if a not in released]
    free, stuck = modes.name_of(staying), modes.name_of([*staying, contact])
    kind = "bounce" if bouncing else ("impact" if isinstance(c, JointStop) else "touchdown")

    def label(target: str) -> str:
        if target in (free, stuck):
            return f"{kind if target == stuck or bouncing else 'graze'}_{contact}"
        landed = contact in modes.active_contacts(target)
        return f"{kind if landed or bouncing else 'graze'}_{contact}@{target}"

    def solve(x, u, rest=False):
        return friction.event_outcome(
            model, data, modes, spec, x, u, (contact,), {contact: 0.0 if rest else c.restitution}
        )

    def base(x, u):
        return kinematic_guards(model, data, spec, x)[contact]

    out = friction.outcome_transitions(model, data, spec, targets, base, solve, label)
    if bouncing:
        target = modes.spec(stuck)
        rest = Continuation(
            stuck,
            lambda x: map_state(
                model, data, spec, target, x, solve(x, data.control_at(x), True)[1][model.n : 2 * model.n]
            ),
            name=f"rest_{contact}",
        )
        out = [
            Transition(
                tr.source,
                tr.target,
                tr.guard,
                tr.reset,
                tr.name,
                guard_args=tr.guard_args,
                continuation=rest if tr.target == free else None,
            )
            for tr in out
        ]
    return out
