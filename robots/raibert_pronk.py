"""Raibert's controller for the pronk hopper (``robots/pronk_hopper.py``), ``raibert_pronk``.

Each leg is placed by its own neutral point: in flight it swings at ``k_swing (psi* - psi)``
(rad/s) to the body-relative angle ``psi* = phi* + theta`` whose world angle from the vertical is
``phi* = asin((xd T_s / 2 + k_x (xd - xd*)) / l)``, T_s the leg's last stance duration (s),
measured at its liftoff. In stance the hips servo the pitch: the stance legs share the torque
``-(kp_attitude theta + kd_attitude thetad)`` (N m), each leg's share limited so that it takes
at most half the spring's push off the ground's normal force (the foot is pinned, and a hip
torque alone could make the ground pull on it). The springs are passive, so (as for the
SLIP hopper) the hopping height trades with the speed and needs no thrust; with the pitch at 0,
the servo does no work and the energy is conserved.

Written once as a ``ControlLaw`` of compiled functions (``raibert_pronk_input``,
``raibert_pronk_clock``), with the hopper's own geometry helpers: the compiled kernel and the
Python loop evaluate the same law. Its memory (``MEMORY``) is part of the run's state.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Model, Param
from legsim.compiled.functions import model_function
from legsim.control import ControlLaw, ControllerSpec
from legsim.errors import SceneError

from .hopper_laws import attitude_share_compiled, swing_rate_compiled
from .leg_laws import touchdown_angle
from .pronk_hopper import LEGS, MODES, PronkHopper, leg_coordinate, leg_in_stance

#: The share of a stance leg's spring push on the ground that its hip torque may take off.
NORMAL_SHARE = 0.5
#: The memory, per leg in ``LEGS`` order: the last stance's duration T_s (s), which the leg's
#: flight law reads; while it stands, the time of its touchdown (s), from which the next T_s is
#: measured (0 in flight: a gait's memory at a flight section is then periodic whatever the time
#: the return starts at); and 1 while it stands (0 in flight), so that a run's first entry keeps
#: the T_s it starts with (an entry function is told the mode entered, not the one left).
MEMORY = ("T_s_left", "T_s_right", "t_touchdown_left", "t_touchdown_right", "stance_left", "stance_right")
MEMORY_UNITS = ("s", "s", "s", "s", "", "")
M_STANCE_TIME, M_TOUCHDOWN, M_STANCE = 0, 2, 4
#: The parameters in each mode: gains, commanded speed, the hopper's leg length l (m), stiffness
#: k (N/m) and hip spacing d (m) the law uses, then 1.0 for each leg standing there (LEGS order).
C_K_SWING, C_KP, C_KD, C_SPEED, C_K_X, C_L, C_K, C_D, C_LEFT, C_RIGHT = range(10)


@model_function
def stance_torque(share: float, k: float, l: float, r: float, n_x: float, n_z: float) -> float:  # noqa: E741 -- the paper's symbol
    """The hip torque (N m) of a stance leg asked for ``share`` (N m): the leg of length r (m),
    stiffness k (N/m) and rest length l (m), its unit vector foot -> hip (n_x, n_z). The
    ground's normal force is ``k (l - r) n_z + (torque / r) n_x`` (pronk_hopper), so a torque
    within ``NORMAL_SHARE k (l - r) r n_z / |n_x|`` keeps it at least half the spring's push."""
    push = k * max(l - r, 0.0) * n_z
    limit = NORMAL_SHARE * push * r / max(abs(n_x), 1e-12)
    return max(-limit, min(limit, share))


@model_function
def raibert_pronk_input(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, u: np.ndarray) -> None:
    """``u = (swing_left, swing_right, torque_left, torque_right)`` (rad/s, N m) at the plant's
    state x in the mode whose standing legs p names (module docstring)."""
    left, right = p[C_LEFT], p[C_RIGHT]
    for leg in range(2):
        at = leg_coordinate(left, right, leg)
        if (left if leg == 0 else right) != 0.0:
            share = attitude_share_compiled(p[C_KP], p[C_KD], x[2], x[5], left + right)
            n0, n1, r, _ = leg_in_stance(x, p[C_D], leg, x[at])
            u[2 + leg] = stance_torque(share, p[C_K], p[C_L], r, n0, n1)
            u[leg] = 0.0
        else:
            target = touchdown_angle(x[3], m[M_STANCE_TIME + leg], p[C_K_X], p[C_SPEED], p[C_L]) + x[2]
            u[leg] = swing_rate_compiled(p[C_K_SWING], target, x[at])
            u[2 + leg] = 0.0


@model_function
def raibert_pronk_clock(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, m_new: np.ndarray) -> None:
    """Entering a mode at t (s): a leg that lands notes the time, a leg that leaves sets its T_s to
    its stance's duration and its touchdown time to 0 (``MEMORY``)."""
    for leg in range(2):
        landing = (p[C_LEFT] if leg == 0 else p[C_RIGHT]) != 0.0
        standing = m[M_STANCE + leg] > 0.5
        stance_time, touchdown = m[M_STANCE_TIME + leg], m[M_TOUCHDOWN + leg]
        m_new[M_STANCE_TIME + leg] = t - touchdown if standing and not landing else stance_time
        m_new[M_TOUCHDOWN + leg] = (t if not standing else touchdown) if landing else 0.0
        m_new[M_STANCE + leg] = 1.0 if landing else 0.0


def pronk_law(hopper: PronkHopper, gains: dict[str, float]) -> ControlLaw:
    """Raibert's pronk controller for ``hopper``; ``gains``: the ``PRONK`` parameters by name,
    ``stance_time`` (s) resolved: the T_s of both legs before their first liftoff."""
    values = [gains[name] for name in ("k_swing", "kp_attitude", "kd_attitude", "speed", "k_x")]
    values += [hopper.l, hopper.k, hopper.d]
    params = {mode: np.array([*values, *(float(leg in stance) for leg in LEGS)]) for mode, stance in MODES.items()}
    stance_time = float(gains["stance_time"])
    return ControlLaw(
        "raibert_pronk",
        raibert_pronk_input,
        4,
        params.__getitem__,
        raibert_pronk_clock,
        MEMORY,
        MEMORY_UNITS,
        (stance_time, stance_time, 0.0, 0.0, 0.0, 0.0),
    )


def _make(model: Model, params: dict[str, Any]) -> ControlLaw:
    """The controller for a pronk hopper model (SceneError for any other robot)."""
    hopper = model.info.get("pronk_hopper") if isinstance(model.info, dict) else None
    if not isinstance(hopper, PronkHopper):
        raise SceneError(
            f"controller 'raibert_pronk' drives the pronk hopper (robot 'pronk_hopper'); {model.system.name} is not one"
        )
    gains = dict(params)
    # Two legs share the body in stance: half the spring-mass period of the body on both springs.
    gains["stance_time"] = params["stance_time"] or math.pi * math.sqrt(hopper.m / (2 * hopper.k))
    return pronk_law(hopper, gains)


PRONK = ControllerSpec(
    "raibert_pronk",
    "Raibert's foot placement (each flying leg's swing rate) and stance attitude servo for the pronk hopper",
    {
        "speed": Param(1.0, "commanded forward speed xd*", "m/s"),
        "k_x": Param(0.05, "foot placement gain (m per m/s of speed error)", "s", low=0.0),
        "k_swing": Param(20.0, "leg swing servo gain", "1/s", low=0.0, low_open=True),
        "kp_attitude": Param(900.0, "stance pitch servo stiffness", "N m/rad", low=0.0),
        "kd_attitude": Param(60.0, "stance pitch servo damping", "N m s/rad", low=0.0),
        "stance_time": Param(
            0.0,
            "stance duration assumed before a leg's first liftoff; 0: pi sqrt(m / 2k), the body on both springs",
            "s",
            low=0.0,
        ),
    },
    _make,
)
