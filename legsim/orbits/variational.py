"""The variational equation along a stored segment: the saltation Jacobian's inner loop.

``jacobians._segment_sensitivity`` multiplies, step by step, the derivative of each Runge-Kutta
step of a segment: the variational equation stepped by the same method on the same steps,
``dk_j = J(t_j, X_j) dX_j`` with ``dX_j = I + h sum_m A_jm dk_m``. The stage points X_j are the
loop's own (``relaxed.stages.combine``) and the field is the loop's closed-loop evaluation
(``relaxed.evaluate.field_at``), so these functions are compiled like the step loop when the
mode's functions are (``legsim.compiled.kernel.compile_tool``) and run interpreted otherwise.
Field Jacobians are central differences of the field (``legsim.derivatives``' steps, each
coordinate's scaled by max(1, |x_j|): ~1e-10 relative), or, for a Newton step (``newton``),
forward differences interpolated linearly between the stored step points where the Jacobian
changes slowly (~1e-6 on the compass gait, at a quarter of the evaluations).
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any

import numpy as np

from ..derivatives import CENTRAL_STEP, FORWARD_STEP
from ..execution import Segment
from ..relaxed.evaluate import Tables, Visit, field_at
from ..relaxed.stages import INFO_IMPLICIT, MethodArrays, combine, stages
from .errors import OrbitError

#: Largest relative change of the field Jacobian over a step (max norms) for which a Newton
#: Jacobian interpolates it between the step's ends: the interpolation's error is then about
#: (change)^2 / 8 of the step's contribution, ~1e-6 over a compass-gait step at h = 2e-3
#: (changes ~4e-3 a step), against ~1e-8 for forward differences at every stage.
INTERPOLATION_LIMIT = 1e-2


def field_jacobian(tab: Tables, vis: Visit, ws: Any, t: float, x: np.ndarray, central: bool, work: Any) -> None:
    """df/dx at (t, x) by central or forward differences into work.J (n, n)."""
    n = x.shape[0]
    plus, minus, f_plus, f_minus = work.plus, work.minus, work.f_plus, work.f_minus
    for d in range(n):
        plus[d] = x[d]
        minus[d] = x[d]
    if not central:
        field_at(tab, vis, ws, t, x, f_minus)
    for j in range(n):
        scale = max(1.0, abs(x[j]))
        plus[j] = x[j] + (CENTRAL_STEP if central else FORWARD_STEP) * scale
        field_at(tab, vis, ws, t, plus[:n], f_plus)
        if central:
            minus[j] = x[j] - CENTRAL_STEP * scale
            field_at(tab, vis, ws, t, minus[:n], f_minus)
        width = plus[j] - minus[j]  # the step actually taken, after rounding
        for i in range(n):
            work.J[i, j] = (f_plus[i] - f_minus[i]) / width
        plus[j] = x[j]
        minus[j] = x[j]


def copy_into(source: np.ndarray, target: np.ndarray) -> None:
    """target[:, :] = source, for square matrices (element by element: compiled without numba's
    reference counting, as the loop is, an array assignment is not available)."""
    for i in range(source.shape[0]):
        for j in range(source.shape[1]):
            target[i, j] = source[i, j]


def product(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    """out = A @ B for small square matrices (numba's @ calls BLAS, slower at n ~ 5)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += A[i, k] * B[k, j]
            out[i, j] = acc


def stage_input(j: int, h: float, method: MethodArrays, dK: np.ndarray, dX: np.ndarray) -> None:
    """dX = I + h sum_m A_jm dK_m: the derivative of stage j's point."""
    n = dX.shape[0]
    for d in range(n):
        for e in range(n):
            acc = 1.0 if d == e else 0.0
            for m in range(j):
                w = method.A[j, m]
                if w != 0.0:
                    acc += h * w * dK[m, d, e]
            dX[d, e] = acc


def stages_exact(tab: Tables, vis: Visit, ws: Any, method: MethodArrays, t0: float, x0: np.ndarray, h: float,
                 central: bool, work: Any) -> None:  # fmt: skip
    """dK_j = J(t_j, X_j) dX_j with the field Jacobian at each stage point X_j."""
    n = x0.shape[0]
    for j in range(method.info[0]):
        combine(x0, work.K, method.A[j], j, h, work.X)
        stage_input(j, h, method, work.dK, work.dX)
        tj = t0 + method.c[j] * h
        field_at(tab, vis, ws, tj, work.X[:n], work.K[j])
        field_jacobian(tab, vis, ws, tj, work.X[:n], central, work)
        product(work.J, work.dX, work.out)
        copy_into(work.out, work.dK[j])


def stages_interpolated(method: MethodArrays, h: float, full: float, work: Any) -> None:
    """dK_j = J(t_j) dX_j with the field Jacobian interpolated linearly in time between the
    step's stored ends (J0 at its start, J1 a full step of length ``full`` later)."""
    n = work.dX.shape[0]
    for j in range(method.info[0]):
        stage_input(j, h, method, work.dK, work.dX)
        theta = method.c[j] * h / full
        for d in range(n):
            for e in range(n):
                work.J[d, e] = (1.0 - theta) * work.J0[d, e] + theta * work.J1[d, e]
        product(work.J, work.dX, work.out)
        copy_into(work.out, work.dK[j])


def slowly_varying(J0: np.ndarray, J1: np.ndarray) -> bool:
    """Whether the field Jacobian changes over the step by at most INTERPOLATION_LIMIT (max norms)."""
    change = 0.0
    size = 0.0
    for d in range(J0.shape[0]):
        for e in range(J0.shape[1]):
            change = max(change, abs(J1[d, e] - J0[d, e]))
            size = max(size, abs(J0[d, e]))
    return change <= INTERPOLATION_LIMIT * size


def step_derivative(method: MethodArrays, h: float, work: Any) -> None:
    """S = I + h sum_j b_j dK_j, the derivative of the step, into work.S."""
    n = work.S.shape[0]
    for d in range(n):
        for e in range(n):
            acc = 1.0 if d == e else 0.0
            for j in range(method.info[0]):
                acc += h * method.b[j] * work.dK[j, d, e]
            work.S[d, e] = acc


def sensitivity(tab: Tables, vis: Visit, ws: Any, method: MethodArrays, ts: np.ndarray, xs: np.ndarray, count: int,
                t_stop: float, newton: bool, work: Any) -> None:  # fmt: skip
    """work.Phi <- (derivative of step count-1) ... (derivative of step 0) work.Phi, each step from
    its stored start point, the last cut at t_stop (module docstring for ``newton``)."""
    if newton:
        field_jacobian(tab, vis, ws, ts[0], xs[0], False, work)
        copy_into(work.J, work.J0)
    for i in range(count):
        t0 = ts[i]
        if t0 >= t_stop:
            break
        if newton:
            field_jacobian(tab, vis, ws, ts[i + 1], xs[i + 1], False, work)
            copy_into(work.J, work.J1)
        t1 = min(ts[i + 1], t_stop)
        h = t1 - t0
        if h > 0.0:
            if newton and slowly_varying(work.J0, work.J1):
                stages_interpolated(method, h, ts[i + 1] - t0, work)
            else:
                stages_exact(tab, vis, ws, method, t0, xs[i], h, not newton, work)
            step_derivative(method, h, work)
            product(work.S, work.Phi, work.out)
            copy_into(work.out, work.Phi)
        if newton:
            copy_into(work.J1, work.J0)


def step_from(tab: Tables, vis: Visit, ws: Any, method: MethodArrays, t0: float, x0: np.ndarray, h: float,
              out: np.ndarray) -> bool:  # fmt: skip
    """The method's step of length h (s) from the stored point (t0, x0) into out (x0's length):
    the point a run's step of that length reaches, on the integrator's own step rather than an
    interpolant of its stored points. False, and nothing computed, when x0 is wider than the
    workspace's states (a stored state with a memory the evaluator's controller does not have)."""
    n = x0.shape[0]
    if n > ws.x.shape[0]:
        return False
    field_at(tab, vis, ws, t0, x0, ws.K[0, :n])
    stages(tab, vis, ws, method, t0, x0, h, ws.K, ws.XS, out)
    return True


def point_on_step(run: Any, seg: Segment, i: int, h: float) -> np.ndarray:
    """The point h (s) after the stored point i of ``seg`` on the step the run's method takes
    from it, shape (n,), on the run's tables (``legsim.relaxed.driver.Evaluator``), compiled
    when they are. Raises ``OrbitError`` when the evaluator's states are narrower than the
    segment's (an evaluator without the run's controller)."""
    x0 = np.ascontiguousarray(seg.x[i], dtype=float)
    out = np.empty_like(x0)
    if not run.call(step_from, seg.mode, float(seg.t[i]), x0, float(h), out):
        raise OrbitError(
            f"the stored state of mode '{seg.mode}' has {x0.shape[0]} entries, more than the evaluator's run "
            "(build it with the run's controller)",
            "simulation_failed",
        )
    return out


#: The work arrays of ``sensitivity``: stages K (s, n) and their derivatives dK (s, n, n), a
#: stage point X and its derivative dX, field Jacobians J (at a stage), J0 and J1 (at a step's
#: ends), the step's derivative S, a product's result, the product Phi so far, and the
#: difference quotients' points and fields.
SensitivityWork = namedtuple("SensitivityWork", "K dK X dX J J0 J1 S out Phi plus minus f_plus f_minus")


def sensitivity_work(n: int, stages: int) -> SensitivityWork:
    """The work arrays of ``sensitivity`` for an n-dimensional state and ``stages`` stages."""
    return SensitivityWork(
        np.zeros((stages, n)), np.zeros((stages, n, n)), np.zeros(n), np.zeros((n, n)), np.zeros((n, n)),
        np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.eye(n),
        np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
    )  # fmt: skip


def segment_sensitivity(run: Any, seg: Segment, t_stop: float | None, newton: bool) -> np.ndarray | None:
    """d x(end) / d x(start) along ``seg`` (the last step cut at ``t_stop``, s), shape (n, n),
    on the run's tables (``legsim.relaxed.driver.Evaluator``), compiled when they are; None
    when the product is not finite (a perturbed stage past the model's range)."""
    if run.method.info[INFO_IMPLICIT] == 1:
        raise OrbitError(
            "the saltation Jacobian steps the variational equation of explicit Runge-Kutta steps; for a linearly "
            "implicit method use jacobian='fd'",
            "singular_jacobian",
        )
    n = seg.x.shape[1]
    work = sensitivity_work(n, run.method.info[0])
    stop = math.inf if t_stop is None else float(t_stop)
    ts = np.ascontiguousarray(seg.t, dtype=float)
    xs = np.ascontiguousarray(seg.x, dtype=float)
    run.call(sensitivity, seg.mode, ts, xs, len(seg.t) - 1, stop, bool(newton), work)
    return work.Phi if np.all(np.isfinite(work.Phi)) else None
