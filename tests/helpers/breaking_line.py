"""A one-dimensional model that breaks down past its guard, for the certification and
stochastic tests: the flows of paper 004 run on past the guards, into the model's invalid range."""

import numpy as np

from legsim import HybridSystem, Mode, Transition
from legsim.errors import ModelBreakdown


def breaking_line(limit: float = 1.03) -> HybridSystem:
    """x' = 1 towards the guard x = 1; the model is valid only up to x = limit (a runner's hip
    above the ground, say), so flowing on past the guard breaks it down."""

    def field(t, x, u):
        if x[0] > limit:
            raise ModelBreakdown(f"line: x = {x[0]:.4g} is past its range {limit}")
        return np.array([1.0])

    return HybridSystem(
        {"a": Mode(1, field), "b": Mode(1, lambda t, x, u: np.zeros(1))},
        [Transition("a", "b", lambda x: 1.0 - x[0], name="wall")],
        name="line",
    )
