"""State against time with the strips shaded and the mode sequence, as in paper 003 Fig. 2.

One panel per state coordinate (sharing the time axis), each with a gray bar over every
relaxation strip (the interval in which the state is held at the guard point), and a band
below them coloured by the mode of each segment.

Figures are built on matplotlib's Agg canvas directly (``Figure`` + ``FigureCanvasAgg``),
never through pyplot, so no display or global backend is touched.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from legsim.builders import Model
from legsim.execution import Execution

from ._common import (OutputError, PlotData, plot_data_from_execution, plot_data_from_recording, resolve_model,
                      run_title, write_atomic)

#: gid of the strip shading in every state panel, and of the mode band (for tests and tools).
STRIP_GID = "strips"
MODE_GID = "modes"
STRIP_COLOUR = "0.78"
MODE_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                "#bcbd22", "#17becf"]
FORMATS = ("png", "pdf", "svg", "jpg", "jpeg")


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
    from matplotlib.patches import Patch

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
    spans = [(a, b - a) for a, b in data.strips]
    for ax, name in zip(axes[:-1], names):
        t, v = data.series[name]
        ax.plot(t, v, color="k", lw=1.0)
        if spans:
            # One collection per panel (not one patch per strip): a Zeno run has thousands.
            coll = ax.broken_barh(spans, (0, 1), transform=ax.get_xaxis_transform(), facecolors=STRIP_COLOUR,
                                  edgecolors="none", zorder=0)
            coll.set_gid(STRIP_GID)
        ax.set_ylabel(name)
        ax.grid(True, lw=0.3, alpha=0.5)
    band = axes[-1]
    modes = list(dict.fromkeys(m for m, _, _ in data.segments))
    colour = {m: MODE_COLOURS[i % len(MODE_COLOURS)] for i, m in enumerate(modes)}
    for m in modes:
        ranges = [(a, b - a) for mm, a, b in data.segments if mm == m]
        coll = band.broken_barh(ranges, (0, 1), facecolors=colour[m], edgecolors="none")
        coll.set_gid(f"{MODE_GID}:{m}")
    if spans:
        coll = band.broken_barh(spans, (0, 1), facecolors=STRIP_COLOUR, edgecolors="none")
        coll.set_gid(STRIP_GID)
    band.set_ylim(0, 1)
    band.set_yticks([])
    band.set_ylabel("mode", rotation=0, ha="right", va="center")
    band.set_xlabel("time (s)")
    band.set_xlim(data.t0, data.t_end)
    handles = [Patch(color=colour[m], label=m) for m in modes]
    if spans:
        handles.append(Patch(color=STRIP_COLOUR, label="strip"))
    band.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.9), ncol=min(len(handles), 6),
                fontsize="small", frameon=False)
    seq = [m for m, _, _ in data.segments]
    axes[0].set_title(f"{data.title}\nmode sequence: {_short_sequence(seq)}", fontsize="medium")
    return fig


def _short_sequence(seq: list[str], keep: int = 4) -> str:
    """Runs of one mode written once with a count (a bouncing ball is ``flight ×13``); long
    sequences keep their ends."""
    runs: list[list] = []
    for m in seq:
        if runs and runs[-1][0] == m:
            runs[-1][1] += 1
        else:
            runs.append([m, 1])
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
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi), suffix=path.suffix)


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
