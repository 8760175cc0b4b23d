"""Compiled twins of the SLIP hopper's modes (``robots.slip_hopper``; ``legsim.compiled.CompiledMode``):
numba functions computing what the hopper's Python callables compute, in the same order, so
that both paths agree to rounding.

* ``flight``: field ``(xd, zd, u, 0, -g)``, guard touchdown (the foot's height, or
  ``max(height, zd)`` while the mass rises, m), reset ``land`` (the foot pinned at
  ``x + l sin(psi)``);
* ``stance``: field of the spring pushing along the leg, guard liftoff ``max(l - r, -dr/dt)``
  (m), reset ``leave`` (the leg leaves at its stance angle).

The twin computes Raibert's foot placement itself (``CompiledMode.controls``): the control
record (``CONTROL_KINDS``) travels in p, written by Python at every mode entry after the
controller's reset, so the stance time the controller measured at the last liftoff is the one
the next flight's law uses. The flight's swing rate is ``k_swing (psi* - psi)`` with psi* from
``raibert.touchdown_angle`` compiled from its Python source (one rule on both paths); the
stance takes no control (its Python field ignores u).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numba
import numpy as np

from legsim.compiled import CompiledMode
from legsim.control import keeps_law

from .control_laws import swing_rate
from .raibert import SLIP_TWIN, SlipRaibert, touchdown_angle_compiled

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
_swing_rate = _jit(swing_rate)

# p: the hopper (mass kg, stiffness N/m, rest length m, gravity m/s^2), then the control record.
P_M, P_K, P_L, P_G, P_CTRL = range(5)
#: Control records (at p[P_CTRL]): the kind, then its values. ``CTRL_NONE``: no control (a run
#: without one: the leg keeps its angle, u = 0). ``CTRL_SLIP_RAIBERT``: ``(kind, k_swing (1/s),
#: T_s (s), k_x (s), speed (m/s), l (m))``, ``SlipRaibert.compiled_record``: the swing rate
#: ``k_swing (touchdown_angle(xd, T_s, k_x, speed, l) - psi)`` (rad/s) in flight.
CONTROL_KINDS = ("none", "slip_raibert")
CTRL_NONE, CTRL_SLIP_RAIBERT = range(len(CONTROL_KINDS))
R_KIND, R_SWING, R_STANCE_TIME, R_K_X, R_SPEED, R_L = range(6)
RECORD_SIZE = 6


@_jit
def swing_control(x, p):
    """The flight's swing rate u (rad/s) of the record at p[P_CTRL] at state x (0 without control)."""
    at = P_CTRL
    if int(p[at + R_KIND]) == CTRL_NONE:
        return 0.0
    target = touchdown_angle_compiled(x[3], p[at + R_STANCE_TIME], p[at + R_K_X], p[at + R_SPEED], p[at + R_L])
    return _swing_rate(p[at + R_SWING], target, x[2])


@_jit
def flight_field(t, x, p):
    """(xd, zd, u, 0, -g), shape (5,)."""
    out = np.empty(5)
    out[0] = x[3]
    out[1] = x[4]
    out[2] = swing_control(x, p)
    out[3] = 0.0
    out[4] = -p[P_G]
    return out


@_jit
def flight_guards(x, p):
    """Touchdown: the foot's height z - l cos(psi), or max(height, zd) while the mass rises (m), shape (1,)."""
    out = np.empty(1)
    height = x[1] - p[P_L] * math.cos(x[2])
    out[0] = height if x[4] <= 0.0 else (x[4] if x[4] > height else height)
    return out


@_jit
def flight_resets(x, p, e):
    """Touchdown (e = 0): (x, z, xd, zd, foot_x = x + l sin(psi)), shape (5,)."""
    out = np.empty(5)
    out[0] = x[0]
    out[1] = x[1]
    out[2] = x[3]
    out[3] = x[4]
    out[4] = x[0] + p[P_L] * math.sin(x[2])
    return out


@_jit
def stance_field(t, x, p):
    """(xd, zd, k (l - r) / (m r) d - (0, g), 0) with d = (x - foot_x, z), r = |d|, shape (5,)."""
    d0 = x[0] - x[4]
    d1 = x[1]
    r = math.hypot(d0, d1)
    scale = p[P_K] * (p[P_L] - r) / (p[P_M] * r)
    out = np.empty(5)
    out[0] = x[2]
    out[1] = x[3]
    out[2] = scale * d0
    out[3] = scale * d1 - p[P_G]
    out[4] = 0.0
    return out


@_jit
def stance_guards(x, p):
    """Liftoff: max(l - r, -dr/dt) (m), shape (1,)."""
    d0 = x[0] - x[4]
    d1 = x[1]
    r = math.hypot(d0, d1)
    out = np.empty(1)
    a = p[P_L] - r
    b = -(d0 * x[2] + d1 * x[3]) / r
    out[0] = b if b > a else a
    return out


@_jit
def stance_resets(x, p, e):
    """Liftoff (e = 0): (x, z, psi = asin((foot_x - x) / l), xd, zd), shape (5,)."""
    out = np.empty(5)
    out[0] = x[0]
    out[1] = x[1]
    s = (x[4] - x[0]) / p[P_L]
    out[2] = math.asin(max(-1.0, min(1.0, s)))
    out[3] = x[2]
    out[4] = x[3]
    return out


def hopper_twins(m: float, k: float, l: float, g: float) -> dict[str, CompiledMode]:  # noqa: E741 -- the paper's symbols
    """The twins of the hopper's modes (``flight``, ``stance``) for mass m (kg), stiffness k
    (N/m), rest length l (m) and gravity g (m/s^2); each mode has its own p."""

    def params() -> np.ndarray:
        return np.array([m, k, l, g] + [float(CTRL_NONE)] + [0.0] * (RECORD_SIZE - 1))

    return {
        "flight": CompiledMode(flight_field, flight_guards, 1, params(), flight_resets, controls=controls),
        "stance": CompiledMode(stance_field, stance_guards, 1, params(), stance_resets, controls=controls),
    }


def controls(controller: Any) -> Callable[[np.ndarray], None] | None:
    """``CompiledMode.controls`` of the hopper's twins: a run without control writes
    ``CTRL_NONE``; a ``SlipRaibert`` writes its record now (``SlipRaibert.compiled_record``: the
    stance time its last reset measured, and its own leg length, which its foot placement uses
    on the Python path too); any other controller, or a SlipRaibert whose law a subclass
    changed, runs on the Python path (None)."""
    if controller is None:
        return lambda p: write_record(p, [float(CTRL_NONE)])
    if not computes(controller):
        return None
    return lambda p: write_record(p, [float(CTRL_SLIP_RAIBERT), *controller.compiled_record(SLIP_TWIN)])


def computes(controller: Any) -> bool:
    """Whether the twin computes ``controller``'s law: a ``SlipRaibert`` whose class, if a
    subclass, keeps its ``__call__`` and ``target_angle`` (a subclass may change ``reset``,
    whose values reach the twin through the record)."""
    return keeps_law(controller, SlipRaibert, ("__call__", "target_angle"))


def write_record(p: np.ndarray, record: Sequence[float]) -> None:
    """The control record ``record`` into p[P_CTRL:] (zeros past its end)."""
    p[P_CTRL:] = 0.0
    p[P_CTRL : P_CTRL + len(record)] = record
