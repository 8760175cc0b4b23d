"""The digital control system of paper 000, Fig. 1 and Section V-A: two thresholds, four modes.

Two physical quantities ``(xi1, xi2)`` are driven by a digital controller whose state records
which of them has crossed its threshold (zero). The controller's state is the mode:

====  ==========================  ==========================================
mode  meaning                     transitions (guard >= 0 inside)
====  ==========================  ==========================================
"0"   neither has crossed         "0->1" guard -xi1, "0->2" guard -xi2
"1"   xi1 has crossed             "1->3" guard -xi2
"2"   xi2 has crossed             "2->3" guard -xi1
"3"   both have crossed           none
====  ==========================  ==========================================

Resets are the identity, so ``R_(1,3) o R_(0,1)(0, 0) = R_(2,3) o R_(0,2)(0, 0) = (0, 0)`` as in
the paper: an execution that crosses both thresholds at once may take either path. Guards are
in the units of the quantities themselves, so eps is measured in those units.

The paper draws the vector fields (Fig. 1(a)) but gives no numbers; we chose the simplest
fields with a closed-form flow that make the controller matter: in each mode both quantities
relax at ``rate`` (1/s) towards a set-point chosen by the controller,
``d xi / dt = rate * (setpoint_mode - xi)``, with set-points

* mode "0": ``(target, target)``: drive both up towards ``target`` > 0;
* mode "1": ``(hold, boost)``: hold xi1 at ``hold`` once it has crossed, push xi2 harder;
* mode "2": ``(boost, hold)``: the mirror image;
* mode "3": ``(hold, hold)``.

Defaults: rate 1, target 1, hold 0.5, boost 2. With ``boost`` off (boost = target) each
quantity's set-point depends only on its own threshold. From ``nominal_initial_state()``
= (-1, -1) both quantities reach zero together at t = ln(2) / rate, the simultaneous crossing of
the paper's nominal execution x; ``y_delta`` and ``z_delta`` (start shifted by -delta in one
coordinate) take the paths 0 -> 2 -> 3 and 0 -> 1 -> 3. ``DigitalControlReference`` is the
exact execution (exponentials and logarithms only). The modes are written once as compiled
model functions (``legsim.model``): one field and one guard function, the set-points and watched
quantities as each mode's parameters.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..builders import Builder, Effect, Model, Param
from ..compiled.functions import model_function
from ..errors import ModelError
from ..execution import Samples
from ..hybrid import HybridSystem, Mode, Transition
from ..model import ModeFunctions
from ._reference import as_times, box, make_samples, segment

NAMES = ("xi1", "xi2")
P_RATE, P_SET1, P_SET2, P_WATCHED = range(4)
MODES = ("0", "1", "2", "3")
#: For each mode, the transitions out of it: (name, target mode, index of the quantity whose
#: threshold it watches).
EDGES: dict[str, tuple[tuple[str, str, int], ...]] = {
    "0": (("0->1", "1", 0), ("0->2", "2", 1)),
    "1": (("1->3", "3", 1),),
    "2": (("2->3", "3", 0),),
    "3": (),
}


def setpoints(target: float = 1.0, hold: float = 0.5, boost: float = 2.0) -> dict[str, np.ndarray]:
    """The controller's set-point of (xi1, xi2) in each mode."""
    return {
        "0": np.array([target, target]),
        "1": np.array([hold, boost]),
        "2": np.array([boost, hold]),
        "3": np.array([hold, hold]),
    }


def nominal_initial_state() -> np.ndarray:
    """(xi1, xi2) = (-1, -1) in mode "0": both thresholds are reached at the same instant
    t = ln(1 + 1/target) / rate (ln 2 with the defaults), whatever the parameters."""
    return np.array([-1.0, -1.0])


def _check(rate: float, target: float, hold: float, boost: float) -> None:
    for name, value in (("rate", rate), ("target", target), ("hold", hold), ("boost", boost)):
        if not math.isfinite(value):
            raise ModelError(f"digital control: {name} must be finite, got {value}")
    if rate <= 0:
        raise ModelError(f"digital control: rate must be > 0, got {rate}")


@model_function
def relaxation(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """rate (setpoint - xi), shape (2,), for p = (rate (1/s), setpoint of xi1, setpoint of xi2, ...)."""
    dx[0] = p[P_RATE] * (p[P_SET1] - x[0])
    dx[1] = p[P_RATE] * (p[P_SET2] - x[1])


@model_function
def thresholds(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray) -> None:
    """-xi of each quantity the mode's transitions watch, in their order (indices from p[3] on)."""
    for k in range(g.shape[0]):
        g[k] = -x[int(p[P_WATCHED + k])]


def make_system(rate: float = 1.0, target: float = 1.0, hold: float = 0.5, boost: float = 2.0) -> HybridSystem:
    """The digital control system of paper 000 Fig. 1 as a hybrid system of modes "0".."3",
    written once as model functions; each mode's parameters are ``(rate, its set-points, the
    index of the quantity each outgoing transition watches)``.

    Parameters
    ----------
    rate: relaxation rate towards the set-point (1/s), > 0.
    target: set-point of both quantities before they cross (units of xi).
    hold: set-point of a quantity after it has crossed.
    boost: set-point of the other quantity once one has crossed (set it to ``target`` to
        switch the coupling off).
    """
    rate, target, hold, boost = float(rate), float(target), float(hold), float(boost)
    _check(rate, target, hold, boost)
    sp = setpoints(target, hold, boost)
    jac = -rate * np.eye(2)

    def functions(mode: str) -> ModeFunctions:
        watched = [float(i) for _, _, i in EDGES[mode]]
        return ModeFunctions(relaxation, thresholds if watched else None, params=[rate, *sp[mode], *watched])

    def gradient(i: int):
        grad = np.zeros(2)
        grad[i] = -1.0
        return lambda x: grad.copy()

    modes = {m: Mode(2, names=NAMES, jacobian=lambda t, x, u: jac.copy(), functions=functions(m)) for m in MODES}
    transitions = [
        Transition(source, target_mode, name=name, guard_gradient=gradient(i), reset_jacobian=lambda x: np.eye(2))
        for source, edges in EDGES.items()
        for name, target_mode, i in edges
    ]
    return HybridSystem(modes, transitions, name="digital control", initial=("0", nominal_initial_state()))


class DigitalControlReference:
    """The exact execution of the digital control system from ``(mode, x0)`` at t0.

    In a mode with set-point p the flow is ``xi(t) = p + (xi(s) - p) exp(-rate (t - s))``; a
    quantity below zero with a positive set-point crosses zero after
    ``ln((p - xi) / p) / rate``. Crossings closer than 1e-12 s (relative) are simultaneous; the
    reference then lists the path through the lower-numbered mode (0 -> 1 -> 3) with both
    transitions at the same instant (the other path gives the same state: resets are identity).

    Attributes
    ----------
    mode_sequence: modes visited, in order.
    transition_times: time of each transition (s); ``transition_names``: their names.
    simultaneous: True when some two transitions happen at the same instant.
    """

    def __init__(
        self,
        x0: Iterable[float] | None = None,
        mode: str = "0",
        t0: float = 0.0,
        rate: float = 1.0,
        target: float = 1.0,
        hold: float = 0.5,
        boost: float = 2.0,
    ) -> None:
        self.rate, self.target, self.hold, self.boost = float(rate), float(target), float(hold), float(boost)
        _check(self.rate, self.target, self.hold, self.boost)
        if mode not in MODES:
            raise ModelError(f"digital control reference: unknown mode {mode!r}; modes: {list(MODES)}")
        x = nominal_initial_state() if x0 is None else np.array([float(v) for v in x0])
        if x.shape != (2,) or not np.all(np.isfinite(x)):
            raise ModelError(f"digital control reference: x0 must be 2 finite numbers (xi1, xi2), got {x0!r}")
        for _, _, i in EDGES[mode]:
            if x[i] > 0:
                raise ModelError(
                    f"digital control reference: x0 = {x.tolist()} lies past the threshold of "
                    f"{NAMES[i]} in mode '{mode}'"
                )
        self.t0 = float(t0)
        self.x0 = x
        self._sp = setpoints(self.target, self.hold, self.boost)
        # Pieces (start time, mode, state at start); the last one lasts forever.
        self._pieces: list[tuple[float, str, np.ndarray]] = []
        self.transition_times: list[float] = []
        self.transition_names: list[str] = []
        self.simultaneous = False
        t = self.t0
        while True:
            self._pieces.append((t, mode, x.copy()))
            waits = [(self._crossing_delay(mode, x, i), name, nxt, i) for name, nxt, i in EDGES[mode]]
            if not waits:
                break
            delay, name, nxt, i = min(waits, key=lambda w: (w[0], w[2]))
            if math.isinf(delay):
                break
            t_cross = t + delay
            both = len(waits) == 2 and abs(waits[0][0] - waits[1][0]) <= 1e-12 * max(1.0, abs(t_cross))
            x = self._flow(mode, x, delay)
            x[i] = 0.0
            if both:
                # The other quantity reaches its threshold at the same instant: the next mode
                # transitions at once.
                self.simultaneous = True
                x[:] = 0.0
            self.transition_times.append(t_cross)
            self.transition_names.append(name)
            t, mode = t_cross, nxt
        self.mode_sequence = [m for _, m, _ in self._pieces]
        self._starts = np.array([p[0] for p in self._pieces])

    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> DigitalControlReference:
        """The same system from another initial mode and state."""
        return DigitalControlReference(x, mode, t0, self.rate, self.target, self.hold, self.boost)

    def _flow(self, mode: str, x: np.ndarray, dt: float | np.ndarray) -> np.ndarray:
        p = self._sp[mode]
        decay = np.exp(-self.rate * np.asarray(dt, dtype=float))
        return p + (x - p) * decay[..., None] if np.ndim(dt) else p + (x - p) * float(decay)

    def _crossing_delay(self, mode: str, x: np.ndarray, i: int) -> float:
        p = float(self._sp[mode][i])
        if x[i] >= 0.0:
            return 0.0
        if p <= 0.0:
            return math.inf
        return math.log((p - x[i]) / p) / self.rate

    def states(self, times: Iterable[float] | float) -> np.ndarray:
        """Exact states at ``times`` (s), shape (len, 2) (right-continuous at transitions)."""
        arr = as_times(times, self.t0)
        idx = np.searchsorted(self._starts, arr, side="right") - 1
        out = np.empty((len(arr), 2))
        for p in np.unique(idx):
            sel = idx == p
            start, mode, x = self._pieces[p]
            out[sel] = self._flow(mode, x, arr[sel] - start)
        return out

    def modes(self, times: Iterable[float] | float) -> list[str]:
        """Mode at each of ``times`` (the target mode at a transition instant)."""
        arr = as_times(times, self.t0)
        idx = np.searchsorted(self._starts, arr, side="right") - 1
        return [self._pieces[p][1] for p in idx]

    def state(self, t: float) -> np.ndarray:
        """Exact state at t (s)."""
        return self.states([t])[0]

    def sample(self, times: Iterable[float] | float) -> Samples:
        """The exact execution at ``times``, in the format of ``Execution.sample``."""
        arr = as_times(times, self.t0)
        return make_samples(arr, self.modes(arr), self.states(arr))


def make_reference(
    x0: Iterable[float] | None = None, mode: str = "0", t0: float = 0.0, **params: float
) -> DigitalControlReference:
    """The exact execution from (mode, x0) at t0 (default: the nominal simultaneous crossing);
    ``params`` are those of ``make_system``."""
    return DigitalControlReference(x0, mode, t0, **params)


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    boost = effects["boost"]["setpoint"] if "boost" in effects else params["target"]
    system = make_system(params["rate"], params["target"], params["hold"], boost)
    x0 = nominal_initial_state()
    reference = DigitalControlReference(x0, "0", 0.0, params["rate"], params["target"], params["hold"], boost)
    size = 0.05

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        return {"state": box(x[0] - size, x[0] + size, x[1] - size, x[1] + size)}

    scenery = {"threshold_xi1": segment([0.0, -1.5], [0.0, 2.5]), "threshold_xi2": segment([-1.5, 0.0], [2.5, 0.0])}
    return Model(
        system,
        "0",
        {"xi1": float(x0[0]), "xi2": float(x0[1])},
        None,
        geometry,
        scenery,
        reference,
        info={
            "guard units": {
                name: "units of the quantity (threshold at 0)" for edges in EDGES.values() for name, _, _ in edges
            },
            "nominal_crossing_time": reference.transition_times[0],
        },
    )


BUILDER = Builder(
    name="digital_control",
    description="Digital control system of paper 000 Fig. 1: two thresholds, four modes, simultaneous crossing.",
    parameters={
        "rate": Param(1.0, "relaxation rate towards the set-point", "1/s", low=0.0, low_open=True),
        "target": Param(1.0, "set-point of both quantities before crossing", "units of xi", low=0.0, low_open=True),
        "hold": Param(0.5, "set-point of a quantity after its own crossing", "units of xi"),
    },
    effects={
        "boost": Effect(
            "once one quantity has crossed, the controller pushes the other towards `setpoint`",
            default_on=True,
            parameters={"setpoint": Param(2.0, "set-point of the other quantity", "units of xi")},
        )
    },
    build=_build,
)
