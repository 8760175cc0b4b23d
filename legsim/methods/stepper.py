"""One step routine for every tableau, generated as straight-line code, and the error norm.

In Python the per-step cost of a general ``A @ K`` loop (slicing, small matrix products, stage
copies) is several times that of the few array operations a method really needs, so the step is
generated once per tableau with its non-zero coefficients folded in. The compiled kernel
generates its per-component loops from the same grouping of terms (``stage_groups``), so both
paths round alike. A readable textbook ``rk_step`` is the reference the generated steppers are
tested against (tests/helpers/reference_rk.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..errors import ContractError, SimulationError
from .tableau import Tableau

#: A tableau with a row of at least this many non-zero weights keeps its stages stacked and
#: combines every row of at least ``DOT_ROW`` terms by one matrix product: a product costs about
#: three array operations, a sum two per term (DOP853: 25 us a step instead of 44 us, field
#: excluded, n = 6). Methods below this size are combined term by term, which the compiled
#: kernel reproduces to the bit.
DOT_TERMS = 7
DOT_ROW = 3

Stepper = Callable[..., tuple[np.ndarray, tuple[np.ndarray, ...]]]
_GENERATED: dict[tuple[Any, ...], Callable[..., Any]] = {}


def stage_groups(weights: np.ndarray) -> list[tuple[float, list[int]]]:
    """The non-zero weights of a stage combination, stages of equal weight grouped (RK4's b
    becomes two products instead of four): [(weight, [stage indices]), ...] in first-seen order.
    Both the generated Python stepper and the compiled kernel sum in this order."""
    groups: dict[float, list[int]] = {}
    for j, w in enumerate(weights):
        if w != 0.0:
            groups.setdefault(float(w), []).append(j)
    return list(groups.items())


def _key(kind: str, tableau: Tableau) -> tuple[Any, ...]:
    arrays = (tableau.c, tableau.A, tableau.b, tableau.b_err, tableau.b_err_low)
    return (kind, tableau.name, tableau.fsal, *(None if a is None else a.tobytes() for a in arrays))


def field_value(k: Any, x: np.ndarray) -> np.ndarray:
    """A field's output k at a state x, checked to be an array of x's shape (a field that returns
    another shape would be broadcast silently into the step)."""
    value = k if isinstance(k, np.ndarray) else np.asarray(k, dtype=float)
    if value.shape != x.shape:
        raise ContractError(f"field returned shape {value.shape}, expected {x.shape}")
    return value


def make_stepper(tableau: Tableau, checked: bool = True) -> Stepper:
    """``step(field, t, x, h, k0, control) -> (x_new, stages)`` specialised to ``tableau``, with
    ``stages`` the tuple of the s stage derivatives (``stages[0] is k0``). The control is sampled
    at each stage, ``u = control(t + c_i h, x_i)``, so that a time-varying input keeps the
    method's order. Every stage is checked to have x's shape (``field_value``; ContractError
    otherwise; ``checked=False`` leaves that out, to measure its cost). Generated once per
    tableau (compiling the source costs more than a short run).
    """
    key = _key("step" if checked else "step-unchecked", tableau)
    if key not in _GENERATED:
        _GENERATED[key] = _generate_stepper(tableau, checked)
    return _GENERATED[key]


def _combination(base: str, weights: np.ndarray) -> str:
    """Source of ``base + h * sum_j w_j k_j`` with h folded into each group's factor."""
    terms = []
    for w, js in stage_groups(weights):
        summed = f"k{js[0]}" if len(js) == 1 else "(" + " + ".join(f"k{j}" for j in js) + ")"
        terms.append(f"(h * {w!r}) * {summed}")
    return base if not terms else base + " + " + " + ".join(terms)


def _generate_stepper(tableau: Tableau, checked: bool) -> Stepper:
    s = tableau.stages
    weights = [tableau.A[i, :i] for i in range(1, s)] + ([] if tableau.fsal else [tableau.b])
    stacked = any(np.count_nonzero(w) >= DOT_TERMS for w in weights)
    namespace: dict[str, Any] = {"empty": np.empty, "ndarray": np.ndarray, "field_value": field_value}
    lines = ["def step(field, t, x, h, k0, control):"]
    if stacked:
        lines += [f"    K = empty(({s}, x.shape[0]))", "    K[0] = k0"]

    def combination(w: np.ndarray, i: int) -> str:
        if stacked and np.count_nonzero(w) >= DOT_ROW:
            namespace[f"W{i}"] = np.array(w, dtype=float)
            return f"x + h * (W{i} @ K[:{len(w)}])"
        return _combination("x", w)

    for i in range(1, s):
        lines.append(f"    t{i} = t + {float(tableau.c[i])!r} * h")
        lines.append(f"    x{i} = {combination(tableau.A[i, :i], i)}")
        lines.append(f"    k{i} = field(t{i}, x{i}, None if control is None else control(t{i}, x{i}))")
        if checked:
            lines.append(f"    if k{i}.__class__ is not ndarray or k{i}.shape != x.shape:")
            lines.append(f"        k{i} = field_value(k{i}, x)")
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
    exec("\n".join(lines), namespace)  # generated from the tableau's numbers only
    step: Stepper = namespace["step"]
    return step


def _require_embedded(tableau: Tableau) -> np.ndarray:
    """The weights b_err of the tableau's error estimate; SimulationError when it has none."""
    if tableau.b_err is None:
        raise SimulationError(
            f"method '{tableau.name}' has no embedded error estimate; "
            f"use bs32 or dopri5 (low order), or dop853 (high order)"
        )
    return tableau.b_err


def error_estimate(tableau: Tableau, h: float, stages: tuple[np.ndarray, ...]) -> np.ndarray:
    """Local error estimate h * sum_j b_err_j k_j of an embedded pair, shape (n,)."""
    acc: np.ndarray | None = None
    for be, k in zip(_require_embedded(tableau), stages, strict=True):
        if be != 0.0:
            acc = be * k if acc is None else acc + be * k
    # All-zero weights (b_hat equal to b) estimate no error at all.
    return h * acc if acc is not None else np.zeros_like(stages[0])


def error_estimator(
    tableau: Tableau,
) -> Callable[[float, tuple[np.ndarray, ...]], tuple[np.ndarray, np.ndarray | None]]:
    """``estimate(h, stages) -> (err, err_low)``: the local error estimate h sum_j b_err_j k_j of
    an embedded pair, shape (n,), and the lower-order one of ``b_err_low`` (None without).

    Generated as straight-line code like the stepper, summing in stage order as
    ``error_estimate`` does and the compiled kernel does, so both paths take the same step
    decisions to the bit; a blended pair (DOP853) sums by matrix products, which the kernel
    matches to rounding only.
    """
    _require_embedded(tableau)
    key = _key("estimate", tableau)
    if key not in _GENERATED:
        _GENERATED[key] = _generate_estimator(tableau)
    return _GENERATED[key]


def _generate_estimator(tableau: Tableau) -> Callable[..., Any]:
    namespace: dict[str, Any] = {"stack": np.array}
    b_err = _require_embedded(tableau)
    if tableau.b_err_low is None:
        terms = [f"{float(w)!r} * k{j}" for j, w in enumerate(b_err) if w != 0.0]
        lines = [
            "def estimate(h, stages):",
            f"    {', '.join(f'k{j}' for j in range(tableau.stages))}, = stages",
            f"    return h * ({' + '.join(terms)}), None",
        ]
    else:
        namespace["E"], namespace["E_LOW"] = np.array(b_err), np.array(tableau.b_err_low)
        lines = ["def estimate(h, stages):", "    K = stack(stages)", "    return h * (E @ K), h * (E_LOW @ K)"]
    exec("\n".join(lines), namespace)  # generated from the tableau's numbers only
    estimate: Callable[..., Any] = namespace["estimate"]
    return estimate


def error_scale(x: float, x_new: float, rtol: float, atol: float) -> float:
    """The tolerance of one coordinate of a step from x to x_new: atol + rtol max(|x|, |x_new|)."""
    return atol + rtol * max(abs(x), abs(x_new))


def scaled_norm(high: float, low: float, n: int, blended: bool) -> float:
    """The error norm from the sums of squared scaled estimates: RMS of the estimate (``high``);
    ``blended``: Hairer's DOP853 norm, the fifth-order estimate damped where the third-order one
    (``low``) is much larger, so that a step is not rejected for an estimate that is itself poor."""
    if not blended:
        return math.sqrt(high / n)
    if high == 0.0 and low == 0.0:
        return 0.0
    return high / math.sqrt((high + 0.01 * low) * n)


def error_norm(
    err: Sequence[float],
    err_low: Sequence[float],
    x: Sequence[float],
    x_new: Sequence[float],
    rtol: float,
    atol: float,
    blended: bool,
) -> float:
    """Hairer's (and scipy's) error norm of a step's local error estimate ``err`` (and, blended,
    ``err_low``): sequences of length n, summed in index order, each coordinate scaled by
    ``error_scale``."""
    high = 0.0
    low = 0.0
    for d in range(len(x)):
        scale = error_scale(x[d], x_new[d], rtol, atol)
        r = err[d] / scale
        high += r * r
        if blended:
            r_low = err_low[d] / scale
            low += r_low * r_low
    return scaled_norm(high, low, len(x), blended)


def make_error_norm(tableau: Tableau) -> Callable[..., float]:
    """``norm(h, stages, x, x_new, rtol, atol) -> float``: ``error_norm`` of the step's
    estimate (the blended norm for a tableau with ``b_err_low``)."""
    estimate = error_estimator(tableau)
    blended = tableau.b_err_low is not None

    def norm(
        h: float, stages: tuple[np.ndarray, ...], x: np.ndarray, x_new: np.ndarray, rtol: float, atol: float
    ) -> float:
        err, err_low = estimate(h, stages)
        return error_norm(
            err.tolist(),
            err_low.tolist() if err_low is not None else (),
            x.tolist(),
            x_new.tolist(),
            rtol,
            atol,
            blended,
        )

    return norm
