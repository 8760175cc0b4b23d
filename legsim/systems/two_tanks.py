"""The two-tank system (Zhang, Johansson, Lygeros, Sastry 2001; paper 004, Section IV-D, Fig. 2-3).

Two tanks lose water at constant rates ``v1`` and ``v2`` (level units per second); a single
inflow ``w`` is switched to tank 1 in mode ``q1`` and to tank 2 in mode ``q2``. The inflow is
moved to a tank when its level falls to its threshold:

* ``q1``: x1' = w - v1, x2' = -v2; leaves through ``q1->q2`` when x2 reaches r2
  (guard ``x2 - r2``, in level units: m);
* ``q2``: x1' = -v1, x2' = w - v2; leaves through ``q2->q1`` when x1 reaches r1
  (guard ``x1 - r1``).

Resets are the identity. When ``max(v1, v2) < w < v1 + v2`` the total excess volume
``(x1 - r1) + (x2 - r2)`` falls at the constant rate ``v1 + v2 - w`` while every mode visit
is a fixed fraction of the previous one, so the execution is Zeno: infinitely many switches
before ``t_zeno = t0 + excess / (v1 + v2 - w)``. ``TwoTankReference`` gives the switching
times in closed form.

Default parameters (w = 0.75, v1 = v2 = 0.5, r1 = r2 = 0) are the usual textbook values; every
visit then lasts half the previous one after the first two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..builders import Builder, Model, Param
from ..errors import ModelError
from ..hybrid import HybridSystem, Mode, Transition

NAMES = ("x1", "x2")


@dataclass(frozen=True)
class TwoTankReference:
    """Closed-form switching of the two-tank system (flows are constant in each mode)."""

    w: float
    v1: float
    v2: float
    r1: float = 0.0
    r2: float = 0.0

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


def make_system(w: float = 0.75, v1: float = 0.5, v2: float = 0.5, r1: float = 0.0, r2: float = 0.0) -> HybridSystem:
    """The two-tank hybrid system (modes ``q1``, ``q2``; coordinates x1, x2 in m)."""
    f1 = np.array([w - v1, -v2])
    f2 = np.array([-v1, w - v2])
    zero = np.zeros((2, 2))
    modes = {
        "q1": Mode(2, lambda t, x, u: f1.copy(), names=NAMES, jacobian=lambda t, x, u: zero.copy()),
        "q2": Mode(2, lambda t, x, u: f2.copy(), names=NAMES, jacobian=lambda t, x, u: zero.copy()),
    }
    e1 = np.array([1.0, 0.0])
    e2 = np.array([0.0, 1.0])
    transitions = [
        Transition("q1", "q2", guard=lambda x: x[1] - r2, name="q1->q2", guard_gradient=lambda x: e2.copy(),
                   reset_jacobian=lambda x: np.eye(2)),
        Transition("q2", "q1", guard=lambda x: x[0] - r1, name="q2->q1", guard_gradient=lambda x: e1.copy(),
                   reset_jacobian=lambda x: np.eye(2)),
    ]
    return HybridSystem(modes, transitions, name="two tanks")


def _build(params: dict, effects: dict) -> Model:
    ref = TwoTankReference(params["w"], params["v1"], params["v2"], params["r1"], params["r2"])
    system = make_system(params["w"], params["v1"], params["v2"], params["r1"], params["r2"])
    x0 = np.array([1.0, 1.0])
    return Model(
        system=system,
        initial_mode="q1",
        initial_state={"x1": 1.0, "x2": 1.0},
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
