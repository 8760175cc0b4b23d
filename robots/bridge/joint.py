"""Simultaneous impacts: the contacts that close in the same landing step, resolved under one
impact law.

When several rigid contacts or joint stops strike within one landing (their guards crossed in
the same step, within the strip), the integrator hands them here together
(``HybridSystem(joint=...)``). One generalised Newton impact with the stacked Jacobians of every
contact constrained at the impact (those staying active plastically, each striking contact with
its own restitution c_i) gives ``v+ = v + M^-1 J^T Lambda``, ``Lambda = (J M^-1 J^T)^-1 (w - J v)``,
``w_i = -c_i J_i v`` (Pinocchio's impulse dynamics, with one coefficient per contact). Then:

* complementarity: a striking contact whose normal impulse would pull (adhesive, < 0) is dropped
  and the impact solved again without it, until every impulse pushes;
* energy: per-contact coefficients can add kinetic energy at some configurations; should they,
  the impact is solved again with the least coefficient for all (which never does);
* the target mode keeps the staying contacts and adds the plastic (c = 0) strikers whose normal
  force then pushes; the elastic ones bounce off.

Contacts that close in different steps are still taken one after the other; the window is one
landing step's strip. A robot with Coulomb friction resolves them with the friction cone
(``friction.event_outcome``: stuck or sliding impulses, then the mode whose contact forces are
consistent), the post-impact forces taken under the control the strike guards were evaluated
with at x (``BridgeData.control_at``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from legsim.hybrid import JointCrossing

from .dynamics import constraint_forces, constraint_rows, solve_small
from .friction import event_outcome
from .model import BridgeData, BridgeModel
from .modes import ModeCatalog, map_state

#: Transition name prefixes of a strike (an inactive rigid contact's impact).
STRIKES = ("touchdown_", "impact_", "bounce_", "graze_")
#: Kinetic energy an impact may gain to rounding (relative).
ENERGY_TOL = 1e-12


def striking_contacts(model: BridgeModel, names: tuple[str, ...]) -> list[str] | None:
    """The rigid contacts struck by the transitions ``names``, in declared order, or None when one
    of them is not a strike (a liftoff, a release, a spring leg)."""
    struck = []
    for name in names:
        prefix = next((p for p in STRIKES if name.startswith(p)), None)
        contact = name[len(prefix) :].split("@")[0] if prefix else None
        if contact not in model.rigid:
            return None
        struck.append(contact)
    return [c for c in model.order if c in set(struck)]


def newton_impact(
    model: BridgeModel, data: BridgeData, rows: list[tuple[str, float]], q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, dict[str, float]]:
    """The generalised Newton impact of the contacts ``rows`` ((name, restitution), declared
    order): the post-impact velocity (nv,) and each contact's normal impulse (N s or N m s)."""
    rigid = [model.rigid[name] for name, _ in rows]
    J, _ = constraint_rows(model, data, rigid, q, v, drift=False)
    coeff = np.concatenate([np.full(r.rows, c) for r, (_, c) in zip(rigid, rows, strict=True)])
    Minv = pin.computeMinverse(model.pin_model, data.pin_data, q)
    MJt = Minv @ J.T
    impulse = solve_small(J @ MJt, -(1.0 + coeff) * (J @ v))
    normal, i = {}, 0
    for r in rigid:
        i += r.rows
        normal[r.contact.name] = float(impulse[i - 1])
    return v + MJt @ impulse, normal


def joint_impact(
    model: BridgeModel,
    data: BridgeData,
    kept: list[str],
    strikers: list[str],
    q: np.ndarray,
    v: np.ndarray,
    restitution: dict[str, float],
) -> tuple[np.ndarray, list[str]]:
    """The post-impact velocity of the strikers (with the ``kept`` contacts held plastically) and
    the strikers that take part, chosen as complementarity asks (an active set): only approaching
    contacts strike; one whose impulse would pull is dropped; one left out that the impact drives
    into the floor joins plastically; and the kinetic energy never increases."""
    data.counts["impacts"] += 1
    rigid = [model.rigid[name] for name in strikers]
    J, _ = constraint_rows(model, data, rigid, q, v, drift=False)
    rows_end = np.cumsum([r.rows for r in rigid]) - 1
    normal_rows = {name: J[i] for name, i in zip(strikers, rows_end, strict=True)}
    taking = [name for name in strikers if normal_rows[name] @ v < 0.0]
    if not taking:  # none approaches: no impulse
        return v.copy(), []
    plastic: set[str] = set()
    for _ in range(4 * len(strikers) + 1):
        coeff = {name: 0.0 if name in plastic else restitution[name] for name in taking}
        v_plus, normal = newton_impact(model, data, [(n, 0.0) for n in kept] + [(n, coeff[n]) for n in taking], q, v)
        adhesive = min(taking, key=lambda n: normal[n], default=None)
        if adhesive is not None and normal[adhesive] < 0.0 and len(taking) > 1:
            taking.remove(adhesive)
            continue
        scale = 1e-12 * (1.0 + float(np.max(np.abs(v))))
        entering = [n for n in strikers if n not in taking and normal_rows[n] @ v_plus < -scale]
        if not entering:
            break
        taking += entering
        plastic |= set(entering)
    taking = [n for n in strikers if n in taking]
    M = pin.crba(model.pin_model, data.pin_data, q)
    if float(v_plus @ M @ v_plus) > float(v @ M @ v) * (1.0 + ENERGY_TOL) + 1e-300:
        least = min(0.0 if n in plastic else restitution[n] for n in taking)
        v_plus, _ = newton_impact(model, data, [(n, 0.0) for n in kept] + [(n, least) for n in taking], q, v)
    return v_plus, taking


def resolve(
    model: BridgeModel,
    data: BridgeData,
    modes: ModeCatalog,
    mode: str,
    names: tuple[str, ...],
    x: np.ndarray,
    rest: bool,
) -> JointCrossing | None:
    """``HybridSystem(joint=...)`` for the bridge: the contacts struck by ``names`` at x resolved
    together (``rest``: all plastic, as a bouncing contact continues when its bounces
    accumulate), or None when fewer than two rigid contacts strike (the integrator then takes the
    transitions one after the other)."""
    strikers = striking_contacts(model, names)
    if strikers is None or len(strikers) < 2:
        return None
    src = modes.spec(mode)
    if model.coulomb:
        restitution = {name: 0.0 if rest else model.rigid[name].contact.restitution for name in strikers}
        dst, image = event_outcome(model, data, modes, src, x, data.control_at(x), strikers, restitution)
        if dst.name == mode and np.array_equal(image, x):
            return None  # none of them approaches the ground at x: they are crossed one by one
        return JointCrossing(f"{'rest' if rest else 'joint'}_{'+'.join(strikers)}", dst.name, image)
    released = {r for name in strikers for r in getattr(model.contacts[name], "releases", ())}
    staying = [c for c in src.active if c not in released]
    kept = [c for c in staying if c in model.rigid]
    n = model.n
    restitution = {name: 0.0 if rest else model.rigid[name].contact.restitution for name in strikers}
    v_plus, taking = joint_impact(model, data, kept, strikers, x[:n], x[n : 2 * n], restitution)
    plastic = [name for name in taking if restitution[name] == 0.0]
    while True:
        dst = modes.spec(modes.name_of(set(staying) | set(plastic)))
        image = map_state(model, data, src, dst, x, v_plus)
        forces = constraint_forces(model, data, dst, image, None) if plastic else {}
        pulling = [name for name in plastic if forces[name][-1] < 0.0]
        if not pulling:
            break
        plastic = [name for name in plastic if name not in pulling]
    return JointCrossing(f"{'rest' if rest else 'joint'}_{'+'.join(strikers)}", dst.name, image)
