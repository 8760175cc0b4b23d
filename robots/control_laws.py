"""Scalar control laws shared by the controllers (Python, ``robots/controllers.py``) and the
compiled twins that compute them (``robots/bridge/twins.py`` compiles these functions from this
source with numba), so that each law is written once."""

from __future__ import annotations


def pd_torque(kp: float, kd: float, target: float, q: float, v: float) -> float:
    """``kp (target - q) - kd v``: a joint PD's force (N m or N) at position q (rad or m) and
    rate v (rad/s or m/s), for stiffness kp (N m/rad) and damping kd (N m s/rad)."""
    return kp * (target - q) - kd * v
