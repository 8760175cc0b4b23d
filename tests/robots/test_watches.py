"""The checks a robot's run makes on its stored points, evaluated many points per compiled call
(robots/watches.py): each against an independent evaluation point by point; and a run that
builds only the contact modes it enters."""

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge import JointStop
from legsim.robots.bridge.guards import THROUGH_DEPTH
from legsim.robots.urdf import link_heights
from legsim.robots.watches import Inputs

from legsim.compiled.rows import at_rows
from legsim.scene import load_scene
from legsim.terrain import slope_terrain


@pytest.fixture(scope="module")
def quadruped():
    return load_scene("quadruped_pronk", ["integrator.t_final=0.6"])


def random_states(scene, count, seed=0):
    """States near the scene's initial one: every coordinate and rate moved at random."""
    rng = np.random.default_rng(seed)
    x0 = np.asarray(scene.initial_state, dtype=float)
    return x0 + rng.normal(scale=0.3, size=(count, x0.size))


def heights_by_pinocchio(heights, model, q):
    """Every link point's world height at q from Pinocchio's Python forward kinematics."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    rows = []
    for joint, points in heights.links.values():
        placement = data.oMi[joint]
        rows.extend((placement.rotation @ p + placement.translation)[2] for p in points)
    return np.array(rows), data


@pytest.mark.parametrize("terrain", [None, slope_terrain(0.2)])
def test_link_heights_of_many_states_equal_pinocchios_forward_kinematics(quadruped, terrain):
    bridge, outlines = quadruped.model.info["bridge"], quadruped.model.info["outlines"]
    heights = link_heights(bridge, outlines, terrain)
    assert heights.links, "the quadruped's trunk and thighs have no contact"
    states = random_states(quadruped, 16)
    batch = heights.heights_at(states)
    model = bridge.model
    for k, x in enumerate(states):
        z, data = heights_by_pinocchio(heights, model, x[: bridge.n])
        if terrain is not None:
            xs = np.concatenate(
                [
                    [(data.oMi[j].rotation @ p + data.oMi[j].translation)[0] for p in points]
                    for j, points in heights.links.values()
                ]
            )
            z = z - terrain.height(xs)
        np.testing.assert_allclose(batch[k], z, rtol=0, atol=1e-12)
    lowest = heights(states[0])
    assert min(lowest.values()) == pytest.approx(batch[0].min(), abs=0.0)


def test_the_controllers_input_at_many_points_is_its_input_point_by_point(quadruped):
    law = quadruped.control
    execution = quadruped.simulate()
    system = quadruped.model.system
    inputs = Inputs(law, lambda mode: system.mode(mode).dim)
    for seg in execution.segments[:6]:
        batch = inputs(seg.mode, np.asarray(seg.t), np.asarray(seg.x))
        dim = system.mode(seg.mode).dim
        p = law.params_for(seg.mode)
        for k in range(len(seg.t)):
            u = np.zeros(law.inputs)
            law.control(
                float(seg.t[k]), np.ascontiguousarray(seg.x[k][:dim]), np.ascontiguousarray(seg.x[k][dim:]), p, u
            )
            assert np.array_equal(batch[k], u)


def test_a_python_function_at_many_points_is_called_point_by_point():
    def affine(t, x, m, p, out):
        out[0] = p[0] * t + x[0] - m[0]
        out[1] = x[1] * m[0]

    t = np.linspace(0.0, 1.0, 5)
    states = np.arange(15.0).reshape(5, 3)
    out = np.zeros((5, 2))
    at_rows(affine, t, states, 2, np.array([2.0]), out)
    expected = np.column_stack([2.0 * t + states[:, 0] - states[:, 2], states[:, 1] * states[:, 2]])
    assert np.array_equal(out, expected)


def test_a_run_builds_only_the_contact_modes_it_enters(quadruped):
    # Every mode a transition may reach gets a row, but a mode is built (its transitions made,
    # dozens of outcomes each) only when the run enters it.
    scene = load_scene("quadruped_pronk", ["integrator.t_final=0.8"])
    system = scene.model.system
    before = set(system.modes)
    execution = scene.simulate()
    entered = {seg.mode for seg in execution.segments}
    assert execution.counters["transitions"] > 3
    assert set(system.modes) - before <= entered
    assert len(set(system.modes)) < 20, "the reachable outcome modes were built"


def test_the_checks_place_a_batch_once_for_all_and_leave_the_runs_counters_alone(quadruped, monkeypatch):
    # The feet's depths and the links' heights read one forward-kinematics pass of a batch, on a
    # copy of the model: the robot's counters count its run, not the checks over the run.
    import legsim.robots.bridge.placements as placements

    bridge = quadruped.model.info["bridge"]
    heights = link_heights(bridge, quadruped.model.info["outlines"])
    feet = bridge.contact_watches(eps=1e-6)[0]
    calls, real = [], placements.frame_motions
    monkeypatch.setattr(placements, "frame_motions", lambda *args: calls.append(1) or real(*args))
    states = random_states(quadruped, 32, seed=1)
    before = bridge.counters()["kinematics"]
    z = heights.heights_at(states)
    depth = feet.values("flight", np.zeros(32), states)
    assert len(calls) == 1 and bridge.counters()["kinematics"] == before
    z_again, _ = heights_by_pinocchio(heights, bridge.model, states[3][: bridge.n])
    np.testing.assert_allclose(z[3], z_again, rtol=0, atol=1e-12)
    # every contact is inactive in flight: the feet's depths below z = 0 placed by Pinocchio, and
    # the knees' angles past their stops
    model, q = bridge.model, states[3][: bridge.n]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    depths = []
    for c in bridge.contacts:
        if isinstance(c, JointStop):
            past = q[model.joints[model.getJointId(c.joint)].idx_q] - c.position
            depths.append(-past if c.side == "lower" else past)
        else:
            depths.append(c.ground - data.oMf[model.getFrameId(c.frame)].translation[2])
    assert depth[3] == pytest.approx(1e-6 + THROUGH_DEPTH - max(depths), abs=1e-12)
    # rows given as lists are placed alike, and kept nowhere
    np.testing.assert_array_equal(bridge.placements.at(states.tolist()), bridge.placements.at(states))
    del states, q  # q is a view of the batch
    assert not bridge.placements._kept, "the placements of a batch outlive it"
