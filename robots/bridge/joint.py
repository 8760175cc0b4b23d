"""Simultaneous impacts: the rigid contacts whose strikes are crossed in the same landing step,
resolved under one impact law, as the model function ``bridge_joint`` (``legsim.model``).

Without friction, one generalised Newton impact of every contact constrained at the impact (the
active ones that stay, plastically; each striker with its own restitution c_i, or 0 when the
joint crossings accumulate) with complementarity and the energy check (``impacts.joint_impact``);
the target keeps the staying contacts and adds the plastic strikers whose normal force then
pushes (under u); the elastic ones bounce off. With friction, the impact law with the friction
cone and the mode whose forces are consistent (``friction.event_outcome``).

An outcome is named ``joint_<strikers>`` (``rest_<strikers>`` for the continuation), the
strikers in declared order joined by ``+``; its index among the mode's
``ModeFunctions.joint_outcomes`` is found by (strikers, rest, target) in p's joint records.
Transitions crossed together that are not all strikes of rigid contacts (a liftoff, a spring
leg), fewer than two contacts, or a set larger than the mode declares outcomes for
(``transitions._joint_outcomes``) are crossed one after the other (-1), as are, with friction,
strikers none of which approaches the ground and an impact without an outcome (its transitions
then say so).
"""

from __future__ import annotations

import numpy as np

from legsim.compiled.functions import model_function

from .dynamics import accelerate, blocks_of, place_rounds, status_code
from .events import record
from .friction import contact_forces, contact_record, event_outcome
from .impacts import joint_impact
from .layout import (
    BLOCK_SIZE,
    C_RELEASES,
    C_RESTITUTION,
    J_MASK,
    J_REST,
    J_TARGET,
    JOINT_SIZE,
    P_CODE,
    P_COULOMB,
    P_JOINT,
    P_N,
    P_NCONTACT,
    P_NGUARD,
    P_NJOINT,
    P_STATUS,
    S_ABSENT,
    S_ACTIVE,
    TR_STRIKE,
)


@model_function
def strikers_of(p, crossed):
    """The bit mask of the rigid contacts struck by the transitions crossed (crossed[e] > 0), and
    how many; (-1, 0) when one of them is not a strike."""
    mask, count = 0, 0
    for e in range(int(p[P_NGUARD])):
        if crossed[e] > 0.0:
            contact = int(p[record(p, e) + TR_STRIKE])
            if contact < 0:
                return -1, 0
            if not (mask >> contact) & 1:
                mask |= 1 << contact
                count += 1
    return mask, count


@model_function
def outcome_index(p, mask, rest, code):
    """The index of the joint outcome (strikers ``mask``, ``rest``, target ``code``), -1 if none."""
    for k in range(int(p[P_NJOINT])):
        j = int(p[P_JOINT]) + JOINT_SIZE * k
        if p[j + J_MASK] == mask and p[j + J_REST] == rest and p[j + J_TARGET] == code:
            return k
    return -1


@model_function
def bridge_joint(rest, t, q, u, p, crossed, out):
    """The strikes crossed together (crossed[e] > 0) at q under u, resolved at once (module
    docstring): the image into out and the outcome's index, or -1 to cross them one by one."""
    mask, count = strikers_of(p, crossed)
    if count < 2:
        return -1
    place_rounds(q, p)
    contacts = int(p[P_NCONTACT])
    status = np.empty(contacts)
    if p[P_COULOMB] != 0.0:
        if not event_outcome(q, u, p, mask, rest == 1, -1, status, out[: q.shape[0]]):
            return -1
        if status_code(status, contacts) == p[P_CODE] and np.all(out[: q.shape[0]] == q):
            return -1  # none of them approaches the ground at q
    else:
        frictionless_outcome(q, u, p, mask, rest == 1, status, out[: q.shape[0]])
    return outcome_index(p, mask, rest, status_code(status, contacts))


@model_function
def frictionless_outcome(q, u, p, mask, rest, status, image):
    """The joint impact of the strikers of ``mask`` without friction: the target's statuses and
    the image (module docstring; strikers none of which approaches keep the state)."""
    n, contacts = int(p[P_N]), int(p[P_NCONTACT])
    released = 0
    for i in range(contacts):
        if (mask >> i) & 1:
            released |= int(p[contact_record(p, i) + C_RELEASES])
    kept, strikers, restitution = np.empty(contacts, np.int64), np.empty(contacts, np.int64), np.empty(contacts)
    n_kept, n_strikers = 0, 0
    for i in range(contacts):
        active = p[int(p[P_STATUS]) + i] != S_ABSENT and not (released >> i) & 1
        status[i] = S_ACTIVE if active else S_ABSENT
        if active:
            kept[n_kept] = i
            n_kept += 1
        if (mask >> i) & 1:
            strikers[n_strikers] = i
            restitution[n_strikers] = 0.0 if rest else p[contact_record(p, i) + C_RESTITUTION]
            n_strikers += 1
    taking = np.zeros(n_strikers)
    image[:] = q
    joint_impact(q, p, kept, n_kept, strikers, n_strikers, restitution, image[n : 2 * n], taking)
    for k in range(n_strikers):
        if taking[k] == 1.0 and restitution[k] == 0.0:
            status[strikers[k]] = S_ACTIVE
    drop_pulling(image, u, p, status, strikers, n_strikers)


@model_function
def drop_pulling(image, u, p, status, strikers, n_strikers):
    """Drop from ``status`` the plastic strikers whose normal force pulls at the image (under
    u), the forces solved again until none does."""
    contacts = int(p[P_NCONTACT])
    blocks = np.empty(BLOCK_SIZE * contacts)
    normal, tangent = np.zeros(contacts), np.zeros(contacts)
    while True:
        plastic = False
        for k in range(n_strikers):
            plastic = plastic or status[strikers[k]] == S_ACTIVE
        if not plastic:
            return
        n_blocks, rows = blocks_of(p, status, blocks)
        lam = np.empty(max(1, rows))
        accelerate(image, u, p, n_blocks, blocks, 0, np.empty(int(p[P_N])), lam)
        contact_forces(p, status, lam, normal, tangent)
        pulling = False
        for k in range(n_strikers):
            if status[strikers[k]] == S_ACTIVE and normal[strikers[k]] < 0.0:
                status[strikers[k]] = S_ABSENT
                pulling = True
        if not pulling:
            return
