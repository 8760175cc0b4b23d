"""The distance between two hybrid points: the search over walks through the transition graph,
and the public ``distance`` and ``shortest_path``.

Within one mode the direct chord is an upper bound of the quotient distance, and a path
through transitions is searched for only when it could be shorter: each walk (a sequence of
crossings, at most ``max_hops``, with a choice of guard piece per crossing) has the lower bound
``m eps + dist(x_a, first entry set) + dist(x_b, last exit set)`` (exact for coordinate pieces,
a first-order estimate for other guards), and walks are solved (``legsim.metric.walk``) in
order of that bound until it exceeds the best length found. Crossing an edge and straight back
is skipped where the reset does not shrink distances on that side.

What the value is, exactly. The value returned is always the length of an explicit connected
path, so it is >= the distance of the "chord" quotient metric (straight chords inside each
mode); it equals it when the optimiser's minimum is global (coordinate guards with affine
resets) and ``max_hops`` crossings suffice. Inside one mode the distance is Euclidean. The
paper endows a domain with its *induced length* metric (Lemma 6), in which a curve must stay in
the domain: for a convex domain the two agree; for a non-convex one the chord may leave the
domain and the Euclidean value is then only a lower bound of the paper's domain distance. With
a cap of K crossings the triangle inequality that holds is d_2K(a, c) <= d_K(a, b) + d_K(b, c).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ModelError
from ..hybrid import HybridSystem
from .geometry import Geometry, HalfEdge, geometry_of
from .inputs import DEFAULT_MAX_HOPS, HybridPoint, MetricError, check_eps, check_hops, check_point, check_system
from .projection import set_distance_bound
from .walk import Hop, optimise_walk

#: A walk to solve: its crossings, each with the index of the guard piece crossed.
PieceWalk = list[tuple[HalfEdge, int]]


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


def shortest_path(system: HybridSystem, a: Any, b: Any, eps: float, *, max_hops: int = DEFAULT_MAX_HOPS) -> MetricPath:
    """The shortest connected path between hybrid states ``a`` and ``b`` in M^eps (see
    ``distance``), with the transitions it crosses and its guard points."""
    system = check_system(system)
    eps = check_eps(eps)
    max_hops = check_hops(max_hops)
    pa = check_point(system, a, eps, "a")
    pb = check_point(system, b, eps, "b")
    return path_between(system, pa, pb, eps, max_hops)


def path_between(system: HybridSystem, a: HybridPoint, b: HybridPoint, eps: float, max_hops: int) -> MetricPath:
    """``shortest_path`` between checked points: strip points leave their strip through either
    end (or stay in it), then the search joins the two domain points."""
    geo = geometry_of(system)
    geo.ensure([a.mode, b.mode])
    search = _Search(geo, eps, max_hops)
    best = MetricPath(math.inf, (), eps)
    if a.strip is not None and b.strip is not None and a.strip == b.strip and a.mode == b.mode:
        # Inside one strip: the strip metric (12), |q - q'| + |tau - tau'| (chord along the guard).
        best = MetricPath(float(np.linalg.norm(a.x - b.x)) + abs(a.tau - b.tau), (), eps, abs(a.tau - b.tau))
    for ca, pa, cross_a in _strip_exits(geo, a, eps):
        for cb, pb, cross_b in _strip_exits(geo, b, eps):
            extra = ca + cb
            if extra >= best.length:
                continue
            length, crossings = search.run(pa, pb, best.length - extra)
            if length + extra < best.length:
                ends = tuple(c for c in (cross_a,) if c is not None) + crossings
                if cross_b is not None:
                    ends = (*ends, Crossing(cross_b.name, cross_b.end, cross_b.start, False, cross_b.point))
                best = MetricPath(length + extra, ends, eps, extra)
    return best


def _strip_exits(geo: Geometry, point: HybridPoint, eps: float) -> list[tuple[float, HybridPoint, Crossing | None]]:
    """Where a point reaches a domain, at what length, through which crossing: a domain point
    is there already; a strip point reaches the guard end (length tau) or the reset end
    (eps - tau, crossing the transition)."""
    if point.strip is None:
        return [(0.0, point, None)]
    edge = next(e for e in geo.edges if e.source == point.mode and e.tr.name == point.strip)
    image = np.asarray(edge.reset(point.x), dtype=float)
    return [
        (point.tau, HybridPoint(point.mode, point.x), None),
        (
            eps - point.tau,
            HybridPoint(edge.target, image),
            Crossing(edge.tr.name, edge.source, edge.target, True, point.x.copy()),
        ),
    ]


def _dominated(prev: HalfEdge, nxt: HalfEdge) -> bool:
    """Crossing an edge and straight back is never shorter than the chord that skips both
    crossings when the reset does not shrink distances on the far side."""
    if prev.edge is not nxt.edge or prev.forward == nxt.forward or prev.edge.sigma is None:
        return False
    lo, hi = prev.edge.sigma
    return lo >= 1.0 - 1e-12 if prev.forward else hi <= 1.0 + 1e-12


class _EndBounds:
    """Lower bounds of the distance from x to each crossing's entry set and from y to each
    exit set (one per half-edge and piece), computed once per search."""

    def __init__(self, x: np.ndarray, y: np.ndarray, tol: float) -> None:
        self.x, self.y, self.tol = x, y, tol
        self._entry: dict[tuple[int, bool, int], float] = {}
        self._exit: dict[tuple[int, bool, int], float] = {}

    def entry(self, he: HalfEdge, k: int) -> float:
        key = (id(he.edge), he.forward, k)
        if key not in self._entry:
            self._entry[key] = set_distance_bound(he.edge, he.edge.pieces[k], self.x, he.forward, self.tol)
        return self._entry[key]

    def exit(self, he: HalfEdge, k: int) -> float:
        key = (id(he.edge), he.forward, k)
        if key not in self._exit:
            self._exit[key] = set_distance_bound(he.edge, he.edge.pieces[k], self.y, not he.forward, self.tol)
        return self._exit[key]

    def first(self, he: HalfEdge) -> float:
        """The bound for a walk starting with ``he``, whichever piece it crosses."""
        return min((self.entry(he, k) for k in range(len(he.edge.pieces))), default=math.inf)


class _Search:
    """Distance evaluations between domain points of one system, for one eps and hop cap."""

    def __init__(self, geo: Geometry, eps: float, max_hops: int) -> None:
        self.geo = geo
        self.eps = eps
        self.max_hops = max_hops

    def run(self, a: HybridPoint, b: HybridPoint, bound: float = math.inf) -> tuple[float, tuple[Crossing, ...]]:
        """(length, crossings) of the shortest path from a to b (domain points) shorter than
        ``bound``; (bound, ()) when none is."""
        x, y = a.x, b.x
        best = float(np.linalg.norm(x - y)) if a.mode == b.mode else math.inf
        best = min(best, bound)
        if best <= self.eps or self.max_hops == 0 or best == 0.0:
            return best, ()
        scale = 1.0 + float(np.linalg.norm(x)) + float(np.linalg.norm(y))
        tol = 1e-9 * scale
        slack = 1e-12 * scale
        walks = self._walks(a.mode, b.mode, _EndBounds(x, y, tol), best - slack)
        return self._solve(walks, x, y, tol, best, slack)

    def _walks(self, start: str, end: str, bounds: _EndBounds, limit: float) -> list[tuple[float, PieceWalk]]:
        """The walks from mode ``start`` to mode ``end`` (a piece chosen per crossing) whose
        lower bound is below ``limit``, by bound, then fewer crossings first. Prefixes whose
        bound already reaches the limit are pruned."""
        candidates: list[tuple[float, PieceWalk]] = []
        stack: list[tuple[str, list[HalfEdge], float]] = [(start, [], 0.0)]
        while stack:
            mode, walk, lb_first = stack.pop()
            for he in self.geo.adjacent.get(mode, ()):
                if walk and _dominated(walk[-1], he):
                    continue
                m = len(walk) + 1
                lbf = bounds.first(he) if not walk else lb_first
                if m * self.eps + lbf >= limit:
                    continue
                new_walk = [*walk, he]
                if he.there == end:
                    candidates += self._piece_choices(new_walk, bounds, limit)
                if m < self.max_hops:
                    stack.append((he.there, new_walk, lbf))
        candidates.sort(key=lambda c: (c[0], len(c[1])))
        return candidates

    def _piece_choices(self, walk: list[HalfEdge], bounds: _EndBounds, limit: float) -> list[tuple[float, PieceWalk]]:
        out = []
        first, last = walk[0], walk[-1]
        for choice in itertools.product(*(range(len(h.edge.pieces)) for h in walk)):
            lb = len(walk) * self.eps + bounds.entry(first, choice[0]) + bounds.exit(last, choice[-1])
            if lb < limit:
                out.append((lb, list(zip(walk, choice, strict=True))))
        return out

    def _solve(
        self, walks: list[tuple[float, PieceWalk]], x: np.ndarray, y: np.ndarray, tol: float, best: float, slack: float
    ) -> tuple[float, tuple[Crossing, ...]]:
        """The shortest of the walks, solved in order of their bounds until a bound reaches the
        best length found (which starts at ``best``)."""
        best_path: tuple[Crossing, ...] = ()
        for lb, walk in walks:
            if lb >= best - slack:
                break
            hops = [(he, he.edge.pieces[k]) for he, k in walk]
            res = _optimise_or_skip(hops, x, y, tol)
            if res is None:
                continue
            length = res[0] + len(hops) * self.eps
            if length < best:
                best = length
                best_path = tuple(
                    Crossing(he.edge.tr.name, he.here, he.there, he.forward, p.copy())
                    for (he, _), p in zip(hops, res[1], strict=True)
                )
        return best, best_path


def _optimise_or_skip(
    hops: list[Hop], x: np.ndarray, y: np.ndarray, tol: float
) -> tuple[float, list[np.ndarray]] | None:
    try:
        with np.errstate(all="ignore"):
            return optimise_walk(hops, x, y, tol)
    except (MetricError, ModelError):
        raise
    except Exception:  # a guard or reset failed at a probed guard point:
        return None  # this walk gives no path (the direct chord and other walks remain)
