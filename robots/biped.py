"""``raibert_biped``: Raibert's planar biped runner (*Legged Robots That Balance*, 1986, ch. 4) for
a robot with two articulated legs (a hip and a knee each, a point foot), one leg at a time:
foot placement for speed, thrust for hopping height, the stance hip's torque for the trunk's
pitch, the swing leg retracted and moving opposite the other. Its functions are written once in
``robots.biped_laws``; the legs are the ones the scene declares (each point contact on a frame
below two actuated revolute joints, ``raibert.find_legs``), in the order of the scene's
contacts: the first lands first.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from legsim.builders import Model, Param
from legsim.control import ControlLaw, ControllerSpec
from legsim.errors import SceneError

from . import biped_laws as laws
from .controllers import bridge_of
from .raibert import RUNNER_PARAMETERS, Leg, find_legs, leg_entries


@dataclass(frozen=True)
class Gains:
    """The biped controller's settings (units in ``BIPED_PARAMETERS``), in the order of the
    parameter array's head after nv (``biped_laws.B_*``)."""

    speed: float
    height: float
    k_x: float
    k_i: float
    leg_length: float
    stiffness: float
    damping: float
    k_height: float
    max_thrust: float
    kp_attitude: float
    kd_attitude: float
    kp_joint: float
    kd_joint: float
    swing_share: float
    swing_stiffness: float
    swing_damping: float
    preload: float


@dataclass(frozen=True)
class BipedLaw(ControlLaw):
    """Raibert's biped (module docstring), a ``ControlLaw`` of ``biped_laws.biped_control`` and
    ``biped_enter``; ``legs`` and ``gains`` are what its parameters were made from."""

    legs: tuple[Leg, ...] = ()
    gains: Gains | None = None


class BipedParams:
    """``BipedLaw.params``: the parameter array in a mode (``biped_laws.B_*``, then each leg's
    ``runner_laws.RL_*`` entries), each leg in stance where its foot's contact is active; built
    once per mode."""

    def __init__(self, bridge: Any, legs: tuple[Leg, ...], gains: Gains) -> None:
        self.bridge = bridge
        self.head = [float(bridge.handle), float(bridge.n)] + [float(v) for v in gains.__dict__.values()]
        self.legs = legs
        self._made: dict[str, np.ndarray] = {}

    def __call__(self, mode: str) -> np.ndarray:
        made = self._made.get(mode)
        if made is None:
            values = self.head + leg_entries(self.legs, self.bridge.active_contacts(mode))
            made = self._made[mode] = np.array(values, dtype=float)
        return made


def biped_law(bridge: Any, legs: list[Leg], gains: Gains, thrust: float, stance_time: float) -> BipedLaw:
    """Raibert's biped on ``bridge``'s two articulated ``legs`` (the first lands first), starting
    with ``thrust`` (m) and a stance time of ``stance_time`` (s); its memory is
    ``biped_laws.MEMORY_FIELDS`` with each leg's entries named by its contact
    (``stance_<contact>``, ``liftoff_<contact>``)."""
    contacts = [leg.contact for leg in legs]
    names = tuple(
        f"{field[:-2]}_{contacts[int(field[-1])]}" if field[-2:] in ("_0", "_1") else field
        for field, _ in laws.MEMORY_FIELDS
    )
    units = tuple(unit for _, unit in laws.MEMORY_FIELDS)
    initial = {
        "T_s": stance_time,
        "thrust": thrust,
        "apex": laws.LONG_AGO,
        "liftoff_0": laws.LONG_AGO,
        "liftoff_1": laws.LONG_AGO,
    }
    memory = tuple(initial.get(field, 0.0) for field, _ in laws.MEMORY_FIELDS)
    return BipedLaw(
        "raibert_biped",
        laws.biped_control,
        len(bridge.actuated_dofs),
        BipedParams(bridge, tuple(legs), gains),
        laws.biped_enter,
        names,
        units,
        memory,
        memory_frames=tuple(laws.MEMORY_FRAMES.get(field, "") for field, _ in laws.MEMORY_FIELDS),
        legs=tuple(legs),
        gains=gains,
    )


#: The runner family's gains, at the biped's defaults (a stiffer stance spring, firmer
#: attitude servo, one step's speed error feeding the integral), then the biped's own.
BIPED_PARAMETERS = {
    **{
        name: replace(RUNNER_PARAMETERS[name], default=default)
        for name, default in (
            ("speed", 1.0),
            ("height", 0.5),
            ("k_x", 0.05),
            ("k_i", 0.03),
            ("leg_length", 0.42),
            ("stiffness", 5000.0),
            ("damping", 10.0),
            ("thrust", 0.02),
            ("k_height", 0.2),
            ("max_thrust", 0.1),
            ("kp_attitude", 100.0),
            ("kd_attitude", 20.0),
        )
    },
    "kp_joint": Param(30.0, "hip stiffness on the angle of a leg off the ground", "N m/rad", low=0.0),
    "kd_joint": Param(1.5, "hip damping on the angle rate of a leg off the ground", "N m s/rad", low=0.0),
    "swing_share": Param(
        0.6, "the retracted leg's length as a share of leg_length", "", low=0.0, low_open=True, high=1.0
    ),
    "swing_stiffness": Param(
        3000.0, "stiffness along a leg off the ground (to its length)", "N/m", low=0.0, low_open=True
    ),
    "swing_damping": Param(50.0, "damping along a leg off the ground", "N s/m", low=0.0),
    "preload": Param(
        0.01,
        "the landing leg is held this much shorter than leg_length: the stance spring pushes from the touchdown on",
        "m",
        low=0.0,
    ),
    "stance_time": Param(0.12, "stance duration assumed before the first liftoff", "s", low=0.0, low_open=True),
}


def _make_biped(model: Model, params: dict[str, Any]) -> BipedLaw:
    bridge = bridge_of(model, "raibert_biped")
    legs = find_legs(bridge)
    if len(legs) != 2:
        found = ", ".join(leg.contact for leg in legs) or "none"
        raise SceneError(
            f"controller 'raibert_biped' needs two articulated legs (a point contact on a frame below two "
            f"actuated revolute joints, hip and knee, in robot.parameters.contacts); found {len(legs)}: {found}"
        )
    gains = Gains(**{k: params[k] for k in Gains.__dataclass_fields__})
    return biped_law(bridge, legs, gains, params["thrust"], params["stance_time"])


BIPED = ControllerSpec(
    "raibert_biped",
    "Raibert's planar biped: one leg at a time, foot placement, thrust, the stance hip levelling the trunk",
    BIPED_PARAMETERS,
    _make_biped,
)
