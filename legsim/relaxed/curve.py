"""A step's own curve, and where a guard meets it (paper 000 Fig. 12, steps 3 and 10).

A trial step from (t, x) to (t1, x1) defines a curve on [t, t1]: the cubic Hermite interpolant
of its ends (slopes f there), or, for a landing on a method's continuous extension, that
extension up to the fraction theta of the step it landed at. The crossing of a guard is searched
along that curve with the bracketed search of ``rules.crossing_*``; the point returned is the
end of the final bracket past the guard.
"""

from __future__ import annotations

import numpy as np

from .evaluate import Tables, Visit, guards_at
from .layout import CURVE_DENSE, CURVE_HERMITE, F_LAND_H, F_LAND_T1, F_LAND_THETA, F_T, I_LAND_CURVE, I_LAND_E
from .rules import CONVERGED, RESULT, SEARCHING, STATUS, crossing_point, crossing_start, crossing_update
from .stages import MethodArrays, dense_point, dense_slope, hermite_point, hermite_slope


def landing_point(method: MethodArrays, vis: Visit, ws, s: float, out: np.ndarray) -> None:
    """The landing step's curve at fraction s of [t, t1] into out[:n]."""
    n = vis.n
    if ws.iv[I_LAND_CURVE] == CURVE_DENSE:
        dense_point(method, ws.x[:n], ws.fs[F_LAND_H], ws.K, s * ws.fs[F_LAND_THETA], out[:n])
    else:
        hermite_point(ws.x[:n], ws.K[0, :n], ws.x1[:n], ws.k1[:n], ws.fs[F_LAND_T1] - ws.fs[F_T], s, out[:n])


def landing_slope(method: MethodArrays, vis: Visit, ws, s: float, out: np.ndarray) -> None:
    """d/dt of the landing step's curve at fraction s into out[:n]."""
    n = vis.n
    if ws.iv[I_LAND_CURVE] == CURVE_DENSE:
        dense_slope(method, ws.K, s * ws.fs[F_LAND_THETA], out[:n])
    else:
        hermite_slope(ws.x[:n], ws.K[0, :n], ws.x1[:n], ws.k1[:n], ws.fs[F_LAND_T1] - ws.fs[F_T], s, out[:n])


def guard_on_landing(tab: Tables, vis: Visit, ws, method: MethodArrays, e: int, s: float, shift: float) -> float:
    """Guard e (plus ``shift``) at fraction s of the landing step's curve."""
    t = ws.fs[F_T]
    landing_point(method, vis, ws, s, ws.w)
    guards_at(tab, vis, ws, t + s * (ws.fs[F_LAND_T1] - t), ws.w[: vis.n], ws.g_w)
    return ws.g_w[e] + shift


def crossing_on_landing(
    tab: Tables,
    vis: Visit,
    ws,
    method: MethodArrays,
    e: int,
    shift: float,
    g0: float,
    g1: float,
    tol: float,
    s0: float = 0.0,
) -> tuple[float, bool]:
    """Where guard e (plus ``shift``) meets the landing step's curve between the fraction s0
    (where it is g0 >= 0) and the step's end (g1 < 0), within ``tol``: (the fraction u of
    [s0, 1] where it does, converged)."""
    state = crossing_start(g0, g1, tol)
    while state[STATUS] == SEARCHING:
        u = crossing_point(state)
        state = crossing_update(state, u, guard_on_landing(tab, vis, ws, method, e, s0 + u * (1.0 - s0), shift))
    return state[RESULT], state[STATUS] == CONVERGED


def set_hermite(ws, t1: float) -> None:
    """Make the landing step's curve the Hermite interpolant of (t, x, K[0]) and (t1, x1, k1)."""
    ws.iv[I_LAND_CURVE] = CURVE_HERMITE
    ws.iv[I_LAND_E] = -1
    ws.fs[F_LAND_T1] = t1
    ws.fs[F_LAND_H] = t1 - ws.fs[F_T]
    ws.fs[F_LAND_THETA] = 1.0


def set_dense(ws, h: float, theta: float) -> None:
    """Make the landing step's curve the continuous extension of the step of length h (stages
    in K) up to the fraction theta of it."""
    ws.iv[I_LAND_CURVE] = CURVE_DENSE
    ws.fs[F_LAND_H] = h
    ws.fs[F_LAND_THETA] = theta
    ws.fs[F_LAND_T1] = ws.fs[F_T] + theta * h
