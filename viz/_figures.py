"""Helpers of the figure scripts in ``scenarios/fig_*.py``: run a bundled scene, record it, and
draw robot snapshots and state panels on matplotlib axes."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from legsim.errors import OutputError
from legsim.execution import Execution
from legsim.output.rrd import write_rrd

from ._common import axis_label, plot_data_from_execution
from .plots import SPAN_RESOLUTION, mode_band, save_figure, state_panel

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def parse_out(description: str, argv: Sequence[str] | None = None) -> Path:
    """The output folder of a figure script (positional, default ``out``)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("out", nargs="?", default="out", help="output folder (default: out)")
    args = parser.parse_args(argv)
    return Path(args.out)


def run_scene(name: str, out: Path, overrides: Sequence[str] = ()) -> tuple[Any, Execution, Path]:
    """Load and simulate the bundled scene ``name``, record it to ``out/<name>.rrd``."""
    from legsim.scene import load_scene

    scene = load_scene(name, overrides=list(overrides))
    execution = scene.simulate()
    rrd = write_rrd(execution, scene, out / f"{name}.rrd")
    return scene, execution, rrd


def new_figure(width: float, height: float):
    """A matplotlib Figure on an Agg canvas (no pyplot, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def draw_parts(
    ax,
    parts: dict[str, np.ndarray],
    colour,
    *,
    lw: float = 2.0,
    alpha: float = 1.0,
    point_size: float = 30.0,
    zorder: int = 2,
) -> None:
    """Draw a geometry frame (part -> (k, 2) polyline, single points as dots)."""
    for line in parts.values():
        line = np.asarray(line, dtype=float).reshape(-1, 2)
        if len(line) == 1:
            ax.scatter(
                line[:, 0], line[:, 1], s=point_size, color=colour, alpha=alpha, zorder=zorder + 1, edgecolors="none"
            )
        elif len(line):
            ax.plot(line[:, 0], line[:, 1], color=colour, lw=lw, alpha=alpha, zorder=zorder, solid_capstyle="round")


def draw_scenery(ax, scenery: dict[str, np.ndarray]) -> None:
    for line in scenery.values():
        ax.plot(line[:, 0], line[:, 1], color="0.35", lw=1.5, zorder=1)


def snapshot_times(execution: Execution) -> list[tuple[float, str, np.ndarray, str]]:
    """(time, mode, state, label) at the start and at every transition (the guard point q in
    the source mode, at the strip entry)."""
    first = execution.segments[0]
    shots = [(first.t_start, first.mode, first.x[0], f"start ({first.mode})")]
    for tr in execution.transitions:
        shots.append((tr.time, tr.source, tr.state_before, f"{tr.source} → {tr.target}"))
    return shots


def group_shots(
    shots: list[tuple[float, str, np.ndarray, str]], within: float
) -> list[list[tuple[float, str, np.ndarray, str]]]:
    """Snapshots closer than ``within`` seconds to the previous one, grouped (the transitions
    of a simultaneous touchdown follow each other within one strip)."""
    groups: list[list] = []
    for shot in shots:
        if groups and shot[0] - groups[-1][-1][0] < within:
            groups[-1].append(shot)
        else:
            groups.append([shot])
    return groups


def state_panels(
    fig,
    gridspec_column,
    execution: Execution,
    coordinates: Sequence[str],
    title: str,
    units: dict[str, str] | None = None,
) -> list:
    """State against time in a column of ``fig``: one panel per coordinate with the strips
    shaded gray, and a mode band below (paper 003 Fig. 2). Each panel is labelled with the
    coordinate's unit: ``units[name]`` when given, else the model's (``Mode.units``)."""
    data = plot_data_from_execution(execution, title)
    unknown = [c for c in coordinates if c not in data.series]
    if unknown:
        raise OutputError(f"{title}: unknown coordinate(s) {unknown}; recorded: {list(data.series)}")
    sub = gridspec_column.subgridspec(len(coordinates) + 1, 1, height_ratios=[3] * len(coordinates) + [1])
    axes: list[Axes] = []
    tol = (data.t_end - data.t0) / SPAN_RESOLUTION
    for i, name in enumerate(coordinates):
        ax = fig.add_subplot(sub[i], sharex=axes[0] if axes else None)
        state_panel(ax, data, name, tol)
        ax.set_ylabel(axis_label(name, (units or {}).get(name, data.units.get(name))))
        ax.tick_params(labelbottom=False)
        axes.append(ax)
    band = fig.add_subplot(sub[-1], sharex=axes[0])
    handles = mode_band(band, data, tol)
    band.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.8),
        ncol=len(handles),
        fontsize="small",
        frameon=False,
    )
    axes[0].set_title(title, fontsize="medium")
    return [*axes, band]


def finish(fig, path: Path, rrds: Sequence[Path]) -> None:
    """Save the figure atomically and say what was written."""
    save_figure(fig, path, dpi=130)
    print(f"wrote {path}", file=sys.stderr)
    for rrd in rrds:
        print(f"wrote {rrd}", file=sys.stderr)


__all__ = [
    "draw_parts",
    "draw_scenery",
    "finish",
    "group_shots",
    "new_figure",
    "parse_out",
    "run_scene",
    "snapshot_times",
    "state_panels",
]
