"""Coulomb friction at point contacts: the impact law with the friction cone and the choice of
the mode a contact event leads to.

A point contact with ``friction = mu`` is, while active, stuck (``<c>``: x and z constrained,
valid while lambda_n >= 0 and |lambda_t| <= mu lambda_n) or slipping towards s = +-1
(``<c>>``, ``<c><``: z constrained, the friction force ``-s mu lambda_n`` on the point).

**Impact law.** The contacts taking part in an impact (the striking ones, each with its
restitution c, and the active ones, held plastically) first all stick: one generalised Newton
impact ``v+ = v + M^-1 W^T Lambda``, ``J v+ = w`` with ``w_n = -c J_n v`` on the normal rows
and 0 on the tangential ones. Then, one change at a time (an active set, as complementarity
asks): a contact whose normal impulse would pull is freed; a stuck contact whose tangential
impulse leaves the cone, |Lambda_t| > mu Lambda_n, slides: its impulse is ``sigma mu Lambda_n``
along x with sigma the sign of the sticking impulse (``W = J_n + sigma mu J_t``), only its normal
row is constrained; a sliding contact whose slip the friction would reverse sticks; a free
contact the impact drives into the ground joins plastically. Should the result add kinetic
energy (Newton restitution with friction can, in strongly coupled configurations), the impact
is solved again plastically, and, should that too, with every contact stuck (a projection in
the mass metric, which never adds energy).

**The mode after an event.** The contacts that took part and end on the ground (plastic ones)
are stuck, or slip in the direction of their tangential velocity; then, one change at a time,
a contact whose normal force pulls is dropped and a stuck one whose force leaves the cone slips
in the direction the excess pushes it. ``settle`` returns that mode and the image there.

**Transitions with several outcomes.** A strike (or a slipping contact coming to rest) may lead
to any of these modes. Each possible target is one transition whose guard is the event's own
guard where the law chooses that target and its absolute value elsewhere, so exactly one of
them is past (``outcome_transitions``).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.errors import ModelBreakdown, ModelError
from legsim.hybrid import Transition

from .contacts import SLIP_SUFFIX, PointContact, RigidContact
from .dynamics import constraint_forces, control_key, dynamics
from .model import LWA, BridgeData, BridgeModel
from .modes import ModeCatalog, ModeSpec, map_state

STICK, SLIDE, NORMAL, FREE = "stick", "slide", "normal", "free"
#: Relative tolerance of the cone and sign tests (rounding of the impulses and forces).
TOL = 1e-10
#: Most transitions one event may need (one per reachable target mode).
MAX_OUTCOMES = 256


@dataclass
class Engaged:
    """A contact's part in an impact: its resolved record, restitution, status (``stick``: x and
    z constrained; ``normal``: z only (frictionless, or a joint stop); ``slide``: z constrained,
    the friction impulse ``sigma mu Lambda_n`` along x; ``free``: no impulse)."""

    rigid: RigidContact
    restitution: float
    status: str
    sigma: float = 0.0
    #: held stuck whatever its impulse: a slipping contact coming to rest, whose residual slip
    #: velocity (within the strip) is removed by the impact; the forces after it decide.
    held: bool = False

    @property
    def name(self) -> str:
        return self.rigid.contact.name

    @property
    def slide_ratio(self) -> float:
        """sigma mu: the friction impulse of a sliding contact per unit of its normal impulse."""
        mu = self.rigid.mu
        assert mu is not None, "only a contact with friction slides"
        return self.sigma * mu


@dataclass
class ImpactResult:
    """The outcome of ``frictional_impact``: post-impact velocity (nv,), and per engaged contact
    its normal impulse (N s or N m s) and post-impact (tangential, normal) velocity (m/s)."""

    v_plus: np.ndarray
    engaged: list[Engaged]
    normal: dict[str, float]
    velocity: dict[str, tuple[float, float]]


def _rows(model: BridgeModel, data: BridgeData, r: RigidContact, q: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """(tangential row or None, normal row) of contact r at q."""
    if r.kind == "stop":
        row = np.zeros(model.n)
        row[r.dof] = r.sign
        return None, row
    Jf = pin.computeFrameJacobian(model.pin_model, data.pin_data, q, r.frame_id, LWA)
    data.counts["jacobians"] += 1
    return (Jf[0].copy() if r.point.tangential else None), Jf[2].copy()


def _solve(
    engaged: list[Engaged], rows: dict[str, tuple[np.ndarray | None, np.ndarray]], Minv: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, dict[str, tuple[float, float]]]:
    """The impact of the engaged contacts with their current statuses: (v+, per constrained
    contact its (tangential, normal) impulse; the tangential one is the friction impulse of a
    sliding contact and 0 for a frictionless one)."""
    J: list[np.ndarray] = []
    W: list[np.ndarray] = []
    target: list[float] = []
    at: dict[str, tuple[int, int]] = {}
    for e in engaged:
        t_row, n_row = rows[e.name]
        if e.status == FREE:
            continue
        t_index = -1
        w_row = n_row
        if e.status in (STICK, SLIDE):
            assert t_row is not None, "a sticking or sliding contact is a point contact pinned along x"
            if e.status == STICK:
                t_index = len(J)
                J.append(t_row)
                W.append(t_row)
                target.append(0.0)
            else:
                w_row = n_row + e.slide_ratio * t_row
        at[e.name] = (t_index, len(J))
        J.append(n_row)
        W.append(w_row)
        target.append(-e.restitution * float(n_row @ v))
    if not J:
        return v.copy(), {}
    J_, W_ = np.array(J), np.array(W)
    MWt = Minv @ W_.T
    impulse = np.linalg.solve(J_ @ MWt, np.array(target) - J_ @ v)
    out = {}
    for e in engaged:
        if e.name in at:
            i_t, i_n = at[e.name]
            normal = float(impulse[i_n])
            tangential = float(impulse[i_t]) if i_t >= 0 else (e.slide_ratio * normal if e.status == SLIDE else 0.0)
            out[e.name] = (tangential, normal)
    return v + MWt @ impulse, out


def _change(
    e: Engaged, impulse: tuple[float, float], velocity: tuple[float, float], scale: float
) -> tuple[str, float] | None:
    """The (status, sigma) contact e should take instead of its current one, or None when it is
    consistent. A stuck contact whose impulse leaves the cone (a pulling normal impulse leaves
    it too) slides before it is freed: separating needs the sliding impulse to pull."""
    mu = e.rigid.mu
    vt, vn = velocity
    lt, ln = impulse
    if e.held:
        return None
    if e.status == FREE:
        contact = e.rigid.contact
        stuck = STICK if isinstance(contact, PointContact) and contact.tangential else NORMAL
        return (stuck, 0.0) if vn < -TOL * scale else None
    if e.status == STICK and mu is not None and abs(lt) > mu * max(ln, 0.0) * (1 + TOL) + TOL * scale:
        return SLIDE, (1.0 if lt > 0.0 else -1.0)
    if ln < -TOL * scale:
        return FREE, 0.0
    if e.status == SLIDE and e.sigma * vt > TOL * scale:
        return STICK, 0.0
    return None


def frictional_impact(
    model: BridgeModel, data: BridgeData, engaged: list[Engaged], q: np.ndarray, v: np.ndarray
) -> ImpactResult:
    """The impact of the ``engaged`` contacts under the friction cone (module docstring); their
    statuses are updated in place. ``ModelBreakdown`` when the active set finds no consistent
    outcome (every change it asks for leads back to a set of statuses already tried), and when
    its arithmetic overflows: a guard asks for the outcome at a trial stage far outside any
    motion (an adaptive step too long for a stiff controller reaches speeds above 1e150), which
    the integrator then shortens, rather than deciding on a NaN."""
    try:
        with np.errstate(over="raise", invalid="raise"):
            return _active_set_impact(model, data, engaged, q, v)
    except FloatingPointError as exc:
        raise ModelBreakdown(
            f"{model.name}: the impact of {[e.name for e in engaged]} overflows ({exc}) at "
            f"q={q.tolist()}, v={v.tolist()}: a state outside the model's range"
        ) from exc


def _active_set_impact(
    model: BridgeModel, data: BridgeData, engaged: list[Engaged], q: np.ndarray, v: np.ndarray
) -> ImpactResult:
    """``frictional_impact``'s active-set iteration, with numpy's floating-point errors raised."""
    data.counts["impacts"] += 1
    rows = {e.name: _rows(model, data, e.rigid, q) for e in engaged}
    Minv = pin.computeMinverse(model.pin_model, data.pin_data, q)
    scale = 1.0 + float(np.max(np.abs(v)))
    tried = set()
    while True:
        tried.add(tuple((e.status, e.sigma) for e in engaged))
        v_plus, impulses = _solve(engaged, rows, Minv, v)
        velocity = {name: (0.0 if t is None else float(t @ v_plus), float(n @ v_plus)) for name, (t, n) in rows.items()}
        changes = [
            (i, c)
            for i, e in enumerate(engaged)
            if (c := _change(e, impulses.get(e.name, (0.0, 0.0)), velocity[e.name], scale)) is not None
        ]
        if not changes:
            result = ImpactResult(v_plus, engaged, {k: ln for k, (_, ln) in impulses.items()}, velocity)
            return _energy_checked(model, data, result, rows, Minv, q, v)
        fresh = [(i, c) for i, c in changes if _with(engaged, i, c) not in tried]
        if not fresh:
            raise ModelBreakdown(
                f"{model.name}: the impact of {[e.name for e in engaged]} with friction has no "
                f"consistent outcome (stick, slide or separate) at q={q.tolist()}, v={v.tolist()}"
            )
        i, (status, sigma) = fresh[0]
        engaged[i].status, engaged[i].sigma = status, sigma


def _with(engaged: list[Engaged], i: int, change: tuple[str, float]) -> tuple[tuple[str, float], ...]:
    """The statuses of ``engaged`` with contact i's replaced by ``change``."""
    return tuple(change if k == i else (e.status, e.sigma) for k, e in enumerate(engaged))


def _energy_checked(
    model: BridgeModel,
    data: BridgeData,
    result: ImpactResult,
    rows: dict[str, tuple[np.ndarray | None, np.ndarray]],
    Minv: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
) -> ImpactResult:
    """``result``, or when it adds kinetic energy the same contacts plastic, or else all stuck."""
    M = pin.crba(model.pin_model, data.pin_data, q)
    before = float(v @ M @ v)

    def gains(w: np.ndarray) -> bool:
        return float(w @ M @ w) > before * (1.0 + 1e-12) + 1e-300

    if not gains(result.v_plus):
        return result
    for e in result.engaged:
        e.restitution = 0.0
    v_plus, impulses = _solve(result.engaged, rows, Minv, v)
    if gains(v_plus):
        for e in result.engaged:
            if e.status == SLIDE:
                e.status, e.sigma = STICK, 0.0
        v_plus, impulses = _solve(result.engaged, rows, Minv, v)
    velocity = {name: (0.0 if t is None else float(t @ v_plus), float(n @ v_plus)) for name, (t, n) in rows.items()}
    return ImpactResult(v_plus, result.engaged, {k: ln for k, (_, ln) in impulses.items()}, velocity)


def engage(
    model: BridgeModel,
    spec: ModeSpec,
    kept: Sequence[str],
    strikers: Sequence[str],
    restitution: dict[str, float],
    q_v: tuple[np.ndarray, np.ndarray],
    data: BridgeData,
) -> list[Engaged]:
    """The contacts of an impact in mode ``spec``: the ``kept`` active ones as the mode holds
    them (stuck, slipping or normal), and the ``strikers`` (each with its restitution), stuck if
    approaching the ground, else free."""
    q, v = q_v
    out = []
    for name in kept:
        r = spec.rigid_of(name)
        base = model.rigid[name]
        if r.slip:
            out.append(Engaged(base, 0.0, SLIDE, -r.slip))
        else:
            out.append(Engaged(base, 0.0, STICK if base.rows == 2 else NORMAL))
    for name in strikers:
        base = model.rigid[name]
        _, n_row = _rows(model, data, base, q)
        status = (STICK if base.rows == 2 else NORMAL) if float(n_row @ v) < 0.0 else FREE
        out.append(Engaged(base, restitution[name], status))
    return out


def entry(name: str, slip: float) -> str:
    """The mode entry of contact ``name`` slipping in direction ``slip`` (0: stuck)."""
    return name + SLIP_SUFFIX[slip] if slip else name


def settle(
    model: BridgeModel,
    data: BridgeData,
    modes: ModeCatalog,
    src: ModeSpec,
    x: np.ndarray,
    fixed: Sequence[str],
    result: ImpactResult,
    u: Any,
) -> tuple[ModeSpec, np.ndarray]:
    """The mode an impact leads to and the image there (module docstring): ``fixed``, the
    entries of ``src`` the impact leaves as they are; the engaged contacts that end on the
    ground (plastic), stuck or slipping with their velocity; then ``settle_slips``."""
    scale = 1.0 + float(np.max(np.abs(result.v_plus)))
    slips: dict[str, float] = {}
    for e in result.engaged:
        if e.status == FREE or e.restitution > 0.0:
            continue
        vt = result.velocity[e.name][0]
        slips[e.name] = float(np.sign(vt)) if e.status == SLIDE and abs(vt) > TOL * scale else 0.0
    return settle_slips(model, data, modes, src, x, result.v_plus, fixed, slips, u)


def settle_slips(
    model: BridgeModel,
    data: BridgeData,
    modes: ModeCatalog,
    src: ModeSpec,
    x: np.ndarray,
    v_new: np.ndarray | None,
    fixed: Sequence[str],
    slips: dict[str, float],
    u: Any,
) -> tuple[ModeSpec, np.ndarray]:
    """From the rigid contacts ``slips`` (name -> slip direction, 0: stuck) and the ``fixed``
    entries, with velocity ``v_new`` (None: x's), the mode whose contact forces are consistent:
    pulling contacts dropped and stuck ones outside the cone slipping, one change at a time. The
    forces are taken under the control the controller previews for each candidate mode at its
    image (``BridgeData.preview``), else under u. Where slipping has no consistent forces (the
    Painleve paradox: pushing on a slipping point would drive it into the ground), the slipping
    contacts stick instead, their slip stopped by a tangential impulse: the resolution of the
    paradox by an impact without collision (Genot and Brogliato, 1999); counted in
    ``painleve_sticks``."""
    for _ in range(3 * len(slips) + 3):
        dst = modes.spec(modes.name_of(list(fixed) + [entry(c, s) for c, s in slips.items()]))
        image = map_state(model, data, src, dst, x, v_new)
        control = u if data.preview is None else data.preview(dst.name, data.last_time, image)
        try:
            change = _force_change(model, data, dst, image, control, slips)
        except ModelBreakdown:
            if not dst.slipping:
                raise
            v_new = _stick_all(model, data, slips, x, v_new)
            continue
        if change is None:
            return dst, image
        name, slip = change
        if slip is None:
            del slips[name]
        else:
            slips[name] = slip
    return dst, image


def _stick_all(
    model: BridgeModel, data: BridgeData, slips: dict[str, float], x: np.ndarray, v_new: np.ndarray | None
) -> np.ndarray:
    """The velocity after every slipping contact of ``slips`` is stopped (and set stuck there) by
    an impulse that keeps every contact of ``slips`` on the ground."""
    n = model.n
    v = x[n : 2 * n] if v_new is None else v_new
    engaged = [Engaged(model.rigid[c], 0.0, STICK if model.rigid[c].rows == 2 else NORMAL, held=True) for c in slips]
    for c in slips:
        slips[c] = 0.0
    data.counts["painleve_sticks"] += 1
    return frictional_impact(model, data, engaged, x[:n], v).v_plus


def mode_change(
    model: BridgeModel,
    data: BridgeData,
    modes: ModeCatalog,
    spec: ModeSpec,
    x: np.ndarray,
    u: Any,
    contact: str,
    slip: float | None,
) -> tuple[ModeSpec, np.ndarray]:
    """The mode after ``contact`` lifts off (``slip`` None) or starts slipping towards ``slip``
    in mode ``spec`` at x, the others then settled under their new control (no impulse)."""
    fixed = [e for e, c in zip(spec.entries, spec.active, strict=True) if c not in model.rigid]
    slips = {r.contact.name: r.slip for r in spec.rigid}
    if slip is None:
        del slips[contact]
    else:
        slips[contact] = slip
    return settle_slips(model, data, modes, spec, x, None, fixed, slips, u)


def _force_change(
    model: BridgeModel, data: BridgeData, dst: ModeSpec, image: np.ndarray, u: Any, slips: dict[str, float]
) -> tuple[str, float | None] | None:
    """The first change the contact forces of mode ``dst`` at ``image`` ask of the contacts in
    ``slips``: (contact, None) to drop a pulling one, (contact, s) for a stuck one to slip."""
    if not slips:
        return None
    forces = constraint_forces(model, data, dst, image, u)
    scale = 1.0 + max(float(np.max(np.abs(f))) for f in forces.values())
    pulling = [(forces[c][-1], c) for c in slips if forces[c][-1] < -TOL * scale]
    if pulling:
        return min(pulling)[1], None
    for c, s in slips.items():
        mu = model.rigid[c].mu
        if mu is not None and s == 0.0:
            ft, fn = forces[c]
            if abs(ft) > mu * fn * (1 + TOL) + TOL * scale:
                return c, -1.0 if ft > 0.0 else 1.0
    return None


def event_outcome(
    model: BridgeModel,
    data: BridgeData,
    modes: ModeCatalog,
    spec: ModeSpec,
    x: np.ndarray,
    u: Any,
    strikers: Sequence[str],
    restitution: dict[str, float],
    stopping: Sequence[str] = (),
) -> tuple[ModeSpec, np.ndarray]:
    """The mode and image after the ``strikers`` strike in mode ``spec`` at x, and the slipping
    contacts ``stopping`` stop (stuck through the impact); every other active rigid contact not
    released by a striker is held plastically through the impact."""
    n = model.n
    q, v = x[:n], x[n : 2 * n]
    released = {r for c in strikers for r in getattr(model.contacts[c], "releases", ())}
    kept = [
        r.contact.name
        for r in spec.rigid
        if r.contact.name not in released and r.contact.name not in strikers and r.contact.name not in stopping
    ]
    fixed = [e for e, c in zip(spec.entries, spec.active, strict=True) if c not in model.rigid]
    engaged = engage(model, spec, kept, strikers, restitution, (q, v), data)
    if stopping:
        # Coming to rest is continuous: the impact only removes the residual slip velocity the
        # strip leaves (O(eps)), so every contact keeps its constraint through it and the
        # forces after it decide the mode.
        for e in engaged:
            e.held = True
        engaged += [Engaged(model.rigid[c], 0.0, STICK, held=True) for c in stopping]
    result = frictional_impact(model, data, engaged, q, v)
    return settle(model, data, modes, spec, x, fixed, result, u)


def candidate_targets(
    model: BridgeModel,
    modes: ModeCatalog,
    spec: ModeSpec,
    involved: Sequence[str],
    bouncing: Sequence[str] = (),
    dropped: Sequence[str] = (),
) -> list[str]:
    """Every mode an event of the ``involved`` rigid contacts in mode ``spec`` may lead to:
    each involved contact absent, stuck or (with friction) slipping either way; a ``bouncing``
    one only absent; the ``dropped`` ones (released) absent; the other entries unchanged."""
    fixed = [e for e, c in zip(spec.entries, spec.active, strict=True) if c not in involved and c not in dropped]
    options: list[list[float | None]] = []  # per involved contact: absent (None) or its slip
    for c in involved:
        if c in bouncing:
            options.append([None])
        elif model.rigid[c].mu is not None:
            options.append([None, 0.0, 1.0, -1.0])
        else:
            options.append([None, 0.0])
    count = int(np.prod([len(o) for o in options]))
    if count > MAX_OUTCOMES:
        raise ModelError(
            f"{model.name}: an event in mode '{spec.name}' involves {list(involved)}, which could lead "
            f"to {count} modes (at most {MAX_OUTCOMES} are supported): declare fewer contacts with "
            f"friction, or frictionless ones"
        )
    targets = []
    for choice in itertools.product(*options):
        entries = fixed + [entry(c, s) for c, s in zip(involved, choice, strict=True) if s is not None]
        name = modes.name_of(entries)
        if name not in targets:
            targets.append(name)
    return targets


Solve = Callable[[np.ndarray, Any], tuple[ModeSpec, np.ndarray]]


def outcome_transitions(
    model: BridgeModel,
    data: BridgeData,
    spec: ModeSpec,
    targets: Sequence[str],
    base: Callable[[np.ndarray, Any], float],
    solve: Solve,
    label: Callable[[str], str],
) -> list[Transition]:
    """One transition per possible target of an event whose guard is ``base(x, u)`` and whose
    outcome ``solve(x, u)`` gives: target T's guard is the base guard where the event leads to T
    and its absolute value elsewhere (so only the chosen transition is ever past), its reset the
    event's image. ``label(T)`` names the transition. Declared with ``model.guard_args``."""
    cache: dict[str, Any] = {"key": None, "value": None}

    def outcome(x: np.ndarray, u: Any) -> tuple[ModeSpec, np.ndarray]:
        key = x.tobytes() + control_key(u)
        if cache["key"] != key:
            cache["key"], cache["value"], cache["x"] = key, solve(x, u), x.tobytes()
        return cache["value"]

    def make(target: str) -> Transition:
        def value(x: np.ndarray, u: Any, t: float = 0.0) -> float:
            b = base(x, u)
            if b >= 0.0:
                return b
            data.remember_control(x, u)
            data.last_time = t
            dst, image = outcome(x, u)
            if dst.name == spec.name and np.array_equal(image, x):
                return -b  # nothing strikes (a point grazing the ground without approaching it)
            return b if dst.name == target else -b

        def reset(x: np.ndarray) -> np.ndarray:
            if cache.get("x") == x.tobytes():  # the guard was evaluated at this state: its outcome
                return cache["value"][1].copy()
            return outcome(x, data.control_at(x))[1].copy()

        guard = (lambda t, x, u: value(x, u, t)) if model.timed else (lambda x: value(x, None))
        return Transition(spec.name, target, guard, reset, name=label(target), guard_args=model.guard_args)

    return [make(target) for target in targets]


def stick_slip_guard(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str, slip: float
) -> Callable[[np.ndarray, Any], float]:
    """``mu lambda_n + s lambda_t`` (N) of the stuck contact: >= 0 while its force is inside the
    cone on the side that would make it slip towards s."""
    mu = model.rigid[contact].mu
    row = spec.normal_row(contact)

    def value(x: np.ndarray, u: Any) -> float:
        lam = dynamics(model, data, spec, x, u)[1]
        return float(mu * lam[row] + slip * lam[row - 1])

    return value


def slip_rate(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str, x: np.ndarray, u: Any
) -> tuple[float, float]:
    """(tangential velocity (m/s), tangential acceleration (m/s^2)) of a contact point in mode ``spec``."""
    n = model.n
    a, _ = dynamics(model, data, spec, x, u)
    pm, pd = model.pin_model, data.pin_data
    fid = model.rigid[contact].frame_id
    pin.forwardKinematics(pm, pd, x[:n], x[n : 2 * n], a)
    pin.updateFramePlacement(pm, pd, fid)
    return (
        float(pin.getFrameVelocity(pm, pd, fid, LWA).linear[0]),
        float(pin.getFrameClassicalAcceleration(pm, pd, fid, LWA).linear[0]),
    )


def slip_stop_guard(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str
) -> Callable[[np.ndarray, Any], float]:
    """``max(s v_t, s a_t)`` (m/s) of the contact slipping towards s: past once the slip velocity
    has come back through 0 while the friction decelerates it (entering the slipping mode, the
    point accelerates towards s, so the guard is not past there)."""
    s = spec.rigid_of(contact).slip

    def value(x: np.ndarray, u: Any) -> float:
        vt, at = slip_rate(model, data, spec, contact, x, u)
        return max(s * vt, s * at)

    return value
