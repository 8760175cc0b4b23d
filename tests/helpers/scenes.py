"""A tiny builder for scene and CLI tests, registered by monkeypatching the builder registry.

The loader is tested against this builder so that its tests do not depend on the analytic
systems and robots (tested with their own scenes in test_scene_bundled.py and test_cli.py).
A falling ball of height z (m) and velocity zd (m/s) with two effects: ``floor`` (an impact with
restitution, on by default; guard max(z, zd) in metres) and ``drag`` (a linear drag term whose
evaluations the model counts, off by default).
"""

from __future__ import annotations

import numpy as np

from legsim import HybridSystem, Mode, Transition, builders
from legsim.builders import Builder, Effect, Model, Param

TINY = "tinyball"


def _build(params, effects) -> Model:
    g = params["g"]
    counts = {"drag_evals": 0}
    drag = effects.get("drag")

    def field(t, x, u):
        a = -g
        if drag is not None:
            counts["drag_evals"] += 1
            a -= drag["c"] * x[1]
        return np.array([x[1], a])

    transitions = []
    if "floor" in effects:
        e = effects["floor"]["restitution"]
        transitions.append(
            Transition(
                "flight",
                "flight",
                guard=lambda x: max(x[0], x[1]),
                reset=lambda x: np.array([x[0], -e * x[1]]),
                name="bounce",
            )
        )
    system = HybridSystem(
        {"flight": Mode(2, field, names=("z", "zd"))},
        transitions,
        name=TINY,
        energy=lambda mode, x: g * x[0] + 0.5 * x[1] ** 2,
    )
    return Model(system, "flight", {"z": 1.0, "zd": 0.0}, counters=lambda: dict(counts), info={"params": dict(params)})


BUILDER = Builder(
    TINY,
    "a falling ball",
    {"g": Param(9.81, "gravity", "m/s^2", low=0.0, low_open=True)},
    {
        "floor": Effect(
            "impacts with the floor",
            default_on=True,
            parameters={"restitution": Param(0.5, "coefficient of restitution", low=0.0, high=1.0)},
        ),
        "drag": Effect("linear air drag", parameters={"c": Param(0.1, "drag rate", "1/s", low=0.0)}),
    },
    _build,
)


class _EntryPoint:
    name = TINY
    value = "tests.test_scene_support:BUILDER"

    def load(self):
        return BUILDER


def register_tiny(monkeypatch) -> None:
    """Make ``[robot] name = "tinyball"`` resolvable for the duration of a test."""
    original = builders.available
    monkeypatch.setattr(builders, "available", lambda: {**original(), TINY: _EntryPoint()})


TINY_SCENE = """\
[scene]
description = "a tiny ball"

[robot]
name = "tinyball"

[effects]
floor = { restitution = 0.5 }

[initial]
state = { z = 1.0 }

[integrator]
method = "rk4"
h = 1e-3
eps = 1e-3
t_final = 1.0
"""


def write_scene(directory, text: str = TINY_SCENE, name: str = "tiny"):
    path = directory / f"{name}.toml"
    path.write_text(text)
    return path
