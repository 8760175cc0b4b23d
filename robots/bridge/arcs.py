"""Where a round contact rolls round a convex corner of a profile, and the warning that says so.

On a face its centre moves on a line; round a convex corner it moves on the circle of radius r
about the corner. The curvature of that path jumps from 0 to 1 / r at each end of the arc, and
with it the contact's normal acceleration: the field jumps inside the mode, where no guard lands
a step (the face and the arc are one contact mode). Steps cross such a jump at reduced order:
fixed steps to first order, and an embedded pair's error estimate sees only a small share of it.
Rolling a ball r = 0.1 m over a 20 degree corner at 0.3 m/s, the centre ends up off its path by
6.5e-5 m with rk4 at h = 1e-3 s (4.0e-6 m at 1e-4 s) and by 3.4e-9 m with dopri5 at rtol 1e-10
(1.8e-9 m at 1e-12), against 1e-12 m along a face or round an arc alone. A run that rolls a round
contact on a corner's arc says so in a warning (also one that leaves the arc by a liftoff, an
event located as any other: the check sees where the contact is, not how it left).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from legsim.heights import PROFILE, nearest
from legsim.relaxed import Watch

from .contacts import RigidContact
from .model import BridgeModel
from .placements import Placements


class CornerArcs:
    """Whether each round contact active in a mode has its centre nearest a convex corner of
    the profile (on the corner's arc), at many states: ``on_arcs(mode, states)`` (rows, rounds)."""

    def __init__(
        self, model: BridgeModel, active_contacts: Callable[[str], tuple[str, ...]], placements: Placements
    ) -> None:
        self.terrain = model.terrain
        profile = self.terrain is not None and float(self.terrain[0]) == PROFILE
        self.rounds: tuple[RigidContact, ...] = (
            tuple(r for r in model.rigid.values() if r.radius > 0.0) if profile else ()
        )
        self.active_contacts = active_contacts
        self._placements = placements
        self._columns = placements.add_frames([r.centre_id for r in self.rounds])

    def on_arcs(self, mode: str, states: np.ndarray) -> np.ndarray:
        """(rows, rounds) bool: the contact is active in ``mode`` and its centre nearest a corner
        (``legsim.heights.nearest``'s curvature 1 / d there, 0 on a face)."""
        states = np.atleast_2d(states)
        out = np.zeros((states.shape[0], len(self.rounds)), dtype=bool)
        active = set(self.active_contacts(mode))
        centres = self._placements.at(states)[:, self._columns] if self.rounds else None
        for k, r in enumerate(self.rounds):
            if r.contact.name in active and centres is not None:
                out[:, k] = [nearest(self.terrain, 0, xc, zc)[3] != 0.0 for xc, zc in centres[:, k]]
        return out


def corner_arc_watch(arcs: CornerArcs) -> Watch:
    """A warning where a round contact rolls round a convex corner (module docstring); a part per
    round contact."""

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.where(arcs.on_arcs(mode, x), -1.0, 1.0)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        on = arcs.on_arcs(mode, x)[0]
        names = [r.contact.name for r, here in zip(arcs.rounds, on, strict=True) if here]
        return (
            f"round contact {', '.join(repr(n) for n in names)} rolled on the arc round a corner of the terrain from "
            f"t={t:.6g} s in mode '{mode}': where it crosses an end of the arc (onto or off a face) its acceleration "
            f"jumps inside one contact mode, where no step is landed; steps cross such a jump at reduced order "
            f"(fixed steps to first order, and error control sees little of it), so the motion after that is not "
            f"accurate to the method's order"
        )

    return Watch("round_corner", value, "warn", message)
