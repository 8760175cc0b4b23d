"""Maps of sweeps (``legsim sweep``) and the switching-time histograms of ``legsim stochastic``.

* ``basin_figure``: the basin of attraction of a gait, a grid of walks from initial states
  coloured by outcome (converges to the gait, falls, stops, another gait, ...), the gait's
  fixed point marked, and beside it the steps each converging walk took.
* ``stability_figure``: a grid over two parameters of orbit searches, coloured by the spectral
  radius of the Floquet multipliers, with the stability boundary (radius 1) and the
  period-doubling boundary (a real multiplier through -1).
* ``switching_figure``: histograms of the first switching times of a stochastic ensemble, the
  deterministic (relaxed) execution's times marked.

The ``write_*`` functions are the ``legsim.writers`` entry points the commands call as
``writer(data, info, path)``; they save to ``path`` itself (the caller writes it atomically).
Figures are built on matplotlib's Agg canvas (no pyplot).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ._common import axis_label, writer_attributes
from ._figures import new_figure

#: Outcome -> colour of the basin map, in legend order (``legsim.sweep.walk.OUTCOMES``, then
#: rows without a result).
OUTCOME_COLOURS = {
    "converges": "#2ca02c",
    "other_gait": "#1f77b4",
    "falls": "#d62728",
    "stops": "#ff7f0e",
    "undecided": "#bcbd22",
    "failed": "#7f7f7f",
    "no result": "#000000",
}
FORMATS = ("png", "pdf", "svg")
#: The suffixes the map writers write: a command checks its output path against them before it runs.
SUFFIXES = tuple("." + f for f in FORMATS)


def grid_of(table: Any, x: str, y: str, column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x values (nx,), y values (ny,), column values (ny, nx)) of a two-field grid sweep
    (object array; None where a cell has no value)."""
    xs_all = table.column(x).to_pylist()
    ys_all = table.column(y).to_pylist()
    values = table.column(column).to_pylist() if column in table.column_names else [None] * len(xs_all)
    xs, ys = sorted(set(xs_all)), sorted(set(ys_all))
    ix, iy = {v: i for i, v in enumerate(xs)}, {v: i for i, v in enumerate(ys)}
    grid = np.full((len(ys), len(xs)), None, dtype=object)
    for a, b, v in zip(xs_all, ys_all, values, strict=True):
        grid[iy[b], ix[a]] = v
    return np.array(xs, dtype=float), np.array(ys, dtype=float), grid


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around grid values (a single value gets a unit cell)."""
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def _label(key: str) -> str:
    return key.split(".")[-1] if key.startswith("initial.state.") else key


#: Units of the integrator's fields a sweep can vary (eps is in the guard's own units).
INTEGRATOR_UNITS = {"integrator.h": "s", "integrator.t_final": "s", "integrator.t0": "s"}


def field_units(info: Mapping[str, Any]) -> dict[str, str]:
    """Unit of each swept field (``info["x"]``, ``info["y"]``) of the scene ``info["scene"]``:
    ``initial.state.NAME`` from the initial mode's ``Mode.units``, ``robot.parameters.NAME``
    from the builder's ``Param.unit``, the integrator's times in s. A field whose unit is not
    known (or a scene that no longer loads) is left out: its axis says "unit unknown"."""
    from legsim.errors import LegsimError
    from legsim.scene import load_scene

    try:
        scene = load_scene(info["scene"], overrides=list(info.get("overrides") or ()))
    except (LegsimError, KeyError, TypeError):
        return {}
    mode = scene.model.system.mode(scene.initial_mode)
    # Mode fills in names and units (None only before its __post_init__).
    units = dict(zip((f"initial.state.{n}" for n in mode.names or ()), mode.units or (), strict=True))
    units.update({f"robot.parameters.{n}": p.unit for n, p in scene.builder.parameters.items()})
    units.update(INTEGRATOR_UNITS)
    return {key: units[key] for key in (info.get("x"), info.get("y")) if key in units}


def _axis_labels(ax, info: Mapping[str, Any], units: Mapping[str, str]) -> None:
    x, y = info["x"], info["y"]
    ax.set(xlabel=axis_label(_label(x), units.get(x)), ylabel=axis_label(_label(y), units.get(y)))


def basin_figure(table: Any, info: Mapping[str, Any]):
    """The basin map (outcome per cell) and the steps to convergence, side by side."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    x, y = info["x"], info["y"]
    xs, ys, outcome = grid_of(table, x, y, "outcome")
    _, _, status = grid_of(table, x, y, "task_status")
    labels = list(OUTCOME_COLOURS)
    codes = np.array(
        [
            [
                labels.index(o) if (o in OUTCOME_COLOURS and s == "done") else labels.index("no result")
                for o, s in zip(orow, srow, strict=True)
            ]
            for orow, srow in zip(outcome, status, strict=True)
        ],
        dtype=float,
    )
    fig = new_figure(12.0, 5.2)
    ax, ax_steps = fig.subplots(1, 2)
    ax.pcolormesh(
        _edges(xs),
        _edges(ys),
        codes,
        cmap=ListedColormap(list(OUTCOME_COLOURS.values())),
        vmin=-0.5,
        vmax=len(labels) - 0.5,
        shading="flat",
        gid="basin",
    )
    counts = {label: int(np.sum(codes == k)) for k, label in enumerate(labels)}
    handles = [
        Patch(color=OUTCOME_COLOURS[label], label=f"{label.replace('_', ' ')} ({n})")
        for label, n in counts.items()
        if n
    ]
    _mark_fixed_point(ax, info, handles)
    ax.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.85)
    units = field_units(info)
    _axis_labels(ax, info, units)
    ax.set_title(f"{info.get('scene', '')}: basin of attraction ({codes.size} initial states)")
    _, _, steps = grid_of(table, x, y, "steps_to_gait")
    steps = np.array([[np.nan if v is None else float(v) for v in row] for row in steps])
    mesh = ax_steps.pcolormesh(_edges(xs), _edges(ys), np.ma.masked_invalid(steps), cmap="viridis", shading="flat")
    fig.colorbar(mesh, ax=ax_steps, label="steps to converge onto the gait (count)")
    _mark_fixed_point(ax_steps, info, [])
    _axis_labels(ax_steps, info, units)
    ax_steps.set_title("steps to the gait (converging walks)")
    return fig


def _mark_fixed_point(ax, info: Mapping[str, Any], handles: list) -> None:
    """A star at the gait's fixed point when both axes are coordinates of it."""
    from matplotlib.lines import Line2D

    fp = info.get("fixed_point") or {}
    names = [_label(info["x"]), _label(info["y"])]
    if not all(k.startswith("initial.state.") for k in (info["x"], info["y"])) or not all(n in fp for n in names):
        return
    ax.plot(
        [fp[names[0]]],
        [fp[names[1]]],
        marker="*",
        markersize=16,
        color="white",
        markeredgecolor="black",
        linestyle="none",
        gid="fixed_point",
    )
    handles.append(
        Line2D(
            [],
            [],
            marker="*",
            markersize=12,
            color="white",
            markeredgecolor="black",
            linestyle="none",
            label="the gait's fixed point",
        )
    )


def stability_figure(table: Any, info: Mapping[str, Any]):
    """Spectral radius over two parameters, the stability and period-doubling boundaries."""
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.lines import Line2D

    x, y = info["x"], info["y"]
    xs, ys, radius = grid_of(table, x, y, "orbit_spectral_radius")
    _, _, status = grid_of(table, x, y, "orbit_status")
    _, _, re = grid_of(table, x, y, "orbit_multipliers_re")
    _, _, im = grid_of(table, x, y, "orbit_multipliers_im")
    rho = np.array(
        [
            [np.nan if (r is None or s != "converged") else float(r) for r, s in zip(rr, sr, strict=True)]
            for rr, sr in zip(radius, status, strict=True)
        ]
    )
    fig = new_figure(7.5, 5.8)
    ax = fig.subplots()
    ax.set_facecolor("0.85")  # cells without an orbit
    top = max(2.0, float(np.nanmax(rho)) if np.isfinite(rho).any() else 2.0)
    mesh = ax.pcolormesh(
        _edges(xs),
        _edges(ys),
        np.ma.masked_invalid(rho),
        cmap="RdYlGn_r",
        shading="flat",
        norm=TwoSlopeNorm(vmin=0.0, vcenter=1.0, vmax=top),
        gid="spectral_radius",
    )
    fig.colorbar(mesh, ax=ax, label="spectral radius of the Floquet multipliers (dimensionless)")
    handles = [Line2D([], [], color="0.85", marker="s", linestyle="none", markersize=10, label="no orbit found")]
    if len(xs) > 1 and len(ys) > 1 and np.isfinite(rho).sum() >= 4:
        ax.contour(xs, ys, np.ma.masked_invalid(rho), levels=[1.0], colors="black", linewidths=2).set_gid(
            "stability_boundary"
        )
        handles.append(Line2D([], [], color="black", lw=2, label="stability boundary (radius 1)"))
        pd = np.array(
            [
                [_most_negative_real(a, b, s) for a, b, s in zip(ra, ia, sr, strict=True)]
                for ra, ia, sr in zip(re, im, status, strict=True)
            ]
        )
        if np.nanmin(pd, initial=np.inf) < -1.0 < np.nanmax(pd, initial=-np.inf):
            ax.contour(
                xs, ys, np.ma.masked_invalid(pd), levels=[-1.0], colors="blue", linewidths=2, linestyles="dashed"
            ).set_gid("period_doubling")
            handles.append(
                Line2D([], [], color="blue", lw=2, ls="--", label="period doubling (a multiplier through -1)")
            )
    ax.legend(handles=handles, loc="best", fontsize=8, framealpha=0.85)
    _axis_labels(ax, info, field_units(info))
    ax.set_title(f"{info.get('scene', '')}: stability of the periodic orbit")
    return fig


def _most_negative_real(re: Sequence[float] | None, im: Sequence[float] | None, status: str | None) -> float:
    """The most negative real multiplier of a converged search (NaN without one)."""
    if status != "converged" or not re or im is None:
        return np.nan
    real = [
        a for a, b in zip(re, im, strict=False) if a is not None and b is not None and abs(b) <= 1e-9 * max(1.0, abs(a))
    ]
    return min(real) if real else np.nan


def switching_figure(times: Sequence[Sequence[float]], info: Mapping[str, Any]):
    """Histograms of the first switching times (one panel per switch), the deterministic times
    (``info["deterministic"]``) as vertical lines."""
    panels = [np.asarray(t, dtype=float) for t in times if len(t)]
    n = max(1, len(panels))
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig = new_figure(4.0 * cols, 3.0 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    reference = list(info.get("deterministic") or [])
    samples = info.get("samples")
    for k, ax in enumerate(axes):
        if k >= len(panels):
            ax.set_visible(False)
            continue
        ax.hist(panels[k], bins=min(50, max(5, int(np.sqrt(len(panels[k]))))), color="#1f77b4", gid=f"switch_{k + 1}")
        if k < len(reference) and reference[k] is not None:
            ax.axvline(reference[k], color="#d62728", lw=1.5, label="deterministic")
            ax.legend(fontsize=8)
        ax.set(
            xlabel="time (s)",
            ylabel="executions (count)",
            title=f"switch #{k + 1}: {len(panels[k])}" + (f" of {samples}" if samples else ""),
        )
    if not panels:
        axes[0].text(0.5, 0.5, "no execution switched", ha="center", va="center", transform=axes[0].transAxes)
    fig.suptitle(f"{info.get('scene', '')}: switching times of the stochastic executions")
    return fig


def _save(fig, path: str | os.PathLike) -> Path:
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    fig.savefig(path, format=fmt if fmt in FORMATS else "png", dpi=110)
    return path


@writer_attributes(suffixes=SUFFIXES)
def write_basin_map(table: Any, info: Mapping[str, Any], path: str | os.PathLike) -> Path:
    """Entry point ``basin_map``: the basin figure of a walk sweep's table."""
    return _save(basin_figure(table, info), path)


@writer_attributes(suffixes=SUFFIXES)
def write_stability_map(table: Any, info: Mapping[str, Any], path: str | os.PathLike) -> Path:
    """Entry point ``stability_map``: the stability figure of an orbit sweep's table."""
    return _save(stability_figure(table, info), path)


@writer_attributes(suffixes=SUFFIXES)
def write_switching_histograms(
    times: Sequence[Sequence[float]], info: Mapping[str, Any], path: str | os.PathLike
) -> Path:
    """Entry point ``switching_histograms``: the histograms of a stochastic ensemble's switching
    times (``times[i]``: the (i+1)-th switching time of every execution that has one)."""
    return _save(switching_figure(times, info), path)
