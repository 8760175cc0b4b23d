"""The geometry the metric builds from a system: reset models and guard pieces."""

from __future__ import annotations

import numpy as np

from helpers.metric_systems import C, ball
from legsim.metric.geometry import geometry_of


def test_ball_guard_and_reset_are_recognised_in_a_plain_lambda():
    # The probed shape must be exact (snapped), so that projections land exactly on the guard.
    geo = geometry_of(ball())
    geo.ensure(["fall"])
    (edge,) = geo.edges
    assert edge.affine is not None
    np.testing.assert_array_equal(edge.affine[0], [[1.0, 0.0], [0.0, -C]])
    # The piece {zd = 0, z <= 0} maps to itself (a crossing there only costs eps): dropped.
    assert len(edge.pieces) == 1
    np.testing.assert_array_equal(edge.pieces[0].lb, [0.0, -np.inf])
    np.testing.assert_array_equal(edge.pieces[0].ub, [0.0, 0.0])
