"""Dynamics of a mode: applied forces, unconstrained ABA and the constrained KKT solve.

Modes without rigid constraints use the articulated-body algorithm ``pinocchio.aba`` with the
applied generalised forces (spring legs through their hip Jacobians, joint damping, actuation).
Modes with rigid constraints solve the KKT contact dynamics
``M a + b = tau + J^T lambda, J a + dJ/dt v = 0`` through the Schur complement of ABA:
``a0 = aba(q, v, tau)``, ``lambda = (J M^-1 J^T)^-1 (-(J a0 + dJ/dt v))``,
``a = a0 + M^-1 J^T lambda`` (``M^-1`` by ``pinocchio.computeMinverse``). Nothing a mode does not
need is computed: no contact Jacobian without rigid constraints, no spring force without an
active leg, no damping term without damping. Each kind of evaluation is counted in
``data.counts``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.errors import ModelBreakdown, ModelError

from .contacts import LegFrames, RigidContact
from .model import LWA, BridgeData, BridgeModel
from .modes import ModeSpec


def control_key(u: Any) -> bytes:
    """Bytes identifying a control value, for caches keyed by state and control."""
    if u is None:
        return b""
    return np.asarray(u, dtype=float).tobytes()


def control_vector(model: BridgeModel, u: Any) -> np.ndarray:
    """The control u as a vector with one entry (N m or N) per actuated joint."""
    arr = np.asarray(u, dtype=float).reshape(-1)
    if arr.shape != model.actuated_idx.shape:
        raise ModelError(
            f"{model.name}: control u has {arr.size} entries, the robot has {model.actuated_idx.size} actuated joints"
        )
    return arr


def applied_forces(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, q: np.ndarray, v: np.ndarray, x: np.ndarray, u: Any
) -> np.ndarray:
    """Generalised applied force tau (nv,): stance spring legs, joint damping, actuation."""
    tau = np.zeros(model.n)
    pm, pd, counts = model.pin_model, data.pin_data, data.counts
    for i, lg in enumerate(spec.springs):
        J = pin.computeFrameJacobian(pm, pd, q, lg.hip_id, LWA)[:3:2]  # rows x and z
        counts["jacobians"] += 1
        counts["spring_forces"] += 1
        p = pd.oMf[lg.hip_id].translation
        d = np.array((p[0] - x[2 * model.n + i], p[2] - lg.leg.ground))
        r = math.hypot(d[0], d[1])
        d /= r
        f = lg.leg.stiffness * (lg.leg.rest_length - r)
        if lg.leg.damping > 0.0:
            counts["damping_evals"] += 1
            f -= lg.leg.damping * (d @ (J @ v))
        tau += (f * d) @ J
    if model.damping_idx.size:
        counts["damping_evals"] += 1
        tau[model.damping_idx] -= model.damping_b * v[model.damping_idx]
    if u is not None:
        tau[model.actuated_idx] += control_vector(model, u)
        counts["actuation_evals"] += 1
    return tau


def constraint_rows(
    model: BridgeModel, data: BridgeData, rigid: Sequence[RigidContact], q: np.ndarray, v: np.ndarray, drift: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Stacked constraint Jacobian (rows, nv) and, with ``drift``, dJ/dt v (rows,) (else zeros);
    the normal row of each contact is its last row and points into the domain (gap increasing).
    Computing a point's Jacobian also updates its frame placement in ``data.pin_data.oMf``."""
    J, gamma, _ = constraint_system(model, data, rigid, q, v, drift)
    return J, gamma


def constraint_system(
    model: BridgeModel, data: BridgeData, rigid: Sequence[RigidContact], q: np.ndarray, v: np.ndarray, drift: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``constraint_rows`` and the directions W (rows, nv) along which the constraint forces act,
    ``tau_c = W^T lambda``: W = J, except on the normal row of a slipping contact, where the
    friction force ``-s mu lambda_n`` along x joins the normal force: ``W = J_z - s mu J_x``."""
    rows = sum(r.rows for r in rigid)
    J = np.zeros((rows, model.n))
    gamma = np.zeros(rows)
    pm, pd = model.pin_model, data.pin_data
    i = 0
    has_points = False
    friction_rows: list[tuple[int, np.ndarray]] = []
    for r in rigid:
        if r.kind == "stop":
            J[i, r.dof] = r.sign
        else:
            Jf = pin.computeFrameJacobian(pm, pd, q, r.frame_id, LWA)
            data.counts["jacobians"] += 1
            if r.rows == 2:
                J[i] = Jf[0]
                J[i + 1] = Jf[2]
            else:
                J[i] = Jf[2]
                if r.slip:
                    friction_rows.append((i, -r.slip_mu * Jf[0]))
            has_points = True
        i += r.rows
    if drift and has_points:  # a stop's row is constant: no drift
        pin.forwardKinematics(pm, pd, q, v, np.zeros(model.n))
        i = 0
        for r in rigid:
            if r.kind == "point":
                acc = pin.getFrameClassicalAcceleration(pm, pd, r.frame_id, LWA).linear
                if r.rows == 2:
                    gamma[i], gamma[i + 1] = acc[0], acc[2]
                else:
                    gamma[i] = acc[2]
            i += r.rows
    if not friction_rows:
        return J, gamma, J
    W = J.copy()
    for row, friction in friction_rows:
        W[row] += friction
    return J, gamma, W


def solve_small(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve A y = b for the small symmetric positive definite Delassus matrix A; one and two
    rows (a stop, a foot) in closed form, where LAPACK's call overhead would dominate."""
    if A.shape[0] == 1:
        return b / A[0, 0]
    if A.shape[0] == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        return np.array(((A[1, 1] * b[0] - A[0, 1] * b[1]) / det, (A[0, 0] * b[1] - A[1, 0] * b[0]) / det))
    return np.linalg.solve(A, b)


def dynamics(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, x: np.ndarray, u: Any
) -> tuple[np.ndarray, np.ndarray]:
    """(acceleration (nv,), constraint forces (rows,)) of mode ``spec`` at x under control u,
    cached for the last state and control (counted in ``cache_hits``)."""
    # Keyed by the control's value, not its identity: a controller returns a new array at each
    # call, and the guard at a state and the field at the same state must share one solve.
    key = x.tobytes() + control_key(u)
    scratch = data.scratch(spec.name)
    if scratch.dyn_val is not None and key == scratch.dyn_key:
        data.counts["cache_hits"] += 1
        return scratch.dyn_val
    n = model.n
    q = x[:n]
    v = x[n : 2 * n]
    if u is not None:
        data.last_control = u
    tau = applied_forces(model, data, spec, q, v, x, u)
    a = pin.aba(model.pin_model, data.pin_data, q, v, tau).copy()
    data.counts["aba"] += 1
    lam = _constrain(model, data, spec, q, v, a) if spec.rigid else np.zeros(0)
    scratch.dyn_key, scratch.dyn_val = key, (a, lam)
    return a, lam


def _constrain(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, q: np.ndarray, v: np.ndarray, a: np.ndarray
) -> np.ndarray:
    """Turn the unconstrained acceleration ``a`` (changed in place) into the constrained one;
    returns the constraint forces (rows,)."""
    data.counts["kkt"] += 1
    Minv = pin.computeMinverse(model.pin_model, data.pin_data, q)
    if spec.stop_dofs is not None and len(spec.stop_dofs[0]) == 1:
        # one joint stop: J = s e_k, the Delassus "matrix" is (M^-1)_kk
        k, s = int(spec.stop_dofs[0][0]), float(spec.stop_dofs[1][0])
        col = Minv[:, k]
        lam = np.array((-s * a[k] / col[k],))
        a -= col * (a[k] / col[k])
        return lam
    if spec.stop_dofs is not None:
        # joint stops only: J selects (signed) dofs, no Jacobian, no drift
        idx, sign = spec.stop_dofs
        MJt = Minv[:, idx] * sign
        A = MJt[idx] * sign[:, None]
        rhs = -a[idx] * sign
    else:
        J, gamma, W = constraint_system(model, data, spec.rigid, q, v, drift=True)
        MJt = Minv @ W.T
        A = J @ MJt
        rhs = -(J @ a + gamma)
        if spec.slipping:
            check_consistent(model, spec, A)
    lam = solve_small(A, rhs)
    a += MJt @ lam
    return lam


def check_consistent(model: BridgeModel, spec: ModeSpec, A: np.ndarray) -> None:
    """``ModelBreakdown`` when a mode with slipping contacts has no unique contact forces: a
    diagonal entry of its Delassus matrix (normal rows against the normal-plus-friction force
    directions) <= 0, where pushing on the contact would drive it into the ground (the Painleve
    paradox), or a singular matrix. (With several slipping contacts a matrix that is not a
    P-matrix may admit other consistent modes too; this mode's forces are then one of them.)"""
    diagonal = np.diag(A)
    scale = float(np.max(np.abs(A)))
    if np.any(diagonal <= 1e-12 * scale) or abs(np.linalg.det(A)) <= 1e-12 * scale ** len(A):
        raise ModelBreakdown(
            f"{model.name}: mode '{spec.name}': with its slipping contacts the rigid contact "
            f"problem has no unique solution (Delassus matrix {np.round(A, 6).tolist()}: the "
            f"Painleve paradox); lower the friction coefficient"
        )


def constraint_forces(
    model: BridgeModel, data: BridgeData, spec: ModeSpec, x: np.ndarray, u: Any
) -> dict[str, np.ndarray]:
    """Constraint forces of the mode's active rigid contacts at x: ``{name: lambda}`` with
    ``lambda = (f_x, f_z)`` (N) for a sticking or slipping point contact (slipping: f_x is the
    friction force ``-s mu f_z``), ``(f_z,)`` for a frictionless one
    and ``(tau,)`` (N m or N) for a joint stop; the last entry is the normal force, >= 0 when the
    contact pushes the robot into its domain."""
    _, lam = dynamics(model, data, spec, x, u)
    out, i = {}, 0
    for r in spec.rigid:
        out[r.contact.name] = lam[i : i + r.rows].copy()
        if r.slip:  # the friction force joins the normal force: (f_x, f_z)
            out[r.contact.name] = np.array((-r.slip_mu * lam[i], lam[i]))
        i += r.rows
    return out


def leg_length(model: BridgeModel, data: BridgeData, leg: LegFrames, x: np.ndarray, i: int) -> tuple[float, float]:
    """(length r (m), its rate dr/dt (m/s)) of the stance leg whose foothold is ``x[2 nv + i]``."""
    n = model.n
    pm, pd = model.pin_model, data.pin_data
    pin.forwardKinematics(pm, pd, x[:n], x[n : 2 * n])
    p = pin.updateFramePlacement(pm, pd, leg.hip_id).translation
    vel = pin.getFrameVelocity(pm, pd, leg.hip_id, LWA).linear
    dx = p[0] - x[2 * n + i]
    dz = p[2] - leg.leg.ground
    r = math.hypot(dx, dz)
    return r, (dx * vel[0] + dz * vel[2]) / r


def leg_forces(model: BridgeModel, data: BridgeData, spec: ModeSpec, x: np.ndarray) -> dict[str, float]:
    """Axial force (N, > 0 pushing the hip away from the foot) of each active spring leg."""
    out = {}
    for i, lg in enumerate(spec.springs):
        r, rdot = leg_length(model, data, lg, x, i)
        f = lg.leg.stiffness * (lg.leg.rest_length - r)
        if lg.leg.damping > 0.0:
            f -= lg.leg.damping * rdot
        out[lg.leg.name] = f
    return out


def energy(model: BridgeModel, data: BridgeData, spec: ModeSpec, x: np.ndarray) -> float:
    """Total mechanical energy (J): kinetic + gravity (``model.gravity``) + stance leg springs."""
    n = model.n
    pm, pd = model.pin_model, data.pin_data
    data.counts["energy_evals"] += 1
    q, v = x[:n], x[n : 2 * n]
    e = pin.computeKineticEnergy(pm, pd, q, v) + pin.computePotentialEnergy(pm, pd, q)
    for i, lg in enumerate(spec.springs):
        r, _ = leg_length(model, data, lg, x, i)
        e += 0.5 * lg.leg.stiffness * (lg.leg.rest_length - r) ** 2
    return float(e)
