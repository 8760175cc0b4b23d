"""Coulomb friction at point contacts: the frictional impact (``impacts`` module docstring) as an
active set, and the choice of the mode an event leads to, as compiled helpers of the model
functions (``events``, ``joint``).

A point contact with ``friction = mu`` is, while active, stuck (x and z constrained, valid while
lambda_n >= 0 and |lambda_t| <= mu lambda_n) or slipping towards s = +-1 (z constrained, the
friction force ``-s mu lambda_n`` on the point).

**The mode after an event.** The contacts that took part in an impact and end on the ground
(plastic ones) are stuck, or slip in the direction of their tangential velocity; then, one
change at a time, a contact whose normal force pulls is dropped and a stuck one whose force
leaves the cone slips in the direction the excess pushes it (``settle_slips``). The forces are
taken under the input u the model functions receive (the controller's, at the event's state).
Where slipping has no consistent forces (the Painleve paradox: pushing on a slipping point would
drive it into the ground), the slipping contacts stick instead, their slip stopped by a
tangential impulse: the resolution of the paradox by an impact without collision (Genot and
Brogliato, 1999), counted in the robot's ``painleve_sticks``.

Every helper returns False where the law has no outcome (no consistent set of statuses, an
overflow, forces that are not finite): the state is past the model's range, and the model
functions then give nan.
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots._native.calls import lsn_crba, lsn_minverse, lsn_tally

from legsim.compiled.functions import model_function

from .dynamics import accelerate, blocks_of, handle, stuck_mu
from .impacts import ENERGY_TOL, FREE, MAX_TRIES, NORMAL, SLIDE, STICK, TOL, contact_rows, dot, kinetic, solve_rows
from .layout import (
    BLOCK_SIZE,
    C_MU,
    C_RELEASES,
    C_RESTITUTION,
    C_ROWS,
    CONTACT_SIZE,
    P_CONTACT,
    P_N,
    P_NCONTACT,
    P_STATUS,
    S_ABSENT,
    S_ACTIVE,
    S_SLIP_NEG,
    S_SLIP_POS,
    STATUS_BASE,
)
from .native import C_IMPACTS, C_PAINLEVE

#: What ``force_change`` asks: nothing; drop a pulling contact; let a stuck one slip; the forces
#: are not finite.
NO_CHANGE, DROP, SLIP, NOT_FINITE = range(4)


@model_function
def contact_record(p, i):
    """Offset of rigid contact i's record in p."""
    return int(p[P_CONTACT]) + CONTACT_SIZE * i


@model_function
def impulse_solve(engaged, mu, T, N, Minv, v, v_plus, lt, ln):
    """The impact of the engaged contacts with their current statuses (module docstring of
    ``impacts``): v+ into v_plus and each contact's (tangential, normal) impulse into lt, ln
    (the friction impulse of a sliding contact; 0 for a free one). ``engaged`` is (k, 4):
    contact index, restitution, status, sigma. Returns False where the solve has no solution
    (``solve_rows``) or overflows."""
    k, n = engaged.shape[0], v.shape[0]
    m = 0
    for i in range(k):
        status = int(engaged[i, 2])
        m += 2 if status == STICK else 0 if status == FREE else 1
        lt[i] = 0.0
        ln[i] = 0.0
    v_plus[:] = v
    if m == 0:
        return True
    J, W, rhs = np.zeros((m, n)), np.zeros((m, n)), np.empty(m)
    t_at, n_at = np.full(k, -1), np.full(k, -1)
    r = 0
    for i in range(k):
        status = int(engaged[i, 2])
        if status == FREE:
            continue
        if status == STICK:
            J[r], W[r], rhs[r], t_at[i] = T[i], T[i], -dot(T[i], v, n), r
            r += 1
        J[r] = N[i]
        W[r] = N[i] + engaged[i, 3] * mu[i] * T[i] if status == SLIDE else N[i]
        rhs[r] = -engaged[i, 1] * dot(N[i], v, n) - dot(N[i], v, n)
        n_at[i] = r
        r += 1
    MWt, A = np.empty((n, m)), np.empty((m, m))
    for j in range(n):
        for r in range(m):
            MWt[j, r] = dot(Minv[j], W[r], n)
    for a in range(m):
        for b in range(m):
            A[a, b] = dot(J[a], MWt[:, b], n)
    # Dependent rows (two stuck points of one body) take the least-norm impulses shared by the
    # contacts' capacities; with a sliding row, only where the motion is unique: else it is the
    # Painleve case, which has no impact here.
    if not solve_rows(A, rhs, m, np.all(engaged[:, 2] != SLIDE), MWt, impulse_cones(engaged, mu, t_at, n_at)):
        return False
    for j in range(n):
        v_plus[j] = v[j] + dot(MWt[j], rhs, m)
    for i in range(k):
        if n_at[i] >= 0:
            ln[i] = rhs[n_at[i]]
            lt[i] = rhs[t_at[i]] if t_at[i] >= 0 else engaged[i, 3] * mu[i] * ln[i] if engaged[i, 2] == SLIDE else 0.0
    return np.all(np.isfinite(v_plus))


@model_function
def impulse_cones(engaged, mu, t_at, n_at):
    """The cones of the engaged contacts' impulses over the rows of ``impulse_solve`` (k, 3):
    (tangent row, normal row, mu) of a stuck one, (-1, normal row, -1) of a sliding or normal one
    (its normal impulse pushes)."""
    k = engaged.shape[0]
    engaged_rows = 0
    for i in range(k):
        engaged_rows += 1 if n_at[i] >= 0 else 0
    cones = np.empty((engaged_rows, 3))
    j = 0
    for i in range(k):
        if n_at[i] < 0:
            continue
        stuck = t_at[i] >= 0
        cones[j, 0], cones[j, 1], cones[j, 2] = (t_at[i], n_at[i], mu[i]) if stuck else (-1.0, n_at[i], -1.0)
        j += 1
    return cones


@model_function
def contains(values, count, value):
    """Whether value is among values[:count]."""
    for i in range(count):  # noqa: SIM110 -- numba compiles no generator expressions
        if values[i] == value:
            return True
    return False


@model_function
def status_change(status, sigma, held, tangential, mu, lt, ln, vt, vn, scale):
    """(status, sigma) an engaged contact should take instead of its own, or (-1, 0) when it is
    consistent. A stuck contact whose impulse leaves the cone (a pulling normal impulse leaves
    it too) slides before it is freed: separating needs the sliding impulse to pull."""
    if held:
        return -1, 0.0
    if status == FREE:
        return ((STICK if tangential else NORMAL), 0.0) if vn < -TOL * scale else (-1, 0.0)
    if status == STICK and mu >= 0.0 and abs(lt) > mu * max(ln, 0.0) * (1 + TOL) + TOL * scale:
        return SLIDE, (1.0 if lt > 0.0 else -1.0)
    if ln < -TOL * scale:
        return FREE, 0.0
    if status == SLIDE and sigma * vt > TOL * scale:
        return STICK, 0.0
    return -1, 0.0


@model_function
def statuses_code(engaged, changed, status, sigma):
    """The set of statuses of the engaged contacts, contact ``changed``'s replaced by (status,
    sigma) (changed < 0: none), as one number (base 5: free, stick, normal, slide +x, -x)."""
    code, scale = 0.0, 1.0
    for i in range(engaged.shape[0]):
        s, g = (status, sigma) if i == changed else (int(engaged[i, 2]), engaged[i, 3])
        code += scale * (s if s != SLIDE else 3 if g > 0.0 else 4)
        scale *= 5.0
    return code


@model_function
def frictional_impact(x, p, engaged, held, v_plus, vt, vn):
    """The impact of the engaged contacts under the friction cone at x (``impacts``' module
    docstring): their statuses (engaged[:, 2:4]) and restitutions updated in place, v+ into
    v_plus and each contact's post-impact (tangential, normal) velocity into vt, vn. Returns
    False where no consistent outcome exists or the arithmetic overflows."""
    n, k = int(p[P_N]), engaged.shape[0]
    v = x[n : 2 * n]
    T, N, mu, tangential = np.zeros((k, n)), np.zeros((k, n)), np.empty(k), np.empty(k)
    for i in range(k):
        tangential[i] = 1.0 if contact_rows(x, p, int(engaged[i, 0]), T[i], N[i]) else 0.0
        mu[i] = p[contact_record(p, int(engaged[i, 0])) + C_MU]
    Minv = np.empty((n, n))
    lsn_minverse(handle(p), x.ctypes.data, Minv.ctypes.data)
    lsn_tally(handle(p), C_IMPACTS, 1.0)
    lt, ln = np.empty(k), np.empty(k)
    scale = 1.0 + np.abs(v).max()
    tried = np.empty(MAX_TRIES)
    for attempt in range(MAX_TRIES):
        tried[attempt] = statuses_code(engaged, -1, 0, 0.0)
        if not impulse_solve(engaged, mu, T, N, Minv, v, v_plus, lt, ln):
            return False
        velocities(T, N, tangential, v_plus, vt, vn)
        consistent, fresh = True, False
        for i in range(k):
            status, sigma = status_change(int(engaged[i, 2]), engaged[i, 3], held[i] == 1.0, tangential[i] == 1.0,
                                          mu[i], lt[i], ln[i], vt[i], vn[i], scale)  # fmt: skip
            if status < 0:
                continue
            consistent = False
            if not contains(tried, attempt + 1, statuses_code(engaged, i, status, sigma)):
                engaged[i, 2], engaged[i, 3], fresh = status, sigma, True
                break
        if consistent:
            return energy_checked(x, p, engaged, mu, T, N, tangential, Minv, v_plus, lt, ln, vt, vn)
        if not fresh:
            return False
    return False


@model_function
def velocities(T, N, tangential, v_plus, vt, vn):
    """Each engaged contact's post-impact tangential (0 without a tangential row) and normal
    velocity (m/s, or rad/s for a stop)."""
    n = v_plus.shape[0]
    for i in range(T.shape[0]):
        vt[i] = dot(T[i], v_plus, n) if tangential[i] == 1.0 else 0.0
        vn[i] = dot(N[i], v_plus, n)


@model_function
def energy_checked(x, p, engaged, mu, T, N, tangential, Minv, v_plus, lt, ln, vt, vn):
    """Keep v_plus, or where it adds kinetic energy solve the impact again with every
    restitution 0, and should that too, with the sliding contacts stuck; False where the kinetic
    energy overflows (a state past the model's range)."""
    n = int(p[P_N])
    v = x[n : 2 * n]
    M = np.empty(n * n)
    lsn_crba(handle(p), x.ctypes.data, M.ctypes.data)
    before, after = kinetic(M, v, n), kinetic(M, v_plus, n)
    if not (math.isfinite(before) and math.isfinite(after)):
        return False  # speeds no motion of the model reaches: its energy overflows
    if not after > before * (1.0 + ENERGY_TOL) + 1e-300:
        return True
    engaged[:, 1] = 0.0
    if not impulse_solve(engaged, mu, T, N, Minv, v, v_plus, lt, ln):
        return False
    if kinetic(M, v_plus, n) > before * (1.0 + ENERGY_TOL) + 1e-300:
        for i in range(engaged.shape[0]):
            if engaged[i, 2] == SLIDE:
                engaged[i, 2], engaged[i, 3] = STICK, 0.0
        if not impulse_solve(engaged, mu, T, N, Minv, v, v_plus, lt, ln):
            return False
    velocities(T, N, tangential, v_plus, vt, vn)
    return True


# -- the mode after an event -----------------------------------------------------------------


@model_function
def settle(x, u, p, engaged, v_plus, vt, status_out, image):
    """The mode an impact leads to (module docstring) and the image there: the engaged contacts
    that end on the ground plastically, stuck or slipping with their velocity, then settled
    (``settle_slips``). Returns False where the law has no outcome."""
    k = engaged.shape[0]
    scale = 1.0 + np.abs(v_plus).max()
    order, slip = np.empty(k, dtype=np.int64), np.empty(k)
    count = 0
    for i in range(k):
        if engaged[i, 2] == FREE or engaged[i, 1] > 0.0:
            continue
        sliding = engaged[i, 2] == SLIDE and abs(vt[i]) > TOL * scale
        order[count] = int(engaged[i, 0])
        slip[count] = (1.0 if vt[i] > 0.0 else -1.0 if vt[i] < 0.0 else 0.0) if sliding else 0.0
        count += 1
    return settle_slips(x, u, p, v_plus, order, slip, count, status_out, image)


@model_function
def settle_slips(x, u, p, v_new, order, slip, count, status_out, image):
    """From the rigid contacts order[:count] (each slipping towards slip[i], 0: stuck), the
    others absent, and the velocity v_new: the mode whose contact forces are consistent (pulling
    contacts dropped, stuck ones outside the cone slipping, one change at a time; slipping ones
    stuck where their forces are not unique) into status_out and the image there into image.
    Returns False where the forces are not finite without slipping contacts."""
    n = int(p[P_N])
    velocity = v_new.copy()
    for _ in range(3 * count + 3):
        statuses_of(p, order, slip, count, status_out)
        image[:] = x
        image[n : 2 * n] = velocity
        change, j, s = force_change(image, u, p, status_out, order, slip, count)
        if change == NOT_FINITE:
            if not slipping(slip, count) or not stick_all(image, p, order, slip, count, velocity):
                return False
        elif change == NO_CHANGE:
            return True
        elif change == DROP:
            order[j : count - 1] = order[j + 1 : count]
            slip[j : count - 1] = slip[j + 1 : count]
            count -= 1
        else:
            slip[j] = s
    return True


@model_function
def statuses_of(p, order, slip, count, status_out):
    """The statuses of every rigid contact (declared order) when order[:count] are active,
    slipping towards slip[i] (0: stuck), the others absent."""
    status_out[: int(p[P_NCONTACT])] = S_ABSENT
    for j in range(count):
        s = slip[j]
        status_out[order[j]] = S_ACTIVE if s == 0.0 else S_SLIP_POS if s > 0.0 else S_SLIP_NEG


@model_function
def slipping(slip, count):
    """Whether some of slip[:count] is nonzero."""
    return np.any(slip[:count] != 0.0)


@model_function
def stick_all(image, p, order, slip, count, velocity):
    """Stop every slipping contact of order[:count] (and set it stuck) by an impulse that keeps
    every contact of order[:count] on the ground: the new velocity into ``velocity``."""
    engaged = np.zeros((count, 4))
    for j in range(count):
        engaged[j, 0] = order[j]
        rows = p[contact_record(p, order[j]) + C_ROWS]
        engaged[j, 2] = STICK if rows == 2.0 else NORMAL
        slip[j] = 0.0
    lsn_tally(handle(p), C_PAINLEVE, 1.0)
    held = np.ones(count)
    vt, vn = np.empty(count), np.empty(count)
    return frictional_impact(image, p, engaged, held, velocity, vt, vn)


@model_function
def force_change(image, u, p, status, order, slip, count):
    """(change, j, s): the first change the contact forces of the mode ``status`` at ``image``
    under u ask of the contacts order[:count]: ``DROP`` the pulling order[j] (the most pulling
    one), ``SLIP`` the stuck order[j] towards s, ``NO_CHANGE``, or ``NOT_FINITE`` forces."""
    if count == 0:
        return NO_CHANGE, -1, 0.0
    contacts = int(p[P_NCONTACT])
    blocks = np.empty(BLOCK_SIZE * contacts)
    n_blocks, rows = blocks_of(p, status, blocks)
    a, lam = np.empty(int(p[P_N])), np.empty(max(1, rows))
    accelerate(image, u, p, n_blocks, blocks, 0, a, lam)
    if not (np.all(np.isfinite(lam[:rows])) and np.all(np.isfinite(a))):
        return NOT_FINITE, -1, 0.0
    normal, tangent = np.zeros(contacts), np.zeros(contacts)
    scale = 1.0 + contact_forces(p, status, lam, normal, tangent)
    worst, least = -1, 0.0
    for j in range(count):
        if normal[order[j]] < -TOL * scale and (worst < 0 or normal[order[j]] < least):
            worst, least = j, normal[order[j]]
    if worst >= 0:
        return DROP, worst, 0.0
    for j in range(count):
        ft, fn = tangent[order[j]], normal[order[j]]
        mu = stuck_mu(image, p, contact_record(p, order[j])) if slip[j] == 0.0 else 0.0
        if mu >= 0.0 and slip[j] == 0.0 and abs(ft) > mu * fn * (1 + TOL) + TOL * scale:
            return SLIP, j, (-1.0 if ft > 0.0 else 1.0)
    return NO_CHANGE, -1, 0.0


@model_function
def contact_forces(p, status, lam, normal, tangent):
    """Each active contact's normal force and tangential one (a slipping point's friction
    force -s mu f_n; 0 for a single-row contact) from the forces lam of the mode ``status``,
    into normal and tangent by contact index; returns the largest magnitude among them (the
    forces a contact reports: both of a pinned or slipping point, the normal of the others)."""
    largest, row = 0.0, 0
    for i in range(int(p[P_NCONTACT])):
        s = status[i]
        if s == S_ABSENT:
            continue
        c = contact_record(p, i)
        if s == S_SLIP_POS or s == S_SLIP_NEG:  # noqa: SIM109 -- two float compares, no tuple in compiled code
            normal[i] = lam[row]
            tangent[i] = -(1.0 if s == S_SLIP_POS else -1.0) * p[c + C_MU] * lam[row]
            row += 1
        elif p[c + C_ROWS] == 2.0:
            tangent[i], normal[i] = lam[row], lam[row + 1]
            row += 2
        else:
            normal[i] = lam[row]
            row += 1
        largest = max(largest, abs(normal[i]), abs(tangent[i]))
    return largest


# -- the outcomes of the events --------------------------------------------------------------


@model_function
def event_outcome(x, u, p, strikers, rest, stopping, status_out, image):
    """The mode (into status_out) and image (into image) after the rigid contacts of the bit
    mask ``strikers`` strike at x (with their restitutions, or plastically with ``rest``) and the
    slipping contact ``stopping`` (-1: none) stops (stuck through the impact); every other
    active contact not released by a striker is held plastically through the impact."""
    contacts = int(p[P_NCONTACT])
    released = 0
    for i in range(contacts):
        if (strikers >> i) & 1:
            released |= int(p[contact_record(p, i) + C_RELEASES])
    engaged, held = np.zeros((contacts, 4)), np.zeros(contacts)
    k = 0
    for i in range(contacts):
        s = p[int(p[P_STATUS]) + i]
        if s == S_ABSENT or (released >> i) & 1 or (strikers >> i) & 1 or i == stopping:
            continue
        engage_active(p, i, s, engaged, k)
        k += 1
    k = engage_strikers(x, p, strikers, rest, engaged, k)
    if stopping >= 0:
        held[: k + 1] = 1.0
        engaged[k, 0], engaged[k, 2] = stopping, STICK
        k += 1
    v_plus, vt, vn = np.empty(int(p[P_N])), np.empty(k), np.empty(k)
    used = engaged[:k].copy()
    if not frictional_impact(x, p, used, held[:k], v_plus, vt, vn):
        return False
    return settle(x, u, p, used, v_plus, vt, status_out, image)


@model_function
def engage_active(p, i, s, engaged, k):
    """Contact i, active with status s, into engaged[k] for an impact that holds it: sliding its
    way (its impulse opposing the slip) or stuck (normal only without friction rows)."""
    engaged[k, 0] = i
    if s == S_SLIP_POS or s == S_SLIP_NEG:  # noqa: SIM109 -- two float compares, no tuple in compiled code
        engaged[k, 2], engaged[k, 3] = SLIDE, (-1.0 if s == S_SLIP_POS else 1.0)
    else:
        engaged[k, 2] = STICK if p[contact_record(p, i) + C_ROWS] == 2.0 else NORMAL


@model_function
def engage_strikers(x, p, strikers, rest, engaged, k):
    """Append the strikers of the bit mask to engaged[k:] (declared order): stuck (or normal) if
    approaching the ground, else free, with their restitution (0 with ``rest``); returns the new
    count."""
    n = int(p[P_N])
    t_row, n_row = np.empty(n), np.empty(n)
    for i in range(int(p[P_NCONTACT])):
        if not (strikers >> i) & 1:
            continue
        c = contact_record(p, i)
        contact_rows(x, p, i, t_row, n_row)
        stuck = STICK if p[c + C_ROWS] == 2.0 else NORMAL
        engaged[k, 0] = i
        engaged[k, 1] = 0.0 if rest else p[c + C_RESTITUTION]
        engaged[k, 2] = stuck if dot(n_row, x[n : 2 * n], n) < 0.0 else FREE
        k += 1
    return k


@model_function
def mode_change(x, u, p, contact, slip_to, drop, status_out, image):
    """The mode (into status_out) and image after the active rigid ``contact`` lifts off (drop)
    or starts slipping towards ``slip_to``, the others then settled under u (no impulse)."""
    contacts, n = int(p[P_NCONTACT]), int(p[P_N])
    order, slip = np.empty(contacts, dtype=np.int64), np.empty(contacts)
    count = 0
    for i in range(contacts):
        s = p[int(p[P_STATUS]) + i]
        if s == S_ABSENT or (drop and i == contact):
            continue
        order[count] = i
        slip[count] = slip_to if i == contact else 1.0 if s == S_SLIP_POS else -1.0 if s == S_SLIP_NEG else 0.0
        count += 1
    return settle_slips(x, u, p, x[n : 2 * n], order, slip, count, status_out, image)


@model_function
def realize(x, p, code, image):
    """The image at x of the impact that ends in the mode of status code ``code`` (``status_code``):
    its active contacts held in their statuses through the impact (stuck, or sliding their way),
    the others free. Returns False where that impact has no consistent impulses.

    A crossing's outcome is chosen where its step landed, a little past the guard, and its image
    is taken at the guard point: where the impact law's answer changes between the two (a
    slipping contact whose forces become singular there, say), the image realizes the outcome
    chosen, so that a contact entering stuck is at rest."""
    contacts = int(p[P_NCONTACT])
    engaged = np.zeros((contacts, 4))
    k = 0
    rest = code
    for i in range(contacts):
        s = rest % STATUS_BASE
        rest = (rest - s) / STATUS_BASE
        if s == S_ABSENT:
            continue
        engage_active(p, i, s, engaged, k)
        k += 1
    n = int(p[P_N])
    v_plus, vt, vn = np.empty(n), np.empty(k), np.empty(k)
    if not frictional_impact(x, p, engaged[:k].copy(), np.ones(k), v_plus, vt, vn):
        return False
    image[:] = x
    image[n : 2 * n] = v_plus
    return True
