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

On the compiled path the pronk hopper's twins compute this law (``robots/pronk_hopper_twin.py``)
from its record (``compiled_record``), written at every mode entry after ``reset``, with the
same scalar rules compiled (``touchdown_angle``, ``stance_torque``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from legsim.builders import Model, Param
from legsim.control import Controller, ControllerSpec, keeps_law
from legsim.errors import SceneError

from .control_laws import attitude_share, swing_rate
from .pronk_hopper import LEGS, MODES, PronkHopper, state_names
from .raibert import touchdown_angle

#: The share of a stance leg's spring push on the ground that its hip torque may take off.
NORMAL_SHARE = 0.5
#: ``PronkRaibert.compiled_record``'s layout, which the pronk hopper's compiled twin reads
#: (``robots/pronk_hopper_twin.py``): its kind, then the controller's values now.
RECORD_NAMES = ("kind", "k_swing", "kp_attitude", "kd_attitude", "speed", "k_x", "l", "k", "T_s_left", "T_s_right")
#: The methods that compute ``PronkRaibert``'s input, which its compiled twin computes from the record.
LAW = ("__call__", "target_angle")
#: The kind of ``compiled_record`` (0.0 is the twin's record of a run without control).
RECORD_KIND = 1.0


def stance_torque(share: float, k: float, l: float, r: float, n_x: float, n_z: float) -> float:  # noqa: E741 -- the paper's symbol
    """The hip torque (N m) of a stance leg asked for ``share`` (N m): the leg of length r (m),
    stiffness k (N/m) and rest length l (m), its unit vector foot -> hip (n_x, n_z). The
    ground's normal force is ``k (l - r) n_z + (torque / r) n_x`` (pronk_hopper), so a torque
    within ``NORMAL_SHARE k (l - r) r n_z / |n_x|`` keeps it at least half the spring's push.
    Plain scalar code: the compiled twin compiles this same function."""
    push = k * max(l - r, 0.0) * n_z
    limit = NORMAL_SHARE * push * r / max(abs(n_x), 1e-12)
    return max(-limit, min(limit, share))


class PronkRaibert(Controller):
    """Raibert's foot placement and stance attitude servo for the pronk hopper (module docstring).

    Memory: each leg's last stance duration, ``T_s_left, T_s_right`` (s); the touchdown times it
    measures from are written at each touchdown before they are read.
    """

    memory_names = ("T_s_left", "T_s_right")
    memory_units = ("s", "s")

    def __init__(self, hopper: PronkHopper, gains: dict[str, float]) -> None:
        """``gains``: the ``PRONK`` parameters by name, ``stance_time`` resolved (s)."""
        self.hopper, self.l = hopper, hopper.l
        self.speed, self.k_x, self.k_swing = gains["speed"], gains["k_x"], gains["k_swing"]
        self.kp, self.kd = gains["kp_attitude"], gains["kd_attitude"]
        self.stance_time = dict.fromkeys(LEGS, gains["stance_time"])
        self.touchdown = dict.fromkeys(LEGS, 0.0)
        self.in_stance: tuple[str, ...] = ()

    def reset(self, mode: str, t: float, x: np.ndarray) -> None:
        """Entering ``mode`` at t (s): a leg that lands notes the time, one that leaves its T_s."""
        stance = MODES[mode]
        for leg in LEGS:
            if leg in stance and leg not in self.in_stance:
                self.touchdown[leg] = t
            elif leg in self.in_stance and leg not in stance:
                self.stance_time[leg] = t - self.touchdown[leg]
        self.in_stance = stance

    def memory(self) -> np.ndarray:
        """Each leg's last stance duration (s), shape (2,), in ``LEGS`` order."""
        return np.array([self.stance_time[leg] for leg in LEGS])

    def restore(self, mode: str, memory: np.ndarray) -> None:
        """Set each leg's T_s for a run starting in flight: in stance the touchdown a T_s is
        measured from would be memory too, so a section there is refused."""
        if MODES[mode]:
            raise SceneError(
                f"controller 'raibert_pronk' restores its memory at a section in flight ('aerial'), not in "
                f"'{mode}': a leg in stance measures its stance from a touchdown before the section"
            )
        values = np.asarray(memory, dtype=float).reshape(len(LEGS))
        self.stance_time = {leg: float(value) for leg, value in zip(LEGS, values, strict=True)}
        self.in_stance = ()

    def target_angle(self, leg: str, theta: float, xd: float) -> float:
        """The leg's touchdown angle psi* (rad, from the body's downward normal) at pitch theta
        (rad) and forward speed xd (m/s)."""
        return touchdown_angle(xd, self.stance_time[leg], self.k_x, self.speed, self.l) + theta

    def __call__(self, mode: str, t: float, x: np.ndarray) -> np.ndarray:
        """``(swing_left, swing_right, torque_left, torque_right)``, rad/s and N m."""
        stance = MODES[mode]
        names = state_names(stance)
        u = np.zeros(4)
        for i, leg in enumerate(LEGS):
            if leg in stance:
                share = attitude_share(self.kp, self.kd, x[2], x[5], len(stance))
                n, r, _ = self.hopper.leg_in_stance(leg, x, x[names.index(f"{leg}_foot_x")])
                u[2 + i] = stance_torque(share, self.hopper.k, self.l, r, n[0], n[1])
            else:
                psi = x[names.index(f"psi_{leg}")]
                u[i] = swing_rate(self.k_swing, self.target_angle(leg, x[2], x[3]), psi)
        return u

    def compiled_record(self, hopper: Any) -> list[float] | None:
        """The control record (``RECORD_NAMES``) of ``hopper``'s compiled twin: the gains, each
        leg's T_s now (s), and the leg length l (m) and stiffness k (N/m) the law uses; None for
        another robot, or a pronk hopper whose hips are spaced otherwise (the twin takes the
        legs' geometry from its own hopper), or a subclass that changes the law (``__call__``,
        ``target_angle``), which the twin would not follow."""
        if not isinstance(hopper, PronkHopper) or hopper.d != self.hopper.d or not keeps_law(self, PronkRaibert, LAW):
            return None
        gains = [self.k_swing, self.kp, self.kd, self.speed, self.k_x, self.l, self.hopper.k]
        # Each leg's T_s as target_angle reads it (memory() is the orbit search's view, which a
        # subclass may list otherwise).
        return [RECORD_KIND, *map(float, gains), *(float(self.stance_time[leg]) for leg in LEGS)]


def _make(model: Model, params: dict[str, Any]) -> PronkRaibert:
    """The controller for a pronk hopper model (SceneError for any other robot)."""

    hopper = model.info.get("pronk_hopper") if isinstance(model.info, dict) else None
    if not isinstance(hopper, PronkHopper):
        raise SceneError(
            f"controller 'raibert_pronk' drives the pronk hopper (robot 'pronk_hopper'); {model.system.name} is not one"
        )
    gains = dict(params)
    # Two legs share the body in stance: half the spring-mass period of the body on both springs.
    gains["stance_time"] = params["stance_time"] or math.pi * math.sqrt(hopper.m / (2 * hopper.k))
    return PronkRaibert(hopper, gains)


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
