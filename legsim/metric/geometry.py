"""The geometry of one hybrid system as the metric sees it: guard sets cut into pieces, reset
models, and the transition graph in both directions (cached per system).

What a *guard point* is. Guards follow the legsim convention (``g >= 0`` inside, ``< 0`` past),
and "and" conditions are written with ``max``, e.g. a stop ``max(x_max - x, -v)``. The guard
set of a transition e leaving mode j is taken to be

    G_e = { p : g_e(p) = 0  and  g_f(p) >= 0 for every other transition f leaving j },

i.e. the part of the boundary of the domain D_j (where all guards are >= 0) on which e fires;
this is where the integrator applies the reset. For ``max(a(x), b(x))`` the set ``g = 0`` is the
union of ``{a = 0, b <= 0}`` and ``{b = 0, a <= 0}``; the second piece is an artefact of the
encoding (e.g. the stop's ``{v = 0, x >= x_max}``), harmless when the reset maps it to itself,
as the impact laws of the bundled systems do.

A coordinate guard (``legsim.metric.detect``) is split into pieces ``{x[i_k] = c_k,
s_l (x[i_l] - c_l) <= 0}``, each a box with one coordinate fixed, onto which projection is
exact. Any other guard is one piece: the equality ``g(p) = 0`` inside the box the mode's
single-term coordinate guards bound, with the mode's other guards ``>= 0`` as inequalities.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ..derivatives import gradient, jacobian
from ..graph import reachable_modes
from ..hybrid import HybridSystem, Transition
from .detect import detect_affine_reset, detect_coordinate_guard
from .shapes import AffineReset, CoordinateGuard

#: Relative central-difference step of the guard gradients and reset Jacobians a model does
#: not give: every coordinate moves by FD_STEP * (1 + max|p|), one absolute step for the whole
#: point, so that coordinates near 0 still get a step of the point's size.
FD_STEP = 1e-7

#: A pair (h, grad h) of a scalar function of a state and its gradient (shape (n,)).
ScalarWithGradient = tuple[Callable[[np.ndarray], float], Callable[[np.ndarray], np.ndarray]]


@dataclass
class Piece:
    """A piece of a guard set: the box ``lb <= p <= ub`` (shape (n,) each; ``lb == ub`` on a
    fixed coordinate) and, for guards of unknown shape, the equality g(p) = 0 (``eq``) and
    inequalities h(p) >= 0 (``ineqs``), each with its gradient."""

    lb: np.ndarray
    ub: np.ndarray
    eq: ScalarWithGradient | None
    ineqs: tuple[ScalarWithGradient, ...]

    @property
    def boxed(self) -> bool:
        """True when the piece is its box alone (projection onto it is exact)."""
        return self.eq is None and not self.ineqs

    @property
    def free(self) -> np.ndarray:
        """Indices of the coordinates that may vary on the piece."""
        return np.nonzero(self.lb < self.ub)[0]

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(x, self.lb), self.ub)

    def feasible(self, p: np.ndarray, tol: float) -> bool:
        if self.eq is not None and abs(self.eq[0](p)) > tol:
            return False
        return all(h(p) >= -tol for h, _ in self.ineqs)


@dataclass
class Edge:
    """One transition as the metric sees it: guard pieces (source coordinates), the reset, its
    affine model ``(A, r)`` when it has one, and its Jacobian (shape (n_target, n_source))."""

    tr: Transition
    source: str
    target: str
    pieces: list[Piece]
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
class HalfEdge:
    """A transition crossed one way: forwards from its source (enter at the guard point p,
    leave at R(p)) or backwards from its target (enter at R(p), leave at p)."""

    edge: Edge
    forward: bool

    @property
    def here(self) -> str:
        return self.edge.source if self.forward else self.edge.target

    @property
    def there(self) -> str:
        return self.edge.target if self.forward else self.edge.source

    def ends(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(entry, exit): where a path crossing at guard point p arrives and where it leaves."""
        rp = np.asarray(self.edge.reset(p), dtype=float)
        return (p, rp) if self.forward else (rp, p)


class Geometry:
    """Per-system cache: guard pieces, reset models, adjacency (both directions)."""

    def __init__(self, system: HybridSystem) -> None:
        self.system = system
        self.n_modes = -1
        self.edges: list[Edge] = []
        self.adjacent: dict[str, list[HalfEdge]] = {}
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
            self._coordinate[key] = detect_coordinate_guard(state_guard(tr), dim, np.zeros(dim))
        return self._coordinate[key]

    def _build(self, modes: list[str]) -> None:
        dims = {m: self.system.mode(m).dim for m in modes}
        adjacent: dict[str, list[HalfEdge]] = {m: [] for m in modes}
        edges = []
        for mode in modes:
            outgoing = self.system.outgoing(mode)
            shapes = [self._coordinate_shape(tr, dims[mode]) for tr in outgoing]
            for k, tr in enumerate(outgoing):
                domain = _domain_without(k, outgoing, shapes, dims[mode])
                edge = _make_edge(tr, mode, _guard_pieces(tr, shapes[k], *domain), dims[mode], dims[tr.target])
                edges.append(edge)
                adjacent[mode].append(HalfEdge(edge, True))
                adjacent[tr.target].append(HalfEdge(edge, False))
        self.adjacent, self.edges = adjacent, edges
        self.n_modes = len(self.system.modes)


_GEOMETRY: weakref.WeakKeyDictionary[HybridSystem, Geometry] = weakref.WeakKeyDictionary()


def geometry_of(system: HybridSystem) -> Geometry:
    """The cached geometry of ``system`` (built lazily: call ``ensure`` with the modes needed)."""
    geo = _GEOMETRY.get(system)
    if geo is None:
        geo = Geometry(system)
        _GEOMETRY[system] = geo
    return geo


def _domain_without(
    k: int, outgoing: Sequence[Transition], shapes: list[CoordinateGuard | None], n: int
) -> tuple[np.ndarray, np.ndarray, tuple[ScalarWithGradient, ...]]:
    """The domain of the mode as far as every guard but the k-th bounds it (each >= 0): a box
    (lb, ub) from single-term coordinate guards, inequalities from the others."""
    lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
    ineqs = []
    for f, (other, shape) in enumerate(zip(outgoing, shapes, strict=True)):
        if f == k:
            continue
        if shape is not None and len(shape.terms) == 1:
            i, s, c = shape.terms[0]
            if s > 0:
                lb[i] = max(lb[i], c)
            else:
                ub[i] = min(ub[i], c)
            continue
        if other.guard_gradient is not None:
            grad = other.guard_gradient
        elif shape is not None:
            grad = _coordinate_gradient(shape)
        else:
            grad = finite_difference_gradient(state_guard(other))
        ineqs.append((_as_float_fn(state_guard(other)), grad))
    return lb, ub, tuple(ineqs)


def state_guard(tr: Transition) -> Callable[[np.ndarray], float]:
    """The transition's guard as a function of the state alone: a guard of (t, x, u) (a mode's
    model functions) at t = 0 without input, where the quotient space's geometry is taken."""
    if tr.guard_args == "x" and tr.guard is not None:
        return tr.guard
    return lambda x: tr.guard_value(x)


def _guard_pieces(
    tr: Transition,
    shape: CoordinateGuard | None,
    lb0: np.ndarray,
    ub0: np.ndarray,
    ineqs: tuple[ScalarWithGradient, ...],
) -> list[Piece]:
    """The guard set of ``tr`` inside the domain: one box per term of a coordinate guard (that
    term's coordinate fixed, the other terms <= 0), else one piece with the equality g = 0."""
    if shape is None:
        grad = tr.guard_gradient or finite_difference_gradient(state_guard(tr))
        return [Piece(lb0, ub0, (_as_float_fn(state_guard(tr)), grad), ineqs)]
    pieces = []
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
        pieces.append(Piece(lb, ub, None, ineqs))
    return pieces


def _make_edge(tr: Transition, mode: str, pieces: list[Piece], n: int, n_target: int) -> Edge:
    affine = detect_affine_reset(tr.reset, n, n_target, np.zeros(n))
    reset = tr.reset if tr.reset is not None else (lambda x: np.array(x, dtype=float))
    sigma = None
    if affine is not None:
        sv = np.linalg.svd(affine[0], compute_uv=False)
        sigma = (float(sv.min()) if n_target >= n else 0.0, float(sv.max()))
        if tr.target == mode:
            # A self-loop crossing where the reset is the identity (the artefact piece
            # {v = 0, x >= x_max} of a stop) only adds eps: never shortest.
            pieces = [p for p in pieces if not _identity_on(affine, p)]
    return Edge(
        tr, mode, tr.target, pieces, reset, affine, _reset_jacobian(tr, affine, reset, n_target), n, n_target, sigma
    )


def _reset_jacobian(
    tr: Transition, affine: tuple[np.ndarray, np.ndarray] | None, reset: Callable, n_target: int
) -> Callable[[np.ndarray], np.ndarray]:
    """A declared affine matrix first (exact), then the model's own Jacobian, then a probed
    affine matrix, and finite differences last."""
    declared = tr.reset is None or isinstance(tr.reset, AffineReset)
    if affine is not None and (declared or tr.reset_jacobian is None):
        A = affine[0]
        return lambda p: A
    if tr.reset_jacobian is not None:
        return tr.reset_jacobian
    return finite_difference_jacobian(reset)


def _identity_on(affine: tuple[np.ndarray, np.ndarray], piece: Piece) -> bool:
    A, r = affine
    if A.shape[0] != A.shape[1] or not piece.boxed:
        return False
    free = piece.lb < piece.ub
    D = A - np.eye(len(A))
    base = np.where(free, 0.0, piece.lb)
    return bool(np.all(np.abs(D[:, free]) <= 1e-14) and np.all(np.abs(D @ base + r) <= 1e-14 * (1 + np.abs(r))))


def _as_float_fn(fn: Callable) -> Callable[[np.ndarray], float]:
    return lambda p: float(fn(p))


def _coordinate_gradient(shape: CoordinateGuard) -> Callable[[np.ndarray], np.ndarray]:
    """The gradient of a coordinate guard: that of its active (largest) term."""

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


def _fd_scale(p: np.ndarray) -> float:
    return 1.0 + float(np.max(np.abs(p)))


def finite_difference_gradient(fn: Callable[[np.ndarray], float]) -> Callable[[np.ndarray], np.ndarray]:
    """grad fn (shape (n,)) by central differences with the step ``FD_STEP * (1 + max|p|)``."""
    return lambda p: gradient(fn, p, step=FD_STEP, scale=_fd_scale(p))


def finite_difference_jacobian(fn: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """d fn / dp (shape (m, n)) by central differences with the step ``FD_STEP * (1 + max|p|)``."""
    return lambda p: jacobian(fn, p, step=FD_STEP, scale=_fd_scale(p))
