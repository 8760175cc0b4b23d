"""The scalar control laws of ``robots.control_laws`` that the hoppers' Raibert controllers
(``raibert_slip``, ``raibert_pronk``) call from their compiled functions, compiled from their
source once here: the same law on every path, not a copy of it."""

from __future__ import annotations

from legsim.compiled.functions import model_function

from .control_laws import attitude_share, swing_rate

#: ``control_laws.swing_rate``: a massless leg's swing rate (rad/s) towards its target angle.
swing_rate_compiled = model_function(swing_rate)
#: ``control_laws.attitude_share``: each stance leg's share (N m) of the pitch servo's torque.
attitude_share_compiled = model_function(attitude_share)
