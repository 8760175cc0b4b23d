"""The relaxed hybrid quotient-space metric (paper 000, Section III) and distances between executions.

Paper 000 glues the domains of a hybrid system into one metric space: a point on a guard and its
reset image are the same point (Definition 12, the hybrid quotient space M), and with the
relaxation every guard is thickened into a strip of width eps whose transverse coordinate tau
runs from 0 (the guard) to eps (where the reset is applied) (Definitions 14, 15, 19; M^eps).
The distance is the length of the shortest *connected* curve (Definition 5): straight pieces
inside the domains, joined where a guard point p is identified with its reset image R(p), each
identification in M^eps paid for by crossing its strip, a length eps (the strip metric (12) is
d_G + |tau - tau'|, so moving along the guard inside the strip never beats moving in the domain).

``distance(system, a, b, eps)`` computes

    min( |x_a - x_b|                              (same mode only),
         min over edge walks e_1..e_m (m <= max_hops), over guard points p_i:
             |x_a - in_1(p_1)| + sum |out_i(p_i) - in_{i+1}(p_{i+1})| + |out_m(p_m) - x_b| + m eps )

where a walk may cross a transition either way (the quotient is symmetric): forwards
``in(p) = p, out(p) = R(p)``, backwards ``in(p) = R(p), out(p) = p``. eps = 0 gives the
unrelaxed distance on M; d_0 <= d_eps <= d_0 + k eps with k the crossings of a shortest path
(Theorem 21).

What a *guard point* is. Guards follow the legsim convention (``g >= 0`` inside, ``< 0`` past),
and "and" conditions are written with ``max``, e.g. a stop ``max(x_max - x, -v)``. The guard
set of a transition e leaving mode j is taken to be

    G_e = { p : g_e(p) = 0  and  g_f(p) >= 0 for every other transition f leaving j },

i.e. the part of the boundary of the domain D_j (where all guards are >= 0) on which e fires;
this is where the integrator applies the reset. For ``max(a(x), b(x))`` the set ``g = 0`` is the
union of ``{a = 0, b <= 0}`` and ``{b = 0, a <= 0}``; the second piece is an artefact of the
encoding (e.g. the stop's ``{v = 0, x >= x_max}``), harmless when the reset maps it to itself,
as the impact laws of the bundled systems do.

How guard points are found. Guards of the form ``max_k s_k (x[i_k] - c_k)`` with distinct
coordinates (coordinate hyperplanes and their conjunctions) are split into pieces ``{x[i_k] =
c_k, s_l (x[i_l] - c_l) <= 0}``, each a box with one coordinate fixed, onto which projection is
exact. Models can declare this with ``CoordinateGuard``; plain functions of that form are
detected by probing (gradients at random points, exact secant slopes, constants snapped to 12
digits, then the candidate is checked against the function at fresh points). Affine resets are
declared with ``AffineReset`` or detected the same way. With coordinate pieces and affine
resets the minimisation over the guard points of one walk is convex (a sum of norms of affine
maps over a box): one free variable by golden section; more by SLSQP where the minimum is
smooth, and by a log-barrier interior-point method where a leg has zero length at the minimum
(a kink, on which SLSQP stalls). Any other guard is an equality constraint ``g(p) = 0`` (other
guards of the mode ``>= 0`` as inequalities) for one SLSQP run from the better of two greedy
chains (projecting forwards from a and backwards from b): a local minimisation, so the result is
the length of a path that exists but may not be the shortest one. A model function that fails
at a probed point makes that walk unusable, not the distance.

What the value is, exactly. The value returned is always the length of an explicit connected
path, so it is >= the distance of the "chord" quotient metric (straight chords inside each
mode); it equals it when the optimiser's minimum is global (convex cases above) and
``max_hops`` crossings suffice. Inside one mode the distance is Euclidean. The paper endows a
domain with its *induced length* metric (Lemma 6), in which a curve must stay in the domain:
for a convex domain the two agree; for a non-convex one the chord may leave the domain and the
Euclidean value is then only a lower bound of the paper's domain distance. Within one mode the
direct chord is also an upper bound of the quotient distance, and a path through transitions
is searched for only when it could be shorter: each walk has the lower bound
``m eps + dist(x_a, first entry set) + dist(x_b, last exit set)`` (exact for coordinate pieces, a
first-order estimate for other guards), and walks are solved in order of that bound until it
exceeds the best length found; crossing an edge and straight back is skipped where the reset
does not shrink distances on that side. With a cap of K crossings the triangle inequality that
holds is d_2K(a, c) <= d_K(a, b) + d_K(b, c).

Units: the strip width eps is in guard units (paper: the transverse coordinate), added to
Euclidean lengths of states; both are the paper's choice.
"""

from __future__ import annotations

import itertools
import math
import warnings
import weakref
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Sequence

import numpy as np
from scipy.optimize import lsq_linear, minimize

from ..errors import LegsimError, ModelError
from ..hybrid import HybridSystem, Transition, reachable_modes

__all__ = [
    "AffineReset", "CoordinateGuard", "Crossing", "MetricError", "MetricPath", "distance",
    "distances", "position_error", "rho", "shortest_path", "trajectory_space_distance",
]

#: Default number of transition crossings searched for a shortest path.
DEFAULT_MAX_HOPS = 2


class MetricError(LegsimError, ValueError):
    """Invalid input to a metric function (point, eps, times, execution)."""


# ---------------------------------------------------------------------------------------------
# Declarations a model can use so that the metric knows the shape of its guards and resets.
# ---------------------------------------------------------------------------------------------
class CoordinateGuard:
    """A guard ``g(x) = max_k scale_k * (x[index_k] - value_k)`` (distinct indices).

    Callable, so it can be used directly as ``Transition.guard``; the metric projects onto its
    zero set exactly. ``CoordinateGuard((0, 1.0, 0.0), (1, 1.0, 0.0))`` is the bouncing ball's
    ``max(z, zd)``; ``CoordinateGuard((0, -1.0, x_max), (1, -1.0, 0.0))`` the stop
    ``max(x_max - x, -v)``. Units: those of ``scale * x``.
    """

    __slots__ = ("terms",)

    def __init__(self, *terms: tuple[int, float, float]) -> None:
        if not terms:
            raise ModelError("CoordinateGuard needs at least one term (index, scale, value)")
        clean = []
        for term in terms:
            try:
                index, scale, value = term
            except (TypeError, ValueError):
                raise ModelError(f"CoordinateGuard terms are (index, scale, value), got {term!r}") from None
            if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or index < 0:
                raise ModelError(f"CoordinateGuard index must be an integer >= 0, got {index!r}")
            scale, value = float(scale), float(value)
            if not (math.isfinite(scale) and scale != 0.0 and math.isfinite(value)):
                raise ModelError(f"CoordinateGuard term {term!r}: scale must be finite and nonzero, value finite")
            clean.append((int(index), scale, value))
        if len({t[0] for t in clean}) != len(clean):
            raise ModelError(f"CoordinateGuard indices must be distinct, got {[t[0] for t in clean]}")
        self.terms: tuple[tuple[int, float, float], ...] = tuple(clean)

    def __call__(self, x: np.ndarray) -> float:
        best = -math.inf
        for index, scale, value in self.terms:
            v = scale * (float(x[index]) - value)
            if v > best:
                best = v
        return best

    def __repr__(self) -> str:
        return f"CoordinateGuard{self.terms!r}"


class AffineReset:
    """A reset ``R(x) = matrix @ x + offset`` (matrix shape (n_target, n_source)).

    Callable, so it can be used as ``Transition.reset``; the metric then minimises over guard
    points exactly (a convex problem) and uses ``matrix`` as the Jacobian.
    """

    __slots__ = ("matrix", "offset")

    def __init__(self, matrix: Any, offset: Any = None) -> None:
        A = np.array(matrix, dtype=float)
        if A.ndim != 2 or not np.all(np.isfinite(A)):
            raise ModelError(f"AffineReset matrix must be a finite 2-d array, got shape {A.shape}")
        r = np.zeros(A.shape[0]) if offset is None else np.array(offset, dtype=float).reshape(-1)
        if r.shape != (A.shape[0],) or not np.all(np.isfinite(r)):
            raise ModelError(f"AffineReset offset must be finite of shape ({A.shape[0]},), got {r.shape}")
        self.matrix = A
        self.offset = r

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.matrix @ np.asarray(x, dtype=float) + self.offset

    def __repr__(self) -> str:
        return f"AffineReset({self.matrix.tolist()}, {self.offset.tolist()})"


# ---------------------------------------------------------------------------------------------
# Detection of coordinate guards and affine resets by probing.
# ---------------------------------------------------------------------------------------------
def _probe_points(dim: int, center: np.ndarray, rng: np.random.Generator, count: int) -> np.ndarray:
    # Three scales around the query point and around the origin, so that conjunction terms
    # active only far from the query point (the far side of a stop) are met too.
    scale = 1.0 + float(np.max(np.abs(center))) if center.size else 1.0
    out = []
    for k in range(count):
        c = center if k % 2 == 0 else np.zeros(dim)
        s = scale * (0.1, 1.0, 10.0)[k % 3]
        out.append(c + s * rng.standard_normal(dim))
    return np.array(out)


def _safe_float(fn: Callable, x: np.ndarray) -> float | None:
    try:
        with np.errstate(all="ignore"):
            v = float(np.asarray(fn(x), dtype=float).reshape(()))
    except Exception:
        return None
    return v if math.isfinite(v) else None


def _detect_coordinate_guard(guard: Callable, dim: int, center: np.ndarray) -> CoordinateGuard | None:
    declared = guard if isinstance(guard, CoordinateGuard) else None
    if declared is None:
        terms = getattr(guard, "coordinate_terms", None)
        if terms is not None:
            declared = CoordinateGuard(*terms)
    if declared is not None:
        if max(t[0] for t in declared.terms) >= dim:
            raise ModelError(f"{declared!r} refers to coordinate beyond dimension {dim}")
        return declared
    rng = np.random.default_rng(12345)
    found: list[tuple[int, float, float]] = []
    mixed = 0
    for x in _probe_points(dim, center, rng, 30):
        g = _safe_float(guard, x)
        if g is None:
            return None
        step = 1e-6 * (1.0 + float(np.max(np.abs(x))))
        grad = np.empty(dim)
        for i in range(dim):
            e = np.zeros(dim)
            e[i] = step
            gp, gm = _safe_float(guard, x + e), _safe_float(guard, x - e)
            if gp is None or gm is None:
                return None
            grad[i] = (gp - gm) / (2 * step)
        big = np.abs(grad) > 1e-7 * max(1.0, float(np.max(np.abs(grad))))
        if np.count_nonzero(big) != 1:
            mixed += 1  # a kink between the two probes, or not a coordinate guard at all
            if mixed > 3:
                return None
            continue
        i = int(np.argmax(big))
        s = float(grad[i])
        c = float(x[i] - g / s)
        for k, (j, s2, c2) in enumerate(found):
            if j == i and math.copysign(1.0, s2) == math.copysign(1.0, s):
                if abs(s2 - s) > 1e-5 * abs(s) or abs(c2 - c) > 1e-5 * (1.0 + abs(c)):
                    return None
                break
        else:
            if any(j == i for j, _, _ in found):
                return None
            found.append((i, s, c))
    if not found:
        return None
    candidate = CoordinateGuard(*found)
    candidate = _refine_terms(guard, candidate, dim, center, rng)
    if candidate is None:
        return None
    for x in _probe_points(dim, center, rng, 60):
        g = _safe_float(guard, x)
        if g is None or abs(candidate(x) - g) > 1e-9 * (1.0 + abs(g)):
            return None
    return candidate


def _snap(value: float) -> float:
    """Round a probed constant to 12 significant digits when that changes it by rounding error
    only, so that 0.9 or 14 come out exact (the probes see them to about 1e-13)."""
    rounded = float(f"{value:.12g}")
    return rounded if abs(rounded - value) <= 1e-11 * (1.0 + abs(value)) else value


def _refine_terms(guard: Callable, candidate: CoordinateGuard, dim: int, center: np.ndarray,
                  rng: np.random.Generator) -> CoordinateGuard | None:
    """Exact slopes from secants over long steps where one term stays active (the guard is
    affine there), then the offset from one value: finite differences alone give 1e-10."""
    terms = []
    points = _probe_points(dim, center, rng, 60)
    for k, (i, s, c) in enumerate(candidate.terms):
        for x in points:
            values = [s2 * (x[j] - c2) for j, s2, c2 in candidate.terms]
            others = max((v for m, v in enumerate(values) if m != k), default=-math.inf)
            margin = values[k] - others
            if margin <= 0.0:
                continue
            delta = min(0.25 * margin / abs(s), 1e-2 * (1.0 + abs(float(x[i]))))
            e = np.zeros(dim)
            e[i] = delta
            gp, g0, gm = _safe_float(guard, x + e), _safe_float(guard, x), _safe_float(guard, x - e)
            if gp is None or g0 is None or gm is None:
                return None
            s_exact = _snap((gp - gm) / (2 * delta))
            if s_exact == 0.0:
                return None
            terms.append((i, s_exact, _snap(float(x[i]) - g0 / s_exact)))
            break
        else:
            terms.append((i, _snap(s), _snap(c)))
    return CoordinateGuard(*terms)


def _detect_affine_reset(reset: Callable | None, n_in: int, n_out: int,
                         center: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    if reset is None:
        return np.eye(n_in), np.zeros(n_in)
    if isinstance(reset, AffineReset):
        return reset.matrix, reset.offset
    rng = np.random.default_rng(54321)
    x0 = center.copy() if center.shape == (n_in,) else np.zeros(n_in)
    try:
        with np.errstate(all="ignore"):
            r0 = np.asarray(reset(x0), dtype=float)
            step = 1e-3 * (1.0 + float(np.max(np.abs(x0))))
            A = np.empty((n_out, n_in))
            for i in range(n_in):
                e = np.zeros(n_in)
                e[i] = step
                A[:, i] = (np.asarray(reset(x0 + e), dtype=float) - np.asarray(reset(x0 - e), dtype=float)) / (2 * step)
            r = r0 - A @ x0
            if not (np.all(np.isfinite(A)) and np.all(np.isfinite(r))):
                return None
            for x in _probe_points(n_in, x0, rng, 24):
                y = np.asarray(reset(x), dtype=float)
                if y.shape != (n_out,) or not np.all(np.isfinite(y)):
                    return None
                if np.max(np.abs(A @ x + r - y)) > 1e-8 * (1.0 + np.max(np.abs(y)) + np.max(np.abs(x))):
                    return None
    except Exception:
        return None
    snap = np.vectorize(_snap, otypes=[float])
    return snap(A), snap(r)


# ---------------------------------------------------------------------------------------------
# Geometry of one system: guard pieces, resets, the transition graph (cached per system).
# ---------------------------------------------------------------------------------------------
@dataclass
class _Piece:
    """A convex-or-not piece of a guard set: a box (lb == ub on a fixed coordinate) plus, for
    guards of unknown shape, the equality g(p) = 0 and inequalities h(p) >= 0."""

    lb: np.ndarray
    ub: np.ndarray
    eq: tuple[Callable, Callable] | None  # (g, grad g)
    ineqs: tuple[tuple[Callable, Callable], ...]

    @property
    def boxed(self) -> bool:
        return self.eq is None and not self.ineqs

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(x, self.lb), self.ub)

    def feasible(self, p: np.ndarray, tol: float) -> bool:
        if self.eq is not None and abs(self.eq[0](p)) > tol:
            return False
        return all(h(p) >= -tol for h, _ in self.ineqs)


def _fd_gradient(fn: Callable) -> Callable:
    def grad(p: np.ndarray) -> np.ndarray:
        n = len(p)
        out = np.empty(n)
        step = 1e-7 * (1.0 + float(np.max(np.abs(p))))
        for i in range(n):
            e = np.zeros(n)
            e[i] = step
            out[i] = (float(fn(p + e)) - float(fn(p - e))) / (2 * step)
        return out
    return grad


def _fd_jacobian(fn: Callable, n_out: int) -> Callable:
    def jac(p: np.ndarray) -> np.ndarray:
        n = len(p)
        out = np.empty((n_out, n))
        step = 1e-7 * (1.0 + float(np.max(np.abs(p))))
        for i in range(n):
            e = np.zeros(n)
            e[i] = step
            out[:, i] = (np.asarray(fn(p + e), dtype=float) - np.asarray(fn(p - e), dtype=float)) / (2 * step)
        return out
    return jac


@dataclass
class _Edge:
    """One transition as the metric sees it."""

    tr: Transition
    source: str
    target: str
    pieces: list[_Piece]
    reset: Callable[[np.ndarray], np.ndarray]
    affine: tuple[np.ndarray, np.ndarray] | None
    jacobian: Callable[[np.ndarray], np.ndarray]
    n_source: int
    n_target: int

    #: Extreme singular values of an affine reset's matrix (None otherwise): a non-contracting
    #: reset makes "cross, move, cross back" pointless on the target side, a non-expanding one
    #: on the source side (the chord on the other side is never longer).
    sigma: tuple[float, float] | None = None


@dataclass(frozen=True)
class _HalfEdge:
    edge: _Edge
    forward: bool  # True: from edge.source to edge.target (in = p, out = R(p))

    @property
    def here(self) -> str:
        return self.edge.source if self.forward else self.edge.target

    @property
    def there(self) -> str:
        return self.edge.target if self.forward else self.edge.source


class _Geometry:
    """Per-system cache: guard pieces, reset models, adjacency (both directions)."""

    def __init__(self, system: HybridSystem) -> None:
        self.system = system
        self.n_modes = -1
        self.edges: list[_Edge] = []
        self.adjacent: dict[str, list[_HalfEdge]] = {}
        self._coordinate: dict[int, CoordinateGuard | None] = {}

    def ensure(self, modes: Iterable[str]) -> None:
        """Build (or rebuild, when a lazily expanded system has grown) the transition graph over
        every mode reachable from the known ones: reverse crossings need all incoming edges."""
        wanted = [m for m in modes if m not in self.adjacent]
        if not wanted and len(self.system.modes) == self.n_modes:
            return
        self._build(reachable_modes(self.system, list(self.system.modes) + wanted))

    def _coordinate_shape(self, tr: Transition, dim: int) -> CoordinateGuard | None:
        key = id(tr)
        if key not in self._coordinate:
            self._coordinate[key] = _detect_coordinate_guard(tr.guard, dim, np.zeros(dim))
        return self._coordinate[key]

    def _build(self, modes: list[str]) -> None:
        system = self.system
        dims = {m: system.mode(m).dim for m in modes}
        self.adjacent = {m: [] for m in modes}
        edges = []
        for mode in modes:
            outgoing = system.outgoing(mode)
            shapes = [self._coordinate_shape(tr, dims[mode]) for tr in outgoing]
            for k, tr in enumerate(outgoing):
                n = dims[mode]
                # Domain of `mode`: every other guard >= 0 (bounds when single-term coordinate).
                lb0, ub0 = np.full(n, -np.inf), np.full(n, np.inf)
                ineqs = []
                for f, (other, shape) in enumerate(zip(outgoing, shapes)):
                    if f == k:
                        continue
                    if shape is not None and len(shape.terms) == 1:
                        i, s, c = shape.terms[0]
                        if s > 0:
                            lb0[i] = max(lb0[i], c)
                        else:
                            ub0[i] = min(ub0[i], c)
                    else:
                        if other.guard_gradient is not None:
                            grad = other.guard_gradient
                        elif shape is not None:
                            grad = _coordinate_gradient(shape)
                        else:
                            grad = _fd_gradient(other.guard)
                        ineqs.append((_as_float_fn(other.guard), grad))
                pieces = []
                shape = shapes[k]
                if shape is not None:
                    for i, _, c in shape.terms:
                        lb, ub = lb0.copy(), ub0.copy()
                        for j, s2, c2 in shape.terms:
                            if j == i:
                                continue
                            if s2 > 0:  # s2 (x_j - c2) <= 0
                                ub[j] = min(ub[j], c2)
                            else:
                                lb[j] = max(lb[j], c2)
                        if not (lb[i] <= c <= ub[i]) or np.any(lb > ub):
                            continue  # this piece lies outside the domain
                        lb[i] = ub[i] = c
                        pieces.append(_Piece(lb, ub, None, tuple(ineqs)))
                else:
                    grad = tr.guard_gradient or _fd_gradient(tr.guard)
                    pieces.append(_Piece(lb0, ub0, (_as_float_fn(tr.guard), grad), tuple(ineqs)))
                n_target = dims[tr.target]
                affine = _detect_affine_reset(tr.reset, n, n_target, np.zeros(n))
                reset = tr.reset if tr.reset is not None else (lambda x: np.array(x, dtype=float))
                if affine is not None and (tr.reset is None or isinstance(tr.reset, AffineReset)):
                    A = affine[0]
                    jac = lambda p, A=A: A  # noqa: E731
                elif tr.reset_jacobian is not None:
                    jac = tr.reset_jacobian
                elif affine is not None:
                    A = affine[0]
                    jac = lambda p, A=A: A  # noqa: E731
                else:
                    jac = _fd_jacobian(reset, n_target)
                sigma = None
                if affine is not None:
                    sv = np.linalg.svd(affine[0], compute_uv=False)
                    sigma = (float(sv.min()) if n_target >= n else 0.0, float(sv.max()))
                    if tr.target == mode:
                        # A self-loop crossing where the reset is the identity (the artefact
                        # piece {v = 0, x >= x_max} of a stop) only adds eps: never shortest.
                        pieces = [p for p in pieces if not _identity_on(affine, p)]
                edge = _Edge(tr, mode, tr.target, pieces, reset, affine, jac, n, n_target, sigma)
                edges.append(edge)
                self.adjacent[mode].append(_HalfEdge(edge, True))
                self.adjacent[tr.target].append(_HalfEdge(edge, False))
        self.edges = edges
        self.n_modes = len(system.modes)


def _identity_on(affine: tuple[np.ndarray, np.ndarray], piece: _Piece) -> bool:
    A, r = affine
    if A.shape[0] != A.shape[1] or not piece.boxed:
        return False
    free = piece.lb < piece.ub
    D = A - np.eye(len(A))
    base = np.where(free, 0.0, piece.lb)
    return bool(np.all(np.abs(D[:, free]) <= 1e-14) and np.all(np.abs(D @ base + r) <= 1e-14 * (1 + np.abs(r))))


def _as_float_fn(fn: Callable) -> Callable[[np.ndarray], float]:
    return lambda p: float(fn(p))


def _coordinate_gradient(shape: CoordinateGuard) -> Callable:
    def grad(p: np.ndarray) -> np.ndarray:
        best, arg = -math.inf, 0
        for k, (i, s, c) in enumerate(shape.terms):
            v = s * (p[i] - c)
            if v > best:
                best, arg = v, k
        out = np.zeros(len(p))
        i, s, _ = shape.terms[arg]
        out[i] = s
        return out
    return grad


_GEOMETRY: "weakref.WeakKeyDictionary[HybridSystem, _Geometry]" = weakref.WeakKeyDictionary()


def _geometry(system: HybridSystem) -> _Geometry:
    geo = _GEOMETRY.get(system)
    if geo is None:
        geo = _Geometry(system)
        _GEOMETRY[system] = geo
    return geo


# ---------------------------------------------------------------------------------------------
# Projections: distance from a point to the entry / exit set of one piece of a crossing.
# ---------------------------------------------------------------------------------------------
def _slsqp(fun: Callable, z0: np.ndarray, lb: np.ndarray, ub: np.ndarray, constraints: list,
           ftol: float, maxiter: int = 200, converged: list | None = None) -> np.ndarray | None:
    bounds = [(None if not math.isfinite(lo) else lo, None if not math.isfinite(hi) else hi)
              for lo, hi in zip(lb, ub)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            try:
                res = minimize(fun, z0, jac=True, method="SLSQP", bounds=bounds, constraints=constraints,
                               options={"ftol": ftol, "maxiter": maxiter})
            except Exception:  # noqa: BLE001 - a model function failed at a probed point (e.g.
                # a robot whose guard refuses states where the body is below ground): this
                # start yields no path, the others still may.
                return None
    z = np.asarray(res.x, dtype=float)
    if converged is not None:
        converged.append(bool(res.success))
    return z if np.all(np.isfinite(z)) else None


def _piece_constraints(piece: _Piece, free: np.ndarray, full: Callable[[np.ndarray], np.ndarray]) -> list:
    cons = []
    if piece.eq is not None:
        g, dg = piece.eq
        cons.append({"type": "eq", "fun": lambda z: g(full(z)), "jac": lambda z: dg(full(z))[free]})
    for h, dh in piece.ineqs:
        cons.append({"type": "ineq", "fun": lambda z, h=h: h(full(z)), "jac": lambda z, dh=dh: dh(full(z))[free]})
    return cons


def _generic_starts(piece: _Piece, s0: np.ndarray) -> list[np.ndarray]:
    """Starting points for a local search on a guard of unknown shape: the given point, its
    Newton step onto g = 0, then (used only when these fail, e.g. where the guard's gradient
    vanishes as at the centre of a circular guard) points moved along each coordinate."""
    starts = [s0]
    if piece.eq is not None:
        g, dg = piece.eq
        try:
            value, grad = g(s0), np.asarray(dg(s0), dtype=float)
        except Exception:
            value, grad = math.nan, np.zeros(len(s0))
        norm2 = float(grad @ grad)
        if math.isfinite(value) and norm2 > 0.0 and np.all(np.isfinite(grad)):
            starts.append(piece.clip(s0 - value * grad / norm2))
    return starts


def _axis_starts(piece: _Piece, s0: np.ndarray) -> list[np.ndarray]:
    radius = 1.0 + float(np.max(np.abs(s0)))
    out = []
    for i in np.nonzero(piece.lb < piece.ub)[0]:
        for sign in (1.0, -1.0):
            e = np.zeros(len(s0))
            e[i] = sign * radius
            out.append(piece.clip(s0 + e))
    return out


def _local_min(piece: _Piece, fun: Callable[[np.ndarray], tuple[float, np.ndarray]], s0: np.ndarray, tol: float,
               scale: float) -> np.ndarray | None:
    """Best feasible local minimum of fun(p) over the piece (SLSQP from a few starts)."""
    free = np.nonzero(piece.lb < piece.ub)[0]
    best, best_value = None, math.inf
    for group in (_generic_starts(piece, s0), _axis_starts(piece, s0)):
        for start in group:
            base = start.copy()

            def full(z: np.ndarray, base=base) -> np.ndarray:
                p = base.copy()
                p[free] = z
                return p

            z = _slsqp(lambda z, full=full: _restrict(fun(full(z)), free), start[free], piece.lb[free],
                       piece.ub[free], _piece_constraints(piece, free, full), ftol=1e-14 * scale, maxiter=60)
            if z is None:
                continue
            p = piece.clip(full(z))
            if not piece.feasible(p, tol):
                continue
            value = fun(p)[0]
            if value < best_value:
                best, best_value = p, value
            break  # a converged local search from the nearest start is the projection we want
        if best is not None:
            break
    return best


def _restrict(value_grad: tuple[float, np.ndarray], free: np.ndarray) -> tuple[float, np.ndarray]:
    return value_grad[0], value_grad[1][free]


def _project_onto_piece(piece: _Piece, x: np.ndarray, tol: float) -> tuple[float, np.ndarray] | None:
    """Nearest point of the piece to x (exact for a box, local SLSQP otherwise)."""
    p0 = piece.clip(x)
    if piece.boxed or (piece.eq is None and piece.feasible(p0, tol)):
        return float(np.linalg.norm(p0 - x)), p0

    def fun(p: np.ndarray) -> tuple[float, np.ndarray]:
        d = p - x
        return float(d @ d), 2.0 * d

    p = _local_min(piece, fun, p0, tol, 1.0 + float(x @ x))
    return None if p is None else (float(np.linalg.norm(p - x)), p)


def _box_least_squares(A: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """argmin |A z - b| over lo <= z <= hi (a convex QP): closed form for one variable; else the
    unconstrained solution when it is feasible (then optimal), else bounded-variable LSQ."""
    if A.shape[1] == 1:
        a = A[:, 0]
        aa = float(a @ a)
        z = float(a @ b) / aa if aa > 0.0 else 0.0
        return np.array([min(max(z, lo[0]), hi[0])])
    z = np.linalg.lstsq(A, b, rcond=None)[0]
    if np.all(z >= lo) and np.all(z <= hi):
        return z
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-14).x


def _project_onto_image(edge: _Edge, piece: _Piece, x: np.ndarray, tol: float) -> tuple[float, np.ndarray] | None:
    """Guard point p of the piece minimising |R(p) - x| (exact for affine R on a box)."""
    free = np.nonzero(piece.lb < piece.ub)[0]
    base = piece.clip(np.zeros(edge.n_source))
    if edge.affine is not None:
        A, r = edge.affine
        rhs = x - r - A @ base
        if free.size == 0:
            p = base
        elif piece.boxed:
            p = base.copy()
            p[free] = _box_least_squares(A[:, free], rhs, piece.lb[free], piece.ub[free])
            p = piece.clip(p)
            return float(np.linalg.norm(edge.reset(p) - x)), p
        else:
            sol = np.linalg.lstsq(A[:, free], rhs, rcond=None)[0]
            p = base.copy()
            p[free] = sol
            p = piece.clip(p)
    else:
        p = piece.clip(x if x.shape == (edge.n_source,) else base)
    if free.size == 0:
        return (float(np.linalg.norm(edge.reset(p) - x)), p) if piece.feasible(p, tol) else None

    def fun(q: np.ndarray) -> tuple[float, np.ndarray]:
        d = np.asarray(edge.reset(q), dtype=float) - x
        return float(d @ d), 2.0 * (edge.jacobian(q).T @ d)

    q = _local_min(piece, fun, p, tol, 1.0 + float(x @ x))
    return None if q is None else (float(np.linalg.norm(np.asarray(edge.reset(q), dtype=float) - x)), q)


def _set_distance_bound(edge: _Edge, piece: _Piece, x: np.ndarray, guard_side: bool, tol: float) -> float:
    """Lower bound of the distance from x to the guard piece (guard_side) or to its reset image,
    used only to prune walks. Exact for coordinate pieces (with affine resets on the image side).
    For guards of unknown shape a projection would be a local minimisation as costly as the walk
    itself, so a cautious first-order estimate is used instead: about |g(x)| / |grad g| on the
    guard side (``_first_order_offset``);
    on the image side, for an affine reset, the distance from x to the reset's range combined
    with sigma_min times the guard offset of the least-squares preimage; 0 otherwise (no pruning).
    """
    if piece.boxed and (guard_side or edge.affine is not None):
        res = _project_onto_piece(piece, x, tol) if guard_side else _project_onto_image(edge, piece, x, tol)
        return math.inf if res is None else res[0]
    if guard_side:
        if piece.eq is None:
            return float(np.linalg.norm(piece.clip(x) - x))  # the box alone: a superset
        return _first_order_offset(piece, x)
    if edge.affine is None or piece.eq is None:
        return 0.0
    A, r = edge.affine
    pre = np.linalg.lstsq(A, x - r, rcond=None)[0]
    off_range = float(np.linalg.norm(A @ pre + r - x))
    smallest = float(edge.sigma[0]) if edge.sigma is not None else 0.0
    return math.hypot(off_range, smallest * _first_order_offset(piece, pre))


def _first_order_offset(piece: _Piece, x: np.ndarray) -> float:
    """A cautious estimate of the distance from x to {g = 0}: |g(x)| over the larger gradient
    norm at x and at its Newton point, halved. |g| / |grad g| alone overestimates where the
    gradient grows towards the guard (1 - |x|^2 seen from near the centre of the disk)."""
    g, dg = piece.eq  # type: ignore[misc]
    try:
        value, grad = float(g(x)), np.asarray(dg(x), dtype=float)
        norm = float(np.linalg.norm(grad))
        if not (math.isfinite(value) and math.isfinite(norm)) or norm == 0.0:
            return 0.0
        far = float(np.linalg.norm(np.asarray(dg(x - value * grad / (norm * norm)), dtype=float)))
    except Exception:  # noqa: BLE001 - the model refused the probe: no estimate, no pruning
        return 0.0
    if math.isfinite(far):
        norm = max(norm, far)
    return 0.5 * abs(value) / norm


# ---------------------------------------------------------------------------------------------
# One walk: minimise the path length over its guard points.
# ---------------------------------------------------------------------------------------------
def _walk_length(hops: Sequence[tuple[_HalfEdge, _Piece]], points: Sequence[np.ndarray],
                 x: np.ndarray, y: np.ndarray) -> float:
    total = 0.0
    cur = x
    for (he, _), p in zip(hops, points):
        rp = np.asarray(he.edge.reset(p), dtype=float)
        entry, exit_ = (p, rp) if he.forward else (rp, p)
        total += float(np.linalg.norm(entry - cur))
        cur = exit_
    return total + float(np.linalg.norm(y - cur))


def _chain(hops, x: np.ndarray, y: np.ndarray, tol: float, backward: bool) -> list[np.ndarray] | None:
    """Greedy guard points: each the projection of the previous point (forwards from x, or
    backwards from y). Always a valid path, and the start of the minimisation."""
    points: list[np.ndarray | None] = [None] * len(hops)
    order = range(len(hops) - 1, -1, -1) if backward else range(len(hops))
    cur = y if backward else x
    for i in order:
        he, piece = hops[i]
        onto_guard = he.forward != backward  # the point we come from meets p itself
        res = _project_onto_piece(piece, cur, tol) if onto_guard else _project_onto_image(he.edge, piece, cur, tol)
        if res is None:
            return None
        p = res[1]
        points[i] = p
        cur = np.asarray(he.edge.reset(p), dtype=float) if onto_guard else p
    return points  # type: ignore[return-value]


def _optimise_walk(hops, x: np.ndarray, y: np.ndarray, tol: float) -> tuple[float, list[np.ndarray]] | None:
    starts = [c for c in (_chain(hops, x, y, tol, False), _chain(hops, x, y, tol, True)) if c is not None]
    if not starts:
        return None
    scored = sorted(((_walk_length(hops, pts, x, y), pts) for pts in starts), key=lambda s: s[0])
    best_len, best_pts = scored[0]
    convex = all(he.edge.affine is not None and piece.boxed for he, piece in hops)
    frees = [np.nonzero(piece.lb < piece.ub)[0] for _, piece in hops]
    if sum(len(f) for f in frees) == 0 or best_len == 0.0:
        return best_len, best_pts
    offsets = np.cumsum([0] + [len(f) for f in frees])

    def unpack(z: np.ndarray, template: list[np.ndarray]) -> list[np.ndarray]:
        pts = []
        for k, (free, p0) in enumerate(zip(frees, template)):
            p = p0.copy()
            p[free] = z[offsets[k]:offsets[k + 1]]
            pts.append(p)
        return pts

    def objective(z: np.ndarray, template: list[np.ndarray]) -> tuple[float, np.ndarray]:
        pts = unpack(z, template)
        grads = [np.zeros(len(p)) for p in pts]
        total = 0.0
        cur, cur_jac, cur_k = x, None, -1
        for k, ((he, _), p) in enumerate(zip(hops, pts)):
            rp = np.asarray(he.edge.reset(p), dtype=float)
            J = he.edge.jacobian(p)
            entry, exit_ = (p, rp) if he.forward else (rp, p)
            entry_jac, exit_jac = (None, J) if he.forward else (J, None)
            total += _add_leg(entry - cur, grads, k, entry_jac, cur_k, cur_jac)
            cur, cur_jac, cur_k = exit_, exit_jac, k
        total += _add_leg(y - cur, grads, -1, None, cur_k, cur_jac)
        return total, np.concatenate([g[f] for g, f in zip(grads, frees)])

    lb = np.concatenate([piece.lb[f] for (_, piece), f in zip(hops, frees)])
    ub = np.concatenate([piece.ub[f] for (_, piece), f in zip(hops, frees)])
    scale = 1.0 + float(np.linalg.norm(x)) + float(np.linalg.norm(y))
    if convex and len(lb) == 1:
        template = [p.copy() for p in best_pts]
        z0 = float(np.concatenate([p[f] for p, f in zip(template, frees)])[0])
        length = lambda z: _walk_length(hops, unpack(np.array([z]), template), x, y)  # noqa: E731
        z = _golden_convex(length, z0, best_len, float(lb[0]), float(ub[0]), 1e-13 * scale)
        pts = unpack(np.array([z]), template)
        value = _walk_length(hops, pts, x, y)
        return (value, pts) if value < best_len else (best_len, best_pts)
    if convex:
        # SLSQP is fast and exact where the sum of norms is smooth at the minimum; where a leg
        # shrinks to zero length there (a kink) it stalls, and the barrier method takes over.
        template = [p.copy() for p in best_pts]
        z0 = np.concatenate([p[f] for p, f in zip(template, frees)])
        converged: list[bool] = []
        z = _slsqp(lambda z: objective(z, template), z0, lb, ub, [], ftol=1e-14 * scale, maxiter=100,
                   converged=converged)
        smooth = False
        if z is not None and converged and converged[0]:
            legs_at = _leg_residuals(hops, unpack(z, template), x, y)
            # Trusted only at a stationary point: SLSQP also reports convergence where its line
            # search stalls just beside a kink (a leg 1e-3 long, the gradient still ~1 there),
            # which a test on the legs' lengths alone took for smooth.
            grad = objective(z, template)[1]
            grad = np.where(((z <= lb) & (grad > 0.0)) | ((z >= ub) & (grad < 0.0)), 0.0, grad)
            smooth = (min(float(np.linalg.norm(v)) for v in legs_at) > 1e-6 * scale
                      and float(np.linalg.norm(grad)) <= 1e-6)
        candidates = [] if z is None else [z]
        if not smooth:
            legs = _affine_legs(lambda zz: _leg_residuals(hops, unpack(zz, template), x, y), len(z0))
            candidates.append(_sum_of_norms(legs, z0, lb, ub, scale))
        for zc in candidates:
            pts = [piece.clip(p) for (_, piece), p in zip(hops, unpack(zc, template))]
            value = _walk_length(hops, pts, x, y)
            if value < best_len:
                best_len, best_pts = value, pts
        return best_len, best_pts
    # Guards or resets of unknown shape: one local search from the better greedy chain (each
    # evaluation may cost a contact solve; the result is a path that exists, maybe not the
    # shortest, see the module docstring).
    for start_len, start in scored[:1]:
        template = [p.copy() for p in start]
        cons = []
        for k, (_, piece) in enumerate(hops):
            sl = slice(offsets[k], offsets[k + 1])
            full = (lambda z, k=k, sl=sl, template=template: _put(template[k], frees[k], z[sl]))
            for c in _piece_constraints(piece, frees[k], full):
                inner_jac = c["jac"]
                c["jac"] = (lambda z, inner_jac=inner_jac, sl=sl, n=len(lb): _embed(inner_jac(z), sl, n))
                cons.append(c)
        z0 = np.concatenate([p[f] for p, f in zip(start, frees)])
        z = _slsqp(lambda z, template=template: objective(z, template), z0, lb, ub, cons,
                   ftol=1e-12 * scale, maxiter=100)
        if z is None:
            continue
        pts = [piece.clip(p) for (_, piece), p in zip(hops, unpack(z, template))]
        if not all(piece.feasible(p, tol) for (_, piece), p in zip(hops, pts)):
            continue
        length = _walk_length(hops, pts, x, y)
        if length < best_len:
            best_len, best_pts = length, pts
    return best_len, best_pts


def _leg_residuals(hops, points: Sequence[np.ndarray], x: np.ndarray, y: np.ndarray) -> list[np.ndarray]:
    """The vectors whose norms add up to a walk's length (each entry minus the previous exit)."""
    out = []
    cur = x
    for (he, _), p in zip(hops, points):
        rp = np.asarray(he.edge.reset(p), dtype=float)
        entry, exit_ = (p, rp) if he.forward else (rp, p)
        out.append(entry - cur)
        cur = exit_
    out.append(y - cur)
    return out


def _affine_legs(residuals: Callable[[np.ndarray], list[np.ndarray]], q: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each leg of a convex walk as (M_k, c_k), residual M_k z - c_k (columns exact: affine)."""
    base = residuals(np.zeros(q))
    cols = [residuals(np.eye(q)[i]) for i in range(q)]
    return [(np.column_stack([cols[i][k] - base[k] for i in range(q)]), -base[k]) for k in range(len(base))]


def _sum_of_norms(legs: list[tuple[np.ndarray, np.ndarray]], z0: np.ndarray, lb: np.ndarray, ub: np.ndarray,
                  scale: float) -> np.ndarray:
    """Minimise sum_k |M_k z - c_k| over the box lb <= z <= ub (convex): a primal log-barrier
    method on the second-order-cone form, minimise sum_k t_k subject to t_k >= |M_k z - c_k|.

    The barrier -log(t_k^2 - |r_k|^2) - log(z - lb) - log(ub - z) keeps the iterates inside,
    where everything is smooth, so legs that shrink to zero length at the minimum (kinks of
    the sum of norms, on which SLSQP stalls short of the minimum) need no special care. Stops
    when the duality gap, (2 K + number of finite bounds) / weight, is below 1e-11 * scale.
    """
    M = np.vstack([m for m, _ in legs])
    c = np.concatenate([cc for _, cc in legs])
    sizes = np.array([len(cc) for _, cc in legs])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    row_leg = np.repeat(np.arange(len(legs)), sizes)
    q, K = len(z0), len(legs)
    has_lb, has_ub = np.isfinite(lb), np.isfinite(ub)
    lbz, ubz = np.where(has_lb, lb, 0.0), np.where(has_ub, ub, 0.0)
    width = np.where(has_lb & has_ub, ub - lb, np.inf)
    inset = np.minimum(1e-3 * scale, 0.25 * width)
    z = np.clip(z0, np.where(has_lb, lb + inset, -np.inf), np.where(has_ub, ub - inset, np.inf))
    r = M @ z - c
    t = np.sqrt(np.add.reduceat(r * r, starts)) + 1e-2 * scale
    degree = 2 * K + int(has_lb.sum()) + int(has_ub.sum())
    n = q + K
    diag = np.arange(q)
    H = np.empty((n, n))

    def phi(z: np.ndarray, t: np.ndarray, weight: float) -> float:
        if t.min() <= 0.0:  # t^2 > |r|^2 holds on the negative nappe of the cone too
            return math.inf
        r = M @ z - c
        s = t * t - np.add.reduceat(r * r, starts)
        if s.min() <= 0.0:
            return math.inf
        dl, du = (z - lbz)[has_lb], (ubz - z)[has_ub]
        if (dl.size and dl.min() <= 0.0) or (du.size and du.min() <= 0.0):
            return math.inf
        return weight * float(t.sum()) - float(np.log(s).sum() + np.log(dl).sum() + np.log(du).sum())

    weight = degree / float(t.sum())
    with np.errstate(all="ignore"):
        while True:
            f = phi(z, t, weight)
            for _ in range(30):
                r = M @ z - c
                s = t * t - np.add.reduceat(r * r, starts)
                a = np.add.reduceat(M * r[:, None], starts)  # row k: M_k^T r_k
                inv_s = 1.0 / s
                inv_s2 = inv_s * inv_s
                g = np.empty(n)
                g[:q] = 2.0 * (a.T @ inv_s)
                g[q:] = weight - 2.0 * t * inv_s
                H[:q, :q] = 4.0 * (a.T * inv_s2) @ a + 2.0 * (M.T * inv_s[row_leg]) @ M
                H[:q, q:] = -4.0 * a.T * (t * inv_s2)
                H[q:, :q] = H[:q, q:].T
                H[q:, q:] = np.diag(4.0 * t * t * inv_s2 - 2.0 * inv_s)
                if has_lb.any():
                    dl = np.where(has_lb, z - lbz, 1.0)
                    g[:q] -= np.where(has_lb, 1.0 / dl, 0.0)
                    H[diag, diag] += np.where(has_lb, 1.0 / (dl * dl), 0.0)
                if has_ub.any():
                    du = np.where(has_ub, ubz - z, 1.0)
                    g[:q] += np.where(has_ub, 1.0 / du, 0.0)
                    H[diag, diag] += np.where(has_ub, 1.0 / (du * du), 0.0)
                # A walk can have a flat direction (a reset that forgets a coordinate): damp it,
                # or the iterates drift along it to where rounding eats the digits.
                H[np.arange(n), np.arange(n)] += 1e-12 * float(np.max(np.abs(np.diag(H))))
                try:
                    step = -np.linalg.solve(H, g)
                except np.linalg.LinAlgError:
                    step = -g
                decrement = -float(g @ step)
                if not decrement > 1e-8:  # centred (the gap bound needs no more)
                    break
                alpha = 1.0
                while alpha > 1e-12:
                    f_new = phi(z + alpha * step[:q], t + alpha * step[q:], weight)
                    if f_new <= f - 0.25 * alpha * decrement:
                        break
                    alpha *= 0.5
                else:
                    break
                z, t, f = z + alpha * step[:q], t + alpha * step[q:], f_new
            if degree / weight <= 1e-11 * scale:
                break
            weight *= 50.0
    return np.clip(z, lb, ub)


def _golden_convex(f: Callable[[float], float], z0: float, f0: float, lo: float, hi: float, tol: float) -> float:
    """Minimise a convex function of one variable on [lo, hi] from z0 with f(z0) = f0.

    The bracket grows from z0 until f rises on each side (by convexity the minimiser is then
    inside), then golden-section search shrinks it to ``tol``: robust at kinks, where the
    minimiser of a sum of norms often sits and where quasi-Newton methods crawl.
    """
    ends = []
    for direction, limit in ((-1.0, lo), (1.0, hi)):
        step = max(1.0, abs(z0), f0)
        end = z0
        while (end - limit) * direction < 0.0:
            end = z0 + direction * step
            end = max(end, limit) if direction < 0 else min(end, limit)
            if end == limit or f(end) > f0 or step > 1e12 * max(1.0, abs(z0), f0):
                break
            step *= 4.0
        ends.append(end)
    a, b = ends
    invphi = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - invphi * (b - a), a + invphi * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - invphi * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + invphi * (b - a)
            fd = f(d)
    return c if fc <= fd else d


def _put(template: np.ndarray, free: np.ndarray, values: np.ndarray) -> np.ndarray:
    p = template.copy()
    p[free] = values
    return p


def _embed(grad: np.ndarray, sl: slice, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[sl] = grad
    return out


def _add_leg(d: np.ndarray, grads: list[np.ndarray], k_entry: int, entry_jac, k_exit: int, exit_jac) -> float:
    """Add |d| with d = entry(p_{k_entry}) - exit(p_{k_exit}) and its gradient."""
    norm = float(np.linalg.norm(d))
    if norm == 0.0:
        return 0.0  # a leg of zero length: the subgradient 0 is admissible
    u = d / norm
    if k_entry >= 0:
        grads[k_entry] += u if entry_jac is None else entry_jac.T @ u
    if k_exit >= 0:
        grads[k_exit] -= u if exit_jac is None else exit_jac.T @ u
    return norm


# ---------------------------------------------------------------------------------------------
# Public results.
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Crossing:
    """One identification used by a shortest path: transition ``name`` crossed from ``start``
    mode to ``end`` mode (``forward`` when start is the transition's source) at guard point
    ``point`` (source coordinates; the other side is ``reset(point)``)."""

    name: str
    start: str
    end: str
    forward: bool
    point: np.ndarray


@dataclass(frozen=True)
class MetricPath:
    """A shortest connected path found by ``shortest_path``.

    ``length`` is the distance; ``crossings`` the transitions crossed in order (empty for the
    direct chord); ``strip_legs`` the length travelled inside strips at the two ends (for strip
    points); ``eps`` the strip width used.
    """

    length: float
    crossings: tuple[Crossing, ...]
    eps: float
    strip_legs: float = 0.0

    @property
    def hops(self) -> int:
        return len(self.crossings)


# ---------------------------------------------------------------------------------------------
# Input checks.
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Point:
    mode: str
    x: np.ndarray
    strip: str | None = None  # transition name when the point lies in that transition's strip
    tau: float = 0.0


def _check_eps(eps: Any) -> float:
    if isinstance(eps, bool) or not isinstance(eps, (int, float, np.floating, np.integer)):
        raise MetricError(f"eps must be a number >= 0 (strip width, guard units), got {type(eps).__name__} {eps!r}")
    eps = float(eps)
    if not math.isfinite(eps) or eps < 0.0:
        raise MetricError(f"eps must be finite and >= 0 (strip width, guard units), got {eps}")
    return eps


def _check_hops(max_hops: Any) -> int:
    if isinstance(max_hops, bool) or not isinstance(max_hops, (int, np.integer)) or max_hops < 0:
        raise MetricError(f"max_hops must be an integer >= 0, got {max_hops!r}")
    return int(max_hops)


def _check_point(system: HybridSystem, point: Any, eps: float, label: str) -> _Point:
    if isinstance(point, _Point):
        return point
    if not isinstance(point, (tuple, list)) or len(point) not in (2, 4):
        raise MetricError(f"{label} must be (mode, x) or (mode, x, transition name, tau), got {point!r}")
    mode = point[0]
    if not isinstance(mode, str):
        raise MetricError(f"{label}: mode must be a mode name (str), got {mode!r}")
    try:
        dim = system.mode(mode).dim
    except ModelError:
        raise MetricError(f"{label}: unknown mode '{mode}' of {system.name} (modes: {sorted(system.modes)})") from None
    try:
        x = np.array(point[1], dtype=float)
    except (TypeError, ValueError) as exc:
        raise MetricError(f"{label}: state in mode '{mode}' is not a numeric vector: {exc}") from None
    if x.shape != (dim,):
        raise MetricError(f"{label}: state in mode '{mode}' has shape {x.shape}, expected ({dim},) "
                          f"with coordinates {system.state_names(mode)}")
    if not np.all(np.isfinite(x)):
        raise MetricError(f"{label}: state in mode '{mode}' is not finite: {x.tolist()}")
    if len(point) == 2:
        return _Point(mode, x)
    name, tau = point[2], point[3]
    names = [tr.name for tr in system.outgoing(mode)]
    if name not in names:
        raise MetricError(f"{label}: '{name}' is not a transition leaving mode '{mode}' (those are {names})")
    if isinstance(tau, bool) or not isinstance(tau, (int, float, np.floating, np.integer)) \
            or not math.isfinite(float(tau)) or not 0.0 <= float(tau) <= eps:
        raise MetricError(f"{label}: strip coordinate tau must be a number in [0, eps={eps:g}], got {tau!r}")
    return _Point(mode, x, str(name), float(tau))


# ---------------------------------------------------------------------------------------------
# The distance.
# ---------------------------------------------------------------------------------------------
class _Search:
    """One distance evaluation between two domain points, with its projection cache."""

    def __init__(self, geo: _Geometry, eps: float, max_hops: int) -> None:
        self.geo = geo
        self.eps = eps
        self.max_hops = max_hops

    def run(self, a: _Point, b: _Point, bound: float = math.inf) -> tuple[float, tuple[Crossing, ...]]:
        x, y = a.x, b.x
        best = float(np.linalg.norm(x - y)) if a.mode == b.mode else math.inf
        best = min(best, bound)
        best_path: tuple[Crossing, ...] = ()
        eps = self.eps
        if best <= eps or self.max_hops == 0 or best == 0.0:
            return best, best_path
        scale = 1.0 + float(np.linalg.norm(x)) + float(np.linalg.norm(y))
        tol = 1e-9 * scale
        slack = 1e-12 * scale
        entry_cache: dict[tuple[int, bool, int], float] = {}
        exit_cache: dict[tuple[int, bool, int], float] = {}

        def entry_lb(he: _HalfEdge, k: int, piece: _Piece) -> float:
            key = (id(he.edge), he.forward, k)
            if key not in entry_cache:
                entry_cache[key] = _set_distance_bound(he.edge, piece, x, he.forward, tol)
            return entry_cache[key]

        def exit_lb(he: _HalfEdge, k: int, piece: _Piece) -> float:
            key = (id(he.edge), he.forward, k)
            if key not in exit_cache:
                exit_cache[key] = _set_distance_bound(he.edge, piece, y, not he.forward, tol)
            return exit_cache[key]

        def first_lb(he: _HalfEdge) -> float:
            return min((entry_lb(he, k, p) for k, p in enumerate(he.edge.pieces)), default=math.inf)

        # Enumerate walks from a.mode to b.mode, pruning prefixes whose bound already exceeds
        # the direct chord; then expand them into piece choices, each with its own bound.
        candidates: list[tuple[float, list[tuple[_HalfEdge, int]]]] = []
        adjacent = self.geo.adjacent
        stack: list[tuple[str, list[_HalfEdge], float]] = [(a.mode, [], 0.0)]
        while stack:
            mode, walk, lb_first = stack.pop()
            for he in adjacent.get(mode, ()):
                if walk and _dominated(walk[-1], he):
                    continue
                m = len(walk) + 1
                lbf = first_lb(he) if not walk else lb_first
                if m * eps + lbf >= best - slack:
                    continue
                new_walk = walk + [he]
                if he.there == b.mode:
                    for choice in itertools.product(*(range(len(h.edge.pieces)) for h in new_walk)):
                        first, last = new_walk[0], new_walk[-1]
                        lb = (m * eps + entry_lb(first, choice[0], first.edge.pieces[choice[0]])
                              + exit_lb(last, choice[-1], last.edge.pieces[choice[-1]]))
                        if lb < best - slack:
                            candidates.append((lb, list(zip(new_walk, choice))))
                if m < self.max_hops:
                    stack.append((he.there, new_walk, lbf))
        candidates.sort(key=lambda c: (c[0], len(c[1])))
        for lb, walk in candidates:
            if lb >= best - slack:
                break
            hops = [(he, he.edge.pieces[k]) for he, k in walk]
            try:
                with np.errstate(all="ignore"):
                    res = _optimise_walk(hops, x, y, tol)
            except (MetricError, ModelError):
                raise
            except Exception:  # noqa: BLE001 - a guard or reset failed at a probed guard point:
                continue  # this walk gives no path (the direct chord and other walks remain)
            if res is None:
                continue
            length = res[0] + len(hops) * eps
            if length < best:
                best = length
                best_path = tuple(
                    Crossing(he.edge.tr.name, he.here, he.there, he.forward, p.copy())
                    for (he, _), p in zip(hops, res[1]))
        return best, best_path


def _dominated(prev: _HalfEdge, nxt: _HalfEdge) -> bool:
    """Crossing an edge and straight back is never shorter than the chord that skips both
    crossings when the reset does not shrink distances on the far side."""
    if prev.edge is not nxt.edge or prev.forward == nxt.forward or prev.edge.sigma is None:
        return False
    lo, hi = prev.edge.sigma
    return lo >= 1.0 - 1e-12 if prev.forward else hi <= 1.0 + 1e-12


def _strip_options(geo: _Geometry, point: _Point, eps: float) -> list[tuple[float, _Point, Crossing | None]]:
    """A strip point reaches the domain at the guard end (length tau) or the reset end (eps - tau)."""
    if point.strip is None:
        return [(0.0, point, None)]
    edge = next(e for e in geo.edges if e.source == point.mode and e.tr.name == point.strip)
    image = np.asarray(edge.reset(point.x), dtype=float)
    return [(point.tau, _Point(point.mode, point.x), None),
            (eps - point.tau, _Point(edge.target, image),
             Crossing(edge.tr.name, edge.source, edge.target, True, point.x.copy()))]


def _shortest(system: HybridSystem, a: _Point, b: _Point, eps: float, max_hops: int) -> MetricPath:
    geo = _geometry(system)
    geo.ensure([a.mode, b.mode])
    search = _Search(geo, eps, max_hops)
    best = MetricPath(math.inf, (), eps)
    if a.strip is not None and b.strip is not None and a.strip == b.strip and a.mode == b.mode:
        # Inside one strip: the strip metric (12), |q - q'| + |tau - tau'| (chord along the guard).
        best = MetricPath(float(np.linalg.norm(a.x - b.x)) + abs(a.tau - b.tau), (), eps, abs(a.tau - b.tau))
    for ca, pa, cross_a in _strip_options(geo, a, eps):
        for cb, pb, cross_b in _strip_options(geo, b, eps):
            extra = ca + cb
            if extra >= best.length:
                continue
            length, crossings = search.run(pa, pb, best.length - extra)
            if length + extra < best.length:
                ends = tuple(c for c in (cross_a,) if c is not None) + crossings
                if cross_b is not None:
                    ends = ends + (Crossing(cross_b.name, cross_b.end, cross_b.start, False, cross_b.point),)
                best = MetricPath(length + extra, ends, eps, extra)
    return best


def shortest_path(system: HybridSystem, a: Any, b: Any, eps: float, *,
                  max_hops: int = DEFAULT_MAX_HOPS) -> MetricPath:
    """The shortest connected path between hybrid states ``a`` and ``b`` in M^eps (see
    ``distance``), with the transitions it crosses and its guard points."""
    if not isinstance(system, HybridSystem):
        raise MetricError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    eps = _check_eps(eps)
    max_hops = _check_hops(max_hops)
    pa = _check_point(system, a, eps, "a")
    pb = _check_point(system, b, eps, "b")
    return _shortest(system, pa, pb, eps, max_hops)


def distance(system: HybridSystem, a: Any, b: Any, eps: float, *, max_hops: int = DEFAULT_MAX_HOPS) -> float:
    """Relaxed quotient-space distance between two hybrid states (paper 000, Defs. 5, 15, 19).

    Parameters
    ----------
    system: the hybrid system.
    a, b: ``(mode, x)`` with x of shape (n_mode,), a point of the domain of ``mode``; or
        ``(mode, x, transition_name, tau)``, a point of the strip of that transition (x its guard
        point, tau in [0, eps] the transverse coordinate, tau = eps being the reset image).
    eps: strip width (guard units) >= 0; 0 gives the unrelaxed distance on M.
    max_hops: most transition crossings searched (each costs eps); 0 gives the Euclidean
        distance within one mode and inf across modes.

    Returns
    -------
    float
        The length (state units plus eps per crossing) of the shortest connected path found;
        ``inf`` when no path of at most ``max_hops`` crossings joins the two modes. Exact for
        coordinate-hyperplane guards with affine resets and convex domains; see the module
        docstring for the other cases.

    Raises
    ------
    MetricError
        for an unknown mode, a state of the wrong shape or not finite, eps < 0 or max_hops < 0.
    """
    return shortest_path(system, a, b, eps, max_hops=max_hops).length


# ---------------------------------------------------------------------------------------------
# Distances between executions.
# ---------------------------------------------------------------------------------------------
def _check_times(times: Any) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(times, dtype=float))
    except (TypeError, ValueError) as exc:
        raise MetricError(f"times must be a 1-d sequence of numbers (s): {exc}") from None
    if arr.ndim != 1 or arr.size == 0:
        raise MetricError(f"times must be a non-empty 1-d sequence (s), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MetricError("times must be finite")
    return arr


def _sample(execution: Any, times: np.ndarray, label: str):
    sample = getattr(execution, "sample", None)
    if not callable(sample):
        raise MetricError(f"{label} must have a sample(times) -> Samples method "
                          f"(a legsim Execution or a reference), got {type(execution).__name__}")
    samples = sample(times)
    modes, states = getattr(samples, "modes", None), getattr(samples, "states", None)
    if modes is None or states is None or len(modes) != len(times) or len(states) != len(times):
        raise MetricError(f"{label}.sample(times) must return Samples with one mode and state per time")
    return samples


def _strip_taus(execution: Any, samples: Any, eps: float) -> list[tuple[str, float] | None]:
    """For each sample inside a strip: (transition name, tau). tau grows linearly from 0 at the
    strip entry to the landing depth at the landing time, then at unit rate to eps at the exit,
    as in paper 000 Fig. 12 step 12 (a curve continuous in M^eps at both ends)."""
    n = len(samples.times)
    out: list[tuple[str, float] | None] = [None] * n
    in_strip = getattr(samples, "in_strip", None)
    strips = getattr(execution, "strips", None)
    if in_strip is None or strips is None or not np.any(in_strip):
        return out
    records = {(tr.name, tr.time): tr for tr in getattr(execution, "transitions", ())}
    starts = np.array([s.time for s in strips])
    for i in np.nonzero(in_strip)[0]:
        t = float(samples.times[i])
        k = int(np.searchsorted(starts, t, side="right")) - 1
        if k < 0:
            continue
        strip = strips[k]
        rec = records.get((strip.name, strip.time))
        if rec is not None:
            if t <= rec.landing_time:
                span = rec.landing_time - rec.time
                tau = rec.depth if span <= 0 else rec.depth * (t - rec.time) / span
            else:
                tau = rec.depth + (t - rec.landing_time)
        else:
            tau = t - strip.time  # the run ended inside this strip: its landing was not kept
        out[i] = (strip.name, min(max(tau, 0.0), eps))
    return out


def _points(system: HybridSystem, execution: Any, times: np.ndarray, eps: float, label: str) -> list[_Point]:
    samples = _sample(execution, times, label)
    taus = _strip_taus(execution, samples, eps)
    points = []
    for i, (mode, x) in enumerate(zip(samples.modes, samples.states)):
        st = taus[i]
        where = f"{label} at t={times[i]:.12g}"
        if st is None:
            points.append(_check_point(system, (mode, x), eps, where))
        else:
            points.append(_check_point(system, (mode, x, st[0], st[1]), eps, where))
    return points


def distances(system: HybridSystem, execution_a: Any, execution_b: Any, times: Any, eps: float, *,
              max_hops: int = DEFAULT_MAX_HOPS) -> np.ndarray:
    """``distance`` between the two executions at each of ``times`` (s); shape (len(times),).

    Each execution is anything with ``sample(times) -> Samples`` (modes, states, optionally
    in_strip): a legsim ``Execution`` (whose strip samples are placed in their strip with the
    transverse coordinate of paper 000 Fig. 12) or an analytic reference.
    """
    if not isinstance(system, HybridSystem):
        raise MetricError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    eps = _check_eps(eps)
    max_hops = _check_hops(max_hops)
    t = _check_times(times)
    pa = _points(system, execution_a, t, eps, "execution_a")
    pb = _points(system, execution_b, t, eps, "execution_b")
    out = np.empty(len(t))
    for i, (p, q) in enumerate(zip(pa, pb)):
        if p.strip is None and q.strip is None and p.mode == q.mode:
            d0 = float(np.linalg.norm(p.x - q.x))
            if d0 <= eps or max_hops == 0:  # no crossing can be shorter than one strip width
                out[i] = d0
                continue
        out[i] = _shortest(system, p, q, eps, max_hops).length
    return out


def rho(system: HybridSystem, execution_a: Any, execution_b: Any, times: Any, eps: float, *,
        max_hops: int = DEFAULT_MAX_HOPS) -> float:
    """rho^eps of paper 000 Definition 22: the supremum over ``times`` (s) of the relaxed
    quotient distance between the two executions (each anything with ``sample(times)``).

    The supremum is taken over the given sample times; pass times dense enough for the
    execution's time scale (and include the transition times if the extremum matters).
    """
    return float(np.max(distances(system, execution_a, execution_b, times, eps, max_hops=max_hops)))


def trajectory_space_distance(execution_a: Any, execution_b: Any, times: Any) -> float:
    """A trajectory-space comparison that charges mode mismatch, for contrast with ``rho``.

    sup over ``times`` of ``|x_a(t) - x_b(t)| + [mode_a(t) != mode_b(t)]``: the discrete
    metric on modes plus the Euclidean one on states, the form of the trajectory metrics paper
    000 cites ([1]-[4]), which separate states in different modes by at least 1. No time
    reparametrisation is minimised over: a Skorohod time change can shrink the Euclidean part
    but cannot align two different mode sequences (0->1->3 against 0->2->3), so the charge of
    1 stays. States of different dimensions are infinitely far apart.
    """
    t = _check_times(times)
    sa = _sample(execution_a, t, "execution_a")
    sb = _sample(execution_b, t, "execution_b")
    worst = 0.0
    for ma, xa, mb, xb in zip(sa.modes, sa.states, sb.modes, sb.states):
        xa, xb = np.asarray(xa, dtype=float), np.asarray(xb, dtype=float)
        if xa.shape != xb.shape:
            return math.inf
        worst = max(worst, float(np.linalg.norm(xa - xb)) + (0.0 if ma == mb else 1.0))
    return worst


def position_error(simulated: Any, reference: Any, times: Any, *, coordinate: int | str = 0) -> float:
    """Position-only error of paper 000 eq. (30): ``max_k |z_pos(t_k) - x(t_k)|``.

    Parameters
    ----------
    simulated: positions at ``times`` (array of shape (len(times),)), e.g. from a method that
        computes positions only (Paoli-Schatzman), or anything with ``sample(times)``.
    reference: anything with ``sample(times)``, or a callable ``reference(times) -> positions``.
    times: the sample times t_k (s), inside both executions' intervals.
    coordinate: index of the position in the state, or its name (looked up in the
        ``state_names`` of whichever argument has them, per mode).
    """
    t = _check_times(times)
    names = next((n for n in (getattr(simulated, "state_names", None), getattr(reference, "state_names", None))
                  if isinstance(n, dict)), None)
    zs = _positions(simulated, t, coordinate, "simulated", names)
    xs = _positions(reference, t, coordinate, "reference", names)
    return float(np.max(np.abs(zs - xs)))


def _positions(obj: Any, t: np.ndarray, coordinate: int | str, label: str,
               names: dict[str, Sequence[str]] | None) -> np.ndarray:
    if hasattr(obj, "sample") and callable(obj.sample):
        samples = _sample(obj, t, label)
        out = np.empty(len(t))
        for i, (mode, x) in enumerate(zip(samples.modes, samples.states)):
            x = np.asarray(x, dtype=float)
            if isinstance(coordinate, str):
                mode_names = tuple(names.get(mode, ())) if isinstance(names, dict) else ()
                if coordinate not in mode_names:
                    raise MetricError(f"{label}: no coordinate named '{coordinate}' in mode '{mode}' "
                                      f"(names: {mode_names or 'unknown'})")
                idx = mode_names.index(coordinate)
            else:
                idx = coordinate
            if isinstance(idx, bool) or not isinstance(idx, (int, np.integer)) or not -len(x) <= idx < len(x):
                raise MetricError(f"{label}: coordinate {coordinate!r} is not an index of the {len(x)}-d state "
                                  f"in mode '{mode}'")
            out[i] = x[idx]
        return out
    if callable(obj):
        values = obj(t)
    else:
        values = obj
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise MetricError(f"{label} positions must be numbers: {exc}") from None
    if arr.shape != t.shape:
        raise MetricError(f"{label} gives {arr.size} positions for {t.size} times")
    if not np.all(np.isfinite(arr)):
        raise MetricError(f"{label} positions must be finite")
    return arr
