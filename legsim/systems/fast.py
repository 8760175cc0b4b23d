"""Compiled twins of the analytic systems: the forced oscillator with a stop and the bouncing ball.

Each ``make_*`` returns a ``HybridSystem`` whose modes carry both the Python callables (the
reference that serves everything else: transitions, sampling, metric) and a
``legsim.compiled.CompiledMode`` twin, numba-jitted, with which ``simulate`` runs the step loop
compiled. The twins compute the same expressions in the same order as the Python callables,
so both paths agree to rounding (tests/test_compiled.py).

Compiled twins take no control, so the oscillator's forcing ``U cos(Omega t)`` lives inside its
field here (in ``legsim.systems.oscillator`` it is the model's control). The models, their
guard units and their closed-form references are those of ``legsim.systems.oscillator`` and
``legsim.systems.bouncing_ball``.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from ..compiled import CompiledMode
from ..errors import ModelError
from ..hybrid import Continuation, HybridSystem, Mode, Transition

_jit = numba.njit(cache=True, fastmath=False, nogil=True)

# Oscillator parameter vector p: (two_a, w2, amplitude, frequency, inv_m, x_max, c).


@_jit
def oscillator_field(t, x, p):
    """x'' = U/m cos(Omega t) - 2 a x' - omega^2 x as a first-order field, shape (2,)."""
    out = np.empty(2)
    out[0] = x[1]
    out[1] = p[2] * math.cos(p[3] * t) * p[4] - p[0] * x[1] - p[1] * x[0]
    return out


@_jit
def oscillator_guards(x, p):
    """The stop's guard max(x_max - x, -xd) (m), shape (1,)."""
    out = np.empty(1)
    d = p[5] - x[0]
    out[0] = d if d > -x[1] else -x[1]
    return out


@_jit
def oscillator_resets(x, p, e):
    """The impact (x, -c xd), shape (2,)."""
    out = np.empty(2)
    out[0] = x[0]
    out[1] = -p[6] * x[1]
    return out


@_jit
def oscillator_free_guards(x, p):
    """No stop: no guard, shape (0,)."""
    return np.empty(0)


# Bouncing-ball parameter vector p: (g, c).


@_jit
def ball_field(t, x, p):
    """Free fall (zd, -g), shape (2,)."""
    out = np.empty(2)
    out[0] = x[1]
    out[1] = -p[0]
    return out


@_jit
def ball_guards(x, p):
    """The floor's guard max(z, zd) (m), shape (1,)."""
    out = np.empty(1)
    out[0] = x[0] if x[0] > x[1] else x[1]
    return out


@_jit
def ball_resets(x, p, e):
    """The bounce (z, -c zd), shape (2,)."""
    out = np.empty(2)
    out[0] = x[0]
    out[1] = -p[1] * x[1]
    return out


def make_oscillator(
    omega: float = 2.5,
    a: float = 0.05,
    x_max: float | None = 14.0,
    c: float = 0.9,
    mass: float = 1.0,
    amplitude: float = 20.0,
    frequency: float = 2.5,
) -> HybridSystem:
    """The forced oscillator with a stop (paper 000 Sec. V-B) with its forcing
    ``amplitude cos(frequency t)`` (N) inside the field, and a compiled twin.

    Mode ``free``, state (x, xd) (m, m/s); transition ``impact`` with guard
    ``max(x_max - x, -xd)`` (m) and reset ``(x, -c xd)``; no transition when x_max is None.
    Defaults: Table I Example 1 (``legsim.systems.oscillator.EXAMPLES``).
    """
    omega, a, c, mass = float(omega), float(a), float(c), float(mass)
    amplitude, frequency = float(amplitude), float(frequency)
    for label, value in (("omega", omega), ("mass", mass)):
        if not (value > 0 and math.isfinite(value)):
            raise ModelError(f"fast oscillator: {label} must be finite and > 0, got {value}")
    if not (a >= 0 and math.isfinite(a)):
        raise ModelError(f"fast oscillator: damping a must be finite and >= 0, got {a}")
    if not 0.0 <= c <= 1.0:
        raise ModelError(f"fast oscillator: restitution c must lie in [0, 1], got {c}")
    if not (math.isfinite(amplitude) and math.isfinite(frequency)):
        raise ModelError(
            f"fast oscillator: forcing amplitude and frequency must be finite, got {amplitude}, {frequency}"
        )
    two_a, w2, inv_m = 2.0 * a, omega * omega, 1.0 / mass
    stop = math.nan if x_max is None else float(x_max)
    if x_max is not None and not math.isfinite(stop):
        raise ModelError(f"fast oscillator: stop position x_max must be finite, got {x_max}")
    params = np.array([two_a, w2, amplitude, frequency, inv_m, stop, c])

    def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[1], amplitude * math.cos(frequency * t) * inv_m - two_a * x[1] - w2 * x[0]])

    def jacobian(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([[0.0, 1.0], [-w2, -two_a]])

    def energy(mode: str, x: np.ndarray) -> float:
        return 0.5 * mass * (float(x[1]) ** 2 + w2 * float(x[0]) ** 2)

    transitions = []
    if x_max is not None:

        def guard(x: np.ndarray) -> float:
            d = stop - x[0]
            return d if d > -x[1] else -x[1]

        def reset(x: np.ndarray) -> np.ndarray:
            return np.array([x[0], -c * x[1]])

        def pressing(t: float, x: np.ndarray, u: Any) -> float:
            return amplitude * math.cos(frequency * t) * inv_m - w2 * x[0]

        stick = Continuation("stuck", lambda x: np.array([x[0], 0.0]), name="stick")
        transitions.append(
            Transition(
                "free",
                "free",
                guard,
                reset,
                name="impact",
                guard_gradient=lambda x: np.array([-1.0, 0.0]) if stop - x[0] > -x[1] else np.array([0.0, -1.0]),
                reset_jacobian=lambda x: np.diag([1.0, -c]),
                continuation=stick,
            )
        )
        transitions.append(Transition("stuck", "free", pressing, name="release", guard_args="t,x,u"))
        twin = CompiledMode(oscillator_field, oscillator_guards, 1, params, oscillator_resets)
    else:
        twin = CompiledMode(oscillator_field, oscillator_free_guards, 0, params)
    modes = {"free": Mode(2, field, ("x", "xd"), jacobian, compiled=twin)}
    if transitions:  # at rest on the stop, where accumulating impacts continue (legsim.relaxed.zeno)
        modes["stuck"] = Mode(2, lambda t, x, u: np.zeros(2), ("x", "xd"), lambda t, x, u: np.zeros((2, 2)))
    return HybridSystem(
        modes,
        transitions,
        name="oscillator with stop (compiled)" if transitions else "oscillator (compiled)",
        energy=energy,
    )


def make_oscillator_example(name: str) -> tuple[HybridSystem, np.ndarray, float]:
    """Table I example ``ex1`` or ``ex2``: (system, initial state, t_max)."""
    from .oscillator import EXAMPLES

    if name not in EXAMPLES:
        raise ModelError(f"unknown oscillator example {name!r}; choose one of {sorted(EXAMPLES)}")
    p = EXAMPLES[name]
    system = make_oscillator(p["omega"], p["a"], p["x_max"], p["c"], p["mass"], p["amplitude"], p["frequency"])
    return system, np.array([p["x0"], p["xd0"]]), float(p["t_max"])


def make_bouncing_ball(g: float = 9.81, restitution: float = 0.5) -> HybridSystem:
    """The bouncing ball (``legsim.systems.bouncing_ball``) with a compiled twin: mode ``flight``,
    state (z, zd) (m, m/s), transition ``bounce`` with guard ``max(z, zd)`` (m)."""
    g, c = float(g), float(restitution)
    if not (g > 0 and math.isfinite(g)):
        raise ModelError(f"fast bouncing ball: g must be finite and > 0, got {g}")
    if not 0.0 <= c <= 1.0:
        raise ModelError(f"fast bouncing ball: restitution must lie in [0, 1], got {c}")

    def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[1], -g])

    def guard(x: np.ndarray) -> float:
        return x[0] if x[0] > x[1] else x[1]

    def reset(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], -c * x[1]])

    twin = CompiledMode(ball_field, ball_guards, 1, np.array([g, c]), ball_resets)
    held = Mode(2, lambda t, x, u: np.zeros(2), ("z", "zd"), lambda t, x, u: np.zeros((2, 2)))
    mode = Mode(2, field, ("z", "zd"), lambda t, x, u: np.array([[0.0, 1.0], [0.0, 0.0]]), compiled=twin)
    rest = Continuation("rest", lambda x: np.array([x[0], 0.0]), name="rest")
    return HybridSystem(
        {"flight": mode, "rest": held},
        [
            Transition(
                "flight",
                "flight",
                guard,
                reset,
                name="bounce",
                reset_jacobian=lambda x: np.diag([1.0, -c]),
                continuation=rest,
            )
        ],
        name="bouncing ball (compiled)",
        energy=lambda mode, x: g * float(x[0]) + 0.5 * float(x[1]) ** 2,
    )
