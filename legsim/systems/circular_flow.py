"""A clockwise circular flow cut by the plane x1 = wall (paper 004, Section IV-D, Fig. 1: grazing).

Both modes carry the same linear field, a clockwise rotation at ``omega`` rad/s about the
origin: x1' = omega x2, x2' = -omega x1. The plane x1 = wall only relabels the state:

* ``inside`` (x1 <= wall) leaves through ``cross`` when x1 reaches the wall
  (guard ``wall - x1``, in the units of x1);
* ``outside`` (x1 >= wall) leaves through ``return`` (guard ``x1 - wall``).

Resets are the identity, so the true execution is the circle through the initial state and
switches only when the circle's radius exceeds the wall. From the default state (0, wall) the
circle has radius wall and touches the plane at t = pi / (2 omega) without crossing it: the
grazing of paper 004 Fig. 1. The exact solution is a rotation (``CircularReference``). Both
modes are written once as compiled model functions (``legsim.model``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from ..builders import Builder, Model, Param
from ..compiled.functions import model_function
from ..errors import ModelError
from ..execution import Samples
from ..hybrid import HybridSystem, Mode, Transition
from ..model import ModeFunctions
from ._reference import as_times, box, make_samples, segment

NAMES = ("x1", "x2")
P_OMEGA, P_WALL, P_SIDE = range(3)


@dataclass(frozen=True)
class CircularReference:
    """Exact solution of the clockwise rotation at ``omega`` rad/s, and the exact execution
    from ``x0`` at ``t0`` (``sample``, ``with_initial``): the mode is ``inside`` where
    x1 <= wall, ``outside`` beyond (the resets are the identity)."""

    omega: float
    wall: float
    x0: tuple[float, float] = (0.0, 1.0)
    t0: float = 0.0

    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> CircularReference:
        """The same flow from ``x`` at t0 (the mode follows from x)."""
        if mode not in ("inside", "outside"):
            raise ModelError(f"circular_flow reference: unknown mode '{mode}' (modes: ['inside', 'outside'])")
        x1, x2 = (float(v) for v in x)
        return replace(self, x0=(x1, x2), t0=float(t0))

    def sample(self, times: Iterable[float] | float) -> Samples:
        """Mode and state at ``times`` (s) in ``Execution.sample``'s format."""
        t = as_times(times, self.t0)
        states = self.state(np.array(self.x0), t, self.t0).reshape(len(t), 2)
        modes = ["inside" if x[0] <= self.wall else "outside" for x in states]
        return make_samples(t, modes, states)

    def state(self, x0: np.ndarray, t: float | np.ndarray, t0: float = 0.0) -> np.ndarray:
        """x(t) from x(t0) = x0; shape (2,) for scalar t, (len(t), 2) otherwise."""
        a = self.omega * (np.asarray(t, dtype=float) - t0)
        c, s = np.cos(a), np.sin(a)
        x1 = c * x0[0] + s * x0[1]
        x2 = -s * x0[0] + c * x0[1]
        return np.stack([x1, x2], axis=-1)

    def crossing_time(self, x0: np.ndarray, t0: float = 0.0) -> float:
        """First time (s) after t0 at which x1 reaches the wall from below; inf when the circle
        through x0 does not cross it (radius <= wall: a grazing circle touches without crossing)."""
        radius = float(np.hypot(x0[0], x0[1]))
        if radius <= self.wall:
            return float("inf")
        # x1(t) = radius * cos(omega (t - t0) - phi) with phi the angle of (x1, x2) from the x1 axis.
        phi = float(np.arctan2(x0[1], x0[0]))
        target = float(np.arccos(self.wall / radius))  # x1 = wall where the phase is +-target
        # Phase theta(t) = omega t - phi grows; first theta >= -target with cos(theta) = wall / radius.
        theta0 = -phi
        k = np.ceil((theta0 + target) / (2 * np.pi))
        theta = -target + 2 * np.pi * k
        if theta < theta0:
            theta += 2 * np.pi
        return t0 + (theta - theta0) / self.omega


@model_function
def rotation(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """The clockwise rotation (omega x2, -omega x1) for p[0] = omega (rad/s)."""
    dx[0] = p[P_OMEGA] * x[1]
    dx[1] = -p[P_OMEGA] * x[0]


@model_function
def wall_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """side * (wall - x1) (units of x1): side +1 inside (x1 <= wall), -1 outside."""
    g[0] = p[P_SIDE] * (p[P_WALL] - x[0])


def make_system(omega: float = 1.0, wall: float = 1.0) -> HybridSystem:
    """The circular flow with the switching plane x1 = wall (modes ``inside``, ``outside``),
    written once as model functions with parameters ``(omega (rad/s), wall, side)``."""
    A = np.array([[0.0, omega], [-omega, 0.0]])

    def jacobian(t, x, u):
        return A.copy()

    def mode(side: float) -> Mode:
        functions = ModeFunctions(rotation, wall_guard, params=[omega, wall, side])
        return Mode(2, names=NAMES, jacobian=jacobian, functions=functions)

    modes = {"inside": mode(1.0), "outside": mode(-1.0)}
    transitions = [
        Transition(
            "inside",
            "outside",
            name="cross",
            guard_gradient=lambda x: np.array([-1.0, 0.0]),
            reset_jacobian=lambda x: np.eye(2),
        ),
        Transition(
            "outside",
            "inside",
            name="return",
            guard_gradient=lambda x: np.array([1.0, 0.0]),
            reset_jacobian=lambda x: np.eye(2),
        ),
    ]
    return HybridSystem(modes, transitions, name="circular flow")


def _build(params: dict, effects: dict) -> Model:
    omega, wall = params["omega"], params["wall"]

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        # The state drawn as a small square in the (x1, x2) plane, read as (x, z).
        half = 0.03 * wall
        return {"state": box(float(x[0]) - half, float(x[0]) + half, float(x[1]) - half, float(x[1]) + half)}

    angles = np.linspace(0.0, 2.0 * np.pi, 97)
    scenery = {
        "wall": segment([wall, -1.5 * wall], [wall, 1.5 * wall]),
        "grazing_circle": np.column_stack([wall * np.cos(angles), wall * np.sin(angles)]),
    }
    return Model(
        system=make_system(omega, wall),
        initial_mode="inside",
        initial_state={"x1": 0.0, "x2": wall},
        geometry=geometry,
        scenery=scenery,
        reference=CircularReference(omega, wall, (0.0, wall)),
        info={"guard_units": {"cross": "units of x1", "return": "units of x1"}},
    )


BUILDER = Builder(
    name="circular_flow",
    description="clockwise circular flow cut by the plane x1 = wall; grazes it from (0, wall) (paper 004 Fig. 1)",
    parameters={
        "omega": Param(1.0, "angular speed (clockwise)", "rad/s", low=0.0, low_open=True),
        "wall": Param(1.0, "position of the switching plane x1 = wall", "units of x1", low=0.0, low_open=True),
    },
    effects={},
    build=_build,
)
