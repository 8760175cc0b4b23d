"""Named measures of a run, asked for with ``--measure KIND:COORD[:FROM]``: each adds one column
to a sweep's table, computed from the variation's execution.

Kinds (``KINDS``):

* ``mean_rate``: the mean rate of a coordinate over [FROM, t_end] (s), (c(t_end) - c(FROM)) /
  (t_end - FROM): of the body's ``x``, the mean forward speed (m/s). Column ``mean_rate_COORD``.
* ``max_abs``: the largest |c| over the stored points in [FROM, t_end]: of ``pitch``, how far
  the body pitched. Column ``max_abs_COORD``.

One measure per kind and coordinate (its column's name). FROM defaults to the scene's t0. The
value at FROM is interpolated linearly between the stored points around it (points h apart, so
its error is O(h^2) times the coordinate's second derivative). A run that ended at or before
FROM (a fall, a failure) has no window: its value is null. A FROM outside [t0, t_final) of a
variation's scene is refused before anything runs. A run that ended after FROM but
before t_final is measured over [FROM, t_end]; its status says it ended early.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SweepError

#: The measures' kinds, with what they compute (the error messages quote these).
KINDS = {
    "mean_rate": "the coordinate's mean rate over [FROM, t_end] (units per s)",
    "max_abs": "the largest |coordinate| over [FROM, t_end]",
}
_FORM = "KIND:COORD[:FROM], e.g. mean_rate:x:5"


@dataclass(frozen=True)
class Measure:
    """One measure: its ``kind`` (a key of ``KINDS``), the ``coordinate`` by name and the
    window's start ``start`` (s; None: the scene's t0)."""

    kind: str
    coordinate: str
    start: float | None = None

    @property
    def column(self) -> str:
        return f"{self.kind}_{self.coordinate}"


def parse_measure(text: str) -> Measure:
    """``KIND:COORD[:FROM]`` into a Measure; SweepError naming ``--measure`` and what is allowed."""
    parts = text.split(":") if isinstance(text, str) else []
    if len(parts) not in (2, 3) or not all(p.strip() for p in parts):
        raise SweepError(f"--measure {text!r}: expected {_FORM}")
    kind, coordinate = parts[0].strip(), parts[1].strip()
    if kind not in KINDS:
        raise SweepError(f"--measure {text!r}: unknown kind {kind!r}; allowed: {sorted(KINDS)}")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", coordinate):
        raise SweepError(f"--measure {text!r}: {coordinate!r} is no coordinate name")
    start = None
    if len(parts) == 3:
        try:
            start = float(parts[2])
        except ValueError:
            start = math.nan
        if not math.isfinite(start):
            raise SweepError(f"--measure {text!r}: FROM must be a finite time (s), got {parts[2].strip()!r}")
    return Measure(kind, coordinate, start)


def check_measures(texts: tuple[str, ...]) -> list[Measure]:
    """The measures of a sweep, each parsed, no column asked for twice."""
    measures = [parse_measure(t) for t in texts]
    columns = [m.column for m in measures]
    repeated = sorted({c for c in columns if columns.count(c) > 1})
    if repeated:
        raise SweepError(f"--measure: column(s) {repeated} asked for twice")
    return measures


def check_coordinates(measures: list[Measure], system: Any, scene_path: Any) -> None:
    """SweepError naming the measure when a mode of the scene's system lacks its coordinate."""
    for m in measures:
        lacking = [mode for mode in system.modes if m.coordinate not in system.state_names(mode)]
        if lacking:
            some = system.state_names(lacking[0])
            raise SweepError(
                f"--measure {m.kind}:{m.coordinate}: {scene_path}: mode(s) {lacking[:5]} have no coordinate "
                f"{m.coordinate!r}; the coordinates of '{lacking[0]}': {list(some)}"
            )


def check_windows(measures: list[Measure], t0: float, t_final: float, scene_path: Any) -> None:
    """SweepError naming the measure when its window [FROM, t_final] holds no time of the run:
    FROM at or past ``t_final`` (s) would give every row a null column, FROM before ``t0`` (s)
    a value the run never had."""
    for m in measures:
        if m.start is not None and not t0 <= m.start < t_final:
            raise SweepError(
                f"--measure {m.kind}:{m.coordinate}:{m.start:g}: FROM must lie in [t0, t_final) = "
                f"[{t0:g}, {t_final:g}) s of {scene_path}"
            )


def samples(execution: Any, system: Any, coordinate: str) -> tuple[np.ndarray, np.ndarray]:
    """The execution's stored times (s) and one coordinate's values, over all its segments."""
    times, values = [], []
    for seg in execution.segments:
        column = system.state_names(seg.mode).index(coordinate)
        times.append(seg.t)
        values.append(seg.x[:, column])
    return np.concatenate(times), np.concatenate(values)


def measure_columns(measures: list[Measure], execution: Any, system: Any) -> dict[str, float | None]:
    """Each measure's column of a run's row (None where the run ended at or before FROM)."""
    out: dict[str, float | None] = {}
    for m in measures:
        t, c = samples(execution, system, m.coordinate)
        start = float(execution.t0) if m.start is None else m.start
        end = float(t[-1])
        if end <= start:
            out[m.column] = None
        elif m.kind == "mean_rate":
            out[m.column] = float((c[-1] - np.interp(start, t, c)) / (end - start))
        else:
            inside = c[t >= start]
            out[m.column] = float(max(np.max(np.abs(inside)), abs(np.interp(start, t, c))))
    return out
