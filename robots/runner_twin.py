"""Raibert's runner (``robots.raibert.RunnerRaibert``, pronk gait) computed by a compiled twin:
its control record and ``runner_control``, the torques ``RunnerRaibert.__call__`` computes,
through the same scalar laws (``robots.runner_laws``) compiled from their Python source.

The record (``RunnerRaibert.compiled_record``, kind ``CTRL_RUNNER`` of
``robots.bridge.control_records.CONTROL_KINDS``) is a head of ``RUNNER_HEAD`` values (``HEAD_FIELDS``:
the kind, the number of legs, then the gains of ``raibert.Gains`` that the pronk's torques
read) and ``RUNNER_LEG`` values per leg (``LEG_FIELDS``: the leg's hip and knee velocity indices
in the state, their positions in u, its geometry, what the controller remembers of it --
stance_time (s), thrust (m), bias (m), written after the controller's reset at every mode
entry -- and the Pinocchio frame id of its foot, by which the twin tells its contact). Units:
``raibert.Gains`` and ``raibert.Leg``.

The bound gait has no record: its stance law reads the time since the leg's liftoff (the
refractory term), and a twin's guards take no time.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba
import numpy as np

from .bridge.control_records import CTRL_RUNNER
from .runner_laws import pronk_flight_torques, stance_torques

#: The record's head and each leg's entries, in order; each leg's entries after the kind and the
#: number of legs are named as the attributes of ``raibert.Gains`` and ``raibert.Leg`` they copy.
HEAD_FIELDS = (
    "kind",
    "legs",
    "speed",
    "k_x",
    "leg_length",
    "stiffness",
    "damping",
    "kp_attitude",
    "kd_attitude",
    "kp_joint",
    "kd_joint",
)
LEG_FIELDS = (
    "hip",
    "knee",
    "u_hip",
    "u_knee",
    "thigh",
    "shank",
    "bend",
    "offset",
    "stance_time",
    "thrust",
    "bias",
    "frame",
)
(
    H_KIND,
    H_LEGS,
    H_SPEED,
    H_K_X,
    H_LEG_LENGTH,
    H_STIFFNESS,
    H_DAMPING,
    H_KP_ATTITUDE,
    H_KD_ATTITUDE,
    H_KP_JOINT,
    H_KD_JOINT,
) = range(len(HEAD_FIELDS))
(L_HIP, L_KNEE, L_U_HIP, L_U_KNEE, L_THIGH, L_SHANK, L_BEND, L_OFFSET, L_STANCE_TIME, L_THRUST, L_BIAS, L_FRAME) = (
    range(len(LEG_FIELDS))
)
RUNNER_HEAD = len(HEAD_FIELDS)
RUNNER_LEG = len(LEG_FIELDS)


def record_size(n_legs: int) -> int:
    """The length of the record of a runner with ``n_legs`` legs."""
    return RUNNER_HEAD + RUNNER_LEG * n_legs


def pack_record(gains: Any, legs: Sequence[Any], frames: Sequence[int]) -> list[float]:
    """The record of a runner with ``gains`` (``raibert.Gains``) and ``legs`` (``raibert.Leg``,
    their memory as it is now), whose feet are Pinocchio frames ``frames`` (ids, one per leg)."""
    record = [float(CTRL_RUNNER), float(len(legs))]
    record += [float(getattr(gains, name)) for name in HEAD_FIELDS[H_SPEED:]]
    for leg, frame in zip(legs, frames, strict=True):
        record += [float(getattr(leg, name)) for name in LEG_FIELDS[:L_FRAME]]
        record.append(float(frame))
    return record


@numba.njit(cache=True, fastmath=False, nogil=True)
def runner_control(x, n, p, at, stance, gravity, u):
    """The pronk's torques (N m) into u (float64 (nact,), the controller's output order) at state
    x (q then v, first 2n entries) for the record at p[at:] (the module docstring), ``stance``
    (float64 (legs,), 1.0 where the leg's contact is active in the mode, in record order) and the
    generalized ``gravity`` at q (float64 (n,), N m; read for legs in flight only), as
    ``RunnerRaibert.__call__`` computes them."""
    u[:] = 0.0
    count = int(p[at + H_LEGS])
    stance_count = 0
    for i in range(count):
        if stance[i] != 0.0:
            stance_count += 1
    attitude = p[at + H_KP_ATTITUDE] * x[2] + p[at + H_KD_ATTITUDE] * x[n + 2]
    # A pronk lifts off together: once a leg has left, the others unload while they extend.
    together = stance_count < count
    for i in range(count):
        leg = at + RUNNER_HEAD + RUNNER_LEG * i
        hip, knee = int(p[leg + L_HIP]), int(p[leg + L_KNEE])
        if stance[i] != 0.0:
            torque = stance_torques(
                p[leg + L_THIGH],
                p[leg + L_SHANK],
                x[hip],
                x[knee],
                x[n + hip],
                x[n + knee],
                p[at + H_LEG_LENGTH],
                p[leg + L_THRUST],
                p[at + H_STIFFNESS],
                p[at + H_DAMPING],
                attitude / stance_count,
                together,
            )
        else:
            torque = pronk_flight_torques(
                p[leg + L_THIGH],
                p[leg + L_SHANK],
                p[leg + L_BEND],
                p[leg + L_OFFSET],
                x[hip],
                x[knee],
                x[n + hip],
                x[n + knee],
                x[2],
                x[n],
                x[n + 1] < 0.0,
                p[leg + L_STANCE_TIME],
                p[leg + L_BIAS],
                p[at + H_SPEED],
                p[at + H_K_X],
                p[at + H_LEG_LENGTH],
                p[at + H_KP_JOINT],
                p[at + H_KD_JOINT],
                gravity[hip],
                gravity[knee],
            )
        u[int(p[leg + L_U_HIP])] += torque[0]
        u[int(p[leg + L_U_KNEE])] += torque[1]


def stance_flags(record: Sequence[float], active_frames: Sequence[int]) -> np.ndarray:
    """``runner_control``'s ``stance`` for ``record``: 1.0 for each leg whose foot frame is in
    ``active_frames`` (the frame ids of the contacts active in the mode), else 0.0."""
    count = int(record[H_LEGS])
    frames = [int(record[RUNNER_HEAD + RUNNER_LEG * i + L_FRAME]) for i in range(count)]
    return np.array([1.0 if frame in active_frames else 0.0 for frame in frames])
