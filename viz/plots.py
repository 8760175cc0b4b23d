"""State against time with the strips shaded and the mode sequence, as in paper 003 Fig. 2.

One panel per state coordinate (sharing the time axis), each labelled with the coordinate's
unit (``Mode.units``) and with a gray bar over every relaxation strip (the interval in which the
state is held at the guard point), and a band below them coloured by the mode of each segment;
a strip is gray on the band with a stripe in the colour of the mode it holds the state in, so a
mode that only lives inside strips (the pronk's one-leg mode between two touchdowns of one
step) is on the band too. Coordinates that do not change over the run (the symmetric pronk's
pitch) get no panel: the title says ``theta = 0 rad throughout`` instead of autoscaling
rounding noise into a curve.

Figures are built on matplotlib's Agg canvas directly (``Figure`` + ``FigureCanvasAgg``),
never through pyplot, so no display or global backend is touched.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from itertools import groupby
from pathlib import Path
from typing import Any

import numpy as np

from legsim.builders import Model
from legsim.errors import OutputError
from legsim.execution import Execution
from legsim.hybrid import HybridSystem
from legsim.output.files import write_atomic
from legsim.output.trace import resolve_model

from ._common import (
    PlotData,
    axis_label,
    plot_data_from_execution,
    plot_data_from_recording,
    run_title,
    writer_attributes,
)

#: gid of the strip shading in every state panel, and of the mode band (for tests and tools);
#: on the band, ``modes:<mode>`` shades the segments of a mode, ``modes:<mode>:held`` the strips
#: holding the state in it and ``modes:<mode>:marks`` its intervals too narrow to see.
STRIP_GID = "strips"
MODE_GID = "modes"
#: A coordinate whose values spread by at most this fraction of the state's magnitude (the
#: median over coordinates of each one's largest magnitude), or not at all, is drawn as a note,
#: not a panel: its variation is rounding noise. The median, not the largest magnitude: one
#: large coordinate (a runner's x after a long run) would otherwise hide real small motions.
CONSTANT_RTOL = 1e-9
#: Band intervals narrower than this fraction of the run are also drawn as a line of fixed
#: width, so that a mode visited for an instant stays visible.
THIN_FRACTION = 1 / 500
#: Height (axes fraction) of the stripe that shows a strip's mode on the band.
HELD_STRIPE = (0.3, 0.7)
STRIP_COLOUR = "0.78"
MODE_COLOURS = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
]
FORMATS = ("png", "pdf", "svg", "jpg", "jpeg")
SPAN_RESOLUTION = 20_000


def plot_data(
    execution: Execution | None = None,
    scene: Any = None,
    *,
    model: Model | HybridSystem | None = None,
    recording: dict[str, Any] | None = None,
) -> PlotData:
    """What ``write_plot`` draws, from an execution or from ``legsim.record.read_rrd`` output."""
    if recording is not None:
        return plot_data_from_recording(recording)
    if not isinstance(execution, Execution):
        raise OutputError(f"a plot needs a legsim Execution (or recording=), got {type(execution).__name__}")
    model = resolve_model(scene, model, "plot")
    return plot_data_from_execution(execution, run_title(execution, scene, model))


def state_figure(data: PlotData, coordinates: Sequence[str] | None = None, *, width: float = 8.0):
    """The figure: one panel per coordinate (default: all that change, see
    ``constant_coordinates``), strips shaded, mode band below. Returns a
    ``matplotlib.figure.Figure`` attached to an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    constants = constant_coordinates(data)
    if coordinates is None:
        names = [n for n in data.series if n not in constants]
    else:
        names = list(coordinates)
        unknown = [n for n in names if n not in data.series]
        if unknown:
            raise OutputError(f"plot: unknown coordinate(s) {unknown}; recorded: {list(data.series)}")
    n = len(names)
    fig = Figure(figsize=(width, 1.5 * max(n, 1) + 1.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(n + 1, 1, sharex=True, gridspec_kw={"height_ratios": [3] * n + [1]}))
    # Intervals closer than 1/20 of a pixel (at 1000 px across) are drawn joined.
    tol = (data.t_end - data.t0) / SPAN_RESOLUTION
    for ax, name in zip(axes[:-1], names, strict=True):
        state_panel(ax, data, name, tol)
        ax.set_ylabel(axis_label(name, data.units.get(name)))
    band = axes[-1]
    handles = mode_band(band, data, tol)
    band.set_ylim(0, 1)
    band.set_ylabel("mode", rotation=0, ha="right", va="center")
    band.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.9),
        ncol=min(len(handles), 6),
        fontsize="small",
        frameon=False,
    )
    seq = [m for m, _, _ in data.segments]
    # Say what a diverged run's plot leaves out, so that a line ending early is not misread.
    notes = [note for note in (constants_note(constants, data, skip=names), data.omitted_note) if note]
    axes[0].set_title("\n".join([data.title, f"mode sequence: {_short_sequence(seq)}", *notes]), fontsize="medium")
    return fig


def constant_coordinates(data: PlotData) -> dict[str, float]:
    """Coordinate name -> value of the coordinates that stay constant over the run: spread
    (max - min of the drawn values) at most ``CONSTANT_RTOL`` times the state's magnitude, or
    zero. The value is the common value when it is exact, else the mean (0 when the mean is
    itself within the tolerance of 0)."""
    drawn = {name: v[np.isfinite(v)] for name, (_, v) in data.series.items()}
    tops = [float(np.max(np.abs(v))) for v in drawn.values() if len(v)]
    tolerance = CONSTANT_RTOL * (float(np.median(tops)) if tops else 0.0)
    out = {}
    for name, v in drawn.items():
        if not len(v):
            continue
        spread = float(np.ptp(v))
        if spread == 0.0:
            out[name] = float(v[0])
        elif spread <= tolerance:
            mean = float(np.mean(v))
            out[name] = 0.0 if abs(mean) <= tolerance else mean
    return out


def constants_note(constants: dict[str, float], data: PlotData, skip: Sequence[str] = ()) -> str:
    """``theta = 0 rad, thetad = 0 rad/s throughout``: the constant coordinates not drawn
    (``skip``: those drawn anyway); "wherever defined" for one absent in some modes."""
    parts: dict[str, list[str]] = {"throughout": [], "wherever defined": []}
    for name, value in constants.items():
        if name in skip:
            continue
        unit = data.units.get(name) or ""
        absent = bool(np.isnan(data.series[name][1]).any())
        shown = f"{name} = {value:.6g}" + (f" {unit}" if unit else "")
        parts["wherever defined" if absent else "throughout"].append(shown)
    return "; ".join(", ".join(items) + f" {when}" for when, items in parts.items() if items).replace("$", r"\$")


def state_panel(ax, data: PlotData, name: str, tol: float) -> None:
    """One coordinate against time on ``ax``, with the strips shaded (``span_patch``, joined
    within ``tol`` s)."""
    t, v = data.series[name]
    ax.plot(t, v, color="k", lw=1.0)
    if data.strips:
        span_patch(ax, data.strips, STRIP_COLOUR, STRIP_GID, tol)
    ax.grid(True, lw=0.3, alpha=0.5)


def mode_band(band, data: PlotData, tol: float) -> list:
    """The mode band on ``band``: each segment's interval in its mode's colour, the strips gray
    over them with a stripe in the colour of the mode they hold the state in, intervals too
    narrow to see marked by a line; over the run's time span with time labelled. Returns the
    legend handles (one per mode, and one for the strips)."""
    from matplotlib.patches import Patch

    modes = list(dict.fromkeys([m for m, _, _ in data.segments] + list(data.strip_modes)))
    colour = {m: MODE_COLOURS[i % len(MODE_COLOURS)] for i, m in enumerate(modes)}
    thin = (data.t_end - data.t0) * THIN_FRACTION
    for m in modes:
        spans = [(a, b) for mm, a, b in data.segments if mm == m]
        held = [span for span, mm in zip(data.strips, data.strip_modes, strict=True) if mm == m]
        if spans:
            span_patch(band, spans, colour[m], f"{MODE_GID}:{m}", tol)
        if held:
            span_patch(band, held, colour[m], f"{MODE_GID}:{m}:held", tol, y=HELD_STRIPE, zorder=2)
        _thin_marks(band, spans + held, colour[m], f"{MODE_GID}:{m}:marks", tol, thin)
    if data.strips:
        span_patch(band, data.strips, STRIP_COLOUR, STRIP_GID, tol, zorder=1)
    band.set_yticks([])
    band.set_xlabel("time (s)")
    band.set_xlim(data.t0, data.t_end)
    handles = [Patch(color=colour[m], label=m) for m in modes]
    if data.strips:
        handles.append(Patch(color=STRIP_COLOUR, label="strip"))
    return handles


def _thin_marks(ax, spans: Sequence[tuple[float, float]], colour: str, gid: str, tol: float, thin: float) -> None:
    """A 1.5 pt line at each interval (joined within ``tol``) narrower than ``thin`` s: a
    span patch of that width would be under a pixel."""
    merged = merge_spans(spans, tol)
    narrow = merged[merged[:, 1] - merged[:, 0] < thin] if len(merged) else merged
    if len(narrow):
        lines = ax.vlines(
            narrow.mean(axis=1), 0.0, 1.0, colors=colour, linewidth=1.5, transform=ax.get_xaxis_transform(), zorder=3
        )
        lines.set_gid(gid)


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


def span_patch(
    ax,
    spans: Sequence[tuple[float, float]],
    colour: str,
    gid: str,
    tol: float = 0.0,
    *,
    y: tuple[float, float] = (0.0, 1.0),
    zorder: float = 0,
):
    """Shade the time intervals ``spans`` over the height ``y`` (axes fraction; default the
    full height) of ``ax`` with one patch.

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
    verts[:, [0, 1, 4], 1] = y[0]
    verts[:, [2, 3], 1] = y[1]
    codes = np.tile([MPath.MOVETO, MPath.LINETO, MPath.LINETO, MPath.LINETO, MPath.CLOSEPOLY], len(a))
    patch = PathPatch(
        MPath(verts.reshape(-1, 2), codes),
        facecolor=colour,
        edgecolor="none",
        linewidth=0,
        transform=ax.get_xaxis_transform(),
        zorder=zorder,
        antialiased=False,
    )  # adjacent intervals would show anti-aliasing seams
    patch.set_gid(gid)
    ax.add_artist(patch)
    return patch


def span_bounds(patch) -> np.ndarray:
    """The (start, end) intervals (S, 2) drawn by ``span_patch``."""
    v = patch.get_path().vertices.reshape(-1, 5, 2)
    return np.stack([v[:, 0, 0], v[:, 1, 0]], axis=1)


def _short_sequence(seq: list[str], keep: int = 4) -> str:
    """Runs of one mode written once with a count (a bouncing ball is ``flight ×13``); long
    sequences keep their ends."""  # noqa: RUF002 (the multiplication sign the band shows)
    runs = [(mode, len(list(repeats))) for mode, repeats in groupby(seq)]
    # The multiplication sign, not the letter x: the band's labels are typeset.
    words = [m if k == 1 else f"{m} ×{k}" for m, k in runs]  # noqa: RUF001
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


# ``legsim run`` checks a --plot path against these suffixes before the run.
@writer_attributes(suffixes=tuple("." + f for f in FORMATS))
def write_plot(
    execution: Execution | None,
    scene: Any = None,
    path: str | os.PathLike | None = None,
    *,
    model: Model | HybridSystem | None = None,
    recording: dict[str, Any] | None = None,
    coordinates: Sequence[str] | None = None,
) -> Path:
    """Write the state-against-time figure of a run (the ``--plot`` output) to ``path``.

    ``scene`` is a ``legsim.scene.Scene`` or None (then ``model=`` may name the model, a
    ``legsim.builders.Model`` or a ``HybridSystem``, which a plot does not need);
    ``recording=`` takes ``legsim.record.read_rrd`` output instead of an execution. The format
    follows the suffix (.png, .pdf, .svg, .jpg). Atomic write.
    """
    if path is None:
        raise OutputError("write_plot needs a path to write to")
    fig = state_figure(plot_data(execution, scene, model=model, recording=recording), coordinates)
    return save_figure(fig, path)
