"""The forced oscillator with a stop as a hybrid system: ``make_system``, its forcing control
``forcing``, and Table I of paper 000 (``EXAMPLES``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ...errors import ModelError
from ...hybrid import Continuation, HybridSystem, Mode, Transition

MODE = "free"
STUCK = "stuck"  # at rest on the stop: where accumulating impacts continue
NAMES = ("x", "xd")
UNITS = ("m", "m/s")

#: Table I of paper 000, as keyword arguments of ``make_system``/``OscillatorReference`` plus the
#: initial state and the end time.
EXAMPLES: dict[str, dict[str, float]] = {
    "ex1": {
        "a": 0.05,
        "c": 0.9,
        "t_max": 40.0 * math.pi,
        "amplitude": 20.0,
        "frequency": 2.5,
        "x0": 11.36,
        "xd0": 31.4,
        "x_max": 14.0,
        "omega": 2.5,
        "mass": 1.0,
    },
    "ex2": {
        "a": 0.95,
        "c": 0.5,
        "t_max": 4.0 * math.pi,
        "amplitude": 1.0,
        "frequency": 1.0,
        "x0": -0.8,
        "xd0": 0.0,
        "x_max": -0.8,
        "omega": 1.0,
        "mass": 1.0,
    },
}

Field = Callable[[float, np.ndarray, Any], np.ndarray]


def forcing(
    amplitude: float, frequency: float, counters: dict[str, int] | None = None
) -> Callable[[float, np.ndarray], float]:
    """The control ``u(t, x) = amplitude * cos(frequency * t)`` (N; frequency in rad/s).

    ``counters``, when given, counts the evaluations under ``forcing_evals``.
    """
    amplitude, frequency = float(amplitude), float(frequency)

    if counters is None:

        def u(t: float, x: np.ndarray) -> float:
            return amplitude * math.cos(frequency * t)
    else:
        counters.setdefault("forcing_evals", 0)

        def u(t: float, x: np.ndarray) -> float:
            counters["forcing_evals"] += 1
            return amplitude * math.cos(frequency * t)

    return u


def make_system(
    omega: float = 2.5,
    a: float = 0.05,
    x_max: float | None = 14.0,
    c: float = 0.9,
    mass: float = 1.0,
    counters: dict[str, int] | None = None,
) -> HybridSystem:
    """The oscillator as a hybrid system; pass ``x_max=None`` for no stop (no guard).

    Parameters
    ----------
    omega: natural frequency sqrt(k / m) (rad/s), > 0.
    a: damping rate mu / (2 m) (1/s), >= 0.
    x_max: position of the stop (m), or None.
    c: coefficient of restitution at the stop, in [0, 1].
    mass: m (kg), > 0; the control u is a force (N), the field uses u / m (None means u = 0).
    counters: when given, ``damping_evals`` counts the evaluations of the damping term (none
        at all when a = 0: the field then has no such term).

    With a stop, the impact's continuation (taken when impacts accumulate, ``legsim.relaxed.zeno``)
    is ``stick``: the mass rests on the stop in mode ``stuck`` (x, xd held) and leaves it through
    ``release`` where the stop's force changes sign (paper 000 below Table I).
    """
    omega, a, c, mass = float(omega), float(a), float(c), float(mass)
    _check_parameters(omega, a, c, mass)
    w2, two_a, inv_m = omega * omega, 2.0 * a, 1.0 / mass

    def jacobian(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([[0.0, 1.0], [-w2, -two_a]])

    def energy(mode: str, x: np.ndarray) -> float:
        # Products, not float powers: ** raises OverflowError where * gives inf.
        q, qd = float(x[0]), float(x[1])
        return 0.5 * mass * (qd * qd + w2 * q * q)

    transitions: list[Transition] = []
    x0 = 0.0
    if x_max is not None:
        stop = float(x_max)
        if not math.isfinite(stop):
            raise ModelError(f"oscillator: stop position x_max must be finite, got {x_max}")
        x0 = min(0.0, stop)
        transitions = _stop_transitions(stop, c, w2, inv_m)
    modes = {MODE: Mode(2, _field(w2, two_a, inv_m, counters), NAMES, jacobian, units=UNITS)}
    if transitions:
        modes[STUCK] = Mode(2, lambda t, x, u: np.zeros(2), NAMES, lambda t, x, u: np.zeros((2, 2)), units=UNITS)
    return HybridSystem(
        modes,
        transitions,
        name="oscillator with stop" if transitions else "oscillator",
        energy=energy,
        initial=(MODE, np.array([x0, 0.0])),
    )


def _check_parameters(omega: float, a: float, c: float, mass: float) -> None:
    """ModelError naming the first parameter ``make_system`` cannot build a field from."""
    if not (omega > 0 and math.isfinite(omega)):
        raise ModelError(f"oscillator: omega must be finite and > 0, got {omega}")
    if not (a >= 0 and math.isfinite(a)):
        raise ModelError(f"oscillator: damping a must be finite and >= 0, got {a}")
    if not 0.0 <= c <= 1.0:
        raise ModelError(f"oscillator: restitution c must lie in [0, 1], got {c}")
    if not (mass > 0 and math.isfinite(mass)):
        raise ModelError(f"oscillator: mass must be finite and > 0, got {mass}")
    # Finite parameters can still overflow the field's coefficients (omega = 1e300): refuse
    # them here by name rather than let every field value be inf or nan.
    for label, value in (("omega^2", omega * omega), ("2 a", 2.0 * a), ("1 / mass", 1.0 / mass)):
        if not math.isfinite(value):
            raise ModelError(f"oscillator: {label} overflows (omega = {omega:g}, a = {a:g}, mass = {mass:g})")


def _field(w2: float, two_a: float, inv_m: float, counters: dict[str, int] | None) -> Field:
    """The field (xd, u/m - 2 a xd - omega^2 x) of mode ``free``. Undamped, it has no damping
    term at all, so that ``damping_evals`` shows a scene without damping computes none."""
    if two_a == 0.0:

        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - w2 * x[0]])
    elif counters is None:

        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - two_a * x[1] - w2 * x[0]])
    else:
        counters.setdefault("damping_evals", 0)

        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            counters["damping_evals"] += 1
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - two_a * x[1] - w2 * x[0]])

    return field


def _stop_transitions(stop: float, c: float, w2: float, inv_m: float) -> list[Transition]:
    """The stop at ``x = stop`` (m): ``impact`` from ``free``, continued by ``stick`` into
    ``stuck``, and ``release`` from ``stuck``.

    The impact's guard ``max(x_max - x, -xd)`` is past only beyond the stop *and* moving into it,
    so near an impact its value is the distance to the stop and eps is measured in metres.
    ``release``: the free acceleration at rest on the stop, ``F = u/m - omega^2 x`` (m/s^2), the
    stop pushing while F >= 0; it depends on the forcing, so it is declared on (t, x, u)."""

    def guard(x: np.ndarray) -> float:
        d = stop - x[0]
        return d if d > -x[1] else -x[1]

    def guard_gradient(x: np.ndarray) -> np.ndarray:
        return np.array([-1.0, 0.0]) if stop - x[0] > -x[1] else np.array([0.0, -1.0])

    def reset(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], -c * x[1]])

    def pressing(t: float, x: np.ndarray, u: Any) -> float:
        return (0.0 if u is None else u) * inv_m - w2 * x[0]

    stick = Continuation(STUCK, lambda x: np.array([x[0], 0.0]), name="stick")
    return [
        Transition(
            MODE,
            MODE,
            guard,
            reset,
            name="impact",
            guard_gradient=guard_gradient,
            reset_jacobian=lambda x: np.diag([1.0, -c]),
            continuation=stick,
        ),
        Transition(STUCK, MODE, pressing, name="release", guard_args="t,x,u"),
    ]
