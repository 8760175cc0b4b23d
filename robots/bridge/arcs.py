"""Where a round contact rolls round a convex corner of a profile, and the warnings that say so.

On a face its centre moves on a line; round a convex corner it moves on the circle of radius r
about the corner. The curvature of that path jumps from 0 to 1 / r at each end of the arc, and
with it the contact's normal acceleration: the field jumps inside the mode, where no guard lands
a step (the face and the arc are one contact mode). Steps cross such a jump at reduced order
(first order for fixed steps; an embedded pair's error estimate sees little of it), and leave an
error in the velocity along the normal, which the steering of the normal row
(``dynamics.ROUND_RETURN_RATE``) makes die out instead of drift on. Rolling a ball r = 0.1 m over
a 20 degree corner at 0.3 m/s, the centre is at most 2.8e-6 m off its path with rk4 at h = 1e-3
s, 6.4e-7 m at 1e-4 s, its position along it 5.8e-6 m and 5.6e-7 m behind (first order); fixed
steps are refused there by a scene (``needs_error_control``). A run with a contact on a
corner's arc says so (``round_corner``), and one whose contact lies off its path by more than
eps + ``guards.THROUGH_DEPTH`` says that too (``round_drift``: the steering's safety net).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from legsim.heights import PROFILE
from legsim.relaxed import Watch
from legsim.terrain import nearest_points

from ..kept import KeptWhileAlive
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
        self._kept = KeptWhileAlive()

    def on_arcs(self, mode: str, states: np.ndarray) -> np.ndarray:
        """(rows, rounds) bool: the contact is active in ``mode`` and its centre nearest a corner
        (``legsim.heights.nearest``'s curvature 1 / d there, 0 on a face)."""
        return self._nearest(mode, states)[1] != 0.0

    def offsets(self, mode: str, states: np.ndarray) -> np.ndarray:
        """(rows, rounds): |d - r| (m), how far each contact active in ``mode`` lies off the curve
        r from the terrain that it keeps to in contact (0 for the inactive ones)."""
        distances = self._nearest(mode, states)[0]
        radii = np.array([r.radius for r in self.rounds])
        return np.where(np.isnan(distances), 0.0, np.abs(distances - radii))

    def _nearest(self, mode: str, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, rounds) each: the distance d (m) from each active contact's centre to the
        terrain and the curvature k (1/m) there (``legsim.heights.nearest``); nan and 0 for a
        contact inactive in ``mode``. Both watches read it of the same batch: kept while it lives."""
        kept = self._kept.get(states)
        if kept is not None and kept[0] == mode:
            return kept[1]
        rows = np.atleast_2d(states)
        distance = np.full((rows.shape[0], len(self.rounds)), np.nan)
        curvature = np.zeros_like(distance)
        active = set(self.active_contacts(mode))
        if not self.rounds or self.terrain is None:  # rounds only on a profile: a terrain
            return distance, curvature
        centres = self._placements.at(rows)[:, self._columns]
        for k, r in enumerate(self.rounds):
            if r.contact.name in active:
                found = nearest_points(self.terrain, centres[:, k])
                distance[:, k], curvature[:, k] = found[:, 1], found[:, 3]
        self._kept.keep(states, (mode, (distance, curvature)))
        return distance, curvature


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

    return Watch("round_corner", value, "warn", message, graded=False)


def round_drift_watch(arcs: CornerArcs, allowed: float) -> Watch:
    """A warning where a round contact in contact lies off the curve r from the terrain by more
    than ``allowed`` (m): it drifted after the jump at an arc's end (module docstring)."""

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return allowed - arcs.offsets(mode, x)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        off = arcs.offsets(mode, x)[0]
        k = int(np.argmax(off))
        return (
            f"round contact '{arcs.rounds[k].contact.name}' is {off[k]:.3g} m off the terrain at t={t:.6g} s in mode "
            f"'{mode}' while in contact (more than eps + {allowed:.3g} m): it drifts after rolling round a corner, "
            f"where the steps crossed a jump of its acceleration; give a tighter rtol"
        )

    return Watch("round_drift", value, "warn", message)
