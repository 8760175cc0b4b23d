"""What a robot's runs are checked for besides their status (``legsim.relaxed.Watch``): the time
each actuated joint spends at its effort limit, and links without a contact that pass below the
ground. Both are evaluated on the run's stored points (the driver's scan), so they hold for the
compiled kernel and the Python loop alike.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.control import ControlLaw
from legsim.execution import Status
from legsim.relaxed import Watch
from legsim.terrain import Terrain


def saturation_counter(joint: str) -> str:
    """The counter of the time (s) joint ``joint``'s input spent at its effort limit."""
    return f"saturated_{joint}_s"


class Inputs:
    """The controller's input at stored points: ``law.control`` at each point's plant state and
    memory, the mode's parameters built once; the last batch kept, since every joint's watch
    asks for the same points."""

    def __init__(self, law: ControlLaw, dims: Callable[[str], int]) -> None:
        self.law, self.dims = law, dims
        self._params: dict[str, np.ndarray] = {}
        self._last: tuple[Any, np.ndarray] | None = None

    def __call__(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        key = (mode, t.shape[0], t.tobytes(), x.tobytes())
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        p = self._params.get(mode)
        if p is None:
            p = self._params[mode] = self.law.params_for(mode)
        dim = self.dims(mode)
        out = np.zeros((t.shape[0], self.law.inputs))
        for k in range(t.shape[0]):
            row = np.ascontiguousarray(x[k], dtype=float)
            self.law.control(float(t[k]), row[:dim], row[dim:], p, out[k])
        self._last = (key, out)
        return out


def saturation_watches(
    control: Any, names: Sequence[str], limits: np.ndarray, dims: Callable[[str], int]
) -> list[Watch]:
    """One time watch per actuated joint with a finite effort limit: the time |u_i| >= limit_i
    (counter ``saturated_<joint>_s``), u the ``ControlLaw``'s input at the stored points. None
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
    """The lowest point (m) of each link without a contact at configuration q: its points (in its
    joint's frame, (k, 3)) placed by Pinocchio's forward kinematics; with a terrain, each point's
    height above the terrain under it."""

    def __init__(
        self, model: pin.Model, links: Mapping[str, tuple[int, np.ndarray]], n: int, terrain: Terrain | None = None
    ) -> None:
        self.model, self.data, self.n = model, model.createData(), n
        self.terrain = terrain
        self.links = dict(links)
        self.names = list(self.links)
        self.joints = [joint for joint, _ in self.links.values()]
        # every link's points in one array, with the index of the link each belongs to
        self.points = np.vstack([points for _, points in self.links.values()]) if self.links else np.zeros((0, 3))
        owners = [np.full(len(p), k, dtype=int) for k, (_, p) in enumerate(self.links.values())]
        self.owner = np.concatenate(owners) if owners else np.zeros(0, dtype=int)

    def heights(self, q: np.ndarray) -> np.ndarray:
        """The world height (m) of every link point at configuration q."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q[: self.n], dtype=float))
        rows = np.empty((len(self.joints), 2, 3))
        shift = np.empty((len(self.joints), 2))
        for k, joint in enumerate(self.joints):
            placement = self.data.oMi[joint]
            rows[k], shift[k] = placement.rotation[[0, 2]], placement.translation[[0, 2]]
        z = np.einsum("ij,ij->i", self.points, rows[self.owner, 1]) + shift[self.owner, 1]
        if self.terrain is None:
            return z
        x = np.einsum("ij,ij->i", self.points, rows[self.owner, 0]) + shift[self.owner, 0]
        return z - self.terrain.height(x)

    def lowest(self, q: np.ndarray) -> float:
        """The lowest point of all the links (m)."""
        return float(np.min(self.heights(q)))

    def __call__(self, q: np.ndarray) -> dict[str, float]:
        """Each link's lowest point (m)."""
        z = self.heights(q)
        return {name: float(np.min(z[self.owner == k])) for k, name in enumerate(self.names)}


def below_ground_watch(heights: LinkHeights, ground: float, strict: bool) -> Watch:
    """A link without a contact below the ground z = ``ground``: a warning naming the link, the
    time and the depth, or with ``strict`` a stop with status ``model_breakdown``."""

    def lowest(x: np.ndarray) -> tuple[str, float]:
        h = heights(x)
        name = min(h, key=lambda k: h[k])
        return name, h[name] - ground

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.array([heights.lowest(row) for row in x]) - ground

    def message(t: float, mode: str, x: np.ndarray) -> str:
        h = heights(x)
        below = sorted((v - ground, k) for k, v in h.items() if v < ground)
        named = ", ".join(f"'{k}' {-d:.3g} m" for d, k in below) or f"'{lowest(x)[0]}' at the ground"
        return (
            f"link(s) without a contact below the ground at t={t:.17g} in mode '{mode}': {named} deep "
            f"(declare a contact on the link, or it passes through the ground)"
        )

    if strict:
        return Watch("below_ground", value, "stop", message, status=Status.MODEL_BREAKDOWN.value)
    return Watch("below_ground", value, "warn", message)
