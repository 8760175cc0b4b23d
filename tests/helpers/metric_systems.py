"""Small hybrid systems whose quotient distances are known in closed form, shared by the metric
tests (tests/metric/).

* ball: one mode (z, zd), self-transition ``bounce`` with guard max(z, zd) and reset
  (z, zd) -> (z, -c zd). Guard set G = {z = 0, zd <= 0}, image R(G) = {z = 0, zd >= 0}. For
  a = (0, -v1) in G and b = (0, c v2) in R(G), c < 1, the shortest path either goes straight
  (v1 + c v2) or crosses once at (0, -v1), where the legs cost 0 and c |v1 - v2|:
  d = min(v1 + c v2, c |v1 - v2| + eps).
* two_mode: mode a = (x, y), domain x <= 1; mode b = (u, v, w), domain u >= -1 (different
  dimensions). a->b at x = 1 resets (x, y) -> (0, y, 0); b->a at u = -1 resets
  (u, v, w) -> (0, v + w) (a projection: not an isometry). Crossing a->b from (x, y) to
  (u, v, w) costs, after unfolding the two legs into one plane,
  sqrt((1 - x + sqrt(u^2 + w^2))^2 + (y - v)^2) + eps; crossing b->a backwards costs
  min over s of sqrt((u + 1)^2 + (v + w - s)^2 / 2) + sqrt(x^2 + (y - s)^2) + eps (the guard
  points with v' + w' = s are a line at distance |v + w - s| / sqrt 2).
* disk: the unit disk with a guard of no coordinate form, 1 - x^2 - y^2 (found by SLSQP),
  self-transition reset p -> -p / 2.

``declared=True`` builds the same system with ``CoordinateGuard`` / ``AffineReset`` instead of
plain lambdas, so that both the declared and the probed shapes are tested.
"""

from __future__ import annotations

import numpy as np

from legsim import HybridSystem, Mode, Transition
from legsim.metric import AffineReset, CoordinateGuard

#: The ball's coefficient of restitution.
C = 0.5


def still(t: float, x: np.ndarray, u) -> np.ndarray:
    """A vector field that does not move: only the geometry matters to the metric."""
    return np.zeros_like(x)


def ball(c: float = C, declared: bool = False) -> HybridSystem:
    guard = CoordinateGuard((0, 1.0, 0.0), (1, 1.0, 0.0)) if declared else (lambda x: max(x[0], x[1]))
    reset = AffineReset([[1.0, 0.0], [0.0, -c]]) if declared else (lambda x: np.array([x[0], -c * x[1]]))
    return HybridSystem(
        {"fall": Mode(2, lambda t, x, u: np.array([x[1], -9.81]), names=("z", "zd"))},
        [Transition("fall", "fall", guard=guard, reset=reset, name="bounce")],
        name="ball",
    )


def two_mode(declared: bool = False) -> HybridSystem:
    g_ab = CoordinateGuard((0, -1.0, 1.0)) if declared else (lambda x: 1.0 - x[0])
    return HybridSystem(
        {"a": Mode(2, still, names=("x", "y")), "b": Mode(3, still, names=("u", "v", "w"))},
        [
            Transition("a", "b", guard=g_ab, reset=lambda x: np.array([0.0, x[1], 0.0]), name="a->b"),
            Transition("b", "a", guard=lambda x: x[0] + 1.0, reset=lambda x: np.array([0.0, x[1] + x[2]]), name="b->a"),
        ],
        name="two-mode",
    )


def disk() -> HybridSystem:
    return HybridSystem(
        {"disk": Mode(2, still)},
        [Transition("disk", "disk", guard=lambda x: 1.0 - x[0] ** 2 - x[1] ** 2, reset=lambda x: -0.5 * x, name="rim")],
        name="disk",
    )
