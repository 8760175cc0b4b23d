"""State against time with the strips shaded and the mode sequence, as in paper 003 Fig. 2.

One panel per state coordinate (sharing the time axis), each with a gray bar over every
relaxation strip (the interval in which the state is held at the guard point), and a band
below them coloured by the mode of each segment.

Figures are built on matplotlib's Agg canvas directly (``Figure`` + ``FigureCanvasAgg``),
never through pyplot, so no display or global backend is touched.
"""

from __future__ import annotations

import os
from itertools import groupby
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from legsim.builders import Model
from legsim.execution import Execution

from legsim.errors import OutputError
from legsim.output.files import write_atomic
from legsim.output.trace import resolve_model

from ._common import PlotData, plot_data_from_execution, plot_data_from_recording, run_title

#: gid of the strip shading in every state panel, and of the mode band (for tests and tools).
STRIP_GID = "strips"
MODE_GID = "modes"
STRIP_COLOUR = "0.78"
MODE_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                "#bcbd22", "#17becf"]
FORMATS = ("png", "pdf", "svg", "jpg", "jpeg")
SPAN_RESOLUTION = 20_000


def plot_data(execution: Execution | None = None, scene: Any = None, *, model: Model | None = None,
              recording: dict[str, Any] | None = None) -> PlotData:
    """What ``write_plot`` draws, from an execution or from ``legsim.record.read_rrd`` output."""
    if recording is not None:
        return plot_data_from_recording(recording)
    if not isinstance(execution, Execution):
        raise OutputError(f"a plot needs a legsim Execution (or recording=), got {type(execution).__name__}")
    model = resolve_model(scene, model, "plot")
    return plot_data_from_execution(execution, run_title(execution, scene, model))


def state_figure(data: PlotData, coordinates: Sequence[str] | None = None, *, width: float = 8.0):
    """The figure: one panel per coordinate (default: all), strips shaded, mode band below.

    Returns a ``matplotlib.figure.Figure`` attached to an Agg canvas.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    names = list(data.series) if coordinates is None else list(coordinates)
    unknown = [n for n in names if n not in data.series]
    if unknown:
        raise OutputError(f"plot: unknown coordinate(s) {unknown}; recorded: {list(data.series)}")
    n = len(names)
    fig = Figure(figsize=(width, 1.5 * max(n, 1) + 1.0), layout="constrained")
    FigureCanvasAgg(fig)
    ratios = [3] * n + [1]
    axes = fig.subplots(n + 1, 1, sharex=True, gridspec_kw={"height_ratios": ratios})
    axes = np.atleast_1d(axes)
    # Intervals closer than 1/20 of a pixel (at 1000 px across) are drawn joined.
    tol = (data.t_end - data.t0) / SPAN_RESOLUTION
    for ax, name in zip(axes[:-1], names):
        state_panel(ax, data, name, tol)
        ax.set_ylabel(name)
    band = axes[-1]
    handles = mode_band(band, data, tol)
    band.set_ylim(0, 1)
    band.set_ylabel("mode", rotation=0, ha="right", va="center")
    band.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.9), ncol=min(len(handles), 6),
                fontsize="small", frameon=False)
    seq = [m for m, _, _ in data.segments]
    # Say what a diverged run's plot leaves out, so that a line ending early is not misread.
    note = f"\n{data.omitted_note}" if data.omitted_note else ""
    axes[0].set_title(f"{data.title}\nmode sequence: {_short_sequence(seq)}{note}", fontsize="medium")
    return fig


def state_panel(ax, data: PlotData, name: str, tol: float) -> None:
    """One coordinate against time on ``ax``, with the strips shaded (``span_patch``, joined
    within ``tol`` s)."""
    t, v = data.series[name]
    ax.plot(t, v, color="k", lw=1.0)
    if data.strips:
        span_patch(ax, data.strips, STRIP_COLOUR, STRIP_GID, tol)
    ax.grid(True, lw=0.3, alpha=0.5)


def mode_band(band, data: PlotData, tol: float) -> list:
    """The mode band on ``band``: each segment's interval in its mode's colour, the strips over
    them, over the run's time span with time labelled. Returns the legend handles (one per mode,
    and one for the strips)."""
    from matplotlib.patches import Patch

    modes = list(dict.fromkeys(m for m, _, _ in data.segments))
    colour = {m: MODE_COLOURS[i % len(MODE_COLOURS)] for i, m in enumerate(modes)}
    for m in modes:
        span_patch(band, [(a, b) for mm, a, b in data.segments if mm == m], colour[m], f"{MODE_GID}:{m}", tol)
    if data.strips:
        span_patch(band, data.strips, STRIP_COLOUR, STRIP_GID, tol)
    band.set_yticks([])
    band.set_xlabel("time (s)")
    band.set_xlim(data.t0, data.t_end)
    handles = [Patch(color=colour[m], label=m) for m in modes]
    if data.strips:
        handles.append(Patch(color=STRIP_COLOUR, label="strip"))
    return handles


def merge_spans(spans: Sequence[tuple[float, float]], tol: float = 0.0) -> np.ndarray:
    """The intervals (S, 2) sorted, with those that overlap or lie within ``tol`` of each
    other joined: their union, up to gaps no wider than ``tol``."""
    a = np.asarray(spans, dtype=float).reshape(-1, 2)
    if len(a) < 2:
        return a
    a = a[np.argsort(a[:, 0], kind="stable")]
    reach = np.maximum.accumulate(a[:, 1])
    new = np.concatenate([[True], a[1:, 0] - reach[:-1] > tol])
    first = np.nonzero(new)[0]
    return np.stack([a[first, 0], np.maximum.reduceat(a[:, 1], first)], axis=1)


def span_patch(ax, spans: Sequence[tuple[float, float]], colour: str, gid: str, tol: float = 0.0):
    """Shade the time intervals ``spans`` over the full height of ``ax`` with one patch.

    One compound path of rectangles (5 vertices each) rather than a patch or collection item
    per interval: a Zeno run has tens of thousands of strips. Intervals closer than ``tol``
    are drawn as one (``merge_spans``): rasterising 10^5 sub-pixel rectangles costs seconds
    and shows nothing more. Added as an artist, so it does not change the axes' data
    limits. ``span_bounds`` reads the intervals back.
    """
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MPath

    a = merge_spans(spans, tol)
    verts = np.empty((len(a), 5, 2))
    verts[:, [0, 3, 4], 0] = a[:, :1]
    verts[:, [1, 2], 0] = a[:, 1:]
    verts[:, [0, 1, 4], 1] = 0.0
    verts[:, [2, 3], 1] = 1.0
    codes = np.tile([MPath.MOVETO, MPath.LINETO, MPath.LINETO, MPath.LINETO, MPath.CLOSEPOLY], len(a))
    patch = PathPatch(MPath(verts.reshape(-1, 2), codes), facecolor=colour, edgecolor="none", linewidth=0,
                      transform=ax.get_xaxis_transform(), zorder=0,
                      antialiased=False)  # adjacent intervals would show anti-aliasing seams
    patch.set_gid(gid)
    ax.add_artist(patch)
    return patch


def span_bounds(patch) -> np.ndarray:
    """The (start, end) intervals (S, 2) drawn by ``span_patch``."""
    v = patch.get_path().vertices.reshape(-1, 5, 2)
    return np.stack([v[:, 0, 0], v[:, 1, 0]], axis=1)


def _short_sequence(seq: list[str], keep: int = 4) -> str:
    """Runs of one mode written once with a count (a bouncing ball is ``flight ×13``); long
    sequences keep their ends."""
    runs = [(mode, len(list(repeats))) for mode, repeats in groupby(seq)]
    words = [m if k == 1 else f"{m} ×{k}" for m, k in runs]
    if len(words) <= 2 * keep:
        return " → ".join(words)
    return " → ".join(words[:keep]) + f" → … ({len(words) - 2 * keep} more) → " + " → ".join(words[-keep:])


def save_figure(fig, path: str | os.PathLike, dpi: int = 120) -> Path:
    """Save ``fig`` to ``path`` (format from the suffix) completely or not at all."""
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise OutputError(f"{path}: unsupported figure format '{path.suffix}'; use one of {['.' + f for f in FORMATS]}")
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi), what="figure")


def write_plot(execution: Execution | None, scene: Any = None, path: str | os.PathLike | None = None, *,
               model: Model | None = None, recording: dict[str, Any] | None = None,
               coordinates: Sequence[str] | None = None) -> Path:
    """Write the state-against-time figure of a run (the ``--plot`` output) to ``path``.

    ``scene`` is a ``legsim.scene.Scene`` or None (then ``model=`` may name the model, which a
    plot does not need); ``recording=`` takes ``legsim.record.read_rrd`` output instead of an
    execution. The format follows the suffix (.png, .pdf, .svg, .jpg). Atomic write.
    """
    if path is None:
        raise OutputError("write_plot needs a path to write to")
    fig = state_figure(plot_data(execution, scene, model=model, recording=recording), coordinates)
    return save_figure(fig, path)


#: The suffixes write_plot can write; ``legsim run`` checks a --plot path against them before the run.
write_plot.suffixes = tuple("." + f for f in FORMATS)
