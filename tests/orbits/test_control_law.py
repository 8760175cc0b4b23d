"""Orbits of a closed loop whose controller is a ``ControlLaw``: its memory is part of the
run's state, and the orbit search solves for it with the plant's state."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModeFunctions, Transition, model_function
from legsim.control import ControlLaw
from legsim.errors import ModelError
from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit


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


@model_function
def fall_along(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -9.81 + u[0]
    dx[2] = 1.0  # m/s along x: the ball travels while it bounces


@model_function
def kicked_bounce_along(e, t, x, u, p, out):
    out[0] = x[0]
    out[1] = -p[0] * x[1] + p[1]
    out[2] = x[2]


@model_function
def no_input(t, x, m, p, u):
    u[0] = 0.0


@model_function
def note_bounce(t, x, m, p, m_new):
    """Just after a bounce (rising): the time since the last one (s) and the distance (m) from
    its place, then its time and place. A run starting at the apex notes nothing."""
    m_new[:] = m
    if x[1] > 0.0:
        m_new[1] = t - m[0]
        m_new[3] = x[2] - m[2]
        m_new[0] = t
        m_new[2] = x[2]


def bounce_log(frames):
    def make(model):
        return ControlLaw(
            "bounce log", no_input, 1, lambda mode: np.zeros(1), note_bounce,
            ("last", "interval", "place", "stride"), ("s", "s", "m", "m"), (0.0, 0.0, 0.0, 0.0),
            memory_frames=frames,
        )  # fmt: skip

    return make


def travelling_ball():
    flight = Mode(
        3,
        names=("z", "zd", "x"),
        functions=ModeFunctions(fall_along, floor, kicked_bounce_along, params=[C, V0], inputs=1),
    )
    return HybridSystem({"flight": flight}, [Transition("flight", "flight", name="bounce")], name="travelling ball")


def test_memory_of_epochs_and_places_is_periodic_in_each_returns_frame():
    # The bounce speed V0 / (1 - C) = 5 m/s gives a flight time T = 2 * 5 / 9.81 s. On the orbit
    # at the apex the last bounce was T/2 ago, T/2 m behind, and each interval and stride is T.
    # Every return restarts the clock and x, so the noted time and place repeat only shifted
    # by the return time and the increment of x: their frames "t" and "x".
    T = 2.0 * V0 / (1.0 - C) / 9.81
    problem = OrbitProblem(
        travelling_ball(), Section.level("flight", "zd", 0.0, "decreasing"), h=1e-3, eps=1e-9, t_max=5.0,
        controller=bounce_log(("t", "", "x", "")), cyclic=("x",), method="dopri5", rtol=1e-11, atol=1e-12,
        landing="dense",
    )  # fmt: skip
    result = find_orbit(
        problem, {"z": 1.0, "zd": 0.0, "x": 0.0}, memory=[-0.3, 0.5, -0.2, 0.7], jacobian="fd", tol=1e-9
    )
    assert result.converged, result.message
    assert result.memory == pytest.approx([-T / 2, T, -T / 2, T], abs=1e-7)
    assert result.period == pytest.approx(T, abs=1e-7) and result.step_length == pytest.approx(T, abs=1e-7)


def test_a_memory_frame_that_is_no_coordinate_is_refused():
    with pytest.raises(OrbitError, match=r"memory_frames .*'y'.*coordinate of mode 'flight'"):
        OrbitProblem(
            travelling_ball(), Section.level("flight", "zd", 0.0, "decreasing"), h=1e-3, eps=1e-9, t_max=5.0,
            controller=bounce_log(("t", "", "y", "")), cyclic=("x",),
        )  # fmt: skip


def test_a_law_with_a_frame_missing_is_refused_by_name():
    with pytest.raises(ModelError, match=r"controller bounce log: memory_frames \('t',\) must have one entry per"):
        ControlLaw(
            "bounce log", no_input, 1, lambda mode: np.zeros(1), note_bounce, ("last", "interval"), ("s", "s"),
            memory_frames=("t",),
        )  # fmt: skip
