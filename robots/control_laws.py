"""Scalar control laws of the controllers (``robots/controllers.py``, ``robots/runner_laws.py``),
written once and compiled with numba where a ``ControlLaw`` calls them. ``pd_torque`` is also callable from
jitted code as it is (``register_jitable``), for laws built on it (``robots.runner_laws``)."""

from __future__ import annotations

from numba.extending import register_jitable


@register_jitable
def pd_torque(kp: float, kd: float, target: float, q: float, v: float) -> float:
    """``kp (target - q) - kd v``: a joint PD's force (N m or N) at position q (rad or m) and
    rate v (rad/s or m/s), for stiffness kp (N m/rad) and damping kd (N m s/rad)."""
    return kp * (target - q) - kd * v


def swing_rate(k_swing: float, target: float, angle: float) -> float:
    """``k_swing (target - angle)``: a massless leg's swing rate (rad/s) towards its target
    angle (rad), for a servo gain k_swing (1/s) (Raibert's flight law)."""
    return k_swing * (target - angle)


def attitude_share(kp: float, kd: float, pitch: float, pitch_rate: float, legs: float) -> float:
    """``-(kp pitch + kd pitch_rate) / legs``: each of ``legs`` stance legs' share (N m) of the
    hip torque that servos the body's pitch (rad, rad/s) to 0, for gains kp (N m/rad) and
    kd (N m s/rad)."""
    return -(kp * pitch + kd * pitch_rate) / legs
