"""Sweep specifications: the axes as the command line writes them, the order of the
variations, exact values through the scene's overrides, and the checks of bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from legsim.scene import load_scene
from legsim.sweep.spec import (
    Axis,
    SweepError,
    SweepSpec,
    corners,
    override,
    parse_grid,
    parse_random,
    scene_reference,
    variation_overrides,
)


def test_a_range_grid_is_evenly_spaced_with_both_ends_and_a_list_keeps_its_values():
    axis = parse_grid("initial.state.thetad=-2.0:2:5")
    assert axis.key == "initial.state.thetad"
    assert axis.values == (-2.0, -1.0, 0.0, 1.0, 2.0)
    assert all(isinstance(v, float) for v in axis.values)
    assert parse_grid("a.b=0:1:4").values == (0.0, 1 / 3, 2 / 3, 1.0)
    # Integer ends with integral steps stay integers (an int-valued parameter such as spokes).
    assert parse_grid("robot.parameters.spokes=6:12:4").values == (6, 8, 10, 12)
    assert parse_grid("robot.parameters.spokes=6:12:3").values == (6, 9, 12)
    assert parse_grid("integrator.method=rk4,heun, euler").values == ("rk4", "heun", "euler")
    assert parse_grid("robot.parameters.slope=3.5").values == (3.5,)


@pytest.mark.parametrize(
    "text, message",
    [
        ("thetad", "expected KEY=LO:HI:N"),
        ("=1:2:3", "dotted path"),
        ("a..b=1:2:3", "dotted path"),
        ("a.b=1:2", "expected KEY=LO:HI:N"),
        ("a.b=1:2:0", "N must be an integer >= 1"),
        ("a.b=1:2:2.5", "N must be an integer >= 1"),
        ("a.b=x:2:3", "'x' is not a finite number"),
        ("a.b=1:nan:3", "is not a finite number"),
    ],
)
def test_bad_grids_are_refused_with_the_option_named(text, message):
    with pytest.raises(SweepError, match="--grid") as err:
        parse_grid(text)
    assert message in str(err.value)


def test_random_axes_draw_uniformly_in_their_interval_reproducibly():
    spec = SweepSpec(scene="compass_gait", random=(parse_random("robot.parameters.slope=2:5"),), samples=2000, seed=3)
    draws = np.array([spec.values(i)["robot.parameters.slope"] for i in range(len(spec))])
    assert len(spec) == 2000 and draws.min() >= 2.0 and draws.max() < 5.0
    # Uniform on [2, 5): mean 3.5, std 3 / sqrt(12); the sample mean within 4 standard errors.
    assert abs(draws.mean() - 3.5) < 4 * (3 / np.sqrt(12)) / np.sqrt(2000)
    again = SweepSpec(scene="compass_gait", random=(parse_random("robot.parameters.slope=2:5"),), samples=2000, seed=3)
    assert np.array_equal(draws, [again.values(i)["robot.parameters.slope"] for i in range(2000)])
    with pytest.raises(SweepError, match="HI must be > LO"):
        parse_random("a.b=5:2")


def test_variations_are_the_product_of_the_grids_first_axis_slowest_then_the_draws():
    a, b = parse_grid("x.a=0:1:3"), parse_grid("x.b=10,20")
    r = parse_random("x.r=0:1")
    spec = SweepSpec(scene="compass_gait", grid=(a, b), random=(r,), samples=4, seed=1)
    assert len(spec) == 3 * 2 * 4
    expected = [(va, vb) for va, vb in itertools.product(a.values, b.values) for _ in range(4)]
    got = [(spec.values(i)["x.a"], spec.values(i)["x.b"]) for i in range(len(spec))]
    assert got == expected
    # Every grid cell runs with the same draws (common random numbers).
    assert [spec.values(i)["x.r"] for i in range(4)] == [spec.values(8 + i)["x.r"] for i in range(4)]


def test_overrides_carry_the_values_bit_for_bit_into_the_scene():
    value = 1.0 / 3.0 + 1e-17 * np.pi
    scene = load_scene(
        "compass_gait",
        variation_overrides({"initial.state.stanced": value, "robot.parameters.slope": 3.0000000000000004}),
    )
    assert scene.initial_state[2] == value
    assert scene.parameters["slope"] == 3.0000000000000004
    assert override("a.b", True) == "a.b=true" and override("a.b", "rk4") == 'a.b="rk4"'
    assert override("a.b", 7) == "a.b=7"


def test_the_fingerprint_follows_every_field_and_survives_the_manifest():
    spec = SweepSpec(scene="compass_gait", grid=(parse_grid("initial.state.hipd=-1:0:3"),), run="walk")
    assert SweepSpec.from_json(spec.to_json()).fingerprint() == spec.fingerprint()
    assert (
        SweepSpec(scene="compass_gait", grid=(parse_grid("initial.state.hipd=-1:0:4"),), run="walk").fingerprint()
        != spec.fingerprint()
    )
    assert SweepSpec(scene="compass_gait", grid=spec.grid, run="walk", tol=1e-4).fingerprint() != spec.fingerprint()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"run": "none"}, "nothing to measure"),
        ({"run": "fly"}, "run must be one of"),
        ({"grid": (Axis("a.b", (1, 2)), Axis("a.b", (3,)))}, "varied twice"),
        ({"max_steps": 0}, "--max-steps"),
        ({"tol": -1.0}, "--tol"),
        ({"timeout": 0}, "--timeout"),
        ({"timeout": float("inf")}, "--timeout must be a finite number"),  # the summary is strict JSON
        ({"seed": -1}, "--seed"),
    ],
)
def test_inconsistent_sweeps_are_refused(kwargs, message):
    with pytest.raises(SweepError, match=message):
        SweepSpec(scene="compass_gait", **kwargs)


def test_corners_reach_both_ends_of_every_axis():
    spec = SweepSpec(
        scene="x",
        grid=(parse_grid("a.x=0:1:5"), parse_grid("a.y=3,4,5")),
        random=(parse_random("a.r=-1:1"),),
        samples=3,
    )
    seen = list(corners(spec))
    for key, ends in (("a.x", {0.0, 1.0}), ("a.y", {3, 5})):
        assert {c[key] for c in seen} == ends
    assert min(c["a.r"] for c in seen) == -1.0 and 0.99 < max(c["a.r"] for c in seen) < 1.0


def test_bundled_scenes_travel_by_name_and_files_by_absolute_path(tmp_path, monkeypatch):
    assert scene_reference("compass_gait") == "compass_gait"
    own = tmp_path / "mine.toml"
    own.write_text((load_scene("compass_gait").path).read_text())
    monkeypatch.chdir(tmp_path)
    assert scene_reference("mine.toml") == str(own.resolve())


def test_a_numpy_float_in_a_grid_reaches_the_scene_as_its_number():
    """A grid listing numpy floats (a float subclass, as ``np.linspace`` gives) is set as the
    number: ``repr`` would give ``np.float64(0.5)``, which the scene refuses."""
    import numpy as np

    from legsim.sweep.spec import override

    assert override("terrain.rise", np.float64(-0.1)) == "terrain.rise=-0.1"
    assert override("terrain.rise", 0.1 + 0.2) == "terrain.rise=0.30000000000000004"
