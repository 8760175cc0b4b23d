"""State plots (paper 003 Fig. 2 style): the gray bars are the execution's strips, the mode
band is its mode sequence, the lines are its samples; written atomically."""

from __future__ import annotations

import numpy as np
import pytest
from helpers.models import ball_model, hopper_model

from legsim.errors import OutputError
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import execution_trace, trace_series
from legsim.relaxed import simulate
from legsim.viz.plots import MODE_GID, STRIP_GID, plot_data, span_bounds, state_figure, write_plot


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
    assert [ax.get_ylabel() for ax in panels] == ["z", "zd", "n"]
    want = sorted(ex.strip_intervals())
    for ax in panels + [band]:
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
    for ax, name in zip(fig.axes, ["z", "zd", "n"]):
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
    for ax_a, ax_b in zip(a.axes[:3], b.axes[:3]):
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
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 3.0, 1e-3, 1e-3, max_transitions=2000,
                  continuation=False)
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

    scene = load_scene("oscillator_ex1", overrides=["effects.stop=false", "effects.damping=false",
                                                    'integrator.method="euler"', "integrator.h=0.5",
                                                    "integrator.t_final=5000"])
    # The run's own overflow on the way to non_finite is not what is tested here.
    with np.errstate(over="ignore", invalid="ignore"):
        ex = scene.simulate()
    assert ex.status == "non_finite"
    return scene, ex


def test_diverged_run_is_plotted_up_to_the_divergence(diverged, tmp_path):
    import warnings

    from matplotlib.image import imread

    from legsim.viz._common import PLOT_LIMIT

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
