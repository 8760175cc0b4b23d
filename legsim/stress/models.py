"""The models the stress cases run. All but one are built through the registered builders
(``legsim.builders`` entry points), as a scene would build them, so this package never imports
``robots`` or Pinocchio itself; the lifted ball, a contact that rests and is released by a
growing force, is defined here.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..builders import Model, get_builder
from ..hybrid import HybridSystem, Mode, Transition


def build(robot: str, parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """A model built by a registered builder, as a scene would build it."""
    return get_builder(robot).make(parameters or {}, effects or {})


def model_state(model: Model, mode: str, values: dict[str, float] | None = None) -> np.ndarray:
    """The state vector of ``mode``: the model's initial state with ``values`` (by coordinate
    name) overriding it."""
    names = model.system.state_names(mode)
    merged = {**model.initial_state, **(values or {})}
    return np.array([float(merged[n]) for n in names])


def double_pendulum(c: float, window: float | None) -> tuple[Model, np.ndarray]:
    """The double pendulum with a stop of restitution c (paper 003 Fig. 2c), with Zeno
    continuation when ``window`` (s) is given, and its initial state in ``unconstrained``."""
    effects: dict[str, Any] = {"stop": {"restitution": c}}
    if window is not None:
        effects["zeno"] = {"window": window}
    model = build("double_pendulum", {}, effects)
    return model, model_state(model, "unconstrained")


def oscillator_ex2(continued: bool, window: float = 0.0) -> Model:
    """The forced oscillator with a stop of paper 000 Table I Example 2, with Zeno continuation
    (``window`` in s) when ``continued``."""
    effects: dict[str, Any] = {"stop": {"position": -0.8, "restitution": 0.5}, "damping": {"a": 0.95},
                               "forcing": {"amplitude": 1.0, "frequency": 1.0}}
    if continued:
        effects["zeno"] = {"window": window}
    return build("oscillator", {"omega": 1.0, "mass": 1.0, "x0": -0.8, "xd0": 0.0}, effects)


def pronk(params: dict[str, Any] | None = None) -> Model:
    """The two-legged pronking runner (paper 000 Fig. 17) with its default parameters overridden
    by ``params``."""
    return build("pronk", params or {})


def slip_twin(pronk_params: dict[str, Any] | None = None) -> Model:
    """The SLIP with the pronk's two legs merged (k doubled): its execution is the symmetric
    pronk's eps -> 0 limit (paper 000 Sec. V-C)."""
    p = {"m": 1.0, "k": 30.0, "l": 1.0, "g": 9.81, "psi": math.pi / 5, **(pronk_params or {})}
    return build("slip", {"m": p["m"], "k": 2 * p["k"], "l": p["l"], "g": p["g"], "psi": p["psi"]})


def lifted_ball(c: float, lift_rate: float, g: float = 9.81, mass: float = 1.0,
                window: float | None = None) -> tuple[HybridSystem, Callable[[float, np.ndarray], float]]:
    """A ball on a floor (restitution c) pulled up by the force ``u(t) = lift_rate t`` (N), and
    its control. Modes ``flight`` (z, zd) with field (zd, u/m - g) and ``rest`` (z, zd) with
    field 0, held on the floor while the floor pushes. Guards (eps in metres in flight, N at
    rest):

    * ``bounce`` (c > 0, flight -> flight): ``max(z, zd)``, reset (z, -c zd);
    * ``land`` (flight -> rest): the floor guard when the impact ends at rest: for c = 0 a
      plastic impact after which the floor pushes (m g - u > 0), for c > 0 with Zeno
      continuation (``window``) an impact whose rebound c v0 would fly shorter than the window
      (c v0 < a window / 2, a = g - u/m the acceleration pressing the ball on the floor);
      reset (z, 0);
    * ``graze`` (c = 0, flight -> flight): a plastic impact while the floor would pull (the lift
      exceeds the weight), reset (z, 0);
    * ``release`` (rest -> flight): the floor force ``m g - u(t)`` (N) on (t, x, u), so the
      crossing is located on the force's own time dependence.

    The release is at t* = m g / lift_rate exactly; after a release at t_e the flight is the
    cubic z(t) = (r/m)((t - t*)^3 - (t_e - t*)^3)/6 - (r/m)(t_e - t*)^2 (t - t_e)/2, r = lift_rate,
    which RK4 integrates exactly.
    """
    def control(t: float, x: np.ndarray) -> float:
        return lift_rate * t

    def flight(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[1], (0.0 if u is None else u) / mass - g])

    def rest(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.zeros(2)

    def energy(mode: str, x: np.ndarray) -> float:
        return mass * (g * float(x[0]) + 0.5 * float(x[1]) ** 2)

    system = HybridSystem({"flight": Mode(2, flight, ("z", "zd")), "rest": Mode(2, rest, ("z", "zd"))},
                          _lifted_ball_transitions(c, g, mass, window), name=f"lifted ball c={c:g}", energy=energy)
    return system, control


def _lifted_ball_transitions(c: float, g: float, mass: float, window: float | None) -> list[Transition]:
    """``land``, then ``bounce`` (c > 0) or ``graze`` (c = 0), then ``release`` (see
    ``lifted_ball``). Past the floor, ``land`` and the other flight transition have
    complementary guards: the branch taken has the floor guard itself, the other its opposite."""

    def floor_gap(x: np.ndarray) -> float:
        return x[0] if x[0] > x[1] else x[1]

    def accumulating(t: float, x: np.ndarray, u: float) -> bool:
        a = g - u / mass  # acceleration pressing the ball on the floor
        if c == 0.0:
            return a > 0.0
        if window is None or a <= 0.0:
            return False
        v0 = math.sqrt(max(x[1] * x[1] - 2.0 * a * max(-x[0], 0.0), 0.0))  # approach speed back at z = 0
        return c * v0 < 0.5 * a * window

    def branch(stays: bool):
        def guard(t: float, x: np.ndarray, u: float) -> float:
            base = floor_gap(x)
            if base >= 0.0:
                return base
            return base if accumulating(t, x, u) == stays else -base
        return guard

    def stop(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], 0.0])

    transitions = [Transition("flight", "rest", branch(True), stop, name="land", guard_args="t,x,u")]
    if c > 0.0:
        transitions.append(Transition("flight", "flight", branch(False), lambda x: np.array([x[0], -c * x[1]]),
                                      name="bounce", guard_args="t,x,u"))
    else:
        transitions.append(Transition("flight", "flight", branch(False), stop, name="graze", guard_args="t,x,u"))
    transitions.append(Transition("rest", "flight", lambda t, x, u: mass * g - u, name="release", guard_args="t,x,u"))
    return transitions
