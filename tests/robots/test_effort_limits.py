"""Effort limits: a URDF joint's <limit effort> saturates its input inside the model functions
(both loops, the kernel included), and the time each joint spends saturated is counted.

The closed form: a slider of mass m held at 0 by a PD without damping or gravity compensation,
u = -kp z, under gravity. Until the command reaches the limit L it is a spring:
z(t) = -(g / w^2)(1 - cos w t), w^2 = kp / m, u(t) = m g (1 - cos w t), which reaches L at
t* = acos(1 - L / (m g)) / w; from then on u = L and it falls with acceleration
-(g - L / m), saturated for the rest of the run."""

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.errors import SceneError
from legsim.scene import load_scene
from tests.helpers.urdf_robots import SLIDER_EFFORT, SLIDER_KP, SLIDER_MASS, G, slider

T_FINAL = 1.0
W = math.sqrt(SLIDER_KP / SLIDER_MASS)


def saturated_from(limit):
    """t*, z(t*), zd(t*) where the PD's command reaches the limit."""
    ts = math.acos(1.0 - limit / (SLIDER_MASS * G)) / W
    return ts, -(G / W**2) * (1 - math.cos(W * ts)), -(G / W) * math.sin(W * ts)


def saturated_state(limit, t):
    ts, zs, vs = saturated_from(limit)
    a = -(G - limit / SLIDER_MASS)
    return np.array([zs + vs * (t - ts) + 0.5 * a * (t - ts) ** 2, vs + a * (t - ts)])


THREE = "robot.parameters.effort_limits={lift = 3.0}"
OFF = "robot.parameters.effort_limits={lift = 'off'}"


@pytest.mark.parametrize(("overrides", "limit"), [([], SLIDER_EFFORT), ([THREE], 3.0)])
def test_a_pd_holding_a_load_beyond_its_effort_limit_sags_as_the_closed_form(tmp_path, overrides, limit):
    assert limit < SLIDER_MASS * G  # the limit cannot hold the load
    scene = load_scene(slider(tmp_path), overrides)
    ex = scene.simulate()
    assert ex.status == "finished" and ex.counters["python_steps"] == 0
    ts, _, _ = saturated_from(limit)
    assert ex.counters["saturated_lift_s"] == pytest.approx(T_FINAL - ts, abs=1e-8)
    # RK4 steps over the kink at t*: O(h^2) there, about 1e-6
    assert np.allclose(ex.final_state, saturated_state(limit, T_FINAL), atol=5e-6)
    for t in (0.5 * ts, ts + 0.5 * (T_FINAL - ts)):
        expected = saturated_state(limit, t) if t > ts else [-(G / W**2) * (1 - math.cos(W * t))]
        assert ex.sample([t]).states[0][: len(expected)] == pytest.approx(expected, abs=5e-6)


def test_the_python_loop_saturates_as_the_kernel(tmp_path):
    scene = load_scene(slider(tmp_path))
    control = scene.control
    runs = [
        simulate(scene.model.system, scene.initial_state, scene.initial_mode, T_FINAL, 1e-3, 1e-4, "rk4", control,
                 watches=scene.watches(control), python=python)
        for python in (False, True)
    ]  # fmt: skip
    assert runs[0].counters["python_steps"] == 0 and runs[1].counters["compiled_steps"] == 0
    assert np.array_equal(runs[0].final_state, runs[1].final_state)
    assert runs[0].counters["saturated_lift_s"] == runs[1].counters["saturated_lift_s"] > 0.5


@pytest.mark.parametrize("overrides", [["robot.parameters.saturate=false"], [OFF]])
def test_without_a_limit_the_pd_is_a_spring_and_nothing_is_counted(tmp_path, overrides):
    ex = load_scene(slider(tmp_path), overrides).simulate()
    assert "saturated_lift_s" not in ex.counters
    t = np.linspace(0.0, T_FINAL, 11)
    assert np.allclose(ex.sample(t).stack()[:, 0], -(G / W**2) * (1 - np.cos(W * t)), atol=1e-9)


def test_a_limit_the_load_never_reaches_counts_no_time(tmp_path):
    ex = load_scene(slider(tmp_path), ["robot.parameters.effort_limits={lift = 50.0}"]).simulate()
    assert ex.counters["saturated_lift_s"] == 0.0
    assert ex.sample([T_FINAL]).states[0][0] == pytest.approx(-(G / W**2) * (1 - math.cos(W * T_FINAL)), abs=1e-9)


def test_the_summary_shows_the_time_at_the_limit(tmp_path):
    from legsim.commands.run import format_summary

    scene = load_scene(slider(tmp_path))
    ex = scene.simulate()
    text = format_summary(scene.summary(ex))
    assert f"time at the effort limit: lift {ex.counters['saturated_lift_s']:.6g} s" in text
    assert scene.summary(ex)["saturated_lift_s"] == ex.counters["saturated_lift_s"]


@pytest.mark.parametrize(
    ("overrides", "match"),
    [
        (["robot.parameters.effort_limits={hip = 3.0}"],
         r"effort_limits: unknown joint\(s\) \['hip'\]; actuated joints: \['lift'\]"),
        (["robot.parameters.effort_limits={lift = -3.0}"], r"effort_limits.lift: -3.0 is out of range"),
        (["robot.parameters.effort_limits={lift = 'none'}"],
         r"effort_limits.lift: expected a number > 0 \(N m or N\) or 'off'"),
        ([THREE, "robot.parameters.saturate=false"], r"given with saturate = false"),
    ],
)  # fmt: skip
def test_bad_effort_limits_are_named(tmp_path, overrides, match):
    with pytest.raises(SceneError, match=match):
        load_scene(slider(tmp_path), overrides)
