"""The sweep maps and the switching-time histograms draw what their tables hold: cells coloured
by outcome where the table puts them, the stability and period-doubling boundaries where a
known field crosses them, and histograms that count every switch."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from legsim.viz.maps import OUTCOME_COLOURS, basin_figure, grid_of, stability_figure, switching_figure, write_basin_map


def by_gid(fig, gid):
    found = [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == gid]
    assert found, gid
    return found[0]


def basin_table():
    xs, ys = [0.0, 1.0, 2.0], [10.0, 20.0]
    rows = []
    outcomes = ["converges", "falls", "stops", "other_gait", "undecided", "failed"]
    for k, (y, x) in enumerate((y, x) for y in ys for x in xs):
        rows.append(
            {
                "index": k,
                "initial.state.a": x,
                "initial.state.b": y,
                "task_status": "done",
                "outcome": outcomes[k],
                "steps_to_gait": 4 if outcomes[k] == "converges" else None,
            }
        )
    rows[-1]["task_status"] = "error"  # no result, whatever its outcome column says
    return pa.Table.from_pylist(rows)


def test_grid_of_places_each_row_at_its_pair_of_values():
    xs, ys, grid = grid_of(basin_table(), "initial.state.a", "initial.state.b", "outcome")
    assert xs.tolist() == [0.0, 1.0, 2.0] and ys.tolist() == [10.0, 20.0]
    assert grid[0].tolist() == ["converges", "falls", "stops"] and grid[1, 0] == "other_gait"


def test_the_basin_map_colours_every_cell_by_its_outcome_and_marks_the_fixed_point(tmp_path):
    info = {"x": "initial.state.a", "y": "initial.state.b", "fixed_point": {"a": 1.0, "b": 20.0}, "scene": "toy"}
    fig = basin_figure(basin_table(), info)
    codes = by_gid(fig, "basin").get_array().reshape(2, 3)
    labels = list(OUTCOME_COLOURS)
    assert [labels[int(c)] for c in codes.ravel()] == [
        "converges",
        "falls",
        "stops",
        "other_gait",
        "undecided",
        "no result",
    ]
    star = by_gid(fig, "fixed_point")
    assert star.get_xdata().tolist() == [1.0] and star.get_ydata().tolist() == [20.0]
    path = write_basin_map(basin_table(), info, tmp_path / "basin.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_stability_map_draws_its_boundaries_where_the_multipliers_cross():
    # A field with a known answer: one real multiplier -(x + y), so the spectral radius is x + y
    # and both boundaries are the line x + y = 1.
    rows = []
    values = np.linspace(0.0, 1.5, 16)
    for k, (y, x) in enumerate((y, x) for y in values for x in values):
        failed = k == 0
        rows.append(
            {
                "index": k,
                "robot.parameters.p": float(x),
                "robot.parameters.q": float(y),
                "orbit_status": "no_return" if failed else "converged",
                "orbit_spectral_radius": None if failed else float(x + y),
                "orbit_multipliers_re": None if failed else [-float(x + y), 0.1],
                "orbit_multipliers_im": None if failed else [0.0, 0.0],
            }
        )
    fig = stability_figure(pa.Table.from_pylist(rows), {"x": "robot.parameters.p", "y": "robot.parameters.q"})
    for gid in ("stability_boundary", "period_doubling"):
        vertices = np.concatenate(by_gid(fig, gid).allsegs[0])
        assert len(vertices) > 5
        assert np.allclose(vertices.sum(axis=1), 1.0, atol=1e-9)
    assert np.ma.is_masked(by_gid(fig, "spectral_radius").get_array()[0])  # the failed search is left out


def test_the_switching_histograms_count_every_switch():
    rng = np.random.default_rng(1)
    times = [rng.normal(2.0, 0.1, 200).tolist(), rng.normal(5.0, 0.2, 150).tolist()]
    fig = switching_figure(times, {"deterministic": [2.0, 5.0], "samples": 200, "scene": "toy"})
    for k, expected in ((1, 200), (2, 150)):
        bars = fig.axes[k - 1].patches  # the histogram's bars
        assert sum(b.get_height() for b in bars) == pytest.approx(expected)
        assert fig.axes[k - 1].get_title() == f"switch #{k}: {expected} of 200"
