"""The two-tank system (Zhang, Johansson, Lygeros, Sastry 2001; paper 004, Section IV-D, Fig. 2-3).

Two tanks lose water at constant rates ``v1`` and ``v2`` (level units per second); a single
inflow ``w`` is switched to tank 1 in mode ``q1`` and to tank 2 in mode ``q2``. The inflow is
moved to a tank when its level falls to its threshold:

* ``q1``: x1' = w - v1, x2' = -v2; leaves through ``q1->q2`` when x2 reaches r2
  (guard ``x2 - r2``, in level units: m);
* ``q2``: x1' = -v1, x2' = w - v2; leaves through ``q2->q1`` when x1 reaches r1
  (guard ``x1 - r1``).

Resets are the identity. Both modes are written once as compiled model functions
(``legsim.model``), their flows and watched tank as parameters. When
``max(v1, v2) < w < v1 + v2`` the total excess volume ``(x1 - r1) + (x2 - r2)`` falls at the
constant rate ``v1 + v2 - w`` while every mode visit is a fixed fraction of the previous one,
so the execution is Zeno: infinitely many switches before
``t_zeno = t0 + excess / (v1 + v2 - w)``. ``TwoTankReference`` gives the switching times in
closed form.

Default parameters (w = 0.75, v1 = v2 = 0.5, r1 = r2 = 0) are the usual textbook values; every
visit then lasts half the previous one after the first two.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from ..builders import Builder, Model, Param
from ..compiled.functions import model_function
from ..errors import ModelError, SimulationError
from ..execution import Samples
from ..hybrid import HybridSystem, Mode, Transition
from ..model import ModeFunctions
from ._reference import as_times, box, make_samples, segment

NAMES = ("x1", "x2")
UNITS = ("m", "m")  # water levels
P_RATE1, P_RATE2, P_WATCHED, P_THRESHOLD = range(4)


@dataclass(frozen=True)
class TwoTankReference:
    """Closed-form switching of the two-tank system (flows are constant in each mode), and the
    exact execution from ``(mode, x0)`` at ``t0`` (``sample``, ``with_initial``)."""

    w: float
    v1: float
    v2: float
    r1: float = 0.0
    r2: float = 0.0
    mode: str = "q1"
    x0: tuple[float, float] = (1.0, 1.0)
    t0: float = 0.0
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> TwoTankReference:
        """The same tanks from levels ``x`` in ``mode`` at t0."""
        if mode not in ("q1", "q2"):
            raise ModelError(f"two_tanks reference: unknown mode '{mode}' (modes: ['q1', 'q2'])")
        x1, x2 = (float(v) for v in x)
        return replace(self, mode=mode, x0=(x1, x2), t0=float(t0), _cache={})

    def sample(self, times: Iterable[float] | float, max_switches: int = 2000) -> Samples:
        """Mode and levels at ``times`` (s, before the Zeno time) in ``Execution.sample``'s format."""
        t = as_times(times, self.t0)
        x0 = np.array(self.x0)
        limit = self.zeno_time(x0, self.t0)
        if t.size and t.max() >= limit:
            raise SimulationError(
                f"two_tanks reference: time {t.max()} is at or past the Zeno time {limit}, "
                f"where the execution is not defined"
            )
        if "switches" not in self._cache:
            self._cache["switches"] = self.switching_times(self.mode, x0, max_switches, self.t0)
        switch_times, entered = self._cache["switches"]
        flows = {"q1": np.array([self.w - self.v1, -self.v2]), "q2": np.array([-self.v1, self.w - self.v2])}
        starts = np.concatenate([[self.t0], switch_times])
        modes = [self.mode, *entered]
        states = [x0]
        for k in range(len(switch_times)):
            states.append(states[-1] + (switch_times[k] - starts[k]) * flows[modes[k]])
        out_modes, out_states = [], []
        for tk in t:
            k = int(np.searchsorted(starts, tk, side="right")) - 1
            if k >= len(starts) - 1 and len(switch_times) >= max_switches:
                raise SimulationError(f"two_tanks reference: time {tk} lies beyond the first {max_switches} switches")
            out_modes.append(modes[k])
            out_states.append(states[k] + (tk - starts[k]) * flows[modes[k]])
        return make_samples(t, out_modes, out_states)

    @property
    def zeno(self) -> bool:
        """True when the parameters make every execution Zeno (max(v1, v2) < w < v1 + v2)."""
        return max(self.v1, self.v2) < self.w < self.v1 + self.v2

    def zeno_time(self, x0: np.ndarray, t0: float = 0.0) -> float:
        """Zeno time (s) of the execution from levels ``x0`` (shape (2,)); inf when not Zeno."""
        if not self.zeno:
            return float("inf")
        excess = (x0[0] - self.r1) + (x0[1] - self.r2)
        return t0 + float(excess) / (self.v1 + self.v2 - self.w)

    def switching_times(self, mode: str, x0: np.ndarray, count: int, t0: float = 0.0) -> tuple[np.ndarray, list[str]]:
        """The first ``count`` switching times (s) from ``(mode, x0)`` and the modes entered.

        Each visit lasts (level above threshold of the tank losing water) / (its net loss rate).
        Stops early when a visit would never end (net loss rate <= 0).
        """
        if mode not in ("q1", "q2"):
            raise ModelError(f"two_tanks: unknown mode '{mode}' (modes: ['q1', 'q2'])")
        x = np.array(x0, dtype=float)
        t = float(t0)
        times: list[float] = []
        modes: list[str] = []
        for _ in range(count):
            if mode == "q1":
                rate = self.v2
                if rate <= 0.0:
                    break
                dwell = max(x[1] - self.r2, 0.0) / rate
                x = x + dwell * np.array([self.w - self.v1, -self.v2])
                x[1] = self.r2
                mode = "q2"
            else:
                rate = self.v1
                if rate <= 0.0:
                    break
                dwell = max(x[0] - self.r1, 0.0) / rate
                x = x + dwell * np.array([-self.v1, self.w - self.v2])
                x[0] = self.r1
                mode = "q1"
            t += dwell
            times.append(t)
            modes.append(mode)
        return np.array(times), modes


@model_function
def constant_flow(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """The mode's constant net flows (x1', x2') = (p[0], p[1]) (m/s)."""
    dx[0] = p[P_RATE1]
    dx[1] = p[P_RATE2]


@model_function
def threshold_guard(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """The level of the watched tank (index p[2]) above its threshold p[3] (m)."""
    g[0] = x[int(p[P_WATCHED])] - p[P_THRESHOLD]


def make_system(w: float = 0.75, v1: float = 0.5, v2: float = 0.5, r1: float = 0.0, r2: float = 0.0) -> HybridSystem:
    """The two-tank hybrid system (modes ``q1``, ``q2``; coordinates x1, x2 in m), written once
    as model functions: both modes share them, each with its parameters
    ``(x1' (m/s), x2' (m/s), watched tank (0 or 1), its threshold (m))``."""
    zero = np.zeros((2, 2))
    flows = {"q1": [w - v1, -v2, 1.0, r2], "q2": [-v1, w - v2, 0.0, r1]}
    modes = {
        name: Mode(
            2,
            names=NAMES,
            jacobian=lambda t, x, u: zero.copy(),
            units=UNITS,
            functions=ModeFunctions(constant_flow, threshold_guard, params=params),
        )
        for name, params in flows.items()
    }
    e1 = np.array([1.0, 0.0])
    e2 = np.array([0.0, 1.0])
    transitions = [
        Transition("q1", "q2", name="q1->q2", guard_gradient=lambda x: e2.copy(), reset_jacobian=lambda x: np.eye(2)),
        Transition("q2", "q1", name="q2->q1", guard_gradient=lambda x: e1.copy(), reset_jacobian=lambda x: np.eye(2)),
    ]
    return HybridSystem(modes, transitions, name="two tanks")


def _build(params: dict, effects: dict) -> Model:
    ref = TwoTankReference(params["w"], params["v1"], params["v2"], params["r1"], params["r2"])
    system = make_system(params["w"], params["v1"], params["v2"], params["r1"], params["r2"])
    x0 = np.array([1.0, 1.0])
    r1, r2 = params["r1"], params["r2"]

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        # Tank 1 spans x in [-1.2, -0.2] m, tank 2 [0.2, 1.2] m; levels drawn as water lines,
        # the inflow as a line from above into the tank that receives it.
        inlet = -0.7 if mode == "q1" else 0.7
        return {
            "water_1": segment([-1.2, float(x[0])], [-0.2, float(x[0])]),
            "water_2": segment([0.2, float(x[1])], [1.2, float(x[1])]),
            "inflow": segment([inlet, 2.5], [inlet, max(float(x[0] if mode == "q1" else x[1]), 0.0)]),
        }

    scenery = {
        "tank_1": box(-1.2, -0.2, min(0.0, r1), 2.0),
        "tank_2": box(0.2, 1.2, min(0.0, r2), 2.0),
        "threshold_1": segment([-1.2, r1], [-0.2, r1]),
        "threshold_2": segment([0.2, r2], [1.2, r2]),
    }
    return Model(
        system=system,
        initial_mode="q1",
        initial_state={"x1": 1.0, "x2": 1.0},
        geometry=geometry,
        scenery=scenery,
        reference=ref,
        info={
            "guard_units": {"q1->q2": "m (level of tank 2 above r2)", "q2->q1": "m (level of tank 1 above r1)"},
            "zeno": ref.zeno,
            "zeno_time_from_default_state": ref.zeno_time(x0),
        },
    )


BUILDER = Builder(
    name="two_tanks",
    description="two tanks with one switched inflow (paper 004 Sec. IV-D); Zeno when max(v1,v2) < w < v1+v2",
    parameters={
        "w": Param(0.75, "inflow rate", "m/s", low=0.0),
        "v1": Param(0.5, "outflow rate of tank 1", "m/s", low=0.0),
        "v2": Param(0.5, "outflow rate of tank 2", "m/s", low=0.0),
        "r1": Param(0.0, "threshold level of tank 1", "m"),
        "r2": Param(0.0, "threshold level of tank 2", "m"),
    },
    effects={},
    build=_build,
)
