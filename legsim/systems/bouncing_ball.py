"""The bouncing ball: free fall onto a floor with restitution c, and its closed-form Zeno execution.

Written once as model functions (``legsim.model``), compiled. One mode ``flight`` with state
``(z, zd)``: z the height of the ball's lowest point above the
floor (m), zd its vertical velocity (m/s). Field ``(zd, -g)``. One transition ``bounce``
(``flight -> flight``) with guard ``max(z, zd)`` and reset ``(z, -c zd)``: the ball is past the
guard when it is below the floor *and* falling, so the guard's value near an impact is the
height z, and eps is measured in metres.

Closed form (exact, with v1 the speed of the first impact): the k-th flight after the first
impact has take-off speed ``c^k v1`` and lasts ``2 c^k v1 / g``, so the impact times are
``t_k = t_1 + 2 v1 c (1 - c^(k-1)) / (g (1 - c))`` and they accumulate at the Zeno time
``t_1 + 2 v1 c / (g (1 - c))`` (c < 1), after which the ball rests on the floor.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..builders import ZENO_EFFECT, ZENO_WINDOW, Builder, Effect, Model, Param
from ..compiled.functions import model_function
from ..errors import ModelError
from ..execution import Samples
from ..hybrid import Continuation, HybridSystem, Mode, Transition
from ..model import ModeFunctions
from ._reference import as_times, box, make_samples, segment

MODE = "flight"
REST = "rest"  # on the floor at rest: where accumulating bounces continue
NAMES = ("z", "zd")
UNITS = ("m", "m/s")


@model_function
def free_fall(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """Free fall (zd, -g); p = (g, c)."""
    dx[0] = x[1]
    dx[1] = -p[0]


@model_function
def floor_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """The floor's guard max(z, zd) (m): past only below the floor *and* falling."""
    g[0] = x[0] if x[0] > x[1] else x[1]


@model_function
def bounce(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The bounce (z, -c zd) (e = 0), or its continuation, the plastic impact (z, 0) (e = 1)."""
    out[0] = x[0]
    out[1] = -p[1] * x[1] if e == 0 else 0.0


@model_function
def at_rest(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """On the floor at rest, for good: nothing moves."""
    dx[0] = 0.0
    dx[1] = 0.0


def make_system(g: float = 9.81, restitution: float = 0.5, floor: bool = True, mass: float = 1.0) -> HybridSystem:
    """The bouncing ball as a hybrid system.

    Parameters
    ----------
    g: gravitational acceleration (m/s^2), > 0.
    restitution: coefficient of restitution c in [0, 1] (the floor's reset is ``zd -> -c zd``).
    floor: without a floor the ball falls freely (one mode, no transition).
    mass: mass (kg), only used by the energy ``mass (g z + zd^2 / 2)`` (J).

    The bounce's continuation (taken when bounces accumulate, ``legsim.relaxed.zeno``) is the
    plastic impact into mode ``rest``: the ball lies on the floor, held there for good (gravity
    never lifts it again).
    """
    g, c, mass = float(g), float(restitution), float(mass)
    if not (g > 0 and math.isfinite(g)):
        raise ModelError(f"bouncing ball: g must be finite and > 0, got {g}")
    if not 0.0 <= c <= 1.0:
        raise ModelError(f"bouncing ball: restitution must lie in [0, 1], got {c}")
    if not (mass > 0 and math.isfinite(mass)):
        raise ModelError(f"bouncing ball: mass must be finite and > 0, got {mass}")

    def jacobian(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([[0.0, 1.0], [0.0, 0.0]])

    def guard_gradient(x: np.ndarray) -> np.ndarray:
        return np.array([1.0, 0.0]) if x[0] > x[1] else np.array([0.0, 1.0])

    def energy(mode: str, x: np.ndarray) -> float:
        # zd * zd, not zd ** 2: a float power raises OverflowError where a product gives inf.
        zd = float(x[1])
        return mass * (g * float(x[0]) + 0.5 * zd * zd)

    functions = ModeFunctions(free_fall, floor_guard if floor else None, bounce, params=[g, c])
    modes = {MODE: Mode(2, names=NAMES, jacobian=jacobian, units=UNITS, functions=functions)}
    transitions = []
    if floor:
        transitions.append(
            Transition(
                MODE,
                MODE,
                name="bounce",
                guard_gradient=guard_gradient,
                reset_jacobian=lambda x: np.diag([1.0, -c]),
                continuation=Continuation(REST, name="rest"),
            )
        )
        rest = ModeFunctions(at_rest)
        modes[REST] = Mode(2, names=NAMES, jacobian=lambda t, x, u: np.zeros((2, 2)), units=UNITS, functions=rest)
    return HybridSystem(modes, transitions, name="bouncing ball", energy=energy, initial=(MODE, np.array([1.0, 0.0])))


class BouncingBallReference:
    """The exact execution of the bouncing ball from ``(z0, zd0)`` at time t0.

    Attributes
    ----------
    first_impact: time of the first impact t_1 (s), inf without a floor.
    impact_speed: speed of the first impact v1 (m/s).
    zeno_time: accumulation time of the impacts (s); inf when c == 1 or without a floor;
        equal to ``first_impact`` when c == 0 (the ball stops at its first impact).
    """

    def __init__(
        self,
        g: float = 9.81,
        restitution: float = 0.5,
        z0: float = 1.0,
        zd0: float = 0.0,
        t0: float = 0.0,
        floor: bool = True,
    ) -> None:
        self.g, self.c, self.floor = float(g), float(restitution), bool(floor)
        self.z0, self.zd0, self.t0 = float(z0), float(zd0), float(t0)
        if not (self.g > 0):
            raise ModelError(f"bouncing ball reference: g must be > 0, got {g}")
        if not 0.0 <= self.c <= 1.0:
            raise ModelError(f"bouncing ball reference: restitution must lie in [0, 1], got {restitution}")
        if self.floor and self.z0 < 0:
            raise ModelError(f"bouncing ball reference: z0 = {z0} lies below the floor")
        g, z0, zd0 = self.g, self.z0, self.zd0
        speed = math.sqrt(zd0 * zd0 + 2.0 * g * z0)
        if not self.floor:
            self.first_impact = math.inf
            self.impact_speed = 0.0
            self.zeno_time = math.inf
            return
        # Root of z0 + zd0 tau - g tau^2 / 2 = 0 written without cancellation for either sign of zd0.
        tau1 = (zd0 + speed) / g if zd0 >= 0 else 2.0 * z0 / (speed - zd0) if speed - zd0 > 0 else 0.0
        self.first_impact = self.t0 + tau1
        self.impact_speed = speed
        c = self.c
        if speed == 0.0 or c == 0.0:
            self.zeno_time = self.first_impact
        elif c < 1.0:
            self.zeno_time = self.first_impact + 2.0 * speed * c / (g * (1.0 - c))
        else:
            self.zeno_time = math.inf

    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> BouncingBallReference:
        """The same ball from another initial state ``x = (z, zd)`` in mode ``flight`` at t0."""
        if mode != MODE:
            raise ModelError(f"bouncing ball reference: unknown mode '{mode}' (modes: ['{MODE}'])")
        z, zd = (float(v) for v in x)
        return BouncingBallReference(self.g, self.c, z, zd, t0, self.floor)

    def impact_time(self, k: int | np.ndarray) -> np.ndarray:
        """Time of the k-th impact (k >= 1), in closed form (s)."""
        k = np.asarray(k, dtype=float)
        if np.any(k < 1):
            raise ValueError("impact numbers start at 1")
        c, v1, g = self.c, self.impact_speed, self.g
        if not self.floor:
            return np.full(k.shape, math.inf)
        if c == 1.0:
            return self.first_impact + 2.0 * v1 * (k - 1.0) / g
        if c == 0.0 or v1 == 0.0:
            return np.where(k == 1, self.first_impact, math.inf)
        return self.first_impact + 2.0 * v1 * c * (1.0 - c ** (k - 1.0)) / (g * (1.0 - c))

    def impact_times(self, t_end: float, max_count: int = 100_000) -> np.ndarray:
        """Impact times <= t_end (s), at most ``max_count`` of them (there are infinitely many
        once t_end reaches the Zeno time)."""
        n = min(self.impact_count(t_end), max_count)
        return self.impact_time(np.arange(1, n + 1)) if n else np.empty(0)

    def impact_speeds(self, t_end: float, max_count: int = 100_000) -> np.ndarray:
        """Speeds (m/s) at the impacts of ``impact_times``: ``c^(k-1) v1``."""
        n = min(self.impact_count(t_end), max_count)
        return self.impact_speed * self.c ** np.arange(n, dtype=float)

    def impact_count(self, t: float) -> int | float:
        """Number of impacts in [t0, t] (inf from the Zeno time on, when c > 0)."""
        if not self.floor or t < self.first_impact:
            return 0
        c, v1, g = self.c, self.impact_speed, self.g
        if c == 0.0 or v1 == 0.0:
            return 1
        if c < 1.0 and t >= self.zeno_time:
            return math.inf
        if c == 1.0:
            k = int((t - self.first_impact) * g / (2.0 * v1)) + 1
        else:
            frac = 1.0 - (t - self.first_impact) * g * (1.0 - c) / (2.0 * v1 * c)
            k = math.floor(math.log(frac) / math.log(c)) + 1 if frac > 0 else 1
        # The logarithm can be off by one at a boundary: settle it with the closed-form times.
        while k > 1 and float(self.impact_time(k)) > t:
            k -= 1
        while float(self.impact_time(k + 1)) <= t:
            k += 1
        return k

    def states(self, times: Iterable[float] | float) -> np.ndarray:
        """Exact states (z, zd) at ``times`` (s), shape (len, 2); right-continuous at impacts
        (the state at an impact time is the reset image)."""
        arr = as_times(times, self.t0)
        out = np.empty((len(arr), 2))
        g = self.g
        for i, t in enumerate(arr):
            if t < self.first_impact:
                tau = t - self.t0
                out[i] = (self.z0 + self.zd0 * tau - 0.5 * g * tau * tau, self.zd0 - g * tau)
            elif t >= self.zeno_time:
                out[i] = (0.0, 0.0)
            else:
                k = int(self.impact_count(t))  # finite before the Zeno time
                tk = float(self.impact_time(k))
                v = self.impact_speed * self.c**k
                tau = t - tk
                out[i] = (v * tau - 0.5 * g * tau * tau, v - g * tau)
        return out

    def state(self, t: float) -> np.ndarray:
        """Exact state (z, zd) at time t (s)."""
        return self.states([t])[0]

    def sample(self, times: Iterable[float] | float) -> Samples:
        """The exact execution at ``times``, in the format of ``Execution.sample``."""
        arr = as_times(times, self.t0)
        return make_samples(arr, [MODE] * len(arr), self.states(arr))

    def energy(self, t: float, mass: float = 1.0) -> float:
        """Mechanical energy at t (J): ``mass * c^(2k) * (energy before the first impact)``."""
        z, zd = self.state(t)
        return mass * (self.g * z + 0.5 * zd * zd)


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    floor = "floor" in effects
    c = effects["floor"]["restitution"] if floor else 0.0
    system = make_system(params["g"], c, floor, params["mass"])
    size = params["size"]

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        return {"ball": box(-0.5 * size, 0.5 * size, float(x[0]), float(x[0]) + size)}

    scenery = {"floor": segment([-1.0, 0.0], [1.0, 0.0])} if floor else {}
    reference = BouncingBallReference(params["g"], c, params["z0"], params["zd0"], 0.0, floor)
    info: dict[str, Any] = {
        "guard units": {"bounce": "m (height of the ball above the floor)"},
        "zeno_time": reference.zeno_time,
        "first_impact": reference.first_impact,
    }
    if floor:
        info["initial_check"] = below_the_floor
    if "zeno" in effects:
        info[ZENO_WINDOW] = effects["zeno"]["window"]
    return Model(system, MODE, {"z": params["z0"], "zd": params["zd0"]}, None, geometry, scenery, reference, info=info)


def below_the_floor(mode: str, x: np.ndarray, eps: float) -> str | None:
    """Why (z, zd) cannot start a run on the floor, or None. The guard max(z, zd) counts a ball
    under the floor as inside while it rises or rests (that is how it leaves the floor after a
    bounce in the strip), so a start deeper than the strip must be refused by name."""
    if x[0] < -eps:
        return f"z = {x[0]:g} m lies below the floor (z >= 0) by more than eps = {eps:g} m"
    return None


BUILDER = Builder(
    name="bouncing_ball",
    description="A ball falling onto a floor with restitution c: closed-form impact times and Zeno time.",
    parameters={
        "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0, low_open=True),
        "mass": Param(1.0, "mass (energy only)", "kg", low=0.0, low_open=True),
        "z0": Param(1.0, "default initial height of the ball's lowest point", "m", low=0.0),
        "zd0": Param(0.0, "default initial vertical velocity", "m/s"),
        "size": Param(0.1, "side of the box drawn for the ball", "m", low=0.0, low_open=True),
    },
    effects={
        "floor": Effect(
            "a rigid floor at z = 0 with an impact law zd -> -c zd",
            default_on=True,
            parameters={"restitution": Param(0.5, "coefficient of restitution c", "", low=0.0, high=1.0)},
        ),
        "zeno": ZENO_EFFECT,
    },
    build=_build,
)
