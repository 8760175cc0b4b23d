"""The terrain's height h(x), slope dh/dx and curvature d2h/dx2 as model functions over its
encoding (``legsim.terrain`` describes the kinds and their arrays): a leaf module, so that the
compiled code of the model functions that read the terrain does not depend on how a scene's
``[terrain]`` table is read.
"""

from __future__ import annotations

import math

from .compiled.functions import model_function

FLAT, SLOPE, PROFILE, SINE = 0.0, 1.0, 2.0, 3.0


@model_function
def _segment(p, at, x):
    """Index i of the profile segment [x_i, x_{i+1}) holding x (bisection); -1 left of x_0, n - 1
    at or right of x_{n-1}."""
    n = int(p[at + 1])
    xs = at + 2
    if x < p[xs]:
        return -1
    if x >= p[xs + n - 1]:
        return n - 1
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if p[xs + mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@model_function
def height(p, at, x):
    """h(x) (m) of the terrain encoded at p[at:]."""
    kind = p[at]
    if kind == FLAT:
        return p[at + 1]
    if kind == SLOPE:
        return p[at + 3] + p[at + 1] * (x - p[at + 2])
    if kind == SINE:
        return p[at + 1] + p[at + 2] * math.sin(p[at + 3] * x + p[at + 4])
    n = int(p[at + 1])
    xs, zs = at + 2, at + 2 + n
    i = _segment(p, at, x)
    if i < 0:
        return p[zs]
    if i >= n - 1:
        return p[zs + n - 1]
    w = (x - p[xs + i]) / (p[xs + i + 1] - p[xs + i])
    return p[zs + i] + w * (p[zs + i + 1] - p[zs + i])


@model_function
def slope(p, at, x):
    """dh/dx at x of the terrain encoded at p[at:] (the right segment's at a breakpoint)."""
    kind = p[at]
    if kind == FLAT:
        return 0.0
    if kind == SLOPE:
        return p[at + 1]
    if kind == SINE:
        return p[at + 2] * p[at + 3] * math.cos(p[at + 3] * x + p[at + 4])
    n = int(p[at + 1])
    xs, zs = at + 2, at + 2 + n
    i = _segment(p, at, x)
    if i < 0 or i >= n - 1:
        return 0.0
    return (p[zs + i + 1] - p[zs + i]) / (p[xs + i + 1] - p[xs + i])


@model_function
def curvature(p, at, x):
    """d2h/dx2 (1/m) at x of the terrain encoded at p[at:] (0 but on a sine)."""
    if p[at] == SINE:
        return -p[at + 2] * p[at + 3] * p[at + 3] * math.sin(p[at + 3] * x + p[at + 4])
    return 0.0
