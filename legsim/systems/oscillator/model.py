"""The forced oscillator with a stop as a hybrid system written once as model functions
(``legsim.model``): ``make_system``, its forcing ``forcing`` (a ``ControlLaw``), and Table I of
paper 000 (``EXAMPLES``).

Every mode's parameter array is ``p = (2 a, omega^2, 1 / m, x_max, c)`` (1/s, rad^2/s^2, 1/kg,
m, -); the input is ``u = (force,)`` (N), zero without forcing. A run under ``forcing`` with
these compiled functions steps in the compiled kernel.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...compiled.functions import model_function
from ...control import ControlLaw
from ...errors import ModelError
from ...hybrid import Continuation, HybridSystem, Mode, Transition
from ...model import ModeFunctions

MODE = "free"
STUCK = "stuck"  # at rest on the stop: where accumulating impacts continue
NAMES = ("x", "xd")
UNITS = ("m", "m/s")
P_TWO_A, P_W2, P_INV_M, P_X_MAX, P_C = range(5)

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


@model_function
def damped_field(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """(xd, u/m - 2 a xd - omega^2 x), shape (2,)."""
    dx[0] = x[1]
    dx[1] = u[0] * p[P_INV_M] - p[P_TWO_A] * x[1] - p[P_W2] * x[0]


@model_function
def undamped_field(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """(xd, u/m - omega^2 x), shape (2,): a scene without damping computes no damping term."""
    dx[0] = x[1]
    dx[1] = u[0] * p[P_INV_M] - p[P_W2] * x[0]


@model_function
def stop_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """The stop's guard max(x_max - x, -xd) (m): past only beyond the stop *and* moving into it."""
    d = p[P_X_MAX] - x[0]
    g[0] = d if d > -x[1] else -x[1]


@model_function
def stop_impact(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The impact (x, -c xd) (e = 0), or its continuation ``stick``, the plastic impact (x, 0) (e = 1)."""
    out[0] = x[0]
    out[1] = -p[P_C] * x[1] if e == 0 else 0.0


@model_function
def held(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """At rest on the stop: nothing moves."""
    dx[0] = 0.0
    dx[1] = 0.0


@model_function
def release_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """``release``: the free acceleration at rest on the stop, F = u/m - omega^2 x (m/s^2); the stop
    pushes while F >= 0."""
    g[0] = u[0] * p[P_INV_M] - p[P_W2] * x[0]


@model_function
def cosine_force(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, u: np.ndarray) -> None:
    """u = (U cos(Omega t),) (N) for p = (U (N), Omega (rad/s))."""
    u[0] = p[0] * math.cos(p[1] * t)


class SameInEveryMode:
    """``params(mode)`` of a control law whose parameters do not depend on the mode."""

    def __init__(self, values: Any) -> None:
        self.values = np.asarray(values, dtype=float)

    def __call__(self, mode: str) -> np.ndarray:
        return self.values


class Forcing(ControlLaw):
    """The forcing ``u(t) = U cos(Omega t)`` as a control law (no memory, evaluated at every
    stage). Also callable as a plain control ``u(t, x) -> force`` (N), for the tools that take
    one (error bounds, certificates, the event-driven baseline)."""

    def __call__(self, t: float, x: Any = None) -> float:
        u = np.zeros(1)
        state = np.zeros(2) if x is None else np.ascontiguousarray(x, dtype=float)
        self.control(float(t), state, np.zeros(0), self.params_for(MODE), u)
        return float(u[0])


def forcing(amplitude: float, frequency: float) -> Forcing:
    """The control ``u(t, x) = amplitude * cos(frequency * t)`` (N; frequency in rad/s), written
    once (``cosine_force``): the compiled kernel and the Python loop both evaluate it."""
    amplitude, frequency = float(amplitude), float(frequency)
    if not (math.isfinite(amplitude) and math.isfinite(frequency)):
        raise ModelError(f"oscillator: forcing amplitude and frequency must be finite, got {amplitude}, {frequency}")
    return Forcing("forcing", cosine_force, 1, SameInEveryMode([amplitude, frequency]))


def make_system(
    omega: float = 2.5, a: float = 0.05, x_max: float | None = 14.0, c: float = 0.9, mass: float = 1.0
) -> HybridSystem:
    """The oscillator as a hybrid system; pass ``x_max=None`` for no stop (no guard).

    Parameters
    ----------
    omega: natural frequency sqrt(k / m) (rad/s), > 0.
    a: damping rate mu / (2 m) (1/s), >= 0; a = 0 builds the field without a damping term.
    x_max: position of the stop (m), or None.
    c: coefficient of restitution at the stop, in [0, 1].
    mass: m (kg), > 0; the input u is a force (N), the field uses u / m (no input: u = 0).

    With a stop, the impact's continuation (taken when impacts accumulate, ``legsim.relaxed.zeno``)
    is ``stick``: the mass rests on the stop in mode ``stuck`` (x, xd held) and leaves it through
    ``release`` where the stop's force changes sign (paper 000 below Table I).
    """
    omega, a, c, mass = float(omega), float(a), float(c), float(mass)
    _check_parameters(omega, a, c, mass)
    w2, two_a = omega * omega, 2.0 * a
    stop = math.nan if x_max is None else float(x_max)
    if x_max is not None and not math.isfinite(stop):
        raise ModelError(f"oscillator: stop position x_max must be finite, got {x_max}")
    params = [two_a, w2, 1.0 / mass, stop, c]

    def jacobian(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([[0.0, 1.0], [-w2, -two_a]])

    def energy(mode: str, x: np.ndarray) -> float:
        # Products, not float powers: ** raises OverflowError where * gives inf.
        q, qd = float(x[0]), float(x[1])
        return 0.5 * mass * (qd * qd + w2 * q * q)

    field = undamped_field if two_a == 0.0 else damped_field
    guards = None if x_max is None else stop_guard
    free = ModeFunctions(field, guards, stop_impact if guards else None, params=params, inputs=1)
    modes = {MODE: Mode(2, names=NAMES, jacobian=jacobian, units=UNITS, functions=free)}
    transitions: list[Transition] = []
    if x_max is not None:
        stuck = ModeFunctions(held, release_guard, params=params, inputs=1)
        zero = lambda t, x, u: np.zeros((2, 2))  # noqa: E731
        modes[STUCK] = Mode(2, names=NAMES, jacobian=zero, units=UNITS, functions=stuck)
        transitions = _stop_transitions(stop, c)
    return HybridSystem(
        modes,
        transitions,
        name="oscillator with stop" if transitions else "oscillator",
        energy=energy,
        initial=(MODE, np.array([0.0 if x_max is None else min(0.0, stop), 0.0])),
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


def _stop_transitions(stop: float, c: float) -> list[Transition]:
    """The stop at ``x = stop`` (m): ``impact`` from ``free``, continued by ``stick`` into
    ``stuck``, and ``release`` from ``stuck``; guards and resets are the modes' functions, in
    this order."""

    def guard_gradient(x: np.ndarray) -> np.ndarray:
        return np.array([-1.0, 0.0]) if stop - x[0] > -x[1] else np.array([0.0, -1.0])

    return [
        Transition(
            MODE,
            MODE,
            name="impact",
            guard_gradient=guard_gradient,
            reset_jacobian=lambda x: np.diag([1.0, -c]),
            continuation=Continuation(STUCK, name="stick"),
        ),
        Transition(STUCK, MODE, name="release"),
    ]
