"""A Runge-Kutta step from a method's arrays: its stages, its error estimate and its continuous
extension, written once for every path that steps a field (the step loop, interpreted or
compiled, and the variational equations of ``legsim.orbits``).

A method is data (``MethodArrays``, from a ``legsim.methods.Tableau``): nodes c (s,), the stage
matrix A (s, s), weights b (s,), the error weights b_err (s,) and the blended lower-order ones
(DOP853), and, for a method with a continuous extension, the polynomial weights P (s + m,
degree) over its s stages and m extra stages (nodes c_extra (m,), rows A_extra (m, s + m)).
Stages are rows of K (s + m, n); the caller fills K[0] with f(t, x). The field is the closed
loop's in the mode of ``vis`` (``legsim.relaxed.evaluate.field_at``).

Units: t and h in s; x in the model's units, K in those units per second.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .evaluate import Tables, Visit, field_at

#: A method as the step loop's arrays (``method_arrays``); ``info`` holds the integers
#: ``INFO_*``; a linearly implicit method's coupling G (s, s), gamma (in ``gamma[0]``) and the
#: weights of df/dt in its stages (s,).
MethodArrays = namedtuple("MethodArrays", "c A b b_err b_err_low P c_extra A_extra info G gamma time_weights")
#: Stage rows s; 1 when the last stage is f at the new point (FSAL); 1 when the method has an
#: error estimate; 1 when its norm blends a lower-order estimate (DOP853); the extra stages m of
#: its continuous extension (-1: none); the degree of the extension's polynomials; 1 for a
#: linearly implicit method, whose stages are rows 1..s of K, row 0 holding f(t, x).
INFO_STAGES, INFO_FSAL, INFO_EMBEDDED, INFO_BLENDED, INFO_EXTRA, INFO_DEGREE, INFO_IMPLICIT = range(7)
#: Accepted steps a linearly implicit method's Jacobian serves before it is evaluated again (a
#: W-method keeps its order with an old Jacobian; it is also evaluated at every mode entry and
#: after every rejected step).
JACOBIAN_REUSE = 50


#: The arrays of the tableaux made so far, by identity (a Tableau holds arrays and has no hash):
#: every run of a method reads the same arrays, which nothing writes.
_ARRAYS: dict[int, tuple[object, MethodArrays]] = {}
#: Tableaux whose arrays are kept at most (a program uses a few).
KEPT_TABLEAUX = 64


def method_arrays(tableau) -> MethodArrays:
    """The tableau as ``MethodArrays`` (contiguous float64 and int64 arrays), made once per
    tableau."""
    found = _ARRAYS.get(id(tableau))
    if found is not None and found[0] is tableau:
        return found[1]
    arrays = _implicit_arrays(tableau) if tableau.implicit else _explicit_arrays(tableau)
    if len(_ARRAYS) < KEPT_TABLEAUX:
        _ARRAYS[id(tableau)] = (tableau, arrays)  # holding the tableau keeps its id its own
    return arrays


def _explicit_arrays(tableau) -> MethodArrays:
    """An explicit method's arrays."""
    s = tableau.stages
    b_err = np.zeros(s) if tableau.b_err is None else np.asarray(tableau.b_err, dtype=float)
    b_low = np.zeros(s) if tableau.b_err_low is None else np.asarray(tableau.b_err_low, dtype=float)
    dense = tableau.dense
    if dense is None:
        P, c_extra, A_extra, extra, degree = np.zeros((s, 1)), np.zeros(0), np.zeros((0, s)), -1, 0
    else:
        P, degree = np.asarray(dense.P, dtype=float), dense.P.shape[1]
        c_extra = np.asarray(dense.c_extra, dtype=float)
        extra = c_extra.shape[0]
        A_extra = np.zeros((extra, s + extra))
        if extra:
            A_extra[:, : dense.A_extra.shape[1]] = dense.A_extra
    info = np.array(
        [s, int(tableau.fsal), int(tableau.b_err is not None), int(tableau.b_err_low is not None), extra, degree, 0],
        dtype=np.int64,
    )
    return MethodArrays(
        np.ascontiguousarray(tableau.c, dtype=float),
        np.ascontiguousarray(tableau.A, dtype=float),
        np.ascontiguousarray(tableau.b, dtype=float),
        np.ascontiguousarray(b_err),
        np.ascontiguousarray(b_low),
        np.ascontiguousarray(P),
        np.ascontiguousarray(c_extra),
        np.ascontiguousarray(A_extra),
        info,
        np.zeros((s, s)),
        np.zeros(1),
        np.zeros(s),
    )


def _implicit_arrays(tableau) -> MethodArrays:
    """A linearly implicit method's arrays, its stages shifted to rows 1..s (row 0: f(t, x))."""
    s = tableau.stages + 1

    def shifted(values, shape):
        out = np.zeros(shape)
        out[(slice(1, None),) * len(shape)] = values
        return out

    b_err = np.zeros(s - 1) if tableau.b_err is None else np.asarray(tableau.b_err, dtype=float)
    info = np.array([s, 0, int(tableau.b_err is not None), 0, -1, 0, 1], dtype=np.int64)
    return MethodArrays(
        shifted(tableau.c, (s,)),
        shifted(tableau.A, (s, s)),
        shifted(tableau.b, (s,)),
        shifted(b_err, (s,)),
        np.zeros(s),
        np.zeros((s, 1)),
        np.zeros(0),
        np.zeros((0, s)),
        info,
        shifted(tableau.G, (s, s)),
        np.array([float(tableau.gamma)]),
        shifted(np.zeros(s - 1) if tableau.time_weights is None else tableau.time_weights, (s,)),
    )


def combine(x: np.ndarray, K: np.ndarray, weights: np.ndarray, count: int, h: float, out: np.ndarray) -> None:
    """out = x + h * sum_{j < count} weights[j] K[j], over the state's n = len(x) coordinates."""
    for d in range(x.shape[0]):
        acc = 0.0
        for j in range(count):
            w = weights[j]
            if w != 0.0:
                acc += w * K[j, d]
        out[d] = x[d] + h * acc


def stages(tab: Tables, vis: Visit, ws, method: MethodArrays, t: float, x: np.ndarray, h: float, K: np.ndarray,
           XS: np.ndarray, x_new: np.ndarray) -> None:  # fmt: skip
    """The step of size h from (t, x): the stages K[1:s] (K[0] = f(t, x) given) and the new
    point x_new; XS is scratch of x's length. With FSAL the last stage is f(t + h, x_new)."""
    if method.info[INFO_IMPLICIT] == 1:
        implicit_stages(tab, vis, ws, method, t, x, h, K, XS, x_new)
        return
    s = method.info[INFO_STAGES]
    n = x.shape[0]
    for i in range(1, s):
        combine(x, K, method.A[i], i, h, XS)
        field_at(tab, vis, ws, t + method.c[i] * h, XS, K[i, :n])
    if method.info[INFO_FSAL] == 1:
        for d in range(n):
            x_new[d] = XS[d]
    else:
        combine(x, K, method.b, s, h, x_new)


def implicit_stages(tab: Tables, vis: Visit, ws, method: MethodArrays, t: float, x: np.ndarray, h: float,
                    K: np.ndarray, XS: np.ndarray, x_new: np.ndarray) -> None:  # fmt: skip
    """A linearly implicit (Rosenbrock W) step: each stage k_i (row i of K) solves
    (I - gamma h J) k_i = f(t + c_i h, x + h sum_{j<i} A_ij k_j) + sum_{j<i} G_ij k_j
    + g_i h df/dt, with the Jacobian ws.J and df/dt ws.ft evaluated before (``jacobian``);
    x_new = x + h sum_i b_i k_i."""
    n = x.shape[0]
    rows = method.info[INFO_STAGES]
    factor(ws.J, ws.LU, ws.piv, method.gamma[0] * h, n)
    for i in range(1, rows):
        combine(x, K, method.A[i], i, h, XS)
        field_at(tab, vis, ws, t + method.c[i] * h, XS[:n], K[i, :n])
        for j in range(1, i):
            weight = method.G[i, j]
            if weight != 0.0:
                for d in range(n):
                    K[i, d] += weight * K[j, d]
        drift = method.time_weights[i] * h
        for d in range(n):
            K[i, d] += drift * ws.ft[d]
        solve(ws.LU, ws.piv, K[i, :n], n)
    combine(x, K, method.b, rows, h, x_new)


def jacobian(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray, f0: np.ndarray) -> None:
    """df/dx at (t, x) into ws.J (n, n) and df/dt into ws.ft by forward differences, f0 = f(t, x)
    given; the steps are sqrt(machine eps) scaled by max(1, |x_j|) (max(1, |t|) for t), the step
    actually taken divided by."""
    n = x.shape[0]
    for d in range(n):
        ws.XS[d] = x[d]
    dt = (t + 1.4901161193847656e-08 * max(1.0, abs(t))) - t
    field_at(tab, vis, ws, t + dt, ws.XS[:n], ws.w)
    for d in range(n):
        ws.ft[d] = (ws.w[d] - f0[d]) / dt
    for j in range(n):
        step = 1.4901161193847656e-08 * max(1.0, abs(x[j]))
        ws.XS[j] = x[j] + step
        field_at(tab, vis, ws, t, ws.XS[:n], ws.w)
        width = ws.XS[j] - x[j]
        for i in range(n):
            ws.J[i, j] = (ws.w[i] - f0[i]) / width
        ws.XS[j] = x[j]


def factor(J: np.ndarray, LU: np.ndarray, piv: np.ndarray, gh: float, n: int) -> None:
    """LU of I - gh J with partial pivoting, in place in LU (rows swapped, their order in piv);
    a zero pivot is left for ``solve`` to turn into non-finite stages."""
    for i in range(n):
        for j in range(n):
            LU[i, j] = (1.0 if i == j else 0.0) - gh * J[i, j]
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(LU[i, k]) > abs(LU[p, k]):
                p = i
        piv[k] = p
        if p != k:
            for j in range(n):
                LU[k, j], LU[p, j] = LU[p, j], LU[k, j]
        if LU[k, k] == 0.0:
            continue
        for i in range(k + 1, n):
            LU[i, k] /= LU[k, k]
            for j in range(k + 1, n):
                LU[i, j] -= LU[i, k] * LU[k, j]


def solve(LU: np.ndarray, piv: np.ndarray, b: np.ndarray, n: int) -> None:
    """Solve (LU) y = b in place, with the row swaps of ``factor``."""
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for i in range(n):
        for j in range(i):
            b[i] -= LU[i, j] * b[j]
    for i in range(n - 1, -1, -1):
        for j in range(i + 1, n):
            b[i] -= LU[i, j] * b[j]
        b[i] /= LU[i, i]


def estimate(method: MethodArrays, K: np.ndarray, h: float, d: int) -> tuple[float, float]:
    """The step's local error estimates of coordinate d: h sum_j b_err_j K[j, d] and the blended
    lower-order one (0 for a method without)."""
    err = 0.0
    err_low = 0.0
    for j in range(method.info[INFO_STAGES]):
        err += method.b_err[j] * K[j, d]
        err_low += method.b_err_low[j] * K[j, d]
    return h * err, h * err_low


def error_norm(method: MethodArrays, K: np.ndarray, h: float, x: np.ndarray, x_new: np.ndarray, rtol: float,
               atol: float) -> float:  # fmt: skip
    """Hairer's (and scipy's) RMS norm of the step's local error estimate, each coordinate
    scaled by atol + rtol max(|x|, |x_new|); for a blended pair (DOP853) the fifth-order
    estimate damped where the third-order one is much larger."""
    blended = method.info[INFO_BLENDED] == 1
    n = x.shape[0]
    high = 0.0
    low = 0.0
    for d in range(n):
        scale = atol + rtol * max(abs(x[d]), abs(x_new[d]))
        err, err_low = estimate(method, K, h, d)
        r = err / scale
        high += r * r
        r_low = err_low / scale
        low += r_low * r_low
    if not blended:
        return math.sqrt(high / n)
    if high == 0.0 and low == 0.0:
        return 0.0
    return high / math.sqrt((high + 0.01 * low) * n)


def extend(tab: Tables, vis: Visit, ws, method: MethodArrays, t: float, x: np.ndarray, h: float, K: np.ndarray,
           XS: np.ndarray) -> int:  # fmt: skip
    """The extra stages of the method's continuous extension into K[s:s + m]; returns m, the
    field evaluations they cost."""
    s = method.info[INFO_STAGES]
    m = method.info[INFO_EXTRA]
    n = x.shape[0]
    for i in range(m):
        combine(x, K, method.A_extra[i], s + i, h, XS)
        field_at(tab, vis, ws, t + method.c_extra[i] * h, XS, K[s + i, :n])
    return m


def dense_point(method: MethodArrays, x: np.ndarray, h: float, K: np.ndarray, theta: float, out: np.ndarray) -> None:
    """x at t + theta h on the step's continuous extension (K holding its s + m stages); out
    must not share memory with x. Each stage's weight is a polynomial in theta, evaluated once
    for all components."""
    rows = method.info[INFO_STAGES] + max(method.info[INFO_EXTRA], 0)
    degree = method.info[INFO_DEGREE]
    n = x.shape[0]
    for d in range(n):
        out[d] = 0.0
    for i in range(rows):
        w = 0.0
        power = theta
        for j in range(degree):
            w += method.P[i, j] * power
            power *= theta
        for d in range(n):
            out[d] += w * K[i, d]
    for d in range(n):
        out[d] = x[d] + h * out[d]


def dense_slope(method: MethodArrays, K: np.ndarray, theta: float, out: np.ndarray) -> None:
    """dx/dt at t + theta h on the step's continuous extension."""
    rows = method.info[INFO_STAGES] + max(method.info[INFO_EXTRA], 0)
    degree = method.info[INFO_DEGREE]
    n = out.shape[0]
    for d in range(n):
        out[d] = 0.0
    for i in range(rows):
        w = 0.0
        power = 1.0
        for j in range(degree):
            w += (j + 1) * method.P[i, j] * power
            power *= theta
        for d in range(n):
            out[d] += w * K[i, d]


def hermite_point(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: float,
                  out: np.ndarray) -> None:  # fmt: skip
    """The cubic Hermite interpolant of a step of length dt (ends x0, x1, slopes d0, d1) at
    fraction s, into out. A coordinate held along the step (x1 = x0, zero slopes: a
    controller's memory) keeps its value to the bit, which the weighted sum of its ends would
    miss by a float spacing at some s."""
    s2 = s * s
    s3 = s2 * s
    w0 = 2.0 * s3 - 3.0 * s2 + 1.0
    w1 = (s3 - 2.0 * s2 + s) * dt
    w2 = -2.0 * s3 + 3.0 * s2
    w3 = (s3 - s2) * dt
    for d in range(out.shape[0]):
        if x1[d] == x0[d] and d0[d] == 0.0 and d1[d] == 0.0:
            out[d] = x0[d]
        else:
            out[d] = w0 * x0[d] + w1 * d0[d] + w2 * x1[d] + w3 * d1[d]


def hermite_slope(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: float,
                  out: np.ndarray) -> None:  # fmt: skip
    """d/dt of ``hermite_point`` at fraction s, into out."""
    s2 = s * s
    v0 = (6.0 * s2 - 6.0 * s) / dt
    v1 = 3.0 * s2 - 4.0 * s + 1.0
    v2 = (-6.0 * s2 + 6.0 * s) / dt
    v3 = 3.0 * s2 - 2.0 * s
    for d in range(out.shape[0]):
        out[d] = v0 * x0[d] + v1 * d0[d] + v2 * x1[d] + v3 * d1[d]


def all_finite(x: np.ndarray) -> bool:
    """Whether every entry of x is finite."""
    for d in range(x.shape[0]):  # noqa: SIM110 -- a loop numba compiles, not a generator
        if not math.isfinite(x[d]):
            return False
    return True
