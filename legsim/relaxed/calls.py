"""How the step loop calls a model's functions: by their index in the run's function table.

A run's ``Tables.functions`` holds every function its modes and controller use. Interpreted, it
is a list of Python callables (a model's compiled functions are callable from Python, and a
plain Python model's callables are adapted to the same signatures by ``legsim.relaxed.adapt``);
compiled, ``legsim.compiled`` gives these three helpers numba implementations that call the same
compiled functions by address. The signatures (``legsim.model`` documents them):

* ``call_state(functions, i, t, a, b, c, out)``: ``fn(t, a, b, c, out)`` -- a field
  ``(t, x, u, p, dx)``, guards ``(t, x, u, p, g)``, a control ``(t, x, m, p, u)`` or a
  controller's entry ``(t, x, m, p, m_new)``;
* ``call_indexed(functions, i, e, t, a, b, c, out)``: ``fn(e, t, a, b, c, out)`` -- a reset
  ``(e, t, x, u, p, x_new)``;
* ``call_joint(functions, i, rest, t, q, u, p, crossed, out)``: ``fn(rest, t, q, u, p, crossed,
  out) -> int`` -- a joint resolution, returning the joint outcome's index or -1.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def call_state(functions: Any, i: int, t: float, a: np.ndarray, b: np.ndarray, c: np.ndarray, out: np.ndarray) -> None:
    """Call function i of the table as ``fn(t, a, b, c, out)``."""
    functions[i](t, a, b, c, out)


def call_indexed(
    functions: Any, i: int, e: int, t: float, a: np.ndarray, b: np.ndarray, c: np.ndarray, out: np.ndarray
) -> None:
    """Call function i of the table as ``fn(e, t, a, b, c, out)``."""
    functions[i](e, t, a, b, c, out)


def call_joint(
    functions: Any,
    i: int,
    rest: int,
    t: float,
    q: np.ndarray,
    u: np.ndarray,
    p: np.ndarray,
    crossed: np.ndarray,
    out: np.ndarray,
) -> int:
    """Call function i of the table as a joint resolution ``fn(rest, t, q, u, p, crossed, out)``."""
    return int(functions[i](rest, t, q, u, p, crossed, out))
