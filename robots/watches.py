"""What a robot's runs are checked for besides their status (``legsim.relaxed.Watch``): the time
each actuated joint spends at its effort limit, and links without a contact that pass below the
ground. The first is measured on the run's stored points, the second checked there and at the
steps' middles (the driver's scan, ``legsim.relaxed.watches``), so they hold for the compiled
kernel and the Python loop alike.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from legsim.compiled.rows import at_rows
from legsim.control import ControlLaw
from legsim.relaxed import Watch
from legsim.terrain import SINE, Terrain, corner_positions

from .bridge.guards import ground_watch
from .bridge.placements import Placements
from .bridge.sweeps import placed_turns, swept
from .kept import KeptWhileAlive


def saturation_counter(joint: str) -> str:
    """The counter of the time (s) joint ``joint``'s input spent at its effort limit."""
    return f"saturated_{joint}_s"


class Inputs:
    """The controller's input at a run's points: ``law.control`` at each point's plant state and
    memory, the mode's parameters built once; a batch's inputs kept while it lives, since every
    joint's watch asks for the very same arrays of points in turn (``watches.PointsByMode``)."""

    def __init__(self, law: ControlLaw, dims: Callable[[str], int]) -> None:
        self.law, self.dims = law, dims
        self._params: dict[str, np.ndarray] = {}
        self._kept = KeptWhileAlive()

    def __call__(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        kept = self._kept.get(x)
        if kept is not None and kept[0] is t and kept[1] == mode:
            return kept[2]
        p = self._params.get(mode)
        if p is None:
            p = self._params[mode] = self.law.params_for(mode)
        states = np.ascontiguousarray(x, dtype=float)
        out = np.zeros((t.shape[0], self.law.inputs))
        at_rows(self.law.control, np.ascontiguousarray(t, dtype=float), states, self.dims(mode), p, out)
        self._kept.keep(x, (t, mode, out))
        return out


def saturation_watches(
    control: Any, names: Sequence[str], limits: np.ndarray, dims: Callable[[str], int]
) -> list[Watch]:
    """One time watch per actuated joint with a finite effort limit: the time |u_i| >= limit_i
    (counter ``saturated_<joint>_s``), u the ``ControlLaw``'s input at the run's points. None
    for other controls (a Python controller keeps state the points do not carry)."""
    if not isinstance(control, ControlLaw):
        return []
    inputs = Inputs(control, dims)
    out = []
    for i, (name, limit) in enumerate(zip(names, limits, strict=True)):
        if not np.isfinite(limit) or i >= control.inputs:
            continue

        def value(mode: str, t: np.ndarray, x: np.ndarray, i: int = i, limit: float = float(limit)) -> np.ndarray:
            return limit - np.abs(inputs(mode, t, x)[:, i])

        out.append(Watch(f"saturated_{name}", value, "time", counter=saturation_counter(name)))
    return out


class LinkHeights:
    """The lowest point (m) of each link without a contact: its points (in its joint's frame,
    (k, 3)) placed by the robot's ``Placements`` (Pinocchio's forward kinematics in the native
    library, many states in one compiled call); with a terrain, each point's height above the
    terrain under it."""

    def __init__(
        self, placements: Placements, links: Mapping[str, tuple[int, np.ndarray]], terrain: Terrain | None = None
    ) -> None:
        self.terrain = terrain
        self.links = dict(links)
        self.names = list(self.links)
        owners = [np.full(len(p), k, dtype=int) for k, (_, p) in enumerate(self.links.values())]
        self.owner = np.concatenate(owners) if owners else np.zeros(0, dtype=int)
        self._placements = placements
        self._columns = placements.add_points(self.links)
        self._kept = KeptWhileAlive()

    def heights_at(self, states: np.ndarray) -> np.ndarray:
        """The height (m) of every link point at each state, (rows, points): states (rows, >= 2 n).
        A batch's heights are kept while it lives (the watch's value and rate both read them)."""
        kept = self._kept.get(states)
        if kept is not None:
            return kept
        out = self._placements.at(states)[:, self._columns]
        heights = out[:, :, 1] if self.terrain is None else out[:, :, 1] - self.terrain.height(out[:, :, 0])
        self._kept.keep(states, heights)
        return heights

    def rates_at(self, states: np.ndarray) -> np.ndarray:
        """d/dt (m/s) of every link point's height along the flow at each state, (rows, points):
        its vertical velocity, less the terrain's slope times its horizontal one."""
        velocity = self._placements.velocities(states)[:, self._columns]
        if self.terrain is None:
            return velocity[:, :, 1]
        x = self._placements.at(states)[:, self._columns, 0]
        return velocity[:, :, 1] - self.terrain.slope(x) * velocity[:, :, 0]

    @property
    def cornered(self) -> bool:
        """Whether the terrain has corners (a profile's, steps'), where a point's height kinks."""
        return self.terrain is not None and not self.terrain.smooth

    def pieces_at(self, states: np.ndarray) -> np.ndarray:
        """The piece of the terrain under every link point at each state, (rows, points)
        (``Terrain.pieces``; 0 everywhere on a smooth terrain)."""
        x = self._placements.at(states)[:, self._columns, 0]
        return np.zeros(x.shape) if self.terrain is None else self.terrain.pieces(x)

    def clear(self, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray, ground: float) -> np.ndarray:
        """(J, points): whether each link point stays more than ``ground`` (m) above the highest
        terrain under the x it sweeps between two checked points at times ta, tb (J,) and states
        xa, xb (J, >= 2 n) (``sweeps.swept``): it cannot reach the ground there."""
        assert self.terrain is not None  # given only on a terrain with corners
        x_low, x_high, z_low = swept(self._placements, self._columns, ta, xa, tb, xb)
        return z_low - self.terrain.highest(x_low, x_high) > ground

    def turns(self, t: np.ndarray, states: np.ndarray) -> np.ndarray:
        """(N - 1, points, 2): between each two neighbouring checked points at times t (N,) and
        states (N, >= 2 n), the times a link point's x turns on another piece of the terrain than
        the one it starts on (``sweeps.turns_onto_other_pieces``), nan where it does not."""
        assert self.terrain is not None  # given only on a terrain with corners
        return placed_turns(self._placements, self._columns, self.terrain.array, t, states)

    def __call__(self, x: np.ndarray) -> dict[str, float]:
        """Each link's lowest point (m) at one state x."""
        z = self.heights_at(x)[0]
        return {name: float(np.min(z[self.owner == k])) for k, name in enumerate(self.names)}


def below_ground_watch(heights: LinkHeights, ground: float, action: str = "warn") -> Watch:
    """A link without a contact below the ground z = ``ground``: with ``action`` "warn" a
    warning naming the link, the time and the depth; "strict" a stop with status
    ``model_breakdown`` (the model has no contact there); "fall" a stop with status ``fell``
    (the robot crashed into the ground, a scene's fall condition)."""

    def lowest(x: np.ndarray) -> tuple[str, float]:
        h = heights(x)
        name = min(h, key=lambda k: h[k])
        return name, h[name] - ground

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        # a part per point of the links, each checked between points by its own vertical speed
        return heights.heights_at(x) - ground

    def rate(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return heights.rates_at(x)

    def piece(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return heights.pieces_at(x)

    def clear(mode: str, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray) -> np.ndarray:
        return heights.clear(ta, xa, tb, xb, ground)

    def probe(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return heights.turns(t, x)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        h = heights(x)
        below = sorted((v - ground, k) for k, v in h.items() if v < ground)
        named = ", ".join(f"'{k}' {-d:.3g} m" for d, k in below) or f"'{lowest(x)[0]}' at the ground"
        return (
            f"link(s) without a contact below the ground at t={t:.17g} in mode '{mode}': {named} deep "
            f"(declare a contact on the link, or it passes through the ground)"
        )

    pieces = (piece, clear, probe) if heights.cornered else (None, None, None)
    return ground_watch("below_ground", value, message, action, rate, *pieces)


#: How deep (m) a point of the terrain may lie inside a body before the body counts as passing
#: through it: far above the drift of a body resting on its corners (micrometres over a stance),
#: far below any visible overlap.
PIERCING_DEPTH = 1e-4
#: Samples per wavelength of a sine terrain's points tested against the bodies: the curve between
#: two of them bulges by a k^2 (wavelength / 128)^2 / 8, 3e-4 of the amplitude, below PIERCING_DEPTH
#: for any sine a robot walks on.
SINE_SAMPLES = 128
#: Stored points whose bodies are tested against the terrain's points at once (each batch against
#: the terrain's points under its own bodies' span).
PIERCING_ROWS = 256


class TerrainPiercing:
    """How deep the terrain's points lie inside the robot's bodies whose contacts are the corners
    of their collision outlines (boxes, cylinders in the plane): a terrain corner between two
    contact corners touches no contact, so a body can rest on the ground with a step's edge inside
    it. Each body is a convex polygon in the (x, z) plane (its corners in its joint's frame,
    placed by the native forward kinematics); the terrain's points are a profile's breakpoints,
    or a sine sampled ``SINE_SAMPLES`` times a wavelength, near the bodies."""

    def __init__(self, placements: Placements, bodies: Mapping[str, tuple[int, np.ndarray]], terrain: Terrain) -> None:
        self.terrain, self.names = terrain, list(bodies)
        self.sine = terrain.array[0] == SINE
        ordered = {name: (joint, _counterclockwise(corners)) for name, (joint, corners) in bodies.items()}
        self.sizes = [len(corners) for _, corners in ordered.values()]
        self._placements = placements
        self._columns = placements.add_points(ordered)
        self._kept = KeptWhileAlive()

    def corners_at(self, states: np.ndarray) -> np.ndarray:
        """Every body corner's world (x, z) (m) at each state, (rows, corners, 2)."""
        return self._placements.at(states)[:, self._columns]

    def terrain_points(self, x_low: float, x_high: float) -> np.ndarray:
        """The terrain's points (k, 2) over [x_low, x_high] (m): its polyline (a profile's
        breakpoints and the range's ends; a sine ``SINE_SAMPLES`` times a wavelength)."""
        waves = (x_high - x_low) * float(self.terrain.array[3]) / (2.0 * math.pi) if self.sine else 0.0
        return self.terrain.polyline(x_low, x_high, samples=math.ceil(SINE_SAMPLES * waves) + 2)

    def depths_at(self, states: np.ndarray) -> np.ndarray:
        """The deepest terrain point inside each body at each state (m; negative: outside, its
        distance to the nearest edge's line), (rows, bodies)."""
        return self._scan(states)[0]

    def rates_at(self, states: np.ndarray) -> np.ndarray:
        """d/dt (m/s) of ``depths_at`` along the flow, (rows, bodies): the deepest point's
        (fixed in the terrain) distance inside its nearest edge, as the edge moves with the body."""
        return self._scan(states)[1]

    def pieces_at(self, states: np.ndarray) -> np.ndarray:
        """Which terrain corner is deepest in each body and which edge of the body is nearest it,
        one number per body at each state, (rows, bodies): ``depths_at`` is smooth while these
        stay (on a profile; a sine's sampled points are not the same from batch to batch)."""
        return self._scan(states)[2]

    @property
    def cornered(self) -> bool:
        """Whether the terrain's points are its corners (a profile's, steps'), the same in every
        batch, so that ``pieces_at`` names them."""
        return not self.sine

    def clear(self, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray) -> np.ndarray:
        """(J, bodies): whether each body's lowest corner stays more than ``PIERCING_DEPTH`` above
        the highest terrain under the x its corners sweep between two checked points at times
        ta, tb (J,) and states xa, xb (J, >= 2 n) (``sweeps.swept``): no terrain point can then be
        inside it."""
        x_low, x_high, z_low = swept(self._placements, self._columns, ta, xa, tb, xb)
        ends = np.cumsum([0, *self.sizes])
        out = np.empty((ta.shape[0], len(self.sizes)), dtype=bool)
        for body, (first, last) in enumerate(itertools.pairwise(ends)):
            under = self.terrain.highest(x_low[:, first:last].min(axis=1), x_high[:, first:last].max(axis=1))
            out[:, body] = z_low[:, first:last].min(axis=1) - under > PIERCING_DEPTH
        return out

    def _scan(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(depths, rates, pieces), kept for a batch while it lives (the watch's value, rate and
        piece read them in turn)."""
        kept = self._kept.get(states)
        if kept is not None:
            return kept
        placed = self.corners_at(states)
        moving = self._placements.velocities(states)[:, self._columns]
        shape = (placed.shape[0], len(self.sizes))
        depths, rates, pieces = np.empty(shape), np.empty(shape), np.empty(shape)
        for start in range(0, placed.shape[0], PIERCING_ROWS):
            rows = slice(start, start + PIERCING_ROWS)
            corners = placed[rows]
            points = self.terrain_points(float(corners[..., 0].min()), float(corners[..., 0].max()))
            depths[rows], rates[rows], pieces[rows] = self._depths(corners, moving[rows], points)
        self._kept.keep(states, (depths, rates, pieces))
        return depths, rates, pieces

    def _depths(
        self, corners: np.ndarray, velocities: np.ndarray, points: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, bodies) each: each body's deepest point of ``points`` (k, 2), that depth's rate
        and the piece it is on (``pieces_at``); corners and their velocities (rows, all, 2), each
        body's counterclockwise."""
        ends = np.cumsum([0, *self.sizes])
        found = [_deepest(corners[:, a:b], velocities[:, a:b], points) for a, b in itertools.pairwise(ends)]
        numbers, edges = self._corner_numbers(points), max(self.sizes)
        depths = np.stack([depth for depth, _, _, _ in found], axis=1)
        rates = np.stack([rate for _, rate, _, _ in found], axis=1)
        pieces = np.stack([(numbers[point] + 1) * edges + edge for _, _, point, edge in found], axis=1)
        return depths, rates, pieces

    def _corner_numbers(self, points: np.ndarray) -> np.ndarray:
        """Each of a batch's terrain ``points`` (k, 2) numbered as in every batch: its corner's
        index among the terrain's corners, -1 for the ends of the batch's range, (k,)."""
        corner_xs = corner_positions(self.terrain.array)
        return np.where(np.isin(points[:, 0], corner_xs), np.searchsorted(corner_xs, points[:, 0]), -1)


def _deepest(
    polygon: np.ndarray, speeds: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The deepest of ``points`` (k, 2, fixed in the terrain) inside a convex polygon (rows, m, 2),
    counterclockwise, moving at ``speeds`` (rows, m, 2): its depth, the least distance inside an
    edge's line (m; < 0 outside), that depth's rate (m/s), which point it is and which edge is
    nearest it, (rows,) each."""
    edges = np.roll(polygon, -1, axis=1) - polygon
    lengths = np.linalg.norm(edges, axis=-1)
    inward = np.stack([-edges[..., 1], edges[..., 0]], axis=-1) / lengths[..., None]
    offsets = points[None, None, :, :] - polygon[:, :, None, :]
    inside = np.einsum("rmkd,rmd->rmk", offsets, inward)  # (rows, m, k)
    nearest_edge = inside.argmin(axis=1)  # (rows, k): the edge that sets each point's depth
    depth_of_point = np.take_along_axis(inside, nearest_edge[:, None, :], axis=1)[:, 0]
    rows = np.arange(polygon.shape[0])
    point = depth_of_point.argmax(axis=1)
    edge = nearest_edge[rows, point]
    # the edge's corner moves, and its inward normal turns with the body: d/dt of perp(e) / |e|
    # is perp(e') / |e| for a rigid body
    turning = np.roll(speeds, -1, axis=1)[rows, edge] - speeds[rows, edge]
    turned = np.stack([-turning[:, 1], turning[:, 0]], axis=-1) / lengths[rows, edge][:, None]
    rate = -np.einsum("rd,rd->r", speeds[rows, edge], inward[rows, edge]) + np.einsum(
        "rd,rd->r", offsets[rows, edge, point], turned
    )
    return depth_of_point[rows, point], rate, point, edge


def _counterclockwise(corners: np.ndarray) -> np.ndarray:
    """A convex outline's corners (k, 3) in the joint's frame, ordered counterclockwise in the
    (x, z) plane (a rotation about y keeps the order)."""
    flat = corners[:, [0, 2]]
    centre = flat.mean(axis=0)
    angles = np.arctan2(flat[:, 1] - centre[1], flat[:, 0] - centre[0])
    return corners[np.argsort(angles)]


def terrain_inside_watch(piercing: TerrainPiercing, action: str = "warn") -> Watch:
    """The terrain inside a body by more than ``PIERCING_DEPTH`` (a step's edge between its
    contact corners): with ``action`` as ``below_ground_watch``'s."""

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        # a part per body, each checked between points by its own rate
        return PIERCING_DEPTH - piercing.depths_at(x)

    def rate(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return -piercing.rates_at(x)

    def piece(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return piercing.pieces_at(x)

    def clear(mode: str, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray) -> np.ndarray:
        return piercing.clear(ta, xa, tb, xb)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        # Where the watch first holds (located on the interpolant) the deepest is at PIERCING_DEPTH
        # itself, to rounding: the deepest body is named then.
        ranked = sorted((-d, name) for name, d in zip(piercing.names, piercing.depths_at(x)[0], strict=True))
        inside = [(d, name) for d, name in ranked if -d > PIERCING_DEPTH] or ranked[:1]
        named = ", ".join(f"'{name}' {-d:.3g} m" for d, name in inside)
        return (
            f"the terrain passes into body(ies) at t={t:.17g} in mode '{mode}': {named} deep (a body touches the "
            f"ground only at its contacts, and a terrain corner between them goes through it: add contacts on "
            f"the body, or give a terrain without that corner)"
        )

    pieces = (piece, clear) if piercing.cornered else (None, None)
    return ground_watch("terrain_inside", value, message, action, rate, *pieces)
