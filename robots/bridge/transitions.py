"""The outgoing transitions of a mode, one or two per contact.

* a spring leg: ``touchdown_<leg>`` in flight, ``liftoff_<leg>`` in stance (position guards);
* an active rigid contact: ``liftoff_<point>`` or ``release_<stop>`` on its normal force;
* an inactive rigid contact strikes (after dropping the contacts it ``releases``):
  with c = 0, ``touchdown_<point>`` / ``impact_<stop>`` into the mode with it active and
  ``graze_<name>`` into the mode without it (plastic guards, ``impacts``); with c > 0,
  ``bounce_<name>`` back into the mode without it, continued by ``rest_<name>`` (a plastic impact
  into the mode with it active) when its bounces accumulate (``legsim.relaxed.zeno``).
"""

from __future__ import annotations

from legsim.hybrid import Continuation, Transition

from .contacts import JointStop, SpringLeg
from .guards import kinematic_guard, release_guard
from .impacts import impact_reset, plain_reset, plastic_guard
from .model import BridgeData, BridgeModel
from .modes import ModeCatalog, ModeSpec


def outgoing(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec) -> list[Transition]:
    """Transitions out of mode ``spec``, contact by contact in declared order (their targets are
    resolved in ``modes`` on the way)."""
    out: list[Transition] = []
    active = set(spec.active)
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            out.append(_leg_transition(model, data, modes, spec, cname))
        elif cname in active:
            out.append(_release_transition(model, data, modes, spec, cname))
        else:
            out.extend(_strike_transitions(model, data, modes, spec, cname))
    return out


def _leg_transition(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec,
                    leg: str) -> Transition:
    active = set(spec.active)
    if leg in active:
        dst, kind = modes.spec(modes.name_of(active - {leg})), "liftoff"
    else:
        dst, kind = modes.spec(modes.name_of(active | {leg})), "touchdown"
    return Transition(spec.name, dst.name, kinematic_guard(model, data, spec, leg),
                      plain_reset(model, data, spec, dst), name=f"{kind}_{leg}")


def _release_transition(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec,
                        contact: str) -> Transition:
    dst = modes.spec(modes.name_of(set(spec.active) - {contact}))
    kind = "release" if isinstance(model.contacts[contact], JointStop) else "liftoff"
    guard, args = release_guard(model, data, spec, spec.normal_row(contact))
    return Transition(spec.name, dst.name, guard, plain_reset(model, data, spec, dst),
                      name=f"{kind}_{contact}", guard_args=args)


def _strike_transitions(model: BridgeModel, data: BridgeData, modes: ModeCatalog, spec: ModeSpec,
                        contact: str) -> list[Transition]:
    """Impact transitions of the inactive rigid contact ``contact``. The contacts staying active
    through the impact are constrained plastically with it (rows of ``impact_velocity``)."""
    c = model.contacts[contact]
    staying = set(spec.active) - set(getattr(c, "releases", ()))
    kept = [(r, 0.0) for r in model.contacts if r in staying and r in model.rigid]
    rows = kept + [(contact, c.restitution)]
    stick = modes.spec(modes.name_of(staying | {contact}))
    free = modes.spec(modes.name_of(staying))
    args = model.guard_args
    if c.restitution == 0.0:
        # A plastic impact sticks only if the contact then pushes (lambda > 0); otherwise
        # the contact separates at once. The two cases are two transitions with the same
        # impact law and complementary guards, so no reset lands outside its target.
        kind = "impact" if isinstance(c, JointStop) else "touchdown"
        stick_reset = impact_reset(model, data, spec, stick, rows)
        return [Transition(spec.name, stick.name, plastic_guard(model, data, spec, contact, stick, stick_reset, 1.0),
                           stick_reset, name=f"{kind}_{contact}", guard_args=args),
                Transition(spec.name, free.name, plastic_guard(model, data, spec, contact, stick, stick_reset, -1.0),
                           impact_reset(model, data, spec, free, rows), name=f"graze_{contact}", guard_args=args)]
    bounce_reset = impact_reset(model, data, spec, free, rows)
    # When bounces accumulate the contact rests: the plastic impact into the constrained mode,
    # left again by its release guard where the contact force changes sign.
    rest = Continuation(stick.name, impact_reset(model, data, spec, stick, kept + [(contact, 0.0)]),
                        name=f"rest_{contact}")
    return [Transition(spec.name, free.name, kinematic_guard(model, data, spec, contact), bounce_reset,
                       name=f"bounce_{contact}", continuation=rest)]
