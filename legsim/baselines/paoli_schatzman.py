"""The Paoli-Schatzman (PS) scheme for the forced linear oscillator with a stop (paper 000, eq. (29)).

A two-step, positions-only scheme for x'' + 2a x' + omega^2 x = u(t) with a rigid stop at
x_max and restitution c:

    z_1     = x0 + xd0 h + h^2/2 (u(0) - 2a xd0 - omega^2 x0)
    y_k     = (h^2 u(t_k) + (2 - h^2 omega^2) z_k - ((1 - c) - (1 + c) a h) z_{k-1}) / (1 + a h)
    z_{k+1} = -c z_{k-1} + min(y_k, (1 + c) x_max)

Made fast the same way as legsim's own loop: the forcing is sampled on the whole grid at once
with numpy (one vectorised call), and the recurrence runs on plain floats, either interpreted
(``compiled=False``, the level of legsim's Python integrator) or compiled with numba
(``compiled=True``, the level of a compiled legsim path), so that no comparison handicaps it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import SimulationError


def _recurrence(z: np.ndarray, u: np.ndarray, h: float, a: float, omega: float, c: float, x_max: float) -> None:
    """Fill z[2:] in place from z[0], z[1] and the forcing samples u (same length as z)."""
    h2 = h * h
    inv = 1.0 / (1.0 + a * h)
    coef_now = 2.0 - h2 * omega * omega
    coef_prev = (1.0 - c) - (1.0 + c) * a * h
    cap = (1.0 + c) * x_max
    z_prev = z[0]
    z_now = z[1]
    for k in range(1, len(z) - 1):
        y = (h2 * u[k] + coef_now * z_now - coef_prev * z_prev) * inv
        z_next = -c * z_prev + (y if y < cap else cap)
        z[k + 1] = z_next
        z_prev = z_now
        z_now = z_next


_compiled_recurrence = None


def _get_compiled():
    global _compiled_recurrence
    if _compiled_recurrence is None:
        import numba  # a compiled baseline only when asked for

        _compiled_recurrence = numba.njit(cache=True, fastmath=False)(_recurrence)
    return _compiled_recurrence


def paoli_schatzman(
    a: float,
    omega: float,
    c: float,
    x_max: float,
    forcing: Callable[[np.ndarray], np.ndarray],
    x0: float,
    xd0: float,
    t_max: float,
    h: float,
    *,
    compiled: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions of the PS scheme on the grid t_k = k h, k = 0..floor(t_max / h).

    Parameters
    ----------
    a: damping (1/s), the a of x'' + 2a x' + omega^2 x = u.
    omega: natural frequency (rad/s).
    c: restitution in [0, 1].
    x_max: stop position (m); the mass moves in x <= x_max.
    forcing: vectorised u(t) (m/s^2), called once on the whole time grid.
    x0, xd0: initial position (m) and velocity (m/s).
    t_max: end time (s); h: step (s).
    compiled: run the recurrence with numba.

    Returns
    -------
    (t, z): arrays of shape (N,).
    """
    for label, value in (("h", h), ("t_max", t_max)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise SimulationError(f"{label} must be finite and > 0, got {value!r}")
    if not 0.0 <= c <= 1.0:
        raise SimulationError(f"restitution c must be in [0, 1], got {c}")
    n = math.floor(t_max / h + 1e-9) + 1
    if n < 2:
        raise SimulationError(f"t_max = {t_max} is shorter than one step h = {h}")
    t = np.arange(n) * h
    u = np.asarray(forcing(t), dtype=float)
    if u.shape != t.shape:
        raise SimulationError(f"forcing must be vectorised: u(t) returned shape {u.shape} for t of shape {t.shape}")
    z = np.empty(n)
    z[0] = x0
    z[1] = x0 + xd0 * h + 0.5 * h * h * (u[0] - 2 * a * xd0 - omega * omega * x0)
    (_get_compiled() if compiled else _recurrence)(z, u, float(h), float(a), float(omega), float(c), float(x_max))
    return t, z
