"""What a run looks like to its outputs, independent of the renderer.

* ``Trace`` (``execution_trace``, ``trace_series``): the execution flattened to samples in time
  order, as computed (no resampling): every segment point, and for every strip its held guard
  point q at the strip's entry and at its exit. The Rerun recording stores these samples and
  the plots draw them.
* ``Frames`` (``frame_times``, ``geometry_frames``, ``scenery_only``): the robot's polylines
  (``Model.geometry``) at a sequence of times, and the static scenery. The Rerun recording and
  the meshcat animation draw these.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..builders import Model
from ..errors import LegsimError, ModelError, OutputError
from ..execution import Execution
from ..hybrid import HybridSystem

#: Default frame rate of geometry frames (per simulated second) and their most.
DEFAULT_FPS = 60.0
DEFAULT_MAX_FRAMES = 2000


class RecordingError(LegsimError, ValueError):
    """A recording, or the frames it is drawn from, cannot be made, written or read; the
    message names the file when there is one."""


# -- samples ------------------------------------------------------------------------------------
@dataclass
class Trace:
    """An execution flattened to samples, in time order (what ``state/<name>`` holds).

    times: (N,) s; mode_names: the modes in order of first visit; mode_index: (N,) index of
    each sample's mode in mode_names; in_strip: (N,) bool, True for the strip entry/exit
    samples (state held at q); blocks: mode -> (rows (M,), states (M, n_mode)), the samples
    of that mode; segment_starts: sample index where each segment starts; strip_samples:
    sample index of each strip's entry sample.
    """

    times: np.ndarray
    mode_names: list[str]
    mode_index: np.ndarray
    in_strip: np.ndarray
    blocks: dict[str, tuple[np.ndarray, np.ndarray]]
    segment_starts: np.ndarray
    strip_samples: np.ndarray

    @property
    def modes(self) -> list[str]:
        """The mode of every sample (N names)."""
        return [self.mode_names[i] for i in self.mode_index]


def concatenated_ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``concatenate(arange(s, s + n) for s, n in zip(starts, lengths))`` without a Python
    loop (int64); a Zeno run has as many ranges as strips."""
    lengths = np.asarray(lengths, dtype=np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, dtype=np.int64)
    offsets = np.cumsum(lengths) - lengths
    return np.repeat(np.asarray(starts, dtype=np.int64) - offsets, lengths) + np.arange(total, dtype=np.int64)


def execution_trace(execution: Execution) -> Trace:
    """Flatten an execution into the samples a recording stores.

    Segment points are taken as computed (no interpolation); each strip adds two samples with
    the held guard point q, at its entry and at its exit, so that the recorded series show
    the state standing still through the strip. Pieces come in the execution's own order
    (``Execution._pieces``: segment, strip, segment, ...), which keeps zero-length pieces in
    place.
    """
    _, pieces = execution._pieces()
    is_strip = np.array([kind == "strip" for kind, _ in pieces], dtype=bool)
    lengths = np.array([2 if kind == "strip" else len(execution.segments[k].t) for kind, k in pieces], dtype=np.int64)
    starts = np.cumsum(lengths) - lengths
    times = np.concatenate([_piece_times(execution, kind, k) for kind, k in pieces]) if pieces else np.empty(0)
    piece_modes = [_piece(execution, kind, k).mode for kind, k in pieces]
    mode_names = list(dict.fromkeys(piece_modes))
    code = {m: i for i, m in enumerate(mode_names)}
    piece_code = np.array([code[m] for m in piece_modes], dtype=np.int64)
    blocks = {}
    for mode, i in code.items():
        mine = np.nonzero(piece_code == i)[0]
        states = [_piece_states(execution, *pieces[p]) for p in mine]
        blocks[mode] = (
            concatenated_ranges(starts[mine], lengths[mine]),
            np.concatenate(states).astype(float, copy=False),
        )
    return Trace(
        times=times,
        mode_names=mode_names,
        mode_index=np.repeat(piece_code, lengths),
        in_strip=np.repeat(is_strip, lengths),
        blocks=blocks,
        segment_starts=starts[~is_strip],
        strip_samples=starts[is_strip],
    )


def _piece(execution: Execution, kind: str, k: int) -> Any:
    return execution.strips[k] if kind == "strip" else execution.segments[k]


def _piece_times(execution: Execution, kind: str, k: int) -> np.ndarray:
    """A segment's computed times, or a strip's entry and exit (s)."""
    if kind == "strip":
        strip = execution.strips[k]
        return np.array([strip.time, strip.exit_time], dtype=float)
    return execution.segments[k].t


def _piece_states(execution: Execution, kind: str, k: int) -> np.ndarray:
    """A segment's computed states (n, dim), or a strip's held state twice (2, dim)."""
    if kind == "strip":
        state = np.asarray(execution.strips[k].state, dtype=float)
        return np.broadcast_to(state, (2, len(state)))
    return execution.segments[k].x


def trace_series(execution: Execution, trace: Trace | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Coordinate name -> (sample indices (M,), values (M,)) over the samples of ``trace``
    whose mode has that coordinate; a name present in several modes is one series."""
    if trace is None:
        trace = execution_trace(execution)
    names: dict[str, None] = {}
    for mode in trace.mode_names:
        for name in execution.state_names.get(mode, ()):
            names.setdefault(name, None)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in names:
        rows_list, values = [], []
        for mode, (rows, block) in trace.blocks.items():
            coords = tuple(execution.state_names.get(mode, ()))
            if name in coords:
                rows_list.append(rows)
                values.append(block[:, coords.index(name)])
        rows = np.concatenate(rows_list)
        order = np.argsort(rows, kind="stable")
        out[name] = (rows[order], np.concatenate(values)[order])
    return out


# -- robot geometry -----------------------------------------------------------------------------
@dataclass
class Frames:
    """Robot geometry at a sequence of times (what ``robot/<part>`` holds).

    times: (F,) s; modes: F mode names; parts: part name -> F polylines, each an array (k, 2)
    of (x, z) in metres, or None where the part is absent in that frame; scenery: static
    polylines (k, 2).
    """

    times: np.ndarray
    modes: list[str]
    parts: dict[str, list[np.ndarray | None]]
    scenery: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.times)


def frame_times(execution: Execution, fps: float = DEFAULT_FPS, max_frames: int = DEFAULT_MAX_FRAMES) -> np.ndarray:
    """Times (s) at which to draw the robot: a uniform grid of ``fps`` frames per simulated
    second (coarser when that would exceed ``max_frames``), plus every strip entry and exit
    while the total stays within ``max_frames`` (so that the viewer shows each transition)."""
    if not (fps > 0 and math.isfinite(fps)):
        raise RecordingError(f"fps must be finite and > 0, got {fps!r}")
    if max_frames < 2:
        raise RecordingError(f"max_frames must be >= 2, got {max_frames!r}")
    t0, t1 = float(execution.t0), float(execution.t_end)
    span = t1 - t0
    if span <= 0:
        return np.array([t0])
    count = int(min(max_frames, math.floor(span * fps) + 1))
    grid = np.linspace(t0, t1, max(count, 2))
    events = np.array([t for s in execution.strips for t in (s.time, s.exit_time)])
    if len(grid) + len(events) <= max_frames and len(events):
        grid = np.union1d(grid, events[(events >= t0) & (events <= t1)])
    return grid


def _polyline(value: Any, part: str, mode: str, t: float, system: str) -> np.ndarray:
    """``value`` as a finite (k, 2) array of (x, z) points; ModelError naming the part otherwise."""
    where = f"{system}: geometry part '{part}' in mode '{mode}' at t={t:.6g}"
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{where} is not numeric: {exc}") from exc
    if arr.shape == (2,):
        arr = arr.reshape(1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ModelError(f"{where} has shape {arr.shape}, expected (k, 2) points (x, z) in metres")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where} is not finite")
    return arr


def _draw(
    geometry: Callable[[str, np.ndarray], Any], name: str, mode: str, x: np.ndarray, t: float
) -> dict[str, np.ndarray]:
    """``geometry(mode, x)`` of the system ``name`` checked: part name -> (k, 2) polyline."""
    try:
        parts = geometry(mode, np.asarray(x, dtype=float))
    except ModelError:
        raise
    except Exception as exc:
        raise ModelError(f"{name}: geometry failed in mode '{mode}' at t={t:.6g}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(parts, Mapping):
        raise ModelError(f"{name}: geometry must return a dict part -> (k, 2) array, got {type(parts).__name__}")
    return {str(p): _polyline(v, str(p), mode, t, name) for p, v in parts.items()}


def geometry_frames(
    execution: Execution,
    model: Model,
    times: np.ndarray | None = None,
    *,
    fps: float = DEFAULT_FPS,
    max_frames: int = DEFAULT_MAX_FRAMES,
) -> Frames:
    """Evaluate ``model.geometry(mode, x)`` on the execution at ``times`` (s; default
    ``frame_times``). Raises ModelError naming the part, mode and time when the geometry is
    missing or malformed."""
    geometry = model.geometry
    if geometry is None:
        raise ModelError(
            f"{model.system.name}: the model has no geometry (Model.geometry is None), so there is no robot to draw"
        )
    if times is None:
        times = frame_times(execution, fps, max_frames)
    samples = execution.sample(times)
    drawn = [
        _draw(geometry, model.system.name, mode, x, float(t))
        for t, mode, x in zip(samples.times, samples.modes, samples.states, strict=True)
    ]
    names = sorted({p for d in drawn for p in d})
    per_part = {p: [d.get(p) for d in drawn] for p in names}
    scenery = _scenery(model, float(execution.t0))
    return Frames(np.asarray(samples.times, dtype=float), list(samples.modes), per_part, scenery)


def _scenery(model: Model, t: float) -> dict[str, np.ndarray]:
    return {str(p): _polyline(v, str(p), "scenery", t, model.system.name) for p, v in model.scenery.items()}


def scenery_only(model: Model | None) -> dict[str, np.ndarray]:
    """The model's static polylines (k, 2), validated (empty without a model)."""
    return {} if model is None else _scenery(model, 0.0)


def resolve_model(scene: Any, model: Model | HybridSystem | None, what: str) -> Model | None:
    """The model of ``scene`` or the ``model=`` keyword of a writer (not both): a ``Model``, or
    a plain ``HybridSystem``, which is taken as a model without geometry or scenery (its
    energy, when it defines one, is reported). ``what`` names the writer in the errors."""
    if scene is not None:
        if model is not None and model is not scene.model and model is not scene.model.system:
            raise OutputError(f"{what}: give either a scene or model=, not both")
        return scene.model
    if isinstance(model, HybridSystem):
        return Model(model, initial_mode=next(iter(model.modes), ""), initial_state={})
    if model is not None and not isinstance(model, Model):
        raise OutputError(f"{what}: model= takes a legsim.builders.Model or a HybridSystem, got {type(model).__name__}")
    return model
