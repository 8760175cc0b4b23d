"""The forced oscillator with a stop as a hybrid system: ``make_system``, its forcing control
``forcing``, and Table I of paper 000 (``EXAMPLES``)."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ...errors import ModelError
from ...hybrid import HybridSystem, Mode, Transition

MODE = "free"
STUCK = "stuck"  # at rest on the stop (Zeno continuation only)
NAMES = ("x", "xd")

#: Table I of paper 000, as keyword arguments of ``make_system``/``OscillatorReference`` plus the
#: initial state and the end time.
EXAMPLES: dict[str, dict[str, float]] = {
    "ex1": {"a": 0.05, "c": 0.9, "t_max": 40.0 * math.pi, "amplitude": 20.0, "frequency": 2.5,
            "x0": 11.36, "xd0": 31.4, "x_max": 14.0, "omega": 2.5, "mass": 1.0},
    "ex2": {"a": 0.95, "c": 0.5, "t_max": 4.0 * math.pi, "amplitude": 1.0, "frequency": 1.0,
            "x0": -0.8, "xd0": 0.0, "x_max": -0.8, "omega": 1.0, "mass": 1.0},
}

Field = Callable[[float, np.ndarray, Any], np.ndarray]


def forcing(amplitude: float, frequency: float, counters: dict[str, int] | None = None
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


def make_system(omega: float = 2.5, a: float = 0.05, x_max: float | None = 14.0, c: float = 0.9,
                mass: float = 1.0, counters: dict[str, int] | None = None,
                zeno_window: float = 0.0) -> HybridSystem:
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
    zeno_window: Zeno continuation (s; 0, the default, switches it off): an impact whose next
        flight would be shorter than the window (rebound ``c v0 < F zeno_window / 2``, F the free
        acceleration pressing the mass on the stop, v0 the approach speed back at the stop) and
        after which the stop would push (F > 0) sticks instead: mode ``stuck`` (x, xd held), left
        through ``release`` when F changes sign. Set it to h + eps of the run (see
        docs/stress.md). The guards then depend on the forcing, so they are declared on (t, x, u).
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
        transitions = _stop_transitions(stop, c, w2, inv_m, zeno_window)
    modes = {MODE: Mode(2, _field(w2, two_a, inv_m, counters), NAMES, jacobian)}
    if any(tr.target == STUCK for tr in transitions):
        modes[STUCK] = Mode(2, lambda t, x, u: np.zeros(2), NAMES, lambda t, x, u: np.zeros((2, 2)))
    return HybridSystem(modes, transitions,
                        name="oscillator with stop" if transitions else "oscillator",
                        energy=energy, initial=(MODE, np.array([x0, 0.0])))


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


def _stop_transitions(stop: float, c: float, w2: float, inv_m: float, zeno_window: float) -> list[Transition]:
    """The stop at ``x = stop`` (m): ``impact`` alone, or with Zeno continuation (window > 0 s)
    ``impact``, ``stick`` and ``release``.

    The guard ``max(x_max - x, -xd)`` is past only beyond the stop *and* moving into it, so
    near an impact its value is the distance to the stop and eps is measured in metres."""

    def guard(x: np.ndarray) -> float:
        d = stop - x[0]
        return d if d > -x[1] else -x[1]

    def guard_gradient(x: np.ndarray) -> np.ndarray:
        return np.array([-1.0, 0.0]) if stop - x[0] > -x[1] else np.array([0.0, -1.0])

    def reset(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], -c * x[1]])

    window = float(zeno_window)
    if not (window >= 0.0 and math.isfinite(window)):
        raise ModelError(f"oscillator: zeno_window must be finite and >= 0 s, got {zeno_window}")
    if window == 0.0:
        return [Transition(MODE, MODE, guard, reset, name="impact", guard_gradient=guard_gradient,
                           reset_jacobian=lambda x: np.diag([1.0, -c]))]
    return _zeno_transitions(guard, reset, stop, c, w2, inv_m, window)


def _zeno_transitions(gap: Callable[[np.ndarray], float], bounce: Callable[[np.ndarray], np.ndarray], stop: float,
                      c: float, w2: float, inv_m: float, window: float) -> list[Transition]:
    """Zeno continuation at the stop: ``impact`` (bounce) and ``stick`` (plastic, into ``stuck``)
    from ``free`` with complementary guards, and ``release`` from ``stuck``.

    Past the stop's guard the impact *accumulates* when the free acceleration at rest on the stop,
    ``F = u/m - omega^2 x`` (m/s^2, > 0 pressing), is positive and the rebound ``c v0`` with
    ``v0^2 = xd^2 - 2 F (x - x_max)`` (the approach speed back at the stop, so that the decision is
    the same all along a step through the strip) is below ``F window / 2``. The branch taken has
    the stop's guard itself (m), the other its opposite (not past). ``release``: guard F itself,
    the stop pushes while F >= 0 (paper 000 below Table I)."""

    def pressing(x: np.ndarray, u: Any) -> float:
        return (0.0 if u is None else u) * inv_m - w2 * x[0]

    def branch(sticks: bool):
        def g(t: float, x: np.ndarray, u: Any) -> float:
            base = gap(x)
            if base >= 0.0:
                return base
            F = pressing(x, u)
            v0 = math.sqrt(max(x[1] * x[1] - 2.0 * F * max(x[0] - stop, 0.0), 0.0))
            accumulating = F > 0.0 and c * v0 < 0.5 * F * window
            return base if accumulating == sticks else -base
        return g

    def stick(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], 0.0])

    return [Transition(MODE, MODE, branch(False), bounce, name="impact", guard_args="t,x,u"),
            Transition(MODE, STUCK, branch(True), stick, name="stick", guard_args="t,x,u"),
            Transition(STUCK, MODE, lambda t, x, u: pressing(x, u), name="release", guard_args="t,x,u")]
