"""Bad arguments to the metric functions (points, eps, max_hops, system, times): one test per
kind, asserting the error class and its message."""

from __future__ import annotations

import math

import pytest

from helpers.metric_systems import ball, two_mode
from legsim.errors import LegsimError
from legsim.metric import MetricError, distance, rho, shortest_path, trajectory_space_distance

A = ("fall", [1.0, 0.0])


def test_metric_error_is_a_legsim_value_error():
    assert issubclass(MetricError, LegsimError) and issubclass(MetricError, ValueError)


@pytest.mark.parametrize(
    "eps, message",
    [
        (-1e-3, "eps must be finite and >= 0"),
        (math.nan, "eps must be finite and >= 0"),
        (math.inf, "eps must be finite and >= 0"),
        ("0.1", "eps must be a number >= 0"),
        (True, "eps must be a number >= 0"),
    ],
)
def test_bad_eps(eps, message):
    with pytest.raises(MetricError, match=message):
        distance(ball(), A, A, eps)


@pytest.mark.parametrize("hops", [-1, 1.5, True, "2"])
def test_bad_max_hops(hops):
    with pytest.raises(MetricError, match="max_hops must be an integer >= 0"):
        distance(ball(), A, A, 0.1, max_hops=hops)


def test_system_must_be_a_hybrid_system():
    with pytest.raises(MetricError, match=r"system must be a legsim\.HybridSystem, got dict"):
        distance({}, A, A, 0.1)


@pytest.mark.parametrize(
    "point, message",
    [
        ("fall", r"b must be \(mode, x\) or \(mode, x, transition name, tau\)"),
        (("fall",), r"b must be \(mode, x\)"),
        ((3, [0.0, 0.0]), "b: mode must be a mode name"),
        (("fly", [0.0, 0.0]), r"b: unknown mode 'fly' of ball \(modes: \['fall'\]\)"),
        (("fall", [0.0]), r"b: state in mode 'fall' has shape \(1,\), expected \(2,\) with coordinates \('z', 'zd'\)"),
        (("fall", ["a", "b"]), "b: state in mode 'fall' is not a numeric vector"),
        (("fall", [0.0, math.nan]), "b: state in mode 'fall' is not finite"),
        (
            ("fall", [0.0, -1.0], "skid", 0.0),
            r"b: 'skid' is not a transition leaving mode 'fall' \(those are \['bounce'\]\)",
        ),
        (("fall", [0.0, -1.0], "bounce", 0.2), r"b: strip coordinate tau must be a number in \[0, eps=0.1\]"),
        (("fall", [0.0, -1.0], "bounce", -0.01), r"strip coordinate tau must be a number in \[0, eps=0.1\]"),
    ],
)
def test_bad_points(point, message):
    with pytest.raises(MetricError, match=message):
        distance(ball(), A, point, 0.1)


def test_bad_points_are_checked_in_shortest_path_too():
    with pytest.raises(MetricError, match=r"a: state in mode 'b' has shape \(2,\), expected \(3,\)"):
        shortest_path(two_mode(), ("b", [0.0, 0.0]), ("a", [0.0, 0.0]), 0.1)


@pytest.mark.parametrize(
    "times, message",
    [
        ([], r"times must be a non-empty 1-d sequence \(s\), got shape \(0,\)"),
        ([[0.1, 0.2]], r"times must be a non-empty 1-d sequence \(s\), got shape \(1, 2\)"),
        ([0.1, math.nan], "times must be finite"),
        (["a"], r"times must be a 1-d sequence of numbers \(s\)"),
    ],
)
def test_bad_times(execution, times, message):
    with pytest.raises(MetricError, match=message):
        rho(ball(), execution, execution, times, 1e-3)
    with pytest.raises(MetricError, match=message):
        trajectory_space_distance(execution, execution, times)
