"""Shared plumbing of the writers: atomic files and what to draw from a run or a recording."""

from __future__ import annotations

import os
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from legsim.builders import Model
from legsim.errors import LegsimError
from legsim.execution import Execution
from legsim.record import execution_trace, trace_series


class OutputError(LegsimError, ValueError):
    """An output (html, plot) cannot be produced; the message names the file."""


def resolve_model(scene: Any, model: Model | None, what: str) -> Model | None:
    """The model of ``scene`` or the ``model=`` keyword (not both)."""
    if scene is not None:
        if model is not None and model is not scene.model:
            raise OutputError(f"{what}: give either a scene or model=, not both")
        return scene.model
    return model


def write_atomic(path: str | os.PathLike, write: Callable[[Path], None], suffix: str = "") -> Path:
    """Call ``write(tmp)`` on a temporary file next to ``path``, then rename it to ``path``.

    The file appears complete or not at all; the temporary file is removed on any failure.
    It is created with open(..., "xb") (not mkstemp) so it gets the usual permissions.
    """
    path = Path(path)
    tmp = path.parent / f".{path.name}.{uuid.uuid4().hex[:12]}.tmp{suffix}"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        open(tmp, "xb").close()
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc}") from exc
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise OutputError(f"{path}: cannot write: {exc}") from exc
        raise
    return path


@dataclass
class PlotData:
    """What a state plot shows, from an execution or a recording.

    series: coordinate name -> (times (M,) s, values (M,)), with NaN where the coordinate is
        absent (a mode without it), so lines break there.
    strips: (entry, exit) times of the strips (s).
    segments: (mode, t_start, t_end) of every mode visit (s).
    title: one line; t0, t_end: the executed interval (s).
    """

    series: dict[str, tuple[np.ndarray, np.ndarray]]
    strips: list[tuple[float, float]]
    segments: list[tuple[str, float, float]]
    title: str
    t0: float
    t_end: float
    units: dict[str, str] = field(default_factory=dict)


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
    series = {nm: _with_breaks(rows, trace.times[rows], vals)
              for nm, (rows, vals) in trace_series(execution, trace).items()}
    segments = [(s.mode, s.t_start, s.t_end) for s in execution.segments]
    return PlotData(series, execution.strip_intervals(), segments, title, float(execution.t0), float(execution.t_end))


def plot_data_from_recording(data: dict[str, Any]) -> PlotData:
    """The same, from ``legsim.record.read_rrd`` output."""
    series = {}
    for nm, (t, v) in data["series"].items():
        series[nm] = _with_breaks(np.asarray(data["series_rows"][nm]), np.asarray(t), np.asarray(v))
    s = data["summary"]
    title = _title(s.get("scene") or s.get("system") or "run", s)
    meta = data["meta"]
    strips = [(st["time"], st["exit_time"]) for st in data["strips"]]
    return PlotData(series, strips, list(data["segments"]), title, float(meta["t0"]), float(meta["t_end"]))


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
    return _title(name or "run", execution.summary())
