"""The models the stress cases run. All but one are built through the registered builders
(``legsim.builders`` entry points), as a scene would build them, so this package never imports
``robots`` or Pinocchio itself; the lifted ball, a contact that rests and is released by a
growing force, is defined here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..builders import Model, get_builder
from ..hybrid import Continuation, HybridSystem, Mode, Transition


def build(robot: str, parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """A model built by a registered builder, as a scene would build it."""
    return get_builder(robot).make(parameters or {}, effects or {})


def model_state(model: Model, mode: str, values: dict[str, float] | None = None) -> np.ndarray:
    """The state vector of ``mode``: the model's initial state with ``values`` (by coordinate
    name) overriding it."""
    names = model.system.state_names(mode)
    merged = {**model.initial_state, **(values or {})}
    return np.array([float(merged[n]) for n in names])


def double_pendulum(c: float) -> tuple[Model, np.ndarray]:
    """The double pendulum with a stop of restitution c (paper 003 Fig. 2c) and its initial
    state in ``unconstrained``. Its bounce names the continuation ``rest_stop`` (the plastic
    impact into ``constrained``), which ``simulate`` takes by default when the bounces
    accumulate; ``continuation=False`` runs the paper's relaxed execution."""
    model = build("double_pendulum", {}, {"stop": {"restitution": c}})
    return model, model_state(model, "unconstrained")


def oscillator_ex2() -> Model:
    """The forced oscillator with a stop of paper 000 Table I Example 2. Its impact names the
    continuation ``stick`` (into ``stuck``, left through ``release``), which ``simulate`` takes
    by default when the impacts accumulate; ``continuation=False`` runs the paper's relaxed
    execution, which chatters where the mass sticks."""
    effects: dict[str, Any] = {
        "stop": {"position": -0.8, "restitution": 0.5},
        "damping": {"a": 0.95},
        "forcing": {"amplitude": 1.0, "frequency": 1.0},
    }
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


def lifted_ball(
    c: float, lift_rate: float, g: float = 9.81, mass: float = 1.0
) -> tuple[HybridSystem, Callable[[float, np.ndarray], float]]:
    """A ball on a floor (restitution c) pulled up by the force ``u(t) = lift_rate t`` (N), and
    its control. Modes ``flight`` (z, zd) with field (zd, u/m - g) and ``rest`` (z, zd) with
    field 0, held on the floor while the floor pushes. Guards (eps in metres in flight, N at
    rest):

    * c > 0: ``bounce`` (flight -> flight), guard ``max(z, zd)``, reset (z, -c zd), continued by
      ``land`` (into ``rest``, reset (z, 0)) when the bounces accumulate (``legsim.relaxed.zeno``:
      taken by default, only where the floor then pushes, m g - u >= 0);
    * c = 0: ``land`` (flight -> rest), the plastic impact after which the floor pushes
      (m g - u > 0), and ``graze`` (flight -> flight), the plastic impact while the lift exceeds
      the weight (the floor would pull), both reset (z, 0);
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

    system = HybridSystem(
        {"flight": Mode(2, flight, ("z", "zd")), "rest": Mode(2, rest, ("z", "zd"))},
        _lifted_ball_transitions(c, g, mass),
        name=f"lifted ball c={c:g}",
        energy=energy,
    )
    return system, control


def _floor_gap(x: np.ndarray) -> float:
    return x[0] if x[0] > x[1] else x[1]


def _stop(x: np.ndarray) -> np.ndarray:
    return np.array([x[0], 0.0])


def _lifted_ball_transitions(c: float, g: float, mass: float) -> list[Transition]:
    """``bounce`` continued by ``land`` (c > 0), or ``land`` and ``graze`` (c = 0), then
    ``release`` (see ``lifted_ball``)."""
    release = Transition("rest", "flight", lambda t, x, u: mass * g - u, name="release", guard_args="t,x,u")
    if c > 0.0:
        bounce = Transition(
            "flight",
            "flight",
            _floor_gap,
            lambda x: np.array([x[0], -c * x[1]]),
            name="bounce",
            continuation=Continuation("rest", _stop, name="land"),
        )
        return [bounce, release]

    # A plastic impact lands where the floor then pushes (the weight exceeds the lift) and grazes
    # where it would pull. Past the floor the two have complementary guards: the branch taken has
    # the floor guard itself, the other its opposite.
    def branch(lands: bool):
        def guard(t: float, x: np.ndarray, u: float) -> float:
            base = _floor_gap(x)
            if base >= 0.0:
                return base
            return base if (g - u / mass > 0.0) == lands else -base

        return guard

    return [
        Transition("flight", "rest", branch(True), _stop, name="land", guard_args="t,x,u"),
        Transition("flight", "flight", branch(False), _stop, name="graze", guard_args="t,x,u"),
        release,
    ]


def curved_floor_ball(c: float = 0.8, radius: float = 2.0, g: float = 9.81) -> HybridSystem:
    """A ball (a point) bouncing in a valley, the floor z = x^2 / (2 radius), written with the core
    API only, as a user would: one mode ``fly`` with state (x, z, xd, zd) (m, m/s) and field
    (xd, zd, 0, -g); one transition ``bounce`` with guard ``max(gap, v_n)``, the vertical gap
    z - x^2/(2 radius) (m, so eps is in metres) and the normal velocity v_n = n . v (n the floor's
    upward unit normal), past only below the floor *and* moving into it; reset: the normal
    velocity reflected with restitution c, the tangential one kept.

    The bounces accumulate while the ball keeps sliding along the floor, and the model names no
    continuation (a sliding mode would need the constrained dynamics): past the accumulation the
    relaxed execution holds the state in the strip (``Execution.warnings`` says so)."""
    c, radius, g = float(c), float(radius), float(g)

    def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[2], x[3], 0.0, -g])

    def guard(x: np.ndarray) -> float:
        gap = float(x[1] - x[0] * x[0] / (2.0 * radius))
        v_n = float(floor_normal(x, radius) @ x[2:])
        return gap if gap > v_n else v_n

    def reset(x: np.ndarray) -> np.ndarray:
        n, v = floor_normal(x, radius), x[2:]
        return np.concatenate([x[:2], v - (1.0 + c) * float(n @ v) * n])

    def energy(mode: str, x: np.ndarray) -> float:
        return g * float(x[1]) + 0.5 * float(x[2] * x[2] + x[3] * x[3])

    return HybridSystem(
        {"fly": Mode(4, field, ("x", "z", "xd", "zd"))},
        [Transition("fly", "fly", guard, reset, name="bounce")],
        name="ball on a curved floor",
        energy=energy,
    )


def floor_normal(x: np.ndarray, radius: float) -> np.ndarray:
    """The upward unit normal (2,) of the floor z = x^2 / (2 radius) below the state x = (x, z, ...)."""
    slope = float(x[0]) / radius
    return np.array([-slope, 1.0]) / math.sqrt(1.0 + slope * slope)


def tangential_speed(x: np.ndarray, radius: float) -> float:
    """|v - (n . v) n| (m/s): the speed along the floor of the curved-floor ball at state x."""
    n, v = floor_normal(x, radius), np.asarray(x[2:], dtype=float)
    return float(np.linalg.norm(v - float(n @ v) * n))
