"""Explicit Runge-Kutta methods as data (Butcher tableaux) and the one step routine they share.

Each method is a ``Tableau``: nodes ``c``, matrix ``A`` (strictly lower triangular), weights
``b`` of the propagated solution and, for embedded pairs, ``b_err = b - b_hat`` whose
combination of stages is the local error estimate. ``rk_step`` serves every tableau with a
preallocated stage array, so no method has code of its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .errors import SimulationError


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
    """

    name: str
    order: int
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    b_err: np.ndarray | None = None
    error_order: int | None = None
    fsal: bool = False

    @property
    def stages(self) -> int:
        """Number of stages s."""
        return len(self.b)

    @property
    def embedded(self) -> bool:
        """True when the method carries a local error estimate."""
        return self.b_err is not None


def _tableau(name: str, order: int, c, A, b, b_hat=None, error_order=None, fsal=False) -> Tableau:
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
    return Tableau(name, order, c_arr, A_arr, b_arr, b_err, error_order, fsal)


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


def make_stepper(tableau: Tableau) -> Callable[..., tuple[np.ndarray, tuple[np.ndarray, ...]]]:
    """A step function specialised to ``tableau``: ``step(field, t, x, h, k0, control) ->
    (x_new, stages)``, with ``stages`` the tuple of the s stage derivatives (``stages[0] is k0``).

    The stage combinations are generated as straight-line code with the tableau's non-zero
    coefficients folded in, because in Python the per-step cost of a general ``A @ K`` loop
    (slicing, small matrix products, stage copies) is several times that of the few array
    operations the method really needs. ``rk_step`` is the readable reference it is tested
    against.
    """
    s = tableau.stages
    lines = ["def step(field, t, x, h, k0, control):"]
    for i in range(1, s):
        lines.append(f"    t{i} = t + {float(tableau.c[i])!r} * h")
        lines.append(f"    x{i} = {_combination('x', tableau.A[i, :i])}")
        lines.append(f"    k{i} = field(t{i}, x{i}, None if control is None else control(t{i}, x{i}))")
    stage_tuple = ", ".join(f"k{j}" for j in range(s))
    if tableau.fsal:
        # The last stage is evaluated at the new point itself: reuse it instead of recombining.
        lines.append(f"    return x{s - 1}, ({stage_tuple},)")
    else:
        lines.append(f"    return {_combination('x', tableau.b)}, ({stage_tuple},)")
    namespace: dict[str, Any] = {}
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
