"""The declarations a model can use for the metric: ``CoordinateGuard`` and ``AffineReset``
refuse malformed terms, naming what is wrong."""

from __future__ import annotations

import math

import pytest

from legsim import ModelError
from legsim.metric import AffineReset, CoordinateGuard


@pytest.mark.parametrize(
    "terms, message",
    [
        ((), r"CoordinateGuard needs at least one term \(index, scale, value\)"),
        (((0, 1.0),), r"CoordinateGuard terms are \(index, scale, value\), got \(0, 1.0\)"),
        (((-1, 1.0, 0.0),), "CoordinateGuard index must be an integer >= 0, got -1"),
        (((0, 0.0, 0.0),), "scale must be finite and nonzero"),
        (((0, 1.0, math.nan),), "value finite"),
        (((0, 1.0, 0.0), (0, -1.0, 2.0)), r"CoordinateGuard indices must be distinct, got \[0, 0\]"),
    ],
)
def test_bad_coordinate_guard(terms, message):
    with pytest.raises(ModelError, match=message):
        CoordinateGuard(*terms)


@pytest.mark.parametrize(
    "matrix, offset, message",
    [
        ([1.0, 2.0], None, r"AffineReset matrix must be a finite 2-d array, got shape \(2,\)"),
        ([[1.0, math.inf]], None, "AffineReset matrix must be a finite 2-d array"),
        ([[1.0, 0.0]], [0.0, 1.0], r"AffineReset offset must be finite of shape \(1,\), got \(2,\)"),
    ],
)
def test_bad_affine_reset(matrix, offset, message):
    with pytest.raises(ModelError, match=message):
        AffineReset(matrix, offset)
