"""Compiled twins of modes with Coulomb friction (robots/bridge/friction_twins.py) against the
Python bridge they mirror.

A twin computes the field (stuck contacts' KKT dynamics; slipping ones with their friction force
along W = J_z - s mu J_x) and every event's base guard; where a base is < 0 the event happens and
the twin returns nan guards, so the Python loop takes that step and the frictional impact law
chooses the outcome. Field and guards agree with the Python callables to rounding (1e-12
relative), the whole runs to rounding amplified over the run (1e-9, as the other parity tests).
"""

import math

import numpy as np
import pytest

from legsim import _native
from legsim.relaxed import simulate
from legsim.scene import load_scene

from .test_bridge_friction import block, rod
from .test_twins import assert_same_run, close, counted_run

pytestmark = pytest.mark.skipif(not _native.load(), reason=f"native library: {_native.status()}")

RNG = np.random.default_rng(31)
#: Rod drops (friction mu, state x, z, theta, and rates): each lands, slips and sticks.
DROPS = [
    (0.6, [0.0, 1.0, 0.4, 1.0, 0.0, -1.0]),
    (0.3, [0.0, 1.0, 0.4, 1.0, 0.0, -1.0]),
    (0.6, [0.0, 0.7, 0.3, 2.0, 0.0, -2.0]),
]


def drop(mu, x0):
    bridge = rod(mu)
    return simulate(bridge.system("air", x0), x0, "air", 1.5, 1e-3, 1e-4)


def check_twin_at(system, mode, x):
    """The twin of ``mode`` against the Python field and guards at x: equal where the twin's
    guards are numbers; where they are nan an event's base guard is past, so some Python guard
    is < 0 (the outcome the impact law chooses)."""
    data = system.mode_data(mode)
    twin = data.mode.compiled
    assert twin is not None and twin.fallback, mode
    x = np.ascontiguousarray(x, dtype=float)
    g_twin = twin.guards(x, twin.params)
    g_python = np.array([g(x) for g in data.guards])
    if np.all(np.isnan(g_twin)):
        assert g_python.min() < 0.0, (mode, g_python)
    else:
        close(g_twin, g_python)
    close(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, None))
    return bool(np.isnan(g_twin[0]))


@pytest.mark.parametrize(("mu", "x0"), DROPS)
def test_friction_twins_match_the_bridge_in_every_mode_a_rod_visits(mu, x0):
    """States along a drop (flight, stuck, slipping either way) and perturbed copies of them,
    some of which are past an event (a contact force pulling, a slip reversing)."""
    ex = drop(mu, x0)
    system = rod(mu).system("air", x0)
    visited, handed = set(), 0
    for segment in ex.segments:
        visited.add(segment.mode)
        for x in segment.x[:: max(1, len(segment.x) // 5)]:
            handed += check_twin_at(system, segment.mode, x)
            handed += check_twin_at(system, segment.mode, x + RNG.normal(0.0, 0.3, x.shape) * [0, 0, 0, 1, 1, 1])
    assert {"air", "foot"} <= visited and visited & {"foot>", "foot<"}
    assert handed > 0  # the nan branch was exercised


def test_a_slipping_twin_gives_nan_where_the_contact_forces_are_not_unique():
    """Painleve (test_bridge_friction): the rod slipping towards -x at theta = 0.8 with mu = 2 has
    a negative Delassus diagonal; the Python mode raises ModelBreakdown, the twin's accelerations
    are nan (its guards too, so the Python loop takes that step and says so)."""
    mu, theta = 2.0, 0.8
    x = np.array([0.5 * math.sin(theta), 0.5 * math.cos(theta), theta, -0.1, 0.0, 0.0])
    data = rod(mu).system("foot<").mode_data("foot<")
    twin = data.mode.compiled
    field = twin.field(0.0, x, twin.params)
    assert np.all(np.isnan(field[3:])) and np.array_equal(field[:3], x[3:])
    assert np.all(np.isnan(twin.guards(x, twin.params)))
    # a consistent state of the same mode (mu = 0.5) is a number
    data = rod(0.5).system("foot<").mode_data("foot<")
    assert np.all(np.isfinite(data.mode.compiled.field(0.0, x, data.mode.compiled.params)))


@pytest.mark.parametrize(("mu", "x0"), DROPS)
def test_a_rod_drop_is_the_same_run_on_both_paths(monkeypatch, mu, x0):
    compiled_ex, calls = counted_run(monkeypatch, lambda: drop(mu, x0), python=False)
    python_ex, python_calls = counted_run(monkeypatch, lambda: drop(mu, x0), python=True)
    assert calls > 0 and python_calls == 0
    assert len(compiled_ex.transitions) >= 3  # a touchdown, slips and sticks
    assert_same_run(compiled_ex, python_ex, handed_back=True)


def test_a_block_sliding_to_rest_is_the_same_run_on_both_paths(monkeypatch):
    def slide():
        x0 = [0.0, 0.0, 1.5, 0.0]
        return simulate(block(0.2, 0.4).system("foot>", x0), x0, "foot>", 3.0, 1e-3, 1e-4)

    compiled_ex, calls = counted_run(monkeypatch, slide, python=False)
    python_ex, _ = counted_run(monkeypatch, slide, python=True)
    assert calls > 0 and [t.name for t in compiled_ex.transitions] == ["stick_foot"]
    assert_same_run(compiled_ex, python_ex, handed_back=True)


def test_the_quadruped_standing_up_is_the_same_run_on_both_paths(monkeypatch):
    """A planar-root URDF robot (the root a composite joint), feet with friction, knee stops and
    a joint PD with gravity compensation computed by the twin."""

    def stand():
        return load_scene("quadruped_stand", ["integrator.t_final=1.0"]).simulate()

    compiled_ex, calls = counted_run(monkeypatch, stand, python=False)
    python_ex, _ = counted_run(monkeypatch, stand, python=True)
    assert calls > 0 and compiled_ex.transitions
    assert_same_run(compiled_ex, python_ex, handed_back=True)


def spread(a, b):
    """Per transition, the larger of the time and post-transition state differences of two runs,
    and the final state's difference."""
    steps = [
        max(abs(ta.time - tb.time), float(np.max(np.abs(ta.state_after - tb.state_after))))
        for ta, tb in zip(a.transitions, b.transitions, strict=True)
    ]
    return np.array(steps), float(np.max(np.abs(a.final_state - b.final_state)))


def assert_same_events(a, b):
    """The same statuses and events: each the same kind into the same mode (the steps the
    relaxed rule shortens to land in a strip may differ by a few as the events drift). The symmetric pronk
    lifts both feet off (or slips them) at one instant, and which of the two guards a landing
    finds first is decided by rounding on either path."""
    assert a.status == b.status and a.message == b.message
    assert len(a.transitions) == len(b.transitions)
    for ta, tb in zip(a.transitions, b.transitions, strict=True):
        assert ta.target == tb.target
        assert ta.name == tb.name or ta.name.split("_")[0] == tb.name.split("_")[0]
    assert a.counters["transitions"] == b.counters["transitions"]


@pytest.mark.parametrize("scene", ["quadruped_pronk", "quadruped_run"])
def test_the_quadruped_under_raiberts_controller_is_the_same_run_on_both_paths(monkeypatch, scene):
    """The twins compute ``raibert_runner`` (its pronk gait: ``robots.runner_twin``) in modes with
    friction; 3 s is 7 hops, 21 transitions or more. The gait amplifies rounding about 20-fold
    per hop (its final state is not accurate to 1e-3, the scenes say), so the reference for "equal
    to rounding" is the Python path's own response to rounding: its run from a start 1 ulp higher.
    The compiled run stays within 10 times that spread at every transition (plus 1e-12 for the
    first transitions, where both spreads are rounding itself)."""
    overrides = ["integrator.t_final=3.0"]
    z0 = float(load_scene(scene, overrides).initial_state[1])
    ulp_higher = [*overrides, f"initial.state.z={float(np.nextafter(z0, 1.0))!r}"]

    compiled_ex, calls = counted_run(monkeypatch, lambda: load_scene(scene, overrides).simulate(), python=False)
    python_ex, _ = counted_run(monkeypatch, lambda: load_scene(scene, overrides).simulate(), python=True)
    nudged_ex, _ = counted_run(monkeypatch, lambda: load_scene(scene, ulp_higher).simulate(), python=True)
    assert calls > 0 and len(compiled_ex.transitions) >= 20
    assert_same_events(compiled_ex, python_ex)
    assert_same_events(nudged_ex, python_ex)
    paths, paths_final = spread(compiled_ex, python_ex)
    rounding, rounding_final = spread(nudged_ex, python_ex)
    assert np.all(paths <= 10.0 * rounding + 1e-12), np.max(paths / (rounding + 1e-12))
    assert paths_final <= 10.0 * rounding_final + 1e-12


def test_the_bounding_quadruped_takes_the_python_path(monkeypatch):
    """The bound's law reads the time since a leg's liftoff, which a twin's guards do not take:
    it has no control record, and its runs stay in Python."""

    def bound():
        return load_scene("quadruped_bound", ["integrator.t_final=0.3"]).simulate()

    ex, calls = counted_run(monkeypatch, bound, python=False)
    assert calls == 0 and ex.status == "finished"


def test_a_twin_check_that_meets_nan_guards_says_its_guards_were_not_compared():
    """check_twin compares no guard of a fallback twin at a state where its guards are nan (the
    step goes to Python), and says so, so that the mode is checked again at its next visit."""
    from legsim.compiled.twin import check_twin

    system = rod(0.6).system("foot")
    data = system.mode_data("foot")
    standing = np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.0])  # upright on its end, at rest: pushing
    pulled = np.array([0.0, 0.5, 0.0, 0.0, 0.0, 20.0])  # spinning fast: the end lifts (force < 0)
    for x, compared in ((standing, True), (pulled, False)):
        g_twin = data.mode.compiled.guards(x, data.mode.compiled.params)
        assert bool(np.all(np.isfinite(g_twin))) == compared
        assert check_twin("rod", data, 0.0, x, data.mode.field(0.0, x, None)) == compared
