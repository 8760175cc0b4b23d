"""One walk: the shortest path from x to y that crosses a given sequence of transition pieces,
minimised over its guard points.

A walk crosses hops (half-edge, piece) in order; its length is the sum of its legs
``|x - in_1(p_1)| + sum |out_i(p_i) - in_{i+1}(p_{i+1})| + |out_m(p_m) - y|`` (the strip widths
are added by the caller). Two greedy chains give valid starts: each guard point the projection
of the previous point, forwards from x or backwards from y.

With coordinate pieces and affine resets the minimisation is convex (a sum of norms of affine
maps over a box): one free variable by golden section; more by SLSQP where the minimum is
smooth, and by a log-barrier interior-point method where a leg has zero length at the minimum
(a kink, on which SLSQP stalls). Any other guard is an equality constraint ``g(p) = 0`` (the
mode's other guards ``>= 0`` as inequalities) for one SLSQP run from the better greedy chain: a
local minimisation, so the result is the length of a path that exists but may not be the
shortest one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .geometry import HalfEdge, Piece
from .projection import piece_constraints, project_onto_image, project_onto_piece
from .solvers import golden_convex, slsqp, sum_of_norms

#: One crossing of a walk: the transition and direction, and the piece of its guard set.
Hop = tuple[HalfEdge, Piece]


def optimise_walk(
    hops: Sequence[Hop], x: np.ndarray, y: np.ndarray, tol: float
) -> tuple[float, list[np.ndarray]] | None:
    """(length, guard points) of the shortest path found through ``hops`` from x to y (strip
    widths not included), or None when no greedy chain reaches y's side."""
    starts = [c for c in (chain(hops, x, y, tol, False), chain(hops, x, y, tol, True)) if c is not None]
    if not starts:
        return None
    best_len, best_pts = min(((walk_length(hops, pts, x, y), pts) for pts in starts), key=lambda s: s[0])
    unknowns = _WalkUnknowns(hops, best_pts, x, y)
    if unknowns.size == 0 or best_len == 0.0:
        return best_len, best_pts
    convex = all(he.edge.affine is not None and piece.boxed for he, piece in hops)
    if convex and unknowns.size == 1:
        candidates = [_golden_walk(unknowns, best_len)]
    elif convex:
        candidates = _convex_walk(unknowns)
    else:
        candidates = _generic_walk(unknowns, tol)
    for pts in candidates:
        value = walk_length(hops, pts, x, y)
        if value < best_len:
            best_len, best_pts = value, pts
    return best_len, best_pts


def leg_residuals(hops: Sequence[Hop], points: Sequence[np.ndarray], x: np.ndarray, y: np.ndarray) -> list[np.ndarray]:
    """The vectors whose norms add up to a walk's length (each entry minus the previous exit)."""
    out = []
    cur = x
    for (he, _), p in zip(hops, points, strict=True):
        entry, exit_ = he.ends(p)
        out.append(entry - cur)
        cur = exit_
    out.append(y - cur)
    return out


def walk_length(hops: Sequence[Hop], points: Sequence[np.ndarray], x: np.ndarray, y: np.ndarray) -> float:
    """The length of the path through ``hops`` at guard points ``points``, strip widths excluded."""
    return sum(float(np.linalg.norm(leg)) for leg in leg_residuals(hops, points, x, y))


def chain(hops: Sequence[Hop], x: np.ndarray, y: np.ndarray, tol: float, backward: bool) -> list[np.ndarray] | None:
    """Greedy guard points: each the projection of the previous point (forwards from x, or
    backwards from y). Always a valid path, and the start of the minimisation."""
    points: list[np.ndarray | None] = [None] * len(hops)
    order = range(len(hops) - 1, -1, -1) if backward else range(len(hops))
    cur = y if backward else x
    for i in order:
        he, piece = hops[i]
        onto_guard = he.forward != backward  # the point we come from meets p itself
        res = project_onto_piece(piece, cur, tol) if onto_guard else project_onto_image(he.edge, piece, cur, tol)
        if res is None:
            return None
        p = res[1]
        points[i] = p
        cur = np.asarray(he.edge.reset(p), dtype=float) if onto_guard else p
    return [p for p in points if p is not None]  # the loop filled every hop


class _WalkUnknowns:
    """The free coordinates of a walk's guard points stacked into one vector z (shape (size,));
    the fixed coordinates are those of ``template`` (one guard point per hop)."""

    def __init__(self, hops: Sequence[Hop], template: Sequence[np.ndarray], x: np.ndarray, y: np.ndarray) -> None:
        self.hops, self.x, self.y = hops, x, y
        self.template = [p.copy() for p in template]
        self.frees = [piece.free for _, piece in hops]
        self.offsets = np.cumsum([0] + [len(f) for f in self.frees])
        self.size = int(self.offsets[-1])
        self.lb = np.concatenate([piece.lb[f] for (_, piece), f in zip(hops, self.frees, strict=True)])
        self.ub = np.concatenate([piece.ub[f] for (_, piece), f in zip(hops, self.frees, strict=True)])
        self.scale = 1.0 + float(np.linalg.norm(x)) + float(np.linalg.norm(y))

    def start(self) -> np.ndarray:
        return np.concatenate([p[f] for p, f in zip(self.template, self.frees, strict=True)])

    def points(self, z: np.ndarray) -> list[np.ndarray]:
        return [
            _put(p0, free, z[self.offsets[k] : self.offsets[k + 1]])
            for k, (free, p0) in enumerate(zip(self.frees, self.template, strict=True))
        ]

    def clipped_points(self, z: np.ndarray) -> list[np.ndarray]:
        return [piece.clip(p) for (_, piece), p in zip(self.hops, self.points(z), strict=True)]

    def length(self, z: np.ndarray) -> float:
        return walk_length(self.hops, self.points(z), self.x, self.y)

    def residuals(self, z: np.ndarray) -> list[np.ndarray]:
        return leg_residuals(self.hops, self.points(z), self.x, self.y)

    def length_and_gradient(self, z: np.ndarray) -> tuple[float, np.ndarray]:
        """The walk's length at z and its gradient in z (shape (size,))."""
        pts = self.points(z)
        grads = [np.zeros(len(p)) for p in pts]
        total = 0.0
        cur, cur_jac, cur_k = self.x, None, -1
        for k, ((he, _), p) in enumerate(zip(self.hops, pts, strict=True)):
            J = he.edge.jacobian(p)
            entry, exit_ = he.ends(p)
            entry_jac, exit_jac = (None, J) if he.forward else (J, None)
            total += _add_leg(entry - cur, grads, k, entry_jac, cur_k, cur_jac)
            cur, cur_jac, cur_k = exit_, exit_jac, k
        total += _add_leg(self.y - cur, grads, -1, None, cur_k, cur_jac)
        return total, np.concatenate([g[f] for g, f in zip(grads, self.frees, strict=True)])

    def constraints(self) -> list[dict]:
        """Every piece's equality and inequalities as scipy constraints on z."""
        cons = []
        for k, (_, piece) in enumerate(self.hops):
            sl = slice(self.offsets[k], self.offsets[k + 1])

            def full(z: np.ndarray, k: int = k, sl: slice = sl) -> np.ndarray:
                return _put(self.template[k], self.frees[k], z[sl])

            for c in piece_constraints(piece, self.frees[k], full):
                inner_jac = c["jac"]
                c["jac"] = lambda z, inner_jac=inner_jac, sl=sl: _embed(inner_jac(z), sl, self.size)
                cons.append(c)
        return cons


def _golden_walk(unknowns: _WalkUnknowns, length0: float) -> list[np.ndarray]:
    """The guard points of a convex walk with one free coordinate (golden section)."""
    z0 = float(unknowns.start()[0])
    z = golden_convex(
        lambda v: unknowns.length(np.array([v])),
        z0,
        length0,
        float(unknowns.lb[0]),
        float(unknowns.ub[0]),
        1e-13 * unknowns.scale,
    )
    return unknowns.points(np.array([z]))


def _convex_walk(unknowns: _WalkUnknowns) -> list[list[np.ndarray]]:
    """Candidate guard points of a convex walk: SLSQP's, and the barrier method's where SLSQP
    did not end at a smooth stationary point (a kink of the sum of norms)."""
    z0, lb, ub, scale = unknowns.start(), unknowns.lb, unknowns.ub, unknowns.scale
    converged: list[bool] = []
    z = slsqp(unknowns.length_and_gradient, z0, lb, ub, [], ftol=1e-14 * scale, maxiter=100, converged=converged)
    candidates = [] if z is None else [z]
    if not (z is not None and converged and converged[0] and _smooth_minimum(unknowns, z)):
        legs = _affine_legs(unknowns.residuals, len(z0))
        candidates.append(sum_of_norms(legs, z0, lb, ub, scale))
    return [unknowns.clipped_points(zc) for zc in candidates]


def _smooth_minimum(unknowns: _WalkUnknowns, z: np.ndarray) -> bool:
    """Every leg has length and the projected gradient vanishes at z. SLSQP also reports
    convergence where its line search stalls just beside a kink (a leg 1e-3 long, the gradient
    still ~1 there), so the legs' lengths alone do not show that z is a smooth minimum."""
    lb, ub = unknowns.lb, unknowns.ub
    grad = unknowns.length_and_gradient(z)[1]
    grad = np.where(((z <= lb) & (grad > 0.0)) | ((z >= ub) & (grad < 0.0)), 0.0, grad)
    shortest_leg = min(float(np.linalg.norm(v)) for v in unknowns.residuals(z))
    return shortest_leg > 1e-6 * unknowns.scale and float(np.linalg.norm(grad)) <= 1e-6


def _generic_walk(unknowns: _WalkUnknowns, tol: float) -> list[list[np.ndarray]]:
    """Guard points of a walk through guards or resets of unknown shape: one local search from
    the better greedy chain (each evaluation may cost a contact solve), kept when feasible."""
    z = slsqp(
        unknowns.length_and_gradient,
        unknowns.start(),
        unknowns.lb,
        unknowns.ub,
        unknowns.constraints(),
        ftol=1e-12 * unknowns.scale,
        maxiter=100,
    )
    if z is None:
        return []
    pts = unknowns.clipped_points(z)
    if not all(piece.feasible(p, tol) for (_, piece), p in zip(unknowns.hops, pts, strict=True)):
        return []
    return [pts]


def _affine_legs(residuals: Callable[[np.ndarray], list[np.ndarray]], q: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each leg of a convex walk as (M_k, c_k), residual M_k z - c_k (columns exact: affine)."""
    base = residuals(np.zeros(q))
    cols = [residuals(np.eye(q)[i]) for i in range(q)]
    return [(np.column_stack([cols[i][k] - base[k] for i in range(q)]), -base[k]) for k in range(len(base))]


def _add_leg(
    d: np.ndarray,
    grads: list[np.ndarray],
    k_entry: int,
    entry_jac: np.ndarray | None,
    k_exit: int,
    exit_jac: np.ndarray | None,
) -> float:
    """Add |d| with d = entry(p_{k_entry}) - exit(p_{k_exit}) and its gradient (index -1: the
    fixed end x or y; a Jacobian of None: the identity)."""
    norm = float(np.linalg.norm(d))
    if norm == 0.0:
        return 0.0  # a leg of zero length: the subgradient 0 is admissible
    u = d / norm
    if k_entry >= 0:
        grads[k_entry] += u if entry_jac is None else entry_jac.T @ u
    if k_exit >= 0:
        grads[k_exit] -= u if exit_jac is None else exit_jac.T @ u
    return norm


def _put(template: np.ndarray, free: np.ndarray, values: np.ndarray) -> np.ndarray:
    p = template.copy()
    p[free] = values
    return p


def _embed(grad: np.ndarray, sl: slice, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[sl] = grad
    return out
