"""Small models written once as compiled model functions, for the tests that run every option
of the loop on both paths (tests/relaxed/test_paths.py).

* ``paddle``: a ball above a paddle, pushed by a controller that remembers the height of the
  last bounce (a ``ControlLaw`` with memory, evaluated at every stage or held over each step).
* ``two_balls``: two balls falling side by side onto one floor; equal heights make their
  impacts simultaneous, which the model resolves together (a joint function), and each ball's
  bounces accumulate into its rest (continuations).
* ``wall``: a point drifting at 1 m/s into a wall that puts it back at the far edge of the
  wall's strip, so that every entry crosses at once and time stops advancing (the stall rule).
"""

from __future__ import annotations

import numpy as np

from legsim import Continuation, HybridSystem, Mode, ModeFunctions, Transition, model_function
from legsim.control import ControlLaw

G = 9.81


@model_function
def pushed_fall(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -p[0] + u[0]


@model_function
def above_floor(t, x, u, p, g):
    g[0] = max(x[0], x[1])


@model_function
def paddle_bounce(e, t, x, u, p, out):
    out[0] = x[0]
    out[1] = -p[1] * x[1]


@model_function
def towards_memory(t, x, m, p, u):
    """A spring towards the height the controller remembers, plus a slow drive in t."""
    u[0] = p[0] * (m[0] - x[0]) + 0.5 * np.sin(3.0 * t)


@model_function
def remember_bounce(t, x, m, p, m_new):
    m_new[0] = 0.5 * m[0] + 0.2
    m_new[1] = t


def paddle(hold: bool = False) -> tuple[HybridSystem, ControlLaw]:
    """The paddle ball and its controller."""
    flight = Mode(2, names=("z", "zd"), functions=ModeFunctions(pushed_fall, above_floor, paddle_bounce,
                                                                params=[G, 0.8], inputs=1))  # fmt: skip
    system = HybridSystem({"flight": flight}, [Transition("flight", "flight", name="bounce")], name="paddle")
    law = ControlLaw(
        "spring to memory",
        towards_memory,
        1,
        lambda mode: np.array([3.0]),
        remember_bounce,
        ("level", "t_bounce"),
        ("m", "s"),
        (0.1, 0.0),
        hold=hold,
    )
    return system, law


@model_function
def two_falls(t, x, u, p, dx):
    dx[0] = x[2]
    dx[1] = x[3]
    dx[2] = -p[0]
    dx[3] = -p[0]


@model_function
def two_floors(t, x, u, p, g):
    g[0] = max(x[0], x[2])
    g[1] = max(x[1], x[3])


@model_function
def two_bounces(e, t, x, u, p, out):
    for d in range(4):
        out[d] = x[d]
    k = e % 2
    out[2 + k] = -p[1] * x[2 + k] if e < 2 else 0.0


@model_function
def both_bounce(rest, t, q, u, p, crossed, out):
    """Both balls strike at once: one law for both (both plastic when they accumulate)."""
    if crossed[0] <= 0.0 or crossed[1] <= 0.0:
        return -1
    c = 0.0 if rest == 1 else p[1]
    out[0] = q[0]
    out[1] = q[1]
    out[2] = -c * q[2]
    out[3] = -c * q[3]
    return 0


@model_function
def still(t, x, u, p, dx):
    for d in range(4):
        dx[d] = 0.0


def two_balls(c: float = 0.6) -> HybridSystem:
    """Two balls over one floor, state (z1, z2, zd1, zd2)."""
    names = ("z1", "z2", "zd1", "zd2")
    functions = ModeFunctions(two_falls, two_floors, two_bounces, both_bounce, params=[G, c],
                              joint_outcomes=(("joint_bounce", "falling"),))  # fmt: skip
    falling = Mode(4, names=names, functions=functions)
    resting = Mode(4, names=names, functions=ModeFunctions(still))
    transitions = [
        Transition("falling", "falling", name="bounce_1", continuation=Continuation("resting", name="rest_1")),
        Transition("falling", "falling", name="bounce_2", continuation=Continuation("resting", name="rest_2")),
    ]
    return HybridSystem({"falling": falling, "resting": resting}, transitions, name="two balls")


@model_function
def unit_drift(t, x, u, p, dx):
    dx[0] = 1.0


@model_function
def before_wall(t, x, u, p, g):
    g[0] = p[0] - x[0]


@model_function
def onto_strip_edge(e, t, x, u, p, out):
    out[0] = p[0] + p[1]


def wall(eps: float) -> HybridSystem:
    """The point x (m) drifting into the wall at x = 1 m, put back at 1 + eps: the image lies on
    the strip's far edge (g = -eps), so the next entry crosses with depth eps at once and its
    strip lasts eps - eps = 0 s, without end."""
    functions = ModeFunctions(unit_drift, before_wall, onto_strip_edge, params=[1.0, eps])
    return HybridSystem(
        {"a": Mode(1, names=("x",), functions=functions)}, [Transition("a", "a", name="wall")], name="wall"
    )
