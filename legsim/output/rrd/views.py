"""What the Rerun viewer opens on: the coordinates grouped by unit into plot views named with
the unit, and the blueprint (the 3D robot, the mode and strip band, the plots, the events)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .layout import MODE, NO_UNIT, ROBOT, SCENERY, STRIP, SUMMARY, TIMELINE, UNIT_WORDS, WORLD

#: Plot views stacked in the middle column; further unit groups share a tab container below.
STACKED_VIEWS = 3


@dataclass(frozen=True)
class UnitGroup:
    """The coordinates of one unit: ``unit`` ("" for none), the view's ``title`` and the
    entity paths of its coordinates."""

    unit: str
    title: str
    entities: tuple[str, ...]


def coordinate_units(
    state_names: Mapping[str, tuple[str, ...]], state_units: Mapping[str, tuple[str, ...]]
) -> dict[str, str]:
    """Coordinate name -> its unit, "" when the model gives none or its modes disagree."""
    units: dict[str, str] = {}
    for mode, names in state_names.items():
        given = tuple(state_units.get(mode, ())) or ("",) * len(names)
        for name, unit in zip(names, given, strict=False):
            units[name] = unit if units.get(name, unit) == unit else ""
    return units


def series_label(name: str, unit: str) -> str:
    """The legend name of a coordinate's series: ``x (m)``, or the name alone without a unit."""
    return f"{name} ({unit})" if unit else name


def unit_groups(entities: Mapping[str, str], units: Mapping[str, str]) -> list[UnitGroup]:
    """The plot views: one per unit (coordinate name -> entity path in ``entities``), the units
    of ``UNIT_WORDS`` first in its order, then the others by name, then those without a unit."""
    by_unit: dict[str, list[str]] = {}
    for name, entity in entities.items():
        by_unit.setdefault(units.get(name, ""), []).append(entity)
    order = list(UNIT_WORDS) + sorted(u for u in by_unit if u and u not in UNIT_WORDS) + [""]
    groups = []
    for unit in order:
        if unit in by_unit:
            title = f"{UNIT_WORDS.get(unit, 'values')} ({unit})" if unit else NO_UNIT
            groups.append(UnitGroup(unit, title, tuple(by_unit[unit])))
    return groups


def blueprint(rrb: Any, groups: list[UnitGroup], box: tuple[np.ndarray, np.ndarray] | None) -> Any:
    """The viewer's layout on the ``sim_time`` timeline: the robot in 3D (when there is
    geometry; ``box`` the (x, z) corners of everything drawn) over the mode and strip band, the
    plots by unit, and the summary and event log in tabs."""
    band = rrb.StateTimelineView(contents=[MODE, STRIP], name="mode and strips")
    left = band
    if box is not None:
        robot = rrb.Spatial3DView(
            origin=WORLD, contents=[f"{ROBOT}/**", f"{SCENERY}/**"], name="robot", eye_controls=_eye(rrb, *box)
        )
        left = rrb.Vertical(robot, band, row_shares=[4, 1])
    plots = [rrb.TimeSeriesView(contents=list(g.entities), name=g.title) for g in groups]
    if len(plots) > STACKED_VIEWS:
        plots = [*plots[: STACKED_VIEWS - 1], rrb.Tabs(*plots[STACKED_VIEWS - 1 :])]
    side = rrb.Tabs(
        rrb.TextLogView(origin="/events", name="events"), rrb.TextDocumentView(origin=SUMMARY, name="summary")
    )
    columns = [left, rrb.Vertical(*plots), side] if plots else [left, side]
    shares = [3, 3, 2] if plots else [3, 2]
    return rrb.Blueprint(
        rrb.Horizontal(*columns, column_shares=shares), rrb.TimePanel(timeline=TIMELINE), collapse_panels=True
    )


def _eye(rrb: Any, low: np.ndarray, high: np.ndarray) -> Any:
    """A camera looking along +y at the box (x, z) from ``low`` to ``high`` (m), far enough
    back to see it whole."""
    centre = (low + high) / 2
    size = float(max(high[0] - low[0], high[1] - low[1], 0.5))
    return rrb.EyeControls3D(
        position=(float(centre[0]), -1.6 * size, float(centre[1])),
        look_target=(float(centre[0]), 0.0, float(centre[1])),
        eye_up=(0.0, 0.0, 1.0),
    )
