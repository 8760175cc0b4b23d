"""Zeno continuation: the accumulation measure and the guards of the bounce/rest pair.

With ``zeno_window`` set, a contact with restitution c > 0 gets two impact transitions with
complementary guards: ``bounce_<c>`` as without continuation, and ``rest_<c>``, a plastic
impact into the constrained mode, taken when the rebound would fly shorter than the window
(``c v0 < a_n window / 2``) and the contact would then push; the release guard on the contact
force leaves the constrained mode (docs/stress.md).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from .dynamics import constraint_forces, constraint_rows, control_key, dynamics
from .guards import kinematic_guards, state_guard
from .impacts import Reset
from .model import BridgeData, BridgeModel
from .modes import ModeSpec

Accumulation = Callable[[np.ndarray, Any], tuple[float, float, float]]


def accumulation(model: BridgeModel, data: BridgeData, contact: str, c: float, stick: ModeSpec, free: ModeSpec,
                 stick_reset: Reset) -> Accumulation:
    """``(x, u) -> (w, a_n, lambda+)`` for an impact of ``contact`` (restitution ``c``) at x past
    its gap: a_n (m/s^2 or rad/s^2) is the normal acceleration with which the contact would press
    closed after a plastic impact (``J_n (a_stuck - a_free)`` at the plastic post-impact state:
    what the constraint force has to cancel), lambda+ its normal force there, and w = c v0 the
    rebound speed, with v0 the approach speed back at the gap's zero,
    ``v0^2 = v_n^2 - 2 a_n depth``. Taking v0 rather than the speed at x makes the decision the
    same all along a step's way through the strip (the approach speeds up by a_n there), so the
    crossing search never meets a guard that switches branch inside the strip. Cached for the
    last (x, u)."""
    rigid = model.rigid[contact]
    n = model.n
    cache: dict[str, Any] = {"key": None, "value": None}

    def measure(x: np.ndarray, u: Any) -> tuple[float, float, float]:
        key = x.tobytes() + control_key(u)
        if cache["key"] == key:
            return cache["value"]
        q, v = x[:n], x[n:2 * n]
        J, _ = constraint_rows(model, data, [rigid], q, v, drift=False)
        jn = J[-1]
        if rigid.kind == "stop":
            depth = -rigid.sign * (q[rigid.dof] - rigid.contact.position)
        else:  # the Jacobian's computation has just placed the frame
            depth = rigid.contact.ground - float(data.pin_data.oMf[rigid.frame_id].translation[2])
        after = stick_reset(x)
        a_stuck = dynamics(model, data, stick, after, u)[0].copy()
        lam_n = float(constraint_forces(model, data, stick, after, u)[contact][-1])
        a_free, _ = dynamics(model, data, free, after, u)
        a_n = float(jn @ (a_stuck - a_free))
        v_n = min(0.0, float(jn @ v))
        w = c * math.sqrt(max(v_n * v_n - 2.0 * a_n * max(depth, 0.0), 0.0))
        cache["key"], cache["value"] = key, (w, a_n, lam_n)
        return w, a_n, lam_n

    return measure


def zeno_guard(model: BridgeModel, data: BridgeData, spec: ModeSpec, contact: str, measure: Accumulation,
               rest: bool) -> Callable[..., float]:
    """Guard of the rest (``rest=True``) or bounce impact of a bouncing contact under Zeno
    continuation. Past the gap guard (< 0) the impact *accumulates* when
    ``min(a_n window / 2 - w, lambda+) > 0`` (the next flight would be shorter than the window
    and the contact would push). The guard of the branch taken is the gap guard itself, so the
    strip keeps the gap's units and a bounce is held exactly as without continuation; the other
    branch's guard is ``-gap`` (> 0, not past). Declared with ``model.guard_args``."""
    window = float(model.zeno_window)  # type: ignore[arg-type]

    def value(x: np.ndarray, u: Any) -> float:
        base = kinematic_guards(model, data, spec, x)[contact]
        if base >= 0.0:
            return base
        w, a_n, lam = measure(x, u)
        accumulating = min(0.5 * a_n * window - w, lam) > 0.0
        return base if accumulating == rest else -base

    return state_guard(model, value)[0]
