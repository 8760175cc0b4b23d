"""``--measure KIND:COORD[:FROM]`` columns and ``--orbit-guess run`` (``legsim.sweep.measures``,
``legsim.sweep.tasks``): a cell's achieved speed is the mean speed of its own run computed here
from the run's stored points; a measure past the end of a run that fell is null; a guess from
the run finds the scene's own orbit; bad measures are refused before anything runs."""

from __future__ import annotations

import numpy as np
import pytest

import legsim
from legsim.scene import load_scene
from legsim.sweep.measures import parse_measure
from legsim.sweep.spec import Axis, SweepError, SweepSpec

SHORT_PRONK = ["integrator.t_final=3"]


def stored(execution, column: int) -> tuple[np.ndarray, np.ndarray]:
    """The run's stored times (s) and one state column, over all its segments."""
    return (
        np.concatenate([seg.t for seg in execution.segments]),
        np.concatenate([seg.x[:, column] for seg in execution.segments]),
    )


def test_a_cells_achieved_speed_is_the_mean_speed_of_its_run(tmp_path):
    """The forward pronk commanded 0.5 m/s for 3 s: the cell's ``mean_rate_x`` over [1 s, 3 s]
    is (x(3) - x(1)) / 2 s of the same scene run here (x(1) interpolated between the stored
    points), and ``max_abs_pitch`` the largest |pitch| stored in that window, both to 1e-12
    (the runs are deterministic: only the arithmetic's order may differ)."""
    result = legsim.sweep(
        "quadruped_pronk_forward",
        grid={"controller.parameters.speed": [0.5]},
        overrides=SHORT_PRONK,
        measures=["mean_rate:x:1", "max_abs:pitch:1"],
        out=tmp_path / "sweep",
        in_process=True,
    )
    row = result.table.to_pylist()[0]
    assert row["status"] == "finished" and row["task_status"] == "done"
    ex = load_scene("quadruped_pronk_forward", [*SHORT_PRONK, "controller.parameters.speed=0.5"]).simulate()
    t, x = stored(ex, 0)
    _, pitch = stored(ex, 2)
    start = int(np.searchsorted(t, 1.0))
    x1 = x[start - 1] + (x[start] - x[start - 1]) * (1.0 - t[start - 1]) / (t[start] - t[start - 1])
    assert row["mean_rate_x"] == pytest.approx((x[-1] - x1) / (t[-1] - 1.0), rel=0, abs=1e-12)
    assert row["max_abs_pitch"] == pytest.approx(np.max(np.abs(pitch[start - 1 :])), rel=0, abs=1e-12)
    # From rest the pronk is still speeding up over [1, 3] s (measured 0.4896 m/s).
    assert 0.4 < row["mean_rate_x"] < 0.5


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("speed:x", "unknown kind 'speed'; allowed: ['max_abs', 'mean_rate']"),
        ("mean_rate", "expected KIND:COORD[:FROM]"),
        ("mean_rate:x:soon", "FROM must be a finite time (s), got 'soon'"),
        ("mean_rate:x:inf", "FROM must be a finite time"),
        ("mean_rate:x y", "'x y' is no coordinate name"),
    ],
)
def test_a_malformed_measure_is_refused_naming_it(text, says):
    with pytest.raises(SweepError, match="--measure") as info:
        parse_measure(text)
    assert says in str(info.value)


def test_measures_are_checked_against_the_sweep_before_anything_runs(tmp_path):
    grid = (Axis("initial.state.z", (1.0, 2.0)),)
    with pytest.raises(SweepError, match=r"column\(s\) \['mean_rate_x'\] asked for twice"):
        SweepSpec(scene="bouncing_ball", grid=grid, measures=("mean_rate:x", "mean_rate:x:2"))
    with pytest.raises(SweepError, match="--measure needs runs to t_final"):
        SweepSpec(scene="compass_gait", grid=grid, run="walk", measures=("mean_rate:x",))
    with pytest.raises(SweepError, match="--orbit-guess run needs --orbit"):
        SweepSpec(scene="compass_gait", grid=grid, orbit_guess="run")
    with pytest.raises(SweepError, match=r"mode\(s\) \['flight', 'rest'\] have no coordinate 'x'.*\['z', 'zd'\]"):
        legsim.sweep("bouncing_ball", grid={"initial.state.z": [1.0]}, measures=["mean_rate:x"], in_process=True)
    assert not (tmp_path / "anything").exists()


@pytest.mark.parametrize(("start", "grid"), [(3.5, [0.5]), (-1.0, [0.5]), (2.5, [0.5, 1.0])])
def test_a_measure_window_outside_every_variations_run_is_refused(tmp_path, start, grid):
    """FROM past t_final (or before t0) would give every row a null column, or a value the run
    never had: refused before anything runs, naming the measure, the window and the scene. The
    third case varies t_final itself (2 and 3 s): the corner at 2 s has no window at 2.5 s."""
    axis = "controller.parameters.speed" if len(grid) == 1 else "integrator.t_final"
    values = grid if len(grid) == 1 else [2.0, 3.0]
    with pytest.raises(SweepError, match=rf"--measure mean_rate:x:{start:g}: FROM must lie in \[t0, t_final\)") as info:
        legsim.sweep(
            "quadruped_pronk_forward",
            grid={axis: values},
            overrides=SHORT_PRONK,
            measures=[f"mean_rate:x:{start:g}"],
            out=tmp_path / "sweep",
            in_process=True,
        )
    assert "quadruped_pronk_forward.toml" in str(info.value)
    assert not (tmp_path / "sweep").exists()


def test_a_sweep_without_the_new_options_keeps_its_manifest():
    """``measures`` and ``orbit_guess`` enter the manifest (and the digest ``--resume`` checks)
    only when asked for, so a sweep folder written before they existed resumes."""
    spec = SweepSpec(scene="bouncing_ball", grid=(Axis("initial.state.z", (1.0, 2.0)),))
    assert "measures" not in spec.to_json() and "orbit_guess" not in spec.to_json()
    assert SweepSpec.from_json(spec.to_json()) == spec
    asked = SweepSpec(scene="compass_gait", orbit=True, orbit_guess="run", measures=("max_abs:stance",))
    assert SweepSpec.from_json(asked.to_json()) == asked


def test_an_orbit_guess_from_the_run_finds_the_scenes_orbit(tmp_path):
    """The compass gait walks onto its stable gait in 5 s: the search from its run's last heel
    strike converges to the fixed point the search from the scene's guess finds (to 1e-9: both
    within tol 1e-10 of the same orbit, whose multipliers are at most 0.58), but for the cyclic
    foot position, which keeps its guess: where the run's last step put the foot."""
    rows = {}
    for guess in ("scene", "run"):
        result = legsim.sweep(
            "compass_gait",
            grid={"robot.parameters.mH": [10.0]},
            orbit=True,
            orbit_guess=guess,
            out=tmp_path / guess,
            in_process=True,
        )
        rows[guess] = result.table.to_pylist()[0]
    assert rows["scene"]["orbit_status"] == rows["run"]["orbit_status"] == "converged"
    run, scene = rows["run"]["orbit_fixed_point"], rows["scene"]["orbit_fixed_point"]
    assert np.allclose(run[:4], scene[:4], rtol=0, atol=1e-9)  # stance, hip and their rates
    assert scene[4] == 0.0 and run[4] > 2.0  # foot_x (m): the scene's guess; the run's last foothold
    assert rows["run"]["orbit_stable"] is True


def test_a_runs_memory_enters_the_search_in_the_returns_frames():
    """A runner's memory at a crossing late in its run holds epochs and places on the run's clock
    and track; the search from there sees them as a return does (``ReturnMap``'s frames): an
    epoch less the crossing's time; a place along the cyclic x as it is (the search starts at
    the run's x, and a return measures places from its start's); a value without a frame, and an
    epoch before the run's start (the law's "no liftoff yet" marker), as they are."""
    from legsim.orbits.returns import memory_at_crossing
    from legsim.scene.orbit import problem_from_scene

    problem = problem_from_scene(load_scene("quadruped_run")).problem
    names = list(problem.memory_names)
    memory = problem.memory_guess.copy()
    values = {"touchdown_hind": 7.5, "touchdown_x_hind": 3.0, "liftoff_hind": -1e9, "T_s_hind": 0.12, "apex_hind": 7.9}
    for name, value in values.items():
        memory[names.index(name)] = value
    seen = dict(zip(names, memory_at_crossing(problem, 7.8, memory, 0.0), strict=True))
    assert seen["touchdown_hind"] == pytest.approx(-0.3) and seen["apex_hind"] == pytest.approx(0.1)
    # the search starts at the run's x, the frame of the returns' places
    assert seen["touchdown_x_hind"] == 3.0
    assert seen["liftoff_hind"] == -1e9 and seen["T_s_hind"] == 0.12
