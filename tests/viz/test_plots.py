"""State plots (paper 003 Fig. 2 style): the gray bars are the execution's strips, the mode
band is its mode sequence, the lines are its samples; written atomically."""

from __future__ import annotations

import re

import numpy as np
import pytest
from legsim.viz.plots import MODE_GID, STRIP_GID, plot_data, span_bounds, state_figure, write_plot

from helpers.models import ball_model, hopper_model
from legsim.errors import OutputError
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import execution_trace, trace_series
from legsim.relaxed import simulate


@pytest.fixture(scope="module")
def hopper():
    model = hopper_model()
    ex = simulate(model.system, np.array([0.5, 0.0]), "flight", 1.5, 1e-3, 2e-2)
    assert len(ex.strips) >= 4
    return model, ex


def _spans(patch) -> list[tuple[float, float]]:
    return sorted(map(tuple, span_bounds(patch).tolist()))


def _collections(ax, gid):
    return [a for a in ax.get_children() if a.get_gid() == gid]


def test_strip_bars_match_the_strip_intervals_in_every_panel(hopper):
    model, ex = hopper
    fig = state_figure(plot_data(ex, model=model))
    *panels, band = fig.axes[: len(ex.state_names["stance"]) + 1]
    assert [ax.get_ylabel() for ax in panels] == ["z (no unit)", "zd (no unit)", "n (no unit)"]
    want = sorted(ex.strip_intervals())
    for ax in [*panels, band]:
        (coll,) = _collections(ax, STRIP_GID)
        got = _spans(coll)
        assert len(got) == len(want)
        np.testing.assert_allclose(np.array(got), np.array(want), rtol=0, atol=1e-12)
        # The bars span the panel's full height (axes coordinates 0..1), at the strip times.
        ys = coll.get_path().vertices[:, 1]
        assert ys.min() == 0 and ys.max() == 1 and coll.get_transform() == ax.get_xaxis_transform()


def test_mode_band_shows_the_mode_sequence(hopper):
    model, ex = hopper
    fig = state_figure(plot_data(ex, model=model))
    band = fig.axes[3]
    for mode in ("flight", "stance"):
        (coll,) = _collections(band, f"{MODE_GID}:{mode}")
        want = sorted((s.t_start, s.t_end) for s in ex.segments if s.mode == mode)
        np.testing.assert_allclose(np.array(_spans(coll)), np.array(want), rtol=0, atol=1e-12)
    assert band.get_xlim() == (ex.t0, ex.t_end)


def test_lines_are_the_recorded_samples_with_breaks(hopper):
    model, ex = hopper
    fig = state_figure(plot_data(ex, model=model))
    series = trace_series(ex)
    times = execution_trace(ex).times
    for ax, name in zip(fig.axes, ["z", "zd", "n"], strict=False):
        (line,) = ax.get_lines()
        x, y = line.get_xdata(), line.get_ydata()
        rows, vals = series[name]
        np.testing.assert_array_equal(x[~np.isnan(x)], times[rows])
        np.testing.assert_array_equal(y[~np.isnan(y)], vals)
    # n exists only in stance: its line breaks (NaN) once between consecutive stance phases.
    (line,) = fig.axes[2].get_lines()
    stances = sum(1 for s in ex.segments if s.mode == "stance")
    assert int(np.isnan(line.get_ydata()).sum()) == stances - 1


def test_plot_from_a_recording_equals_the_plot_from_the_execution(hopper, tmp_path):
    model, ex = hopper
    data = read_rrd(write_rrd(ex, None, tmp_path / "h.rrd", model=model))
    a = state_figure(plot_data(ex, model=model))
    b = state_figure(plot_data(recording=data))
    for ax_a, ax_b in zip(a.axes[:3], b.axes[:3], strict=False):
        assert _spans(_collections(ax_a, STRIP_GID)[0]) == _spans(_collections(ax_b, STRIP_GID)[0])
        np.testing.assert_array_equal(ax_a.get_lines()[0].get_ydata(), ax_b.get_lines()[0].get_ydata())


def test_write_plot_writes_a_png_of_the_figure_size(hopper, tmp_path):
    from matplotlib.image import imread

    model, ex = hopper
    path = write_plot(ex, None, tmp_path / "sub" / "h.png", model=model)
    img = imread(path)
    fig = state_figure(plot_data(ex, model=model))
    w, h = fig.get_size_inches() * 120
    assert img.shape[:2] == (round(h), round(w))
    # Gray strip bars are in the picture: pixels of the strip colour (0.78 gray) exist.
    gray = np.all(np.abs(img[..., :3] - 0.78) < 0.01, axis=-1)
    assert gray.sum() > 100
    assert sorted(p.name for p in path.parent.iterdir()) == ["h.png"]


def test_write_plot_without_geometry_works(tmp_path):
    model = ball_model()
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 1.0, 1e-3, 1e-3)
    assert write_plot(ex, None, tmp_path / "b.pdf", model=model).read_bytes().startswith(b"%PDF")


def test_bad_suffix_is_rejected_and_writes_nothing(hopper, tmp_path):
    model, ex = hopper
    with pytest.raises(OutputError, match=r"h\.txt: unsupported figure format '\.txt'"):
        write_plot(ex, None, tmp_path / "h.txt", model=model)
    assert list(tmp_path.iterdir()) == []


def test_unknown_coordinate_is_rejected(hopper, tmp_path):
    model, ex = hopper
    with pytest.raises(OutputError, match=r"unknown coordinate\(s\) \['q'\]; recorded: \['z', 'zd', 'n'\]"):
        write_plot(ex, None, tmp_path / "h.png", model=model, coordinates=["q"])
    assert list(tmp_path.iterdir()) == []


def test_plot_needs_an_execution(tmp_path):
    with pytest.raises(OutputError, match="needs a legsim Execution"):
        write_plot("nope", None, tmp_path / "x.png")


def test_sub_pixel_gaps_between_strips_are_joined():
    # A bouncing ball with c = 0.5 ends in a Zeno cascade in the paper's relaxed execution
    # (continuation=False): strips separated by ever shorter flights. Gaps narrower than the
    # drawing tolerance are shaded through, wider ones not.
    from legsim.viz.plots import SPAN_RESOLUTION

    model = ball_model(c=0.5)
    ex = simulate(
        model.system, np.array([1.0, 0.0]), "flight", 3.0, 1e-3, 1e-3, max_transitions=2000, continuation=False
    )
    fig = state_figure(plot_data(ex, model=model))
    (patch,) = _collections(fig.axes[0], STRIP_GID)
    shaded = span_bounds(patch)
    strips = np.array(ex.strip_intervals())
    tol = (ex.t_end - ex.t0) / SPAN_RESOLUTION
    gaps = strips[1:, 0] - strips[:-1, 1]
    assert np.sum(gaps <= tol) > 10 and np.sum(gaps > tol) > 3  # both cases occur
    assert len(shaded) == 1 + np.sum(gaps > tol)
    # Every strip lies inside one shaded interval, and every shaded interval starts at a strip
    # entry and ends at a strip exit.
    for a, b in strips:
        assert np.any((shaded[:, 0] <= a) & (b <= shaded[:, 1]))
    assert set(shaded[:, 0]) <= set(strips[:, 0]) and set(shaded[:, 1]) <= set(strips[:, 1])
    assert np.all(shaded[1:, 0] - shaded[:-1, 1] > tol)


@pytest.fixture(scope="module")
def diverged():
    """Explicit Euler at h = 0.5 on the undamped oscillator: status non_finite at t = 750.5 s
    with |x| ~ 1e308, beyond what matplotlib's tick arithmetic survives."""
    from legsim.scene import load_scene

    scene = load_scene(
        "oscillator_ex1",
        overrides=[
            "effects.stop=false",
            "effects.damping=false",
            'integrator.method="euler"',
            "integrator.h=0.5",
            "integrator.t_final=5000",
        ],
    )
    # The run's own overflow on the way to non_finite is not what is tested here.
    with np.errstate(over="ignore", invalid="ignore"):
        ex = scene.simulate()
    assert ex.status == "non_finite"
    return scene, ex


def test_diverged_run_is_plotted_up_to_the_divergence(diverged, tmp_path):
    import warnings

    from legsim.viz._common import PLOT_LIMIT
    from matplotlib.image import imread

    scene, ex = diverged
    data = plot_data(ex, scene)
    assert data.omitted_from is not None and 0 < data.omitted_from < ex.t_end
    for t, v in data.series.values():
        drawn = v[~np.isnan(v)]
        assert len(drawn) > 100 and np.all(np.abs(drawn) <= PLOT_LIMIT)
        # Everything before the divergence is drawn.
        assert not np.isnan(v[t < data.omitted_from]).any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy or matplotlib warning on the way
        fig = state_figure(data)
        path = write_plot(ex, scene, tmp_path / "div.png")
    assert "values past t = " in fig.axes[0].get_title() and "omitted" in fig.axes[0].get_title()
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["div.png"]


def test_diverged_recording_is_plotted_too(diverged, tmp_path):
    import warnings

    scene, ex = diverged
    # Rerun stores some fields as float32, where the last states overflow to inf.
    with np.errstate(over="ignore", invalid="ignore"):
        data = read_rrd(write_rrd(ex, scene, tmp_path / "div.rrd"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = write_plot(None, None, tmp_path / "div.png", recording=data)
    assert path.stat().st_size > 1000
    assert plot_data(recording=data).omitted_from is not None


# -- units on every axis, constant coordinates, modes that live in strips ----------------------
#: An axis label that ends with its unit in parentheses: "x (m)", "time (s)", "n (no unit)".
UNIT_LABEL = re.compile(r"\(([^()]+)\)$")


def labels_of_numbered_axes(fig) -> list[str]:
    """The label of every axis that shows numbers (a visible tick label with text)."""
    fig.canvas.draw()
    labels = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for axis, label in ((ax.xaxis, ax.get_xlabel()), (ax.yaxis, ax.get_ylabel())):
            if any(t.get_visible() and t.get_text() for t in axis.get_ticklabels()):
                labels.append(label)
    return labels


def assert_units_everywhere(fig, known: bool = True) -> None:
    labels = labels_of_numbered_axes(fig)
    assert labels, "no axis shows numbers"
    missing = [label for label in labels if not UNIT_LABEL.search(label)]
    assert not missing, f"axes without a unit: {missing}"
    if known:
        assert not [label for label in labels if label.endswith("(unit unknown)")], labels


@pytest.fixture(scope="module")
def pronk():
    from legsim.scene import load_scene

    scene = load_scene("pronk")
    ex = scene.simulate()
    assert ex.status == "finished"
    return scene, ex


def test_every_axis_of_a_run_plot_has_the_models_unit(pronk):
    scene, ex = pronk
    fig = state_figure(plot_data(ex, scene))
    assert_units_everywhere(fig)
    labels = {ax.get_ylabel() for ax in fig.axes}
    assert {"x (m)", "z (m)", "xd (m/s)", "zd (m/s)", "left_foot_x (m)"} <= labels
    assert fig.axes[-1].get_xlabel() == "time (s)"


def test_a_replayed_plot_has_the_recorded_units_or_says_they_are_unknown(pronk, tmp_path):
    scene, ex = pronk
    data = read_rrd(write_rrd(ex, scene, tmp_path / "p.rrd"))
    with_units = {**data, "meta": {**data["meta"], "state_units": {m: list(u) for m, u in ex.state_units.items()}}}
    fig = state_figure(plot_data(recording=with_units))
    assert_units_everywhere(fig)
    assert "theta" not in str([ax.get_ylabel() for ax in fig.axes])  # constant: collapsed here too
    # A recording without units says so on its axes rather than leaving them bare.
    data.pop("units", None)
    data["meta"].pop("state_units", None)
    fig = state_figure(plot_data(recording=data))
    assert_units_everywhere(fig, known=False)
    assert "x (unit unknown)" in {ax.get_ylabel() for ax in fig.axes}


def test_figure_script_panels_take_the_models_units(pronk):
    from legsim.viz._figures import new_figure, state_panels

    _scene, ex = pronk
    fig = new_figure(6.0, 6.0)
    axes = state_panels(fig, fig.add_gridspec(1, 1)[0], ex, ["x", "theta"], "pronk")
    assert [ax.get_ylabel() for ax in axes[:2]] == ["x (m)", "theta (rad)"]
    assert_units_everywhere(fig)


def test_every_axis_of_the_sweep_maps_and_histograms_has_a_unit():
    import pyarrow as pa
    from legsim.viz.maps import basin_figure, stability_figure, switching_figure

    rows = [
        {
            "initial.state.stanced": a,
            "initial.state.hipd": b,
            "robot.parameters.slope": a,
            "robot.parameters.mH": b,
            "task_status": "done",
            "outcome": "converges",
            "steps_to_gait": 3,
            "orbit_status": "converged",
            "orbit_spectral_radius": 0.5 + a / 4 + b / 8,
            "orbit_multipliers_re": [0.5],
            "orbit_multipliers_im": [0.0],
        }
        for a in (0.5, 1.0, 1.5)
        for b in (-1.0, 0.0)
    ]
    table = pa.Table.from_pylist(rows)
    basin = basin_figure(table, {"x": "initial.state.stanced", "y": "initial.state.hipd", "scene": "compass_gait"})
    assert basin.axes[0].get_xlabel() == "stanced (rad/s)" and basin.axes[0].get_ylabel() == "hipd (rad/s)"
    stability = stability_figure(
        table, {"x": "robot.parameters.slope", "y": "robot.parameters.mH", "scene": "compass_gait"}
    )
    assert stability.axes[0].get_xlabel() == "robot.parameters.slope (deg)"
    histograms = switching_figure([[1.0, 1.1, 1.2]], {"deterministic": [1.1], "samples": 3, "scene": "toy"})
    for fig in (basin, stability, histograms):
        assert_units_everywhere(fig)


def test_a_constant_coordinate_is_a_note_not_a_series(pronk):
    scene, ex = pronk
    data = plot_data(ex, scene)
    theta = data.series["theta"][1]
    # What the issue saw: rounding noise, not exactly zero (else this test would prove nothing).
    assert 0 < np.nanmax(np.abs(theta)) < 1e-12
    fig = state_figure(data)
    drawn = [line.get_ydata() for ax in fig.axes for line in ax.get_lines()]
    assert not any(len(y) == len(theta) and np.array_equal(y, theta, equal_nan=True) for y in drawn)
    assert not any(ax.get_ylabel().startswith(("theta", "thetad")) for ax in fig.axes)
    assert "theta = 0 rad, thetad = 0 rad/s throughout" in fig.axes[0].get_title()
    # Asked for by name, it is drawn.
    asked = state_figure(data, ["x", "theta"])
    assert [ax.get_ylabel() for ax in asked.axes[:2]] == ["x (m)", "theta (rad)"]
    assert "theta = 0" not in asked.axes[0].get_title()


def test_small_real_motion_is_not_taken_for_a_constant():
    from legsim.viz._common import PlotData
    from legsim.viz.plots import constant_coordinates

    t = np.linspace(0.0, 10.0, 101)
    series = {
        "x": (t, 1e4 * t / 10),
        "z": (t, 1.0 + 0.1 * np.sin(t)),
        "zd": (t, 0.1 * np.cos(t)),
        "pitch": (t, 1e-6 * np.sin(t)),  # real, small: 1e-6 rad
        "noise": (t, 1e-16 * np.cos(7 * t)),  # rounding noise around 0
        "offset": (t, 2.5 + 1e-15 * np.sin(3 * t)),  # a constant plus noise
        "exact": (t, np.full_like(t, -0.75)),
    }
    data = PlotData(series, [], [("m", 0.0, 10.0)], "t", 0.0, 10.0)
    found = constant_coordinates(data)
    assert set(found) == {"noise", "offset", "exact"}
    assert found["noise"] == 0.0 and found["exact"] == -0.75 and abs(found["offset"] - 2.5) < 1e-14


def test_a_mode_that_only_lives_inside_strips_is_on_the_band(pronk):
    from matplotlib.colors import to_rgb

    scene, ex = pronk
    # The pronk's one-leg mode "left": every visit has zero length (both feet land within one
    # strip), so the segments alone never show it.
    assert all(s.t_end == s.t_start for s in ex.segments if s.mode == "left")
    fig = state_figure(plot_data(ex, scene))
    band = fig.axes[-1]
    (held,) = _collections(band, f"{MODE_GID}:left:held")
    want = sorted((s.time, s.exit_time) for s in ex.strips if s.mode == "left")
    np.testing.assert_allclose(np.array(_spans(held)), np.array(want), rtol=0, atol=1e-12)
    legend = {
        text.get_text(): handle
        for text, handle in zip(band.get_legend().get_texts(), band.get_legend().legend_handles, strict=False)
    }
    colour = to_rgb(legend["left"].get_facecolor())
    # And it is there in the picture: pixels of left's colour inside the band.
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    x0, y0, x1, y1 = band.get_window_extent().extents
    h = img.shape[0]
    crop = img[int(h - y1) + 1 : int(h - y0) - 1, int(x0) + 1 : int(x1) - 1]
    assert np.all(np.abs(crop - colour) < 0.02, axis=-1).sum() >= 4 * len(want)
