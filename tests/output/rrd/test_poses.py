"""A part's shape and its poses: a rigid motion or a stretch along or across the part's axis
is fitted exactly and maps back to the polyline; any other change of shape is not fitted."""

from __future__ import annotations

import numpy as np

from legsim.output.rrd.poses import Shape, apply_poses, to_3d, transform_columns


def _turn(points: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, s], [-s, c]])


def _round_trip(shape: Shape, polylines: np.ndarray) -> np.ndarray:
    origin, angle, scale, fitted = shape.fit(polylines)
    assert np.all(fitted)
    return apply_poses(to_3d(shape.local), *transform_columns(origin, angle, scale))


def test_a_rigidly_moved_trunk_is_fitted_and_reproduced():
    trunk = np.array([[0.0, 0.0], [0.4, 0.1], [0.5, 0.3], [-0.1, 0.2], [0.0, 0.0]])  # closed outline
    shape = Shape.of(trunk)
    angles = np.linspace(-3.0, 3.0, 7)
    moved = np.stack([_turn(trunk, a) + np.array([1.5 * a, 0.2]) for a in angles])
    np.testing.assert_allclose(_round_trip(shape, moved), moved, atol=1e-12)


def test_a_spring_leg_stretched_along_its_axis_is_fitted():
    leg = np.array([[0.0, 1.0], [0.0, 0.5], [0.05, 0.45], [0.0, 0.0]])
    shape = Shape.of(leg)
    lengths = np.array([0.6, 0.8, 1.2])
    # The leg compressed to each length along its axis and leaning by 0.3 rad.
    moved = np.stack([_turn((leg - leg[0]) * [1.0, k], 0.3) + np.array([2.0, 1.0]) for k in lengths])
    np.testing.assert_allclose(_round_trip(shape, moved), moved, atol=1e-12)


def test_a_bent_polyline_is_not_fitted():
    link = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]])
    bent = np.array([[[0.0, 0.0], [0.5, 0.1], [1.0, 0.0]]])
    assert not Shape.of(link).fit(bent)[3][0]


def test_a_point_part_is_a_translation():
    foot = np.array([[0.3, 0.0]])
    shape = Shape.of(foot)
    moved = np.array([[[1.0, 0.2]], [[-2.0, 0.0]]])
    np.testing.assert_array_equal(_round_trip(shape, moved), moved)


def test_the_quaternion_turns_the_plane_as_the_fit_does():
    # Rerun's rotation of (1, 0, 0) by the quaternion about y must land where angle points in
    # the (x, z) plane: (cos a, 0, sin a).
    a = 0.7
    _, q, _ = transform_columns(np.zeros((1, 2)), np.array([a]), np.ones((1, 2)))
    x, y, z, w = q[0]
    v = np.array([1.0, 0.0, 0.0])
    u = np.array([x, y, z])
    turned = v + 2 * w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))
    np.testing.assert_allclose(turned, [np.cos(a), 0.0, np.sin(a)], atol=1e-15)


def test_a_spring_pressed_flat_is_its_shape_scaled_by_zero_along_its_axis():
    spring = np.array([[0.0, 0.0], [0.1, 0.05], [0.2, -0.05], [0.3, 0.05], [0.4, 0.0]])
    flat = (spring * [0.0, 1.0] + [1.0, 0.0])[None]
    np.testing.assert_allclose(_round_trip(Shape.of(spring), flat), flat, atol=1e-15)
