"""Poincare sections: where a return map starts and ends.

``Section.crossing(mode, s, direction)`` is the level set s(x) = 0 of a function of the state of
one mode, crossed in a given direction (e.g. the apex ``zd = 0`` while zd decreases in flight);
``Section.level(mode, name, value, direction)`` is the common case s = x[name] - value;
``Section.after(transition)`` is the set of states just after a transition (e.g. the state after
heel strike), whose return is the next time that transition is taken; where transitions of that
name lead to several modes (a foot's touchdown from flight, or while the other foot stands),
``Section.after(transition, mode)`` names the target mode, and only the transitions of that name
into that mode count.

A ``Section`` names modes, coordinates and transitions; ``bind_section`` resolves those names
against a system once, into a ``BoundSection`` that evaluates s(x) and its gradient.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..derivatives import gradient
from ..errors import LegsimError
from ..hybrid import HybridSystem
from .errors import OrbitError


@dataclass(frozen=True)
class Section:
    """A Poincare section. Build one with ``Section.crossing``, ``Section.level`` or
    ``Section.after``.

    Attributes
    ----------
    mode: the mode the section lies in (for ``after``, the target mode given, or filled in from the
        transition's target when it has only one).
    function: ``s(x) -> float`` for a crossing section; the section is s = 0.
    direction: -1 when s decreases through 0 (from > 0 to <= 0), +1 when it increases, 0 both.
    gradient: optional ``grad s(x)`` of shape (n,); central differences otherwise.
    transition: name of the transition for an ``after`` section.
    coordinate, value: for ``coordinate`` sections, the coordinate's name and level.
    label: a readable name.
    """

    mode: str | None
    function: Callable[[np.ndarray], float] | None = None
    direction: int = -1
    gradient: Callable[[np.ndarray], np.ndarray] | None = None
    transition: str | None = None
    coordinate: str | None = None
    value: float = 0.0
    label: str = ""

    @classmethod
    def crossing(
        cls,
        mode: str,
        function: Callable[[np.ndarray], float],
        direction: int = -1,
        gradient: Callable[[np.ndarray], np.ndarray] | None = None,
        label: str = "",
    ) -> Section:
        """The level set ``function(x) = 0`` in ``mode``, crossed in ``direction`` (-1: s goes
        from > 0 to <= 0; +1: from < 0 to >= 0; 0: either)."""
        if not callable(function):
            raise OrbitError("Section.crossing: function must be callable s(x) -> float")
        return cls(
            mode, function, _check_direction(direction), gradient, None, None, 0.0, label or f"s(x) = 0 in {mode}"
        )

    @classmethod
    def level(cls, mode: str, coordinate: str, value: float = 0.0, direction: int = -1) -> Section:
        """``x[coordinate] = value`` in ``mode``, crossed in ``direction`` (e.g. the apex:
        ``Section.level("flight", "zd", 0.0, -1)``)."""
        if not isinstance(coordinate, str):
            raise OrbitError(f"Section.level: coordinate must be a name, got {coordinate!r}")
        value = float(value)
        if not math.isfinite(value):
            raise OrbitError(f"Section.level: value must be finite, got {value}")
        direction = _check_direction(direction)
        arrow = {-1: "decreasing", 1: "increasing", 0: "either way"}[direction]
        return cls(
            mode, None, direction, None, None, coordinate, value, f"{coordinate} = {value:g} ({arrow}) in {mode}"
        )

    @classmethod
    def after(cls, transition: str, mode: str | None = None) -> Section:
        """The states just after ``transition`` (its reset images), in its target mode; ``mode``
        names that target, needed when transitions of that name lead to several modes (only
        those into ``mode`` then count)."""
        if not isinstance(transition, str) or not transition:
            raise OrbitError(f"Section.after: transition must be a transition name, got {transition!r}")
        if mode is not None and (not isinstance(mode, str) or not mode):
            raise OrbitError(f"Section.after: mode must be a mode name, got {mode!r}")
        label = f"after {transition}" if mode is None else f"after {transition} into {mode}"
        return cls(mode, None, 0, None, transition, None, 0.0, label)

    @property
    def kind(self) -> str:
        """``"transition"`` or ``"crossing"``."""
        return "transition" if self.transition is not None else "crossing"


def _check_direction(direction: Any) -> int:
    """-1, 0 or +1 from a number or one of the words a scene may use."""
    if direction in ("decreasing", "down"):
        return -1
    if direction in ("increasing", "up"):
        return 1
    if direction in ("either", "both"):
        return 0
    if isinstance(direction, bool) or direction not in (-1, 0, 1):
        raise OrbitError(
            f"section direction must be -1, 0, +1 (or 'decreasing', 'increasing', 'either'), got {direction!r}"
        )
    return int(direction)


@dataclass(frozen=True)
class BoundSection:
    """A section resolved against a system: its mode, the mode's coordinate names and, for a
    coordinate section, that coordinate's index; evaluates s(x) and grad s(x)."""

    section: Section
    mode: str
    names: tuple[str, ...]
    index: int | None

    def s(self, x: np.ndarray) -> float:
        """The section function at the state x of the section's mode (0 on the section)."""
        if self.index is not None:
            return float(x[self.index]) - self.section.value
        return float(self.section.function(x))  # type: ignore[misc]

    def grad(self, x: np.ndarray) -> np.ndarray:
        """grad s(x), shape (n,): exact for a coordinate section, the section's own gradient
        when it has one, central differences otherwise."""
        n = len(x)
        if self.index is not None:
            g = np.zeros(n)
            g[self.index] = 1.0
            return g
        if self.section.gradient is not None:
            g = np.asarray(self.section.gradient(x), dtype=float).reshape(-1)
            if g.shape != (n,):
                raise OrbitError(f"section {self.section.label}: gradient has shape {g.shape}, expected ({n},)")
            return g
        return gradient(self.s, x)


def bind_section(section: Section, system: HybridSystem) -> BoundSection:
    """Resolve ``section``'s mode, transition and coordinate names against ``system``; an
    ``OrbitError`` listing the known names for one it does not have."""
    if not isinstance(section, Section):
        raise OrbitError(f"section must be a legsim.orbits.Section, got {type(section).__name__}")
    if section.transition is not None:
        return _bind_after(section, system)
    try:
        names = tuple(system.state_names(section.mode))  # type: ignore[arg-type]
    except LegsimError:
        raise OrbitError(
            f"section {section.label}: unknown mode {section.mode!r}; modes: {sorted(system.modes)}"
        ) from None
    index = None
    if section.coordinate is not None:
        if section.coordinate not in names:
            raise OrbitError(
                f"section {section.label}: mode '{section.mode}' has no coordinate "
                f"'{section.coordinate}'; coordinates: {list(names)}"
            )
        index = names.index(section.coordinate)
    return BoundSection(section, section.mode, names, index)  # type: ignore[arg-type]


def _bind_after(section: Section, system: HybridSystem) -> BoundSection:
    """A section after a transition lies in the transition's target mode: the one named, which
    a transition of that name must lead to, or the only one they lead to."""
    matches = [tr for tr in system.transitions if tr.name == section.transition]
    if not matches:
        known = sorted({tr.name for tr in system.transitions})
        raise OrbitError(
            f"section after '{section.transition}': no transition of that name in {system.name}; transitions: {known}"
        )
    targets = sorted({tr.target for tr in matches})
    if section.mode is not None:
        if section.mode not in targets:
            raise OrbitError(
                f"section {section.label}: no transition '{section.transition}' leads to mode "
                f"'{section.mode}'; it leads to {targets}",
                key="section.mode",
            )
        mode = section.mode
    elif len(targets) > 1:
        raise OrbitError(
            f"section after '{section.transition}': transitions of that name lead to several modes "
            f"{targets}; name the target mode (Section.after(transition, mode), or in a scene "
            f'section = {{ after = "{section.transition}", mode = "{targets[0]}" }})',
            key="section.mode",
        )
    else:
        mode = targets[0]
    return BoundSection(replace(section, mode=mode), mode, tuple(system.state_names(mode)), None)
