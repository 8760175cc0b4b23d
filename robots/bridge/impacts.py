"""Impact laws of the bridge, as compiled helpers of its model functions (``events``, ``joint``).

**Generalised Newton impact** (``newton_impact``): with J the constraint rows of the contacts
held through the impact, ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)``, ``w = -c J v`` row-wise
(c = 0 for the contacts that stay active, the striking contact's own c on its rows; for a joint
stop alone this is paper 003 eq. (30)); Pinocchio's impulse dynamics with one coefficient per
contact (``lsn_impact``).

**Simultaneous strikes without friction** (``joint_impact``): only approaching contacts strike;
one whose impulse would pull is dropped; one left out that the impact drives into the ground
joins plastically (complementarity, as an active set); and should per-contact coefficients add
kinetic energy, the impact is solved again with the least coefficient for all (which never does).

**Impacts with the friction cone** (``frictional_impact``): the engaged contacts (the striking
ones with their restitution, the active ones held plastically) first keep their statuses
(stuck: x and z constrained; normal: z only (frictionless, a joint stop); sliding: z
constrained, the friction impulse ``sigma mu Lambda_n`` along x; free: no impulse), ``J v+ = w``
with ``w_n = -c J_n v`` on normal rows and 0 on tangential ones. Then, one change at a time: a
contact whose normal impulse would pull is freed; a stuck contact whose tangential impulse
leaves the cone slides in its direction; a sliding contact whose slip the friction would
reverse sticks; a free contact the impact drives into the ground joins plastically. Should the
result add kinetic energy, the impact is solved again plastically, and should that too, with
every contact stuck (a projection in the mass metric, which never adds energy).

Each engaged contact is a row of small arrays: its rigid contact index, restitution, status
(``FREE``, ``STICK``, ``NORMAL``, ``SLIDE``), slide direction sigma and whether it is *held*
(kept in its status whatever its impulse: a slipping contact coming to rest).
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots._native.calls import lsn_crba, lsn_frame_jacobian, lsn_impact, lsn_solve

from legsim.compiled.functions import model_function, scratch

from .dynamics import SLOPE_ENTRIES, ground_grade, handle, keep, on_terrain, place_rounds, ptr, terrain_slopes
from .layout import (
    B_POINT,
    B_STOP,
    BLOCK_SIZE,
    C_ID,
    C_KIND,
    C_MU,
    C_ROWS,
    C_SIGN,
    CONTACT_SIZE,
    KIND_STOP,
    P_CONTACT,
    P_N,
)

FREE, STICK, NORMAL, SLIDE = range(4)
#: Relative tolerance of the cone and sign tests (rounding of the impulses and forces).
TOL = 1e-10
#: Kinetic energy an impact may gain to rounding (relative).
ENERGY_TOL = 1e-12
#: Most sets of statuses the active set tries before it gives up (the state is then past the
#: model's range).
MAX_TRIES = 64


@model_function
def contact_rows(x, p, contact, t_row, n_row):
    """Contact ``contact``'s constraint rows at q into t_row (tangential: x, or the terrain's
    tangent under the point) and n_row (normal: z or the terrain's normal, or a stop's signed
    dof); returns whether it has a tangential row (a pinned point)."""
    n = int(p[P_N])
    c = int(p[P_CONTACT]) + CONTACT_SIZE * contact
    if p[c + C_KIND] == KIND_STOP:
        for j in range(n):
            t_row[j] = 0.0
            n_row[j] = 0.0
        n_row[int(p[c + C_ID])] = p[c + C_SIGN]
        return False
    jac = np.empty(2 + 2 * n)
    lsn_frame_jacobian(handle(p), x.ctypes.data, np.int64(p[c + C_ID]), jac.ctypes.data)
    grade, norm = 0.0, 1.0
    if on_terrain(p):
        vx = 0.0
        for j in range(n):
            vx += jac[2 + j] * x[n + j]
        grade = ground_grade(x, p, int(p[c + C_ID]), jac[0], vx)
        norm = math.sqrt(1.0 + grade * grade)
    if grade == 0.0:
        for j in range(n):
            t_row[j] = jac[2 + j]
            n_row[j] = jac[2 + n + j]
    else:  # along the terrain's tangent (1, h') / s and normal (-h', 1) / s
        for j in range(n):
            t_row[j] = (jac[2 + j] + grade * jac[2 + n + j]) / norm
            n_row[j] = (jac[2 + n + j] - grade * jac[2 + j]) / norm
    return p[c + C_ROWS] == 2.0


@model_function
def dot(a, b, n):
    """sum a[j] b[j] over j < n."""
    total = 0.0
    for j in range(n):
        total += a[j] * b[j]
    return total


@model_function
def kinetic(M, v, n):
    """v^T M v (twice the kinetic energy, J) of M (nv * nv, row-major)."""
    total = 0.0
    for i in range(n):
        total += v[i] * dot(M[n * i : n * i + n], v, n)
    return total


@model_function
def solve_rows(A, b, m, least_norm, MWt, cones):
    """Solve A y = b (A (m, m)) in place of b by the native library's small solve, the one its
    constrained dynamics and impacts use (``lsn_solve``): LU where A is regular. Where rows
    depend on one another (two stuck points of one body: a statically indeterminate support),
    y is the least-norm solution (an equal share at a symmetric support): with ``least_norm``
    (A symmetric, no sliding rows) always, else where the motion ``MWt`` y (MWt (n, m) = M^-1 W^T)
    is the same for every solution; that y then shared by the capacities of ``cones`` (k, 3)
    rows (tangent row or -1, normal row, mu): each stuck contact's friction in proportion to
    mu times its normal impulse (``share_by_capacity`` in pinlegsim.cpp). Returns False (b
    unchanged) where there is no solution: A or b not finite, b outside A's range, or a motion
    that is not unique (the Painleve case)."""
    a = np.ascontiguousarray(A[:m, :m])
    rhs = np.ascontiguousarray(b[:m])
    motion = np.ascontiguousarray(MWt[:, :m])
    bounds = np.ascontiguousarray(cones)
    out = np.empty(m + 1)
    lsn_solve(np.int64(m), a.ctypes.data, rhs.ctypes.data, np.int64(1 if least_norm else 0),
              np.int64(motion.shape[0]), motion.ctypes.data, np.int64(bounds.shape[0]), bounds.ctypes.data,
              out.ctypes.data)  # fmt: skip
    keep(a)
    keep(rhs)
    keep(motion)
    keep(bounds)
    if out[m] != 1.0:
        return False
    b[:m] = out[:m]
    return True


# -- the generalised Newton impact (contacts without friction) ---------------------------------


@model_function
def contact_blocks(p, contacts, count, blocks):
    """The constraint blocks of ``contacts[:count]`` (rigid contact indices), each stuck (a point
    pinned as declared, a stop held), into blocks; returns their rows."""
    rows = 0
    for k in range(count):
        c = int(p[P_CONTACT]) + CONTACT_SIZE * contacts[k]
        b = BLOCK_SIZE * k
        blocks[b + 1] = p[c + C_ID]
        if p[c + C_KIND] == KIND_STOP:
            blocks[b], blocks[b + 2], blocks[b + 3] = B_STOP, p[c + C_SIGN], 1.0
        else:
            blocks[b], blocks[b + 2], blocks[b + 3] = B_POINT, p[c + C_MU], p[c + C_ROWS]
        rows += int(blocks[b + 3])
    return rows


@model_function
def newton_impact(x, p, contacts, coeff, count, v_plus, normal):
    """The generalised Newton impact of ``contacts[:count]`` (restitutions coeff[:count]) at x:
    the post-impact velocity into v_plus (nv,) and each contact's normal impulse (N s or N m s)
    into normal[:count]."""
    place_rounds(x, p)
    n = int(p[P_N])
    blocks = np.empty(BLOCK_SIZE * max(1, count))
    rows = contact_blocks(p, contacts, count, blocks)
    impulse = np.empty(max(1, rows))
    slopes = scratch(SLOPE_ENTRIES * max(1, count))
    terrain_slopes(x, p, count, blocks, 0, slopes)
    lsn_impact(handle(p), x.ctypes.data, ptr(x, n), np.int64(count), blocks.ctypes.data, slopes.ctypes.data,
               coeff.ctypes.data, v_plus.ctypes.data, impulse.ctypes.data)  # fmt: skip
    row = 0
    for k in range(count):
        row += int(blocks[BLOCK_SIZE * k + 3])
        normal[k] = impulse[row - 1]


@model_function
def joint_impact(x, p, kept, n_kept, strikers, n_strikers, restitution, v_plus, taking):
    """The post-impact velocity (into v_plus) of the rigid contacts ``strikers[:n_strikers]``
    (restitutions restitution[:n_strikers]) striking together at x, the ``kept[:n_kept]`` held
    plastically (module docstring); taking[k] is set to 1.0 for each striker that takes part
    (0.0 otherwise). Returns whether any takes part."""
    n = int(p[P_N])
    v = x[n : 2 * n]
    t_row, rows = np.empty(n), np.empty((n_strikers, n))
    plastic = np.zeros(n_strikers)
    for k in range(n_strikers):
        contact_rows(x, p, strikers[k], t_row, rows[k])
        taking[k] = 1.0 if dot(rows[k], v, n) < 0.0 else 0.0
    if taking[:n_strikers].sum() == 0.0:
        v_plus[:] = v
        return False
    for _ in range(4 * n_strikers + 1):
        engaged_impact(x, p, kept, n_kept, strikers, n_strikers, taking, plastic, restitution, -1.0, v_plus)
        if not joins(v_plus, rows, n, strikers, n_strikers, taking, plastic, np.abs(v).max()):
            break
    M = np.empty(n * n)
    lsn_crba(handle(p), x.ctypes.data, M.ctypes.data)
    if kinetic(M, v_plus, n) > kinetic(M, v, n) * (1.0 + ENERGY_TOL) + 1e-300:
        least = math.inf
        for k in range(n_strikers):
            if taking[k] == 1.0:
                least = min(least, 0.0 if plastic[k] == 1.0 else restitution[k])
        engaged_impact(x, p, kept, n_kept, strikers, n_strikers, taking, plastic, restitution, least, v_plus)
    return True


@model_function
def engaged_impact(x, p, kept, n_kept, strikers, n_strikers, taking, plastic, restitution, common, v_plus):
    """The Newton impact of the kept contacts (plastic) and the taking strikers (plastic ones at
    0, the others at their restitution, or all at ``common`` when it is >= 0) into v_plus; a
    striker whose impulse would pull, when others take part, is dropped (taking[k] = 0) and the
    impact solved again."""
    contacts = np.empty(n_kept + n_strikers, dtype=np.int64)
    coeff = np.empty(n_kept + n_strikers)
    normal = np.empty(n_kept + n_strikers)
    while True:
        count = 0
        for k in range(n_kept):
            contacts[count], coeff[count] = kept[k], 0.0
            count += 1
        for k in range(n_strikers):
            if taking[k] == 1.0:
                c = 0.0 if plastic[k] == 1.0 else restitution[k]
                contacts[count], coeff[count] = strikers[k], common if common >= 0.0 else c
                count += 1
        newton_impact(x, p, contacts, coeff, count, v_plus, normal)
        adhesive, least, taking_count, i = -1, 0.0, 0, n_kept
        for k in range(n_strikers):
            if taking[k] == 1.0:
                if adhesive < 0 or normal[i] < least:
                    adhesive, least = k, normal[i]
                taking_count += 1
                i += 1
        if common >= 0.0 or not (adhesive >= 0 and least < 0.0 and taking_count > 1):
            return
        taking[adhesive] = 0.0


@model_function
def joins(v_plus, rows, n, strikers, n_strikers, taking, plastic, speed):
    """Strikers left out that the impact drives into the ground join it plastically; returns
    whether any joined."""
    scale = 1e-12 * (1.0 + speed)
    joined = False
    for k in range(n_strikers):
        if taking[k] == 0.0 and dot(rows[k], v_plus, n) < -scale:
            taking[k] = 1.0
            plastic[k] = 1.0
            joined = True
    return joined
