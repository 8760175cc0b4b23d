"""Bad input to the metric: one test per kind, asserting the error class and its message."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import ModelError, simulate
from legsim.errors import LegsimError
from legsim.metric import (AffineReset, CoordinateGuard, MetricError, distance, distances, position_error, rho,
                           shortest_path, trajectory_space_distance)
from test_metric_axioms import ball, two_mode

A = ("fall", [1.0, 0.0])


def test_metric_error_is_a_legsim_value_error():
    assert issubclass(MetricError, LegsimError) and issubclass(MetricError, ValueError)


@pytest.mark.parametrize("eps, message", [
    (-1e-3, "eps must be finite and >= 0"),
    (math.nan, "eps must be finite and >= 0"),
    (math.inf, "eps must be finite and >= 0"),
    ("0.1", "eps must be a number >= 0"),
    (True, "eps must be a number >= 0"),
])
def test_bad_eps(eps, message):
    with pytest.raises(MetricError, match=message):
        distance(ball(), A, A, eps)


@pytest.mark.parametrize("hops", [-1, 1.5, True, "2"])
def test_bad_max_hops(hops):
    with pytest.raises(MetricError, match="max_hops must be an integer >= 0"):
        distance(ball(), A, A, 0.1, max_hops=hops)


def test_system_must_be_a_hybrid_system():
    with pytest.raises(MetricError, match="system must be a legsim.HybridSystem, got dict"):
        distance({}, A, A, 0.1)


@pytest.mark.parametrize("point, message", [
    ("fall", r"b must be \(mode, x\) or \(mode, x, transition name, tau\)"),
    (("fall",), r"b must be \(mode, x\)"),
    ((3, [0.0, 0.0]), "b: mode must be a mode name"),
    (("fly", [0.0, 0.0]), r"b: unknown mode 'fly' of ball \(modes: \['fall'\]\)"),
    (("fall", [0.0]), r"b: state in mode 'fall' has shape \(1,\), expected \(2,\) with coordinates \('z', 'zd'\)"),
    (("fall", ["a", "b"]), "b: state in mode 'fall' is not a numeric vector"),
    (("fall", [0.0, math.nan]), "b: state in mode 'fall' is not finite"),
    (("fall", [0.0, -1.0], "skid", 0.0), r"b: 'skid' is not a transition leaving mode 'fall' \(those are \['bounce'\]\)"),
    (("fall", [0.0, -1.0], "bounce", 0.2), r"b: strip coordinate tau must be a number in \[0, eps=0.1\]"),
    (("fall", [0.0, -1.0], "bounce", -0.01), r"strip coordinate tau must be a number in \[0, eps=0.1\]"),
])
def test_bad_points(point, message):
    with pytest.raises(MetricError, match=message):
        distance(ball(), A, point, 0.1)


def test_bad_points_are_checked_in_shortest_path_too():
    with pytest.raises(MetricError, match=r"a: state in mode 'b' has shape \(2,\), expected \(3,\)"):
        shortest_path(two_mode(), ("b", [0.0, 0.0]), ("a", [0.0, 0.0]), 0.1)


@pytest.fixture(scope="module")
def execution():
    return simulate(ball(), [1.0, 0.0], "fall", 0.5, 1e-3, 1e-3)


@pytest.mark.parametrize("times, message", [
    ([], r"times must be a non-empty 1-d sequence \(s\), got shape \(0,\)"),
    ([[0.1, 0.2]], r"times must be a non-empty 1-d sequence \(s\), got shape \(1, 2\)"),
    ([0.1, math.nan], "times must be finite"),
    (["a"], r"times must be a 1-d sequence of numbers \(s\)"),
])
def test_bad_times(execution, times, message):
    with pytest.raises(MetricError, match=message):
        rho(ball(), execution, execution, times, 1e-3)
    with pytest.raises(MetricError, match=message):
        trajectory_space_distance(execution, execution, times)


def test_times_outside_an_execution_name_its_interval(execution):
    with pytest.raises(LegsimError, match=r"sample times must lie in \[0.0, 0.5\]"):
        rho(ball(), execution, execution, [0.1, 0.7], 1e-3)


def test_an_execution_needs_a_sample_method(execution):
    with pytest.raises(MetricError, match=r"execution_b must have a sample\(times\) -> Samples method .* got list"):
        distances(ball(), execution, [1, 2], [0.1], 1e-3)


def test_samples_must_match_the_system(execution):
    with pytest.raises(MetricError, match=r"execution_a at t=0.1: unknown mode 'fall' of two-mode"):
        rho(two_mode(), execution, execution, [0.1], 1e-3)


def test_samples_must_have_one_state_per_time(execution):
    class Short:
        def sample(self, times):
            return execution.sample(times[:1])
    with pytest.raises(MetricError, match=r"execution_b.sample\(times\) must return Samples with one mode and state"):
        rho(ball(), execution, Short(), [0.1, 0.2], 1e-3)


@pytest.mark.parametrize("simulated, coordinate, message", [
    ([1.0, 2.0, 3.0], 0, "simulated gives 3 positions for 2 times"),
    ([1.0, math.inf], 0, "simulated positions must be finite"),
    (["x", "y"], 0, "simulated positions must be numbers"),
    ("execution", "height", r"simulated: no coordinate named 'height' in mode 'fall' \(names: \('z', 'zd'\)\)"),
    ("execution", 2, r"simulated: coordinate 2 is not an index of the 2-d state in mode 'fall'"),
])
def test_bad_position_error_input(execution, simulated, coordinate, message):
    if simulated == "execution":
        simulated = execution
    with pytest.raises(MetricError, match=message):
        position_error(simulated, execution, [0.1, 0.2], coordinate=coordinate)


@pytest.mark.parametrize("terms, message", [
    ((), r"CoordinateGuard needs at least one term \(index, scale, value\)"),
    (((0, 1.0),), r"CoordinateGuard terms are \(index, scale, value\), got \(0, 1.0\)"),
    (((-1, 1.0, 0.0),), "CoordinateGuard index must be an integer >= 0, got -1"),
    (((0, 0.0, 0.0),), "scale must be finite and nonzero"),
    (((0, 1.0, math.nan),), "value finite"),
    (((0, 1.0, 0.0), (0, -1.0, 2.0)), r"CoordinateGuard indices must be distinct, got \[0, 0\]"),
])
def test_bad_coordinate_guard(terms, message):
    with pytest.raises(ModelError, match=message):
        CoordinateGuard(*terms)


@pytest.mark.parametrize("matrix, offset, message", [
    ([1.0, 2.0], None, r"AffineReset matrix must be a finite 2-d array, got shape \(2,\)"),
    ([[1.0, math.inf]], None, "AffineReset matrix must be a finite 2-d array"),
    ([[1.0, 0.0]], [0.0, 1.0], r"AffineReset offset must be finite of shape \(1,\), got \(2,\)"),
])
def test_bad_affine_reset(matrix, offset, message):
    with pytest.raises(ModelError, match=message):
        AffineReset(matrix, offset)


def test_declared_coordinate_guard_beyond_the_dimension_is_named():
    from legsim import HybridSystem, Mode, Transition
    system = HybridSystem({"m": Mode(1, lambda t, x, u: np.zeros(1))},
                          [Transition("m", "m", CoordinateGuard((0, 1.0, 0.0)), lambda x: -x)])
    # A guard declared on a coordinate the mode does not have.
    bad = HybridSystem({"m": Mode(1, lambda t, x, u: np.zeros(1))},
                       [Transition("m", "m", CoordinateGuard((3, 1.0, 0.0)), lambda x: -x)])
    assert distance(system, ("m", [1.0]), ("m", [2.0]), 0.1) == pytest.approx(1.0)
    with pytest.raises(ModelError, match=r"CoordinateGuard\(\(3, 1.0, 0.0\),\) refers to coordinate beyond dimension 1"):
        distance(bad, ("m", [1.0]), ("m", [-2.0]), 0.1)
