"""What the scene tools read about a bridge robot's guards: how far its inactive contacts lie
past the ground or their stops (``PastDepths``), which the initial-state check and the run's
``passed_through`` watch read, and each guard's unit (the guards themselves are ``events``' model
functions).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator

import numpy as np

from legsim.execution import Status
from legsim.heights import heights_along, slopes_along
from legsim.relaxed import Watch
from legsim.terrain import along, corner_positions, nearest_points, pieces_along

from .contacts import SLIP_SUFFIX, Armed, PointContact, RigidContact, SpringLeg, joint_id
from .model import BridgeModel, rounds_move
from .placements import Placements
from .sweeps import placed_turns

#: How far (m, or rad for a revolute stop) past its ground or stop an inactive contact may lie
#: beyond the strip eps before it counts as passed through: far above a stance's drift
#: (micrometres), far below any visible overlap.
THROUGH_DEPTH = 1e-4


class PastDepths:
    """How far each inactive point contact lies below the ground (the terrain under it; a round
    one's point nearest the ground) and each inactive joint stop past its stop (m or rad), at
    many states: what a guard does not see while the point or joint moves away, since it is past
    only while it closes (``events.gap``). A coarse step can carry a foot through the ground and
    leave it rising; its guard is then inside the domain.

    ``depths(mode, states)`` is (rows, contacts) in ``rigid``'s order, -inf for a contact active
    in the mode, and with ``armed_only`` for an armed point where it is not armed (it may pass
    below the ground there by design)."""

    def __init__(
        self, model: BridgeModel, active_contacts: Callable[[str], tuple[str, ...]], placements: Placements
    ) -> None:
        self.model, self.active_contacts = model, active_contacts
        self.rigid = tuple(model.rigid.values())
        self.moving = rounds_move(model.terrain)
        # The frame each depth reads: a point's contact point, or a round one's centre where its
        # contact point moves in the body (a sine, a profile); then the frames points are armed ahead of.
        points = [self._frame(r) for r in self.rigid if r.kind == "point"]
        ahead = sorted({r.armed_frame for r in self.rigid if r.armed_frame >= 0})
        self._placements = placements
        self._columns = placements.add_frames(points + ahead)
        self._ahead_slot = {frame: len(points) + k for k, frame in enumerate(ahead)}

    def _frame(self, r: RigidContact) -> int:
        return r.centre_id if r.radius > 0.0 and self.moving else r.frame_id

    def depths(self, mode: str, states: np.ndarray, armed_only: bool = False) -> np.ndarray:
        """(rows, contacts): each contact's depth past its ground or stop (m or rad; < 0 clear
        of it) at each state (rows, >= 2 n)."""
        positions = self._placements.at(states)[:, self._columns]
        states = np.atleast_2d(states)
        out = np.full((states.shape[0], len(self.rigid)), -np.inf)
        for k, r, slot in self._inactive(mode):
            if slot < 0:
                out[:, k] = -r.sign * (states[:, r.dof] - r.stop.position)
                continue
            xz = positions[:, slot]
            out[:, k] = self._point_depth(r, xz)
            armed = r.point.armed
            if armed_only and armed is not None:
                out[~self._armed(armed, r, states, xz, positions), k] = -np.inf
        return out

    def rates(self, mode: str, states: np.ndarray) -> np.ndarray:
        """(rows, contacts): d/dt of each inactive contact's ``depths`` along the flow (m/s or
        rad/s), from the frames' velocities of the same kinematics pass; 0 for an active contact."""
        states = np.atleast_2d(states)
        velocities = self._placements.velocities(states)[:, self._columns]
        positions = self._placements.at(states)[:, self._columns]
        out = np.zeros((states.shape[0], len(self.rigid)))
        for k, r, slot in self._inactive(mode):
            if slot < 0:
                out[:, k] = -r.sign * states[:, self.model.n + r.dof]
            else:
                out[:, k] = self._point_rate(r, positions[:, slot], velocities[:, slot])
        return out

    @property
    def cornered(self) -> bool:
        """Whether the terrain has corners (a profile's, steps'), where a point's depth kinks."""
        return self.model.terrain is not None and corner_positions(self.model.terrain).size > 0

    def pieces(self, mode: str, states: np.ndarray) -> np.ndarray:
        """(rows, contacts): the piece of the terrain under each inactive point contact
        (``legsim.terrain.pieces_along``: its depth is smooth on one), 0 for the other contacts."""
        states = np.atleast_2d(states)
        out = np.zeros((states.shape[0], len(self.rigid)))
        if not self.cornered:
            return out
        assert self.model.terrain is not None
        positions = self._placements.at(states)[:, self._columns]
        for k, _, slot in self._inactive(mode):
            if slot >= 0:
                out[:, k] = pieces_along(self.model.terrain, positions[:, slot, 0])
        return out

    def turns(self, mode: str, t: np.ndarray, states: np.ndarray) -> np.ndarray:
        """(N - 1, contacts, 2): between each two neighbouring checked points at times t (N,) and
        states (N, >= 2 n), the times an inactive point contact's x turns on another piece of the
        terrain than the one it starts on (``sweeps.turns_onto_other_pieces``); nan where it does
        not, and for the other contacts."""
        assert self.model.terrain is not None  # given only on a terrain with corners
        states = np.atleast_2d(states)
        out = np.full((states.shape[0] - 1, len(self.rigid), 2), np.nan)
        points = np.array([(k, slot) for k, _, slot in self._inactive(mode) if slot >= 0], dtype=int).reshape(-1, 2)
        if points.size:
            columns = self._columns[points[:, 1]]
            out[:, points[:, 0]] = placed_turns(self._placements, columns, self.model.terrain, t, states)
        return out

    def _inactive(self, mode: str) -> Iterator[tuple[int, RigidContact, int]]:
        """(column, contact, slot) of each contact inactive in ``mode``: the slot of its frame
        among the points' columns, -1 for a joint stop."""
        active = set(self.active_contacts(mode))
        slot = 0
        for k, r in enumerate(self.rigid):
            here = -1 if r.kind == "stop" else slot
            slot += here >= 0
            if r.contact.name not in active:
                yield k, r, here

    def _point_depth(self, r: RigidContact, xz: np.ndarray) -> np.ndarray:
        """A point's depth below the ground at its positions xz (rows, 2)."""
        terrain = self.model.terrain
        if r.radius > 0.0 and self.moving:
            # the point nearest the terrain moves with the centre: its depth is r less the centre's distance
            return r.radius - self._nearest(xz)[:, 1]
        if terrain is None:
            return r.point.ground - xz[:, 1]
        return along(heights_along, terrain, xz[:, 0]) - xz[:, 1]

    def _point_rate(self, r: RigidContact, xz: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d/dt of ``_point_depth`` at positions xz moving at v (rows, 2)."""
        terrain = self.model.terrain
        if r.radius > 0.0 and self.moving:  # d/dt (r - d): the centre's speed towards the curve, -n . v
            g = self._nearest(xz)[:, 2]
            return (g * v[:, 0] - v[:, 1]) / np.sqrt(1.0 + g * g)
        if terrain is None:
            return -v[:, 1]
        return along(slopes_along, terrain, xz[:, 0]) * v[:, 0] - v[:, 1]  # d/dt (h(x) - z)

    def _nearest(self, xz: np.ndarray) -> np.ndarray:
        """``heights.nearest``'s (s, d, g, k) for each centre of xz (rows, 2), (rows, 4)."""
        assert self.model.terrain is not None  # only where round contacts' points move: a terrain
        return nearest_points(self.model.terrain, xz)

    def _armed(
        self, armed: Armed, r: RigidContact, states: np.ndarray, xz: np.ndarray, positions: np.ndarray
    ) -> np.ndarray:
        """Where point r, armed by ``armed``, is armed, (rows,) bool."""
        if armed.coordinate:
            lead = states[:, int(self.model.coordinate_names.index(armed.coordinate))]
        else:
            lead = xz[:, 0] - positions[:, self._ahead_slot[r.armed_frame], 0]
        return lead - armed.beyond > 0.0


def initial_check(past: PastDepths) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x, eps)``
    names the first inactive joint stop or point contact whose position lies past it by more
    than eps (rad or m), else None. The guards are "and" conditions (past the stop AND moving
    into it), so they count a state deep past a stop but moving away as inside; no execution
    reaches such a state, and a run started there would not be the model's."""

    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        x = np.asarray(x, dtype=float)
        depths = past.depths(mode, x[None, :])[0]
        for r, depth in zip(past.rigid, depths, strict=True):
            if depth > eps:
                where = f"in mode '{mode}' where it is inactive"
                return f"{describe(past.model, r, x)} by {depth:.3g} {unit(past.model, r)} > eps = {eps:g} {where}"
        return None

    return check


def describe(model: BridgeModel, r: RigidContact, x: np.ndarray) -> str:
    """What lies past at state x: "contact point 'c' (frame 'f') lies below the ground under it"
    or "theta2 = -1 lies past the lower stop 's' (theta2 >= 0)"."""
    if r.kind == "stop":
        c = r.stop
        name = model.coordinate_names[r.dof]
        bound = ">=" if c.side == "lower" else "<="
        return f"{name} = {x[r.dof]:g} lies past the {c.side} stop '{c.name}' ({name} {bound} {c.position:g})"
    shape = f", radius {r.radius:g} m: its point nearest the ground" if r.radius > 0.0 else ""
    return f"contact point '{r.contact.name}' (frame '{r.point.frame}'{shape}) lies below the ground under it"


def unit(model: BridgeModel, r: RigidContact) -> str:
    """The unit of contact r's depth: m for a point or a prismatic stop, rad for a revolute stop."""
    return "rad" if r.kind == "stop" and _revolute(model, r.stop.joint) else "m"


def _revolute(model: BridgeModel, joint: str) -> bool:
    """Whether the stop's joint ``joint`` turns (its positions in rad) rather than slides (m)."""
    pm = model.pin_model
    return bool(pm.joints[joint_id(pm, joint, "stop", model.name)].shortname().startswith("JointModelR"))


def passed_through_watch(past: PastDepths, eps: float, action: str = "warn") -> Watch:
    """An inactive contact past its ground or stop by more than eps + ``THROUGH_DEPTH`` (a coarse
    step carried it through; an armed point only where it is armed), a part of the watch per
    contact with its depth's rate: with ``action`` as
    ``ground_watch``'s, except that "fall" stops as "strict" does, with ``model_breakdown``: a
    contact carried through is a touchdown the steps missed, which says nothing of a fall. eps
    (guard units: m, or rad for a revolute stop) is the run's: a step landing in a strip leaves a
    contact up to eps past its surface."""
    allowed = eps + THROUGH_DEPTH

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        # a part per contact, each checked between points by its own rate
        return allowed - past.depths(mode, x, armed_only=True)

    def rate(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return -past.rates(mode, x)

    def piece(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return past.pieces(mode, x)

    def probe(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return past.turns(mode, t, x)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        state = np.atleast_2d(x)[0]
        depths = past.depths(mode, state, armed_only=True)[0]
        k = int(np.argmax(depths))
        return (
            f"{describe(past.model, past.rigid[k], state)} by {depths[k]:.3g} {unit(past.model, past.rigid[k])} "
            f"at t={t:.17g} in mode '{mode}' "
            f"where it is inactive, more than eps = {eps:g} + {THROUGH_DEPTH:g}: a step carried it through and "
            f"left it moving away, where its guard does not look (take a smaller h, or tighter tolerances)"
        )

    cornered = past.cornered
    return ground_watch("passed_through", value, message, "strict" if action == "fall" else action, rate,
                        piece if cornered else None, probe=probe if cornered else None)  # fmt: skip


def ground_watch(
    name: str, value: Callable[..., np.ndarray], message: Callable[..., str], action: str,
    rate: Callable[..., np.ndarray] | None = None, piece: Callable[..., np.ndarray] | None = None,
    clear: Callable[..., np.ndarray] | None = None, probe: Callable[..., np.ndarray] | None = None,
) -> Watch:  # fmt: skip
    """The watch of a body through the ground, by the scene's ``below_ground`` ``action``: "warn"
    a warning; "strict" a stop with status ``model_breakdown`` (the model has no contact there);
    "fall" a stop with status ``fell`` (the robot crashed, a scene's fall condition). ``rate``:
    the value's rate along the flow, to check between points (``Watch.rate``); ``piece``: the
    terrain's piece under each part, where the terrain has corners (``Watch.piece``); ``clear``:
    the parts that stay clear of the ground between two checked points (``Watch.clear``);
    ``probe``: where a part may turn onto another piece and back between them (``Watch.probe``)."""
    watch = Watch(name, value, "warn", message, rate=rate, piece=piece, clear=clear, probe=probe)
    if action == "strict":
        return dataclasses.replace(watch, action="stop", status=Status.MODEL_BREAKDOWN.value)
    if action == "fall":

        def fell(t: float, mode: str, x: np.ndarray) -> str:
            return f"fell: {name}: {message(t, mode, x)}"

        return dataclasses.replace(watch, action="stop", message=fell, status=Status.FELL.value)
    return watch


def guard_units(model: BridgeModel) -> dict[str, str]:
    """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
    units = {}
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            units[f"touchdown_{cname}"] = "m (foot height, while descending)"
            units[f"liftoff_{cname}"] = "m (rest length minus leg length, while extending)"
        elif isinstance(c, PointContact):
            kind = "touchdown" if c.restitution == 0.0 else "bounce"
            point = "the round contact's lowest point" if c.radius > 0.0 else "the point"
            units[f"{kind}_{cname}"] = f"m (height of {point}, while descending)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"liftoff_{cname}"] = "N (normal contact force)"
            if c.friction is not None:
                units[f"liftoff_{cname}"] = "N (normal contact force)"
                for suffix in SLIP_SUFFIX.values():
                    units[f"slip_{cname}{suffix}"] = (
                        "N (mu f_n -+ f_t: the force's distance to the friction cone's edge)"
                    )
                units[f"stick_{cname}"] = "m/s (slip velocity, while the friction decelerates it)"
        else:
            rot = _revolute(model, c.joint)
            kind = "impact" if c.restitution == 0.0 else "bounce"
            units[f"{kind}_{cname}"] = f"{'rad' if rot else 'm'} (distance to the stop, while approaching)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"release_{cname}"] = f"{'N m' if rot else 'N'} (stop force)"
    return units
