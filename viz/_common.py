"""Shared plumbing of the writers: what to draw from a run or a recording, and the title."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from legsim.builders import Model
from legsim.execution import Execution
from legsim.output.summary import run_summary
from legsim.output.trace import execution_trace, trace_series

#: Largest magnitude a plot draws. matplotlib's tick and transform arithmetic overflows on
#: values near the float64 limit (1.8e308: "arange: cannot compute length"), which is where a
#: diverging run ends, so larger (and non-finite) values are left out of the lines.
PLOT_LIMIT = 1e300

_Writer = TypeVar("_Writer", bound=Callable[..., Any])


def writer_attributes(**attributes: Any) -> Callable[[_Writer], _Writer]:
    """Decorator: attach to an output writer what ``legsim run`` reads from it with getattr
    before the run (``suffixes``: the file suffixes it writes; ``needs_geometry``: it draws
    the model, so a model without geometry is refused)."""

    def attach(writer: _Writer) -> _Writer:
        writer.__dict__.update(attributes)
        return writer

    return attach


@dataclass
class PlotData:
    """What a state plot shows, from an execution or a recording.

    series: coordinate name -> (times (M,) s, values (M,)), with NaN where the coordinate is
        absent (a mode without it), so lines break there.
    strips: (entry, exit) times of the strips (s).
    segments: (mode, t_start, t_end) of every mode visit (s).
    title: one line; t0, t_end: the executed interval (s).
    units: coordinate name -> unit (``Mode.units``; "" where the model declares none); a name
        missing here has no recorded unit.
    omitted_from: earliest time (s) of a value left out of ``series`` because it is beyond
        ``PLOT_LIMIT`` or not finite (a diverged run), None when every value is drawn.
    strip_modes: the mode each strip holds the state in, one per entry of ``strips``.
    """

    series: dict[str, tuple[np.ndarray, np.ndarray]]
    strips: list[tuple[float, float]]
    segments: list[tuple[str, float, float]]
    title: str
    t0: float
    t_end: float
    units: dict[str, str] = field(default_factory=dict)
    omitted_from: float | None = None
    strip_modes: list[str] = field(default_factory=list)

    @property
    def omitted_note(self) -> str:
        """One line saying which values were left out ('' when none were)."""
        if self.omitted_from is None:
            return ""
        return f"values past t = {self.omitted_from:.6g} s omitted (diverged: |value| > {PLOT_LIMIT:g} or not finite)"


def drawable(
    series: dict[str, tuple[np.ndarray, np.ndarray]],
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], float | None]:
    """``series`` with every value beyond ``PLOT_LIMIT`` or not finite replaced by NaN (a
    break in the line), and the earliest time of such a value (None when there is none).

    The NaN breaks that ``_with_breaks`` inserts (time NaN too) are not counted as omitted.
    """
    out = {}
    first: float | None = None
    for name, (t, v) in series.items():
        v = np.asarray(v, dtype=float)
        t = np.asarray(t, dtype=float)
        # NaN fails the comparison, so a NaN value at a real time (a coordinate the run could
        # not compute) is omitted too; a break (time NaN as well) is not.
        bad = ~(np.abs(v) <= PLOT_LIMIT) & ~np.isnan(t)
        if bad.any():
            v = np.where(bad, np.nan, v)
            t_bad = float(np.min(t[bad]))
            first = t_bad if first is None else min(first, t_bad)
        out[name] = (t, v)
    return out, first


def _with_breaks(rows: np.ndarray, times: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert a NaN between samples whose rows are not consecutive (the coordinate was absent)."""
    if len(rows) < 2:
        return times, values
    gaps = np.nonzero(np.diff(rows) > 1)[0]
    if not len(gaps):
        return times, values
    t = np.insert(times, gaps + 1, np.nan)
    v = np.insert(values, gaps + 1, np.nan)
    return t, v


def plot_data_from_execution(execution: Execution, title: str) -> PlotData:
    """The recorded samples of ``execution`` (segment points and held strip points)."""
    trace = execution_trace(execution)
    series = {
        nm: _with_breaks(rows, trace.times[rows], vals) for nm, (rows, vals) in trace_series(execution, trace).items()
    }
    series, omitted = drawable(series)
    segments = [(s.mode, s.t_start, s.t_end) for s in execution.segments]
    units = units_by_name(execution.state_names, execution.state_units)
    return PlotData(
        series,
        execution.strip_intervals(),
        segments,
        title,
        float(execution.t0),
        float(execution.t_end),
        units=units,
        omitted_from=omitted,
        strip_modes=[s.mode for s in execution.strips],
    )


def units_by_name(names: Mapping[str, Any], units: Mapping[str, Any]) -> dict[str, str]:
    """Coordinate name -> unit from per-mode names and units (``Execution.state_names`` and
    ``state_units``, or a recording's); the first mode that declares a unit for a name wins.
    Entries that are not strings (a recording may come from someone else) are ignored."""
    out: dict[str, str] = {}
    for mode, mode_names in names.items():
        mode_units = units.get(mode)
        if not isinstance(mode_names, (list, tuple)) or not isinstance(mode_units, (list, tuple)):
            continue
        for name, unit in zip(mode_names, mode_units, strict=False):
            # A unit declared in one mode replaces "" (none declared) from another.
            if isinstance(name, str) and isinstance(unit, str) and not out.get(name):
                out[name] = unit
    return out


def axis_label(name: str, unit: str | None) -> str:
    """``name (unit)``; ``name (no unit)`` where the model declares none ("") and ``name (unit
    unknown)`` where nothing is known (None: a recording without units). Dollar signs are
    escaped, so that a name from a file is never parsed as mathtext."""
    shown = "unit unknown" if unit is None else (unit or "no unit")
    return f"{name} ({shown})".replace("$", r"\$")


def plot_data_from_recording(data: dict[str, Any]) -> PlotData:
    """The same, from ``legsim.record.read_rrd`` output (the recorded samples)."""
    series = {}
    for nm, (t, v) in data["series"].items():
        series[nm] = _with_breaks(np.asarray(data["series_rows"][nm]), np.asarray(t), np.asarray(v))
    s = data["summary"]
    title = _title(s.get("scene") or s.get("system") or "run", s)
    meta = data["meta"]
    strips = [(st["time"], st["exit_time"]) for st in data["strips"]]
    # Where Rerun stored a diverged run's values as float32 they are inf: left out the same way.
    series, omitted = drawable(series)
    return PlotData(
        series,
        strips,
        list(data["segments"]),
        title,
        float(meta["t0"]),
        float(meta["t_end"]),
        units=recorded_units(data),
        omitted_from=omitted,
        strip_modes=[str(st.get("mode", "")) for st in data["strips"]],
    )


def recorded_units(data: Mapping[str, Any]) -> dict[str, str]:
    """Coordinate name -> unit of a recording: its reader's ``units`` (name -> unit) when it
    has them, else the ``state_units`` (mode -> units) of its ``legsim/meta``; empty when the
    recording stores no units."""
    flat = data.get("units")
    if isinstance(flat, Mapping):
        return {k: v for k, v in flat.items() if isinstance(k, str) and isinstance(v, str)}
    meta = data.get("meta") or {}
    per_mode = meta.get("state_units")
    if isinstance(per_mode, Mapping) and isinstance(meta.get("state_names"), Mapping):
        return units_by_name(meta["state_names"], per_mode)
    return {}


def _title(name: str, summary: dict[str, Any]) -> str:
    parts = [name]
    if summary.get("method"):
        parts.append(f"{summary['method']}, h = {summary.get('h'):g}, eps = {summary.get('eps'):g}")
    if summary.get("status") and summary["status"] != "finished":
        parts.append(f"stopped: {summary['status']}")
    return "  ·  ".join(parts)


def run_title(execution: Execution, scene: Any = None, model: Model | None = None) -> str:
    """A figure title naming the scene (or system) and the integrator settings."""
    name = getattr(scene, "name", None) or (model.system.name if model is not None else execution.system_name)
    return _title(name or "run", run_summary(execution))
