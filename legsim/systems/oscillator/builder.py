"""The oscillator's builder for scenes (``BUILDER``): effects stop, zeno, damping and forcing,
its picture (a box on a spring against the stop) and the exact reference of the run."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ...builders import ZENO_EFFECT, ZENO_WINDOW, Builder, Effect, Model, Param
from ...errors import ModelError
from .._reference import box, segment, zigzag
from .model import MODE, forcing, make_system
from .reference import OscillatorReference


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """The model a scene names: only the effects that are on (no damping: a field without a
    damping term; no forcing: no control), the forcing as its control law, and the exact
    reference from the scene's initial state (None, with the reason in ``info``, where eq. (28)
    does not apply)."""
    stop = effects.get("stop")
    damping = effects.get("damping")
    force = effects.get("forcing")
    x_max = None if stop is None else stop["position"]
    c = 0.0 if stop is None else stop["restitution"]
    a = 0.0 if damping is None else damping["a"]
    system = make_system(params["omega"], a, x_max, c, params["mass"])
    control = None if force is None else forcing(force["amplitude"], force["frequency"])
    amplitude = 0.0 if force is None else force["amplitude"]
    frequency = 0.0 if force is None else force["frequency"]
    size = params["size"]
    info: dict[str, Any] = {
        "guard units": {
            "impact": "m (distance to the stop)",
            "release": "m/s^2 (free acceleration pressing the mass on the stop)",
        }
        if stop
        else {}
    }
    if "zeno" in effects:
        info[ZENO_WINDOW] = effects["zeno"]["window"]
    if x_max is not None:
        info["initial_check"] = _beyond_the_stop(x_max)
    try:
        reference = OscillatorReference(
            params["omega"], a, x_max, c, params["mass"], amplitude, frequency, params["x0"], params["xd0"]
        )
    except ModelError as exc:  # over-damped or undamped resonance: no closed form here
        reference = None
        info["reference"] = f"none: {exc}"

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        pos = float(x[0])
        wall = -2.0 * size if x_max is None else min(-2.0 * size, x_max - 4.0 * size)
        return {
            "mass": box(pos - size, pos, 0.0, size),
            "spring": zigzag(min(wall, pos - size), pos - size, 0.5 * size, 0.2 * size),
        }

    return Model(
        system,
        MODE,
        {"x": params["x0"], "xd": params["xd0"]},
        control,
        geometry,
        _scenery(params["x0"], x_max, size),
        reference,
        info=info,
    )


def _scenery(x0: float, x_max: float | None, size: float) -> dict[str, np.ndarray]:
    """The floor under the motion (m), the stop (when there is one) and the spring's rest mark."""
    scenery: dict[str, np.ndarray] = {}
    lo = -abs(x0) - 4.0 * size if x_max is None else min(x0, x_max) - 4.0 * size
    hi = abs(x0) + 4.0 * size if x_max is None else x_max + size
    scenery["floor"] = segment([lo, 0.0], [hi, 0.0])
    if x_max is not None:
        scenery["stop"] = segment([x_max, 0.0], [x_max, 2.0 * size])
    scenery["rest"] = segment([0.0, -0.25 * size], [0.0, 0.0])
    return scenery


def _beyond_the_stop(x_max: float) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check: the guard max(x_max - x, -xd) counts a mass beyond the
    stop as inside while it moves away from it (that is how it leaves the stop after an impact
    in the strip), so a start deeper than the strip must be refused by name."""

    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        if x[0] > x_max + eps:
            return f"x = {x[0]:g} m lies beyond the stop x_max = {x_max:g} m by more than eps = {eps:g} m"
        return None

    return check


BUILDER = Builder(
    name="oscillator",
    description="Forced linear oscillator with a stop (paper 000 Sec. V-B); defaults are Table I Example 1.",
    parameters={
        "omega": Param(2.5, "natural frequency sqrt(k/m)", "rad/s", low=0.0, low_open=True),
        "mass": Param(1.0, "mass m (the forcing is a force, the field uses u/m)", "kg", low=0.0, low_open=True),
        "x0": Param(11.36, "default initial position", "m"),
        "xd0": Param(31.4, "default initial velocity", "m/s"),
        "size": Param(1.0, "side of the box drawn for the mass", "m", low=0.0, low_open=True),
    },
    effects={
        "stop": Effect(
            "a rigid stop at x = position with the impact law xd -> -c xd",
            default_on=True,
            parameters={
                "position": Param(14.0, "position of the stop x_max", "m"),
                "restitution": Param(0.9, "coefficient of restitution c", "", low=0.0, high=1.0),
            },
        ),
        "zeno": ZENO_EFFECT,
        "damping": Effect(
            "viscous damping 2 a xd",
            default_on=True,
            parameters={"a": Param(0.05, "damping rate mu / (2 m)", "1/s", low=0.0)},
        ),
        "forcing": Effect(
            "external force u(t) = amplitude cos(frequency t), the model's control law",
            default_on=True,
            parameters={
                "amplitude": Param(20.0, "force amplitude", "N"),
                "frequency": Param(2.5, "forcing frequency", "rad/s", low=0.0),
            },
        ),
    },
    build=_build,
)
