"""The digital control system of paper 000 Fig. 1: two thresholds, four modes, and the nominal
execution that crosses both thresholds at the same instant."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import ModelError, simulate
from legsim.scene import load_scene
from legsim.systems import digital_control as dc

T = 2.0


@pytest.fixture(scope="module")
def system():
    return dc.make_system()


# -- the reference ---------------------------------------------------------------------------------
def test_nominal_reference_crosses_both_thresholds_at_ln2():
    ref = dc.make_reference()
    assert ref.simultaneous
    np.testing.assert_allclose(ref.transition_times, [math.log(2.0)] * 2, rtol=1e-15)
    assert ref.mode_sequence == ["0", "1", "3"]
    # Resets are the identity and both quantities are at their thresholds: R(0, 0) = (0, 0).
    np.testing.assert_array_equal(ref.state(math.log(2.0)), [0.0, 0.0])
    # In mode 3 both relax to the hold set-point 0.5 from 0.
    t = np.array([1.0, 2.0])
    np.testing.assert_allclose(ref.states(t), 0.5 * (1 - np.exp(-(t - math.log(2.0))))[:, None] * [1, 1], rtol=1e-14)


@pytest.mark.parametrize(
    "mode_start, x0", [("0", [-1.2, -0.7]), ("0", [-0.3, -2.0]), ("1", [0.1, -0.4]), ("2", [-0.6, 0.3])]
)
def test_reference_solves_each_mode_ode(mode_start, x0):
    ref = dc.make_reference(x0, mode_start)
    setpoints = dc.setpoints()
    ts = np.linspace(0.0, 3.0, 3001)
    modes = ref.modes(ts)
    states = ref.states(ts)
    d = 1e-5
    for t, m, x in zip(ts[1:-1:50], modes[1:-1:50], states[1:-1:50], strict=True):
        if any(abs(t - tc) < 2 * d for tc in ref.transition_times):
            continue
        fd = (ref.state(t + d) - ref.state(t - d)) / (2 * d)
        np.testing.assert_allclose(fd, setpoints[m] - x, rtol=1e-7, atol=1e-9)
    # At each transition the watched quantity is exactly at its threshold, and the state is
    # continuous (identity resets).
    for tc in ref.transition_times:
        left, right = ref.state(tc - 1e-12), ref.state(tc)
        np.testing.assert_allclose(left, right, atol=1e-11)
    # Domains: a quantity whose threshold the mode still watches is <= 0.
    for m, x in zip(modes, states, strict=True):
        for _, _, i in dc.EDGES[m]:
            assert x[i] <= 1e-15


def test_perturbed_executions_take_the_two_paths_and_converge_to_the_nominal():
    # Paper 000 Sec. V-A: y_delta(0) = x(0) + (-delta, 0) and z_delta(0) = x(0) + (0, -delta) go
    # through different modes, 0 -> 2 -> 3 and 0 -> 1 -> 3, yet approach x as delta -> 0.
    nominal = dc.make_reference()
    gaps = []
    for delta in (1e-2, 1e-3, 1e-4):
        y = dc.make_reference(dc.nominal_initial_state() + np.array([-delta, 0.0]))
        z = dc.make_reference(dc.nominal_initial_state() + np.array([0.0, -delta]))
        assert y.mode_sequence == ["0", "2", "3"] and z.mode_sequence == ["0", "1", "3"]
        assert not y.simultaneous and not z.simultaneous
        gaps.append(max(np.abs(y.state(T) - nominal.state(T)).max(), np.abs(z.state(T) - nominal.state(T)).max()))
    ratios = np.array(gaps[:-1]) / np.array(gaps[1:])
    assert np.all((ratios > 8) & (ratios < 12))  # linear in delta


def test_reference_rejects_states_past_a_threshold():
    with pytest.raises(ModelError, match=r"x0 = \[0.5, -1.0\] lies past the threshold of xi1 in mode '0'"):
        dc.make_reference([0.5, -1.0])
    with pytest.raises(ModelError, match=r"unknown mode '7'"):
        dc.make_reference([0.0, 0.0], "7")


# -- the relaxed integrator --------------------------------------------------------------------
def test_simulation_through_the_simultaneous_crossing(system):
    ref = dc.make_reference()
    errors = []
    for eps in (1e-3, 1e-4, 1e-5):
        ex = simulate(system, dc.nominal_initial_state(), "0", T, 1e-2, eps)
        assert ex.status == "finished"
        # One transition at a time: either path, both through mode 3.
        assert ex.mode_sequence in (["0", "1", "3"], ["0", "2", "3"])
        first, second = ex.transitions
        assert first.time == pytest.approx(math.log(2.0), abs=1e-9)
        # The second guard is already crossed when the first strip is left: the next mode takes
        # it at once, delayed only by the strip holds: eps - tau + tau / v each, at most eps / v
        # with v >= 1 - eps the quantities' speed in the strip (d xi/dt = 1 - xi in mode 0).
        assert second.time == pytest.approx(first.exit_time, abs=1e-12)
        assert second.exit_time - first.time <= 2 * eps / (1 - eps) + 1e-12
        errors.append(np.abs(ex.final_state - ref.state(T)).max())
    assert errors[0] / errors[1] == pytest.approx(10, rel=0.2)
    assert errors[1] / errors[2] == pytest.approx(10, rel=0.2)


@pytest.mark.parametrize("shift, path", [([-1e-3, 0.0], ["0", "2", "3"]), ([0.0, -1e-3], ["0", "1", "3"])])
def test_simulation_of_the_perturbed_executions(system, shift, path):
    x0 = dc.nominal_initial_state() + shift
    ref = dc.make_reference(x0)
    ex = simulate(system, x0, "0", T, 1e-2, 1e-6)
    assert ex.mode_sequence == ref.mode_sequence == path
    np.testing.assert_allclose([tr.time for tr in ex.transitions], ref.transition_times, atol=1e-5)
    # The samples carry the mode too, in Execution.sample's format.
    ts = np.linspace(0, T, 201)
    sim, exact = ex.sample(ts), ref.sample(ts)
    mismatched = [t for t, a, b in zip(ts, sim.modes, exact.modes, strict=True) if a != b]
    assert all(min(abs(t - tc) for tc in ref.transition_times) < 1e-4 for t in mismatched)
    assert np.abs(sim.stack() - exact.stack()).max() < 1e-5


def test_scene_is_the_nominal_execution():
    scene = load_scene("digital_control")
    np.testing.assert_array_equal(scene.initial_state, dc.nominal_initial_state())
    assert scene.initial_mode == "0"
    ex = scene.simulate()
    assert ex.status == "finished" and ex.final_mode == "3"
    ref = scene.model.reference
    eps = scene.integrator["eps"]
    # O(eps): the strips delay mode 3 by at most 2 eps, where xi moves at speed <= 0.5.
    assert np.abs(ex.final_state - ref.state(scene.integrator["t_final"])).max() <= 2 * eps * 0.5 + 1e-9


def test_builder_without_boost():
    model = dc.BUILDER.make({}, {"boost": False})
    ref = model.reference
    # Each quantity's set-point then depends on its own threshold only.
    assert dc.setpoints(1.0, 0.5, 1.0)["1"][1] == 1.0
    np.testing.assert_allclose(ref.transition_times, [math.log(2.0)] * 2)
