"""Orbits of a closed loop whose controller is a ``ControlLaw``: its memory is part of the
run's state, and the orbit search solves for it with the plant's state."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModeFunctions, Transition, model_function
from legsim.control import ControlLaw
from legsim.orbits import OrbitProblem, Section, find_orbit


@model_function
def fall(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -9.81 + u[0]


@model_function
def floor(t, x, u, p, g):
    g[0] = max(x[0], x[1])


@model_function
def kicked_bounce(e, t, x, u, p, out):
    """Restitution c = p[0] plus a kick v0 = p[1] (m/s): the kick feeds what the impact takes."""
    out[0] = x[0]
    out[1] = -p[0] * x[1] + p[1]


@model_function
def spring(t, x, m, p, u):
    u[0] = p[0] * (m[0] - x[0])


@model_function
def halve_towards(t, x, m, p, m_new):
    m_new[0] = 0.5 * m[0] + 0.2


C, V0 = 0.8, 1.0


def kicked_ball():
    flight = Mode(2, names=("z", "zd"), functions=ModeFunctions(fall, floor, kicked_bounce, params=[C, V0], inputs=1))
    return HybridSystem({"flight": flight}, [Transition("flight", "flight", name="bounce")], name="kicked ball")


def law(model):
    return ControlLaw("spring", spring, 1, lambda mode: np.array([2.0]), halve_towards, ("level",), ("m",), (0.0,))


def test_the_orbit_search_finds_the_memory_with_the_state():
    # Fixed point: the level m* = 0.5 m* + 0.2 = 0.4 m; flight from the floor back to it keeps
    # the speed (a conservative field), so after each bounce zd* = C zd* + V0 = V0 / (1 - C).
    problem = OrbitProblem(
        kicked_ball(), Section.after("bounce"), h=1e-3, eps=1e-9, t_max=5.0, controller=law, fixed=("z",),
        method="dopri5", rtol=1e-11, atol=1e-12, landing="dense",
    )  # fmt: skip
    result = find_orbit(problem, {"z": 0.0, "zd": 3.0}, memory=[0.1], jacobian="fd", tol=1e-8)
    assert result.converged, result.message
    assert result.memory == pytest.approx([0.4], abs=1e-8)
    assert result.fixed_point[1] == pytest.approx(V0 / (1.0 - C), abs=1e-6)
    assert result.memory_names == ("level",) and result.memory_units == ("m",)
