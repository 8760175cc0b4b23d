"""The planar quadruped bounding over steps (scene ``quadruped_bound_steps``: ``[terrain] kind =
"steps"`` with an equal ``rise`` per tread, ``[fall] pitch_max``): at a rise of 0 it runs bit for
bit as the forward bound on flat ground; a staircase down 5 cm a step tips it over, status
``fell`` naming the condition; a step taller than the leg is never a finished run; a sweep over
the rise writes each cell's status and ``fell``. CI runs these; the documented grid of
``scenarios/fig_bound_steps.py`` is marked slow."""

from __future__ import annotations

import numpy as np
import pytest

import legsim
from legsim.errors import SceneError
from legsim.scene import load_scene

SCENE = "quadruped_bound_steps"


def test_steps_of_no_rise_run_bit_for_bit_as_the_flat_forward_bound():
    """The profile of steps at rise 0 has height and slope 0.0 everywhere, so the guards,
    constraints and impacts compute what the flat ground computes: the same transitions and the
    same final state to the bit (measured over 4 s, 79 transitions), at the steps scene's
    integrator settings."""
    steps = load_scene(SCENE, ["terrain.rise=0.0", "integrator.t_final=4"])
    settings = [f"integrator.{key}={steps.integrator[key]!r}" for key in ("h", "eps")]
    flat = load_scene(
        "quadruped_bound_forward", ["controller.parameters.speed=0.5", "integrator.t_final=4", *settings]
    ).simulate()
    steps = steps.simulate()
    assert steps.status == flat.status == "finished" and steps.t_end == 4.0
    assert [r.name for r in steps.transitions] == [r.name for r in flat.transitions]
    assert np.array_equal(steps.final_state, flat.final_state)


def test_a_staircase_down_tips_the_bound_over_and_says_so():
    """Steps down 5 cm each: the bound pitches past the scene's pitch_max = 1 rad on the fourth
    tread (measured at t = 7.567 s) and the run ends there with status fell, naming it."""
    ex = load_scene(SCENE, ["terrain.rise=-0.05"]).simulate()
    assert ex.status == "fell"
    assert "pitch_max" in ex.message
    assert 7.0 < ex.t_end < 8.0
    assert abs(abs(ex.final_state[2]) - 1.0) < 1e-6


def test_a_foot_entering_a_stuck_mode_is_at_rest():
    """Steps up 5 cm: every transition into a mode where a foot is stuck leaves that foot at rest
    (its velocity 0 to 1e-9 m/s). Where the impact law's outcome at the landing point (stuck)
    and at the guard point (sliding) differ, the image is the impact into the outcome chosen
    (``friction.realize``): here a front foot's touchdown at 6.189 s, which otherwise entered
    the stuck mode sliding at 0.83 m/s and slid 6 cm in it."""
    import pinocchio as pin

    scene = load_scene(SCENE, ["terrain.rise=0.05", "integrator.t_final=6.3"])
    ex = scene.simulate()
    assert ex.t_end == 6.3
    bridge = scene.model.info["bridge"]
    model = bridge.model
    data = model.createData()
    entered = 0
    for tr in ex.transitions:
        stuck = [part for part in tr.target.split("+") if part in ("hind", "front")]
        q, v = tr.state_after[: model.nq], tr.state_after[model.nq : model.nq + model.nv]
        pin.computeJointJacobians(model, data, q)
        for foot in stuck:
            jacobian = pin.getFrameJacobian(model, data, model.getFrameId(f"{foot}_foot"), pin.LOCAL_WORLD_ALIGNED)
            assert np.abs(jacobian[[0, 2]] @ v).max() < 1e-9, (tr.time, tr.name, foot)
            entered += 1
    assert entered > 20


def test_a_step_taller_than_the_leg_is_never_a_finished_run():
    """A 0.5 m step (the leg is 0.42 m long): the body, which has no contact, runs into the
    riser. The scene's ``below_ground = "fall"`` makes that a crash: the run ends there with
    status fell, naming the link and the time, instead of running on with the body through the
    step. A corner of the body's outline first dips into the riser's face for a fraction of a
    step (measured 2.5873 s, seen between the checked points by the heights' rate), then the
    step's edge enters the body's front face (2.5876 s), and from 2.5975 s a corner stays below
    the tread."""
    ex = load_scene(SCENE, ["terrain.rise=0.5"]).simulate()
    assert ex.status == "fell"
    assert ex.message.startswith("fell: below_ground:") and "'body'" in ex.message
    assert 2.5 < ex.t_end < 2.7
    # Both checks see the body meet the step, the edge inside it within a millisecond after
    warned = load_scene(SCENE, ["terrain.rise=0.5", 'robot.parameters.below_ground="warn"', "integrator.t_final=2.7"])
    when = {w.kind: w.time for w in warned.simulate().warnings}
    assert when["below_ground"] == ex.t_end and 0.0 < when["terrain_inside"] - ex.t_end < 1e-3


def test_rise_excludes_heights_naming_the_field():
    with pytest.raises(SceneError, match=r"terrain\.heights: give exactly one of heights and rise"):
        load_scene(SCENE, ["terrain.heights=[0.1, 0.2, 0.3, 0.4, 0.5]"])
    with pytest.raises(SceneError, match=r"terrain\.rise: got 'x'"):
        load_scene(SCENE, ['terrain.rise="x"'])


def test_the_steps_profile_of_a_rise_is_the_listed_staircase(tmp_path):
    """rise = 0.02 over 5 positions is heights [0.02, 0.04, ..., 0.1] (to 1e-15 m: the products
    0.02 k and the decimal literals differ in the last bit)."""
    from legsim.scene.terrain import parse_terrain

    positions = [1.5, 2.1, 2.7, 3.3, 3.9]
    by_rise = parse_terrain(tmp_path / "s.toml", {"kind": "steps", "positions": positions, "rise": 0.02})
    listed = parse_terrain(
        tmp_path / "s.toml", {"kind": "steps", "positions": positions, "heights": [0.02, 0.04, 0.06, 0.08, 0.1]}
    )
    assert np.allclose(by_rise.array, listed.array, rtol=0, atol=1e-15)


def sweep_rows(tmp_path, rises):
    result = legsim.sweep(
        SCENE,
        grid={"terrain.rise": rises},
        measures=["mean_rate:x:4", "max_abs:pitch:9"],
        out=tmp_path / "steps",
        in_process=True,
    )
    return {row["terrain.rise"]: row for row in result.table.to_pylist()}


def test_a_sweep_over_step_height_writes_fell_or_ran_per_cell(tmp_path):
    """Rise 0 runs (finished, not fell, its mean speed over [4, 10] s within 5% of 0.5 m/s);
    rise -0.05 falls (status fell, ``fell`` true, the message naming pitch_max), and its largest
    |pitch| over [9 s, t_end] is null: the run ended at 7.57 s, before the window."""
    rows = sweep_rows(tmp_path, [-0.05, 0.0])
    ran, fell = rows[0.0], rows[-0.05]
    assert (ran["status"], ran["fell"], ran["task_status"]) == ("finished", False, "done")
    assert abs(ran["mean_rate_x"] / 0.5 - 1.0) < 0.05
    assert (fell["status"], fell["fell"], fell["task_status"]) == ("fell", True, "done")
    assert "pitch_max" in fell["message"]
    assert fell["max_abs_pitch"] is None and ran["max_abs_pitch"] is not None


@pytest.mark.slow
def test_the_documented_step_sweep(tmp_path):
    """The grid of ``scenarios/fig_bound_steps.py`` and docs/sweep.md: rises -0.03 to 0.02 m run
    without a warning, -0.05 m falls, and every cell either ran to t_final, fell, or stopped
    where a step carried a foot through a tread (``model_breakdown``, the ``passed_through``
    check: the method cannot vouch past it), its message naming why: the model takes every step
    height (a foot landing on a riser slips at once, a
    sliding foot passing a tread's edge leaves it or strikes the next face, a foot in the notch
    at a riser's foot is held by both faces). No other way of stopping passes: a foot in a notch
    held by one face only stops a run ``stalled`` or ``max_transitions``."""
    rises = [round(v, 3) for v in np.linspace(-0.1, 0.1, 21)]
    rows = sweep_rows(tmp_path, rises)
    clean = (-0.03, -0.02, -0.01, 0.0, 0.01, 0.02)
    assert all(rows[r]["status"] == "finished" and not rows[r]["warnings"] for r in clean)
    assert rows[-0.05]["status"] == "fell"
    for row in rows.values():
        assert row["task_status"] == "done"
        assert row["status"] in ("finished", "fell", "model_breakdown"), (row["terrain.rise"], row["message"])
        assert row["fell"] == (row["status"] != "finished")
        assert (row["status"] == "finished") == (row["t_end"] == 10.0)
        if row["status"] == "fell":
            assert row["message"].startswith("fell: ")
        if row["status"] == "model_breakdown":
            assert "a step carried it through" in row["message"], row["message"]


def test_a_below_ground_action_not_known_is_named_with_the_allowed_ones():
    with pytest.raises(
        SceneError,
        match=r"robot\.parameters\.below_ground: 'x' is not allowed, choose one of \['warn', 'strict', 'fall'\]",
    ):
        load_scene(SCENE, ['robot.parameters.below_ground="x"'])
