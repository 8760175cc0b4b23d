"""The gait changes of Raibert's runner (``robots.raibert``) during a run: which changes a scene's
schedule asks for, the validated settings of their laws (``runner_laws``, "a change from the pronk
to the bound"; ``stand_laws``, the bound to the pronk) and the memory each declares only where
its change is scheduled (a run without one carries the state it carries without the law: an
adaptive step's error norm is taken over the whole state).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from legsim.builders import Param
from legsim.errors import SceneError

from .runner_layout import GAIT_BOUND, GAIT_PRONK

#: The parameters of a change from the pronk to the bound, in the order of the parameter array's
#: head (``runner_layout.R_TRANSITION_HOPS`` on).
TRANSITION_PARAMETERS = (
    "transition_hops",
    "transition_height",
    "transition_reach",
    "transition_hold",
    "transition_hind_thrust",
    "transition_front_thrust",
    "transition_pitch_rate",
)
#: The parameters of a change from the bound to the pronk, in the order of the parameter array's
#: head (``runner_layout.R_STAND_DAMPING`` on).
STAND_PARAMETERS = (
    "stand_damping",
    "stand_time",
    "stand_thrust",
    "stand_reach",
    "stand_speed",
    "stand_kp",
    "stand_kd",
    "stand_accel",
)
#: Their defaults, units and ranges (``raibert.RUNNER_PARAMETERS`` takes them in).
CHANGE_PARAMETERS = {
    "transition_hops": Param(
        4,
        "a change from the pronk to the bound: the low hops the pronk makes after the change's time before the "
        "bound's law takes over at the next liftoff",
        "",
        low=0,
    ),
    "transition_height": Param(
        0.51,
        "a change from the pronk to the bound: the apex height its low hops' thrust adapts to (the bound's "
        "vertical speeds are lower than the pronk's)",
        "m",
        low=0.0,
        low_open=True,
    ),
    "transition_reach": Param(
        0.49,
        "a change from the pronk to the bound: the front pair's length in the flight where the bound takes over, "
        "so that it lands alone near the top of the hop (about transition_height, below the leg's full length)",
        "m",
        low=0.0,
        low_open=True,
    ),
    "transition_hold": Param(
        0.7,
        "a change from the pronk to the bound: the hind pair's length in that flight, a share of leg_length, "
        "until the front stance has pitched the body nose-up past transition_pitch_rate",
        "",
        low=0.0,
        low_open=True,
        high=1.0,
    ),
    "transition_hind_thrust": Param(
        0.0075, "a change from the pronk to the bound: the hind pair's thrust when the bound takes over", "m", low=0.0
    ),
    "transition_front_thrust": Param(
        0.03, "a change from the pronk to the bound: the front pair's thrust when the bound takes over", "m", low=0.0
    ),
    "transition_pitch_rate": Param(
        2.0,
        "a change from the pronk to the bound: the nose-up pitch rate past which the held hind pair swings out",
        "rad/s",
        low=0.0,
        low_open=True,
    ),
    "stand_speed": Param(
        0.2,
        "a change from the bound to the pronk: the bound slows to a stop and its pairs stand once a touchdown comes "
        "at a forward speed below this",
        "m/s",
        low=0.0,
        low_open=True,
    ),
    "stand_reach": Param(
        0.46,
        "a change from the bound to the pronk: the length the pair still in flight reaches to once the other has "
        "landed, so that it lands soon after",
        "m",
        low=0.0,
        low_open=True,
    ),
    "stand_damping": Param(
        60.0,
        "a change from the bound to the pronk: the damping along the legs while both pairs stand before the hop",
        "N s/m",
        low=0.0,
    ),
    "stand_kp": Param(
        60.0,
        "a change from the bound to the pronk: hip torque per radian a standing leg is off the vertical",
        "N m/rad",
        low=0.0,
    ),
    "stand_kd": Param(
        8.0,
        "a change from the bound to the pronk: hip torque per rad/s of a standing leg's swing",
        "N m s/rad",
        low=0.0,
    ),
    "stand_time": Param(
        0.3,
        "a change from the bound to the pronk: how long both pairs stand, from the later touchdown, before the hop "
        "(the later pair's spring comes back from its touchdown length to leg_length meanwhile)",
        "s",
        low=0.0,
        low_open=True,
    ),
    "stand_thrust": Param(
        0.06,
        "a change from the bound to the pronk: the stance springs' rest-length extension that makes the hop off "
        "both pairs",
        "m",
        low=0.0,
    ),
    "stand_accel": Param(
        0.4,
        "a change from the bound to the pronk: the acceleration at which the pronk's speed command comes back "
        "from 0 to the commanded speed after the hop off the stance",
        "m/s^2",
        low=0.0,
        low_open=True,
    ),
}


def gait_codes(schedule: Sequence[tuple[float, float, float]], start: float) -> list[float]:
    """The gait codes a run goes through: ``start`` (the scene's gait), unless an entry at t = 0
    replaces it, then each entry's of ``schedule`` ((t, speed, gait code) triples)."""
    codes = [entry[2] for entry in schedule]
    if not schedule or schedule[0][0] > 0.0:
        codes.insert(0, start)
    return codes


def changes_pronk_to_bound(schedule: Sequence[tuple[float, float, float]], start: float) -> bool:
    """Whether ``schedule``, starting from the gait code ``start``, commands the bound after the
    pronk (the controller's transition law then runs, ``runner_laws.begin_transition``)."""
    codes = gait_codes(schedule, start)
    return any(code == GAIT_BOUND and GAIT_PRONK in codes[:k] for k, code in enumerate(codes))


def changes_bound_to_pronk(schedule: Sequence[tuple[float, float, float]], start: float) -> bool:
    """Whether ``schedule``, starting from the gait code ``start``, commands the pronk after the
    bound or the gallop (the controller's standing hop then runs, ``stand_laws.begin_stand``)."""
    codes = gait_codes(schedule, start)
    return any(code == GAIT_PRONK and any(c != GAIT_PRONK for c in codes[:k]) for k, code in enumerate(codes))


def check_reach(legs: Sequence[Any], reach: float, field: str) -> None:
    """SceneError naming ``field`` where a leg (``raibert.Leg``) cannot stretch to ``reach`` (m: its
    thigh and shank straight): the pair reaching would not land where its law expects."""
    for leg in legs:
        if reach >= leg.thigh + leg.shank:
            raise SceneError(
                f"controller.parameters.{field}: {reach:g} m is not shorter than the leg {leg.contact!r} "
                f"stretched ({leg.thigh + leg.shank:g} m, thigh and shank)"
            )


def declare_memory(
    contacts: Sequence[str], fields: Sequence[tuple[str, str]], initial: Sequence[float], frames: Sequence[str]
) -> tuple[tuple[str, ...], tuple[str, ...], tuple[float, ...], tuple[str, ...]]:
    """A change's memory for the legs of ``contacts``, leg after leg: its names ``<field>_<contact>``,
    units, initial values and frames (``ControlLaw.memory_frames``) from ``fields`` ((name, unit)
    pairs), ``initial`` and ``frames`` (one per field)."""
    names = tuple(f"{field}_{contact}" for contact in contacts for field, _ in fields)
    units = tuple(unit for _ in contacts for _, unit in fields)
    return names, units, tuple(v for _ in contacts for v in initial), tuple(f for _ in contacts for f in frames)
