"""Explicit Runge-Kutta methods as data (Butcher tableaux) and the one step routine they share.

Each method is a ``Tableau``: nodes ``c``, matrix ``A`` (strictly lower triangular), weights
``b`` of the propagated solution and, for embedded pairs, ``b_err = b - b_hat`` whose
combination of stages is the local error estimate. ``rk_step`` serves every tableau with a
preallocated stage array, so no method has code of its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field as dc_field
from typing import Any, Callable

import numpy as np

from .errors import SimulationError


@dataclass(frozen=True, eq=False)
class DenseOutput:
    """Continuous extension (dense output) of a Runge-Kutta step of size h from (t, x):

        x(t + theta h) = x + h sum_i w_i(theta) k_i,   w_i(theta) = sum_j P[i, j] theta^(j + 1),

    over the step's s stages followed by m extra stages (theta in [0, 1]). Taken at one theta it
    is itself an explicit Runge-Kutta step of size theta h, of order ``order``.

    Attributes
    ----------
    order: order of the interpolant (local error O(h^(order + 1))).
    P: (s + m, degree) polynomial weights.
    c_extra: (m,) nodes of the extra stages (empty when the interpolant is free).
    A_extra: (m, s + m) their stage weights (row i over the stages before it).
    """

    order: int
    P: np.ndarray
    c_extra: np.ndarray = dc_field(default_factory=lambda: np.zeros(0))
    A_extra: np.ndarray = dc_field(default_factory=lambda: np.zeros((0, 0)))


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of an explicit Runge-Kutta method.

    Attributes
    ----------
    name: short name used by ``simulate(method=...)``.
    order: order of the propagated solution.
    c, A, b: nodes (s,), matrix (s, s) and weights (s,).
    b_err: weights of the local error estimate (s,), or None when the method has no
        embedded pair.
    error_order: order of the embedded (lower-order) solution, when there is one.
    fsal: the last stage is f at the new point (First Same As Last), so the next step
        reuses it and saves one field evaluation.
    b_err_low: a second, lower-order error estimate that the error norm blends with b_err as
        Hairer's DOP853 does (``err5^2 / sqrt(err5^2 + 0.01 err3^2)``), or None.
    dense: the method's continuous extension, when it has one (``landing="dense"``); the
        built-in bs32 and dopri5 have theirs through ``dense_output``, loaded on first use.
    """

    name: str
    order: int
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    b_err: np.ndarray | None = None
    error_order: int | None = None
    fsal: bool = False
    dense: DenseOutput | None = None
    b_err_low: np.ndarray | None = None

    @property
    def stages(self) -> int:
        """Number of stages s."""
        return len(self.b)

    @property
    def embedded(self) -> bool:
        """True when the method carries a local error estimate."""
        return self.b_err is not None


def _tableau(name: str, order: int, c, A, b, b_hat=None, error_order=None, fsal=False,
             dense: DenseOutput | None = None) -> Tableau:
    c_arr = np.array(c, dtype=float)
    s = len(c_arr)
    A_arr = np.zeros((s, s))
    for i, row in enumerate(A):
        A_arr[i, : len(row)] = row
    b_arr = np.array(b, dtype=float)
    b_err = None if b_hat is None else b_arr - np.array(b_hat, dtype=float)
    # Consistency checks that catch a mistyped coefficient at import time.
    assert np.allclose(A_arr.sum(axis=1), c_arr), name
    assert abs(b_arr.sum() - 1.0) < 1e-14, name
    return Tableau(name, order, c_arr, A_arr, b_arr, b_err, error_order, fsal, dense)


_BUILTIN_DENSE: dict[str, DenseOutput] = {}


def dense_output(tableau: Tableau) -> DenseOutput | None:
    """The continuous extension of ``tableau``: its own ``dense``, or for the built-in bs32 and
    dopri5 the free interpolants scipy's RK23 and RK45 use (Bogacki-Shampine's cubic Hermite,
    Shampine's quartic for Dormand-Prince: the same stages in the same order), loaded on first
    use so that importing legsim does not import scipy."""
    if tableau.dense is not None:
        return tableau.dense
    if tableau.name not in ("bs32", "dopri5") or METHODS.get(tableau.name) is not tableau:
        return None
    if tableau.name not in _BUILTIN_DENSE:
        from scipy.integrate import RK23, RK45

        cls, order = {"bs32": (RK23, 3), "dopri5": (RK45, 4)}[tableau.name]
        assert cls.P.shape[0] == tableau.stages
        _BUILTIN_DENSE[tableau.name] = DenseOutput(order, np.array(cls.P, dtype=float))
    return _BUILTIN_DENSE[tableau.name]


EULER = _tableau("euler", 1, [0.0], [[]], [1.0])
MIDPOINT = _tableau("rk2", 2, [0.0, 0.5], [[], [0.5]], [0.0, 1.0])
HEUN = _tableau("heun", 2, [0.0, 1.0], [[], [1.0]], [0.5, 0.5])
RK4 = _tableau(
    "rk4",
    4,
    [0.0, 0.5, 0.5, 1.0],
    [[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6],
)
BOGACKI_SHAMPINE = _tableau(
    "bs32",
    3,
    [0.0, 0.5, 0.75, 1.0],
    [[], [0.5], [0.0, 0.75], [2 / 9, 1 / 3, 4 / 9]],
    [2 / 9, 1 / 3, 4 / 9, 0.0],
    b_hat=[7 / 24, 1 / 4, 1 / 3, 1 / 8],
    error_order=2,
    fsal=True,
)
DORMAND_PRINCE = _tableau(
    "dopri5",
    5,
    [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0],
    [
        [],
        [1 / 5],
        [3 / 40, 9 / 40],
        [44 / 45, -56 / 15, 32 / 9],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
        [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    ],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0],
    b_hat=[5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40],
    error_order=4,
    fsal=True,
)

METHODS: dict[str, Tableau] = {
    t.name: t for t in (EULER, MIDPOINT, HEUN, RK4, BOGACKI_SHAMPINE, DORMAND_PRINCE)
}
ALIASES = {"midpoint": "rk2", "rk45": "dopri5", "dp54": "dopri5", "rk23": "bs32"}


def get_method(method: str | Tableau) -> Tableau:
    """Look a method up by name (``euler``, ``rk2``/``midpoint``, ``heun``, ``rk4``, ``bs32``,
    ``dopri5``) or pass a ``Tableau`` through."""
    if isinstance(method, Tableau):
        return method
    if not isinstance(method, str):
        raise SimulationError(f"method must be a name or a Tableau, got {type(method).__name__}")
    key = ALIASES.get(method.lower(), method.lower())
    if key not in METHODS:
        raise SimulationError(f"unknown method '{method}'; choose one of {sorted(METHODS) + sorted(ALIASES)}")
    return METHODS[key]


def rk_step(
    field: Callable[[float, np.ndarray, Any], np.ndarray],
    t: float,
    x: np.ndarray,
    h: float,
    tableau: Tableau,
    K: np.ndarray,
    control: Callable[[float, np.ndarray], Any] | None = None,
) -> np.ndarray:
    """One explicit Runge-Kutta step of size ``h`` from ``(t, x)``.

    ``K`` is the preallocated stage array, shape (s, n); on entry ``K[0]`` must hold
    ``f(t, x, u(t, x))`` (the caller computes it once per state and reuses it across retried
    step sizes); on exit it holds all stages, so ``K.T @ tableau.b_err`` is the local error
    estimate (times h) and, for FSAL methods, ``K[-1]`` is f at the new point.
    The control is sampled at each stage, ``u = control(t + c_i h, x_i)``, so that a
    time-varying input keeps the method's order. Returns the new state (a new array).
    """
    A = tableau.A
    c = tableau.c
    for i in range(1, tableau.stages):
        xi = x + h * (A[i, :i] @ K[:i])
        ti = t + c[i] * h
        K[i] = field(ti, xi, None if control is None else control(ti, xi))
    return x + h * (tableau.b @ K)


def _tableau_key(tableau: Tableau) -> tuple:
    return (tableau.name, tableau.fsal, tableau.c.tobytes(), tableau.A.tobytes(), tableau.b.tobytes(),
            None if tableau.b_err is None else tableau.b_err.tobytes())


_GENERATED: dict[tuple, Callable[..., Any]] = {}


def make_stepper(tableau: Tableau) -> Callable[..., tuple[np.ndarray, tuple[np.ndarray, ...]]]:
    """A step function specialised to ``tableau``: ``step(field, t, x, h, k0, control) ->
    (x_new, stages)``, with ``stages`` the tuple of the s stage derivatives (``stages[0] is k0``).

    The stage combinations are generated as straight-line code with the tableau's non-zero
    coefficients folded in, because in Python the per-step cost of a general ``A @ K`` loop
    (slicing, small matrix products, stage copies) is several times that of the few array
    operations the method really needs. ``rk_step`` is the readable reference it is tested
    against. Generated once per tableau (compiling the source costs more than a short run).
    """
    key = ("step",) + _tableau_key(tableau)
    if key not in _GENERATED:
        _GENERATED[key] = _generate_stepper(tableau)
    return _GENERATED[key]


#: A tableau with a row of at least this many non-zero weights keeps its stages stacked, and
#: combines every row of at least ``_DOT_ROW`` terms by one matrix product: a product costs
#: about three array operations, a sum two per term (DOP853: 25 us a step instead of 44 us,
#: field excluded, n = 6). The built-in methods stay below ``_DOT_TERMS``, so their
#: arithmetic, which the compiled kernel reproduces bit for bit, is unchanged.
_DOT_TERMS = 7
_DOT_ROW = 3


def _generate_stepper(tableau: Tableau) -> Callable[..., Any]:
    s = tableau.stages
    weights = [tableau.A[i, :i] for i in range(1, s)] + ([] if tableau.fsal else [tableau.b])
    stacked = any(np.count_nonzero(w) >= _DOT_TERMS for w in weights)
    namespace: dict[str, Any] = {"empty": np.empty}
    lines = ["def step(field, t, x, h, k0, control):"]
    if stacked:
        lines += [f"    K = empty(({s}, x.shape[0]))", "    K[0] = k0"]

    def combination(w: np.ndarray, i: int) -> str:
        if stacked and np.count_nonzero(w) >= _DOT_ROW:
            namespace[f"W{i}"] = np.array(w, dtype=float)
            return f"x + h * (W{i} @ K[:{len(w)}])"
        return _combination("x", w)

    for i in range(1, s):
        lines.append(f"    t{i} = t + {float(tableau.c[i])!r} * h")
        lines.append(f"    x{i} = {combination(tableau.A[i, :i], i)}")
        lines.append(f"    k{i} = field(t{i}, x{i}, None if control is None else control(t{i}, x{i}))")
        if stacked and i < s - 1:
            lines.append(f"    K[{i}] = k{i}")
    stage_tuple = ", ".join(f"k{j}" for j in range(s))
    if tableau.fsal:
        # The last stage is evaluated at the new point itself: reuse it instead of recombining.
        lines.append(f"    return x{s - 1}, ({stage_tuple},)")
    else:
        if stacked:
            lines.append(f"    K[{s - 1}] = k{s - 1}")
        lines.append(f"    return {combination(tableau.b, s)}, ({stage_tuple},)")
    exec("\n".join(lines), namespace)  # noqa: S102 - generated from the tableau's numbers only
    return namespace["step"]


def error_estimate(tableau: Tableau, h: float, stages: tuple[np.ndarray, ...]) -> np.ndarray:
    """Local error estimate h * sum_j b_err_j k_j of an embedded pair (shape (n,))."""
    if tableau.b_err is None:
        raise SimulationError(f"method '{tableau.name}' has no embedded error estimate; use bs32 or dopri5")
    acc = None
    for be, k in zip(tableau.b_err, stages):
        if be != 0.0:
            acc = be * k if acc is None else acc + be * k
    return h * acc


def make_error_norm(tableau: Tableau) -> Callable[..., float]:
    """``norm(h, stages, x, x_new, rtol, atol) -> float``: the RMS norm of the local error
    estimate scaled by ``atol + rtol max(|x|, |x_new|)`` (Hairer's, and scipy's, error norm).

    Generated as straight-line code like the stepper; the plain norm's arithmetic is that of
    ``error_estimate`` and ``np.mean`` (same order of operations), so the compiled kernel's
    norm, which mimics those, takes the same step decisions to the bit. The blended norm sums
    by matrix products, which the kernel matches to rounding only.
    """
    if tableau.b_err is None:
        raise SimulationError(f"method '{tableau.name}' has no embedded error estimate; use bs32 or dopri5")
    key = ("norm",) + _tableau_key(tableau) + (None if tableau.b_err_low is None else tableau.b_err_low.tobytes(),)
    if key not in _GENERATED:
        namespace: dict[str, Any] = {"maximum": np.maximum, "absolute": np.absolute, "add_reduce": np.add.reduce,
                                     "sqrt": math.sqrt, "stack": np.array}
        scale = "(atol + rtol * maximum(absolute(x), absolute(x_new)))"
        if tableau.b_err_low is None:
            terms = [f"{float(w)!r} * k{j}" for j, w in enumerate(tableau.b_err) if w != 0.0]
            lines = ["def norm(h, stages, x, x_new, rtol, atol):",
                     f"    {', '.join(f'k{j}' for j in range(tableau.stages))}, = stages",
                     f"    r = (h * ({' + '.join(terms)})) / {scale}",
                     "    return sqrt(float(add_reduce(r * r)) / r.shape[0])"]
        else:
            # Hairer's DOP853 norm: the fifth-order estimate, damped where the third-order one is
            # much larger (so that a step is not rejected for an estimate that is itself poor).
            namespace["E"], namespace["E_LOW"] = np.array(tableau.b_err), np.array(tableau.b_err_low)
            lines = ["def norm(h, stages, x, x_new, rtol, atol):",
                     "    K = stack(stages)",
                     f"    scale = {scale}",
                     "    r = (h * (E @ K)) / scale",
                     "    r_low = (h * (E_LOW @ K)) / scale",
                     "    high = float(r @ r)",
                     "    low = float(r_low @ r_low)",
                     "    if high == 0.0 and low == 0.0:",
                     "        return 0.0",
                     "    return high / sqrt((high + 0.01 * low) * r.shape[0])"]
        exec("\n".join(lines), namespace)  # noqa: S102 - generated from the tableau's numbers only
        _GENERATED[key] = namespace["norm"]
    return _GENERATED[key]


class ContinuousStep:
    """The dense output of one step of ``tableau`` (which must carry ``dense``): evaluates its
    extra stages, if any, once; then ``point(theta)`` and ``slope(theta)`` give x and dx/dt at
    t + theta h for theta in [0, 1].

    ``extra_evals`` is the number of field evaluations the extra stages cost.
    """

    def __init__(self, tableau: Tableau, field: Callable[..., np.ndarray], t: float, x: np.ndarray, h: float,
                 stages: tuple[np.ndarray, ...], control: Callable[[float, np.ndarray], Any] | None = None) -> None:
        dense = dense_output(tableau)
        if dense is None:
            raise SimulationError(f"method '{tableau.name}' has no dense output")
        K = np.empty((len(dense.P), len(x)))
        K[: len(stages)] = stages
        for i, (ci, row) in enumerate(zip(dense.c_extra, dense.A_extra)):
            s = len(stages) + i
            xi = x + h * (row[:s] @ K[:s])
            ti = t + float(ci) * h
            K[s] = field(ti, xi, None if control is None else control(ti, xi))
        self.extra_evals = len(dense.c_extra)
        self._x, self._h, self._K, self._P = x, h, K, dense.P
        self._powers = np.arange(1, dense.P.shape[1] + 1)

    def point(self, theta: float) -> np.ndarray:
        """x at t + theta h, shape (n,)."""
        w = self._P @ (theta ** self._powers)
        return self._x + self._h * (w @ self._K)

    def slope(self, theta: float) -> np.ndarray:
        """dx/dt at t + theta h, shape (n,)."""
        w = self._P @ (self._powers * theta ** (self._powers - 1))
        return w @ self._K


def _combination(base: str, weights: np.ndarray) -> str:
    """Source of ``base + h * sum_j w_j k_j`` with h folded into scalar factors and stages of
    equal weight summed first (RK4's b becomes two products instead of four)."""
    groups: dict[float, list[str]] = {}
    for j, w in enumerate(weights):
        if w != 0.0:
            groups.setdefault(float(w), []).append(f"k{j}")
    if not groups:
        return base
    terms = []
    for w, ks in groups.items():
        summed = ks[0] if len(ks) == 1 else "(" + " + ".join(ks) + ")"
        terms.append(f"(h * {w!r}) * {summed}")
    return base + " + " + " + ".join(terms)
