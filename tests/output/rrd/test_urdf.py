"""A URDF robot recorded through Rerun's own URDF loader, read back with Rerun's reader
(``rerun.chunk.RrdReader``): the loader's static geometry for every link with visuals, a
transform per sample for every movable joint and the planar root, and the feet where
Pinocchio's forward kinematics puts them."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.urdf import load_model
from rerun.chunk import RrdReader
from rerun.urdf import UrdfTree

from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import execution_trace
from legsim.scene import load_scene

GEOMETRY = ("Boxes3D:half_sizes", "Cylinders3D:radii", "Ellipsoids3D:half_sizes", "Mesh3D:vertex_positions")
WORLD_FRAME = "tf#/world"


@pytest.fixture(scope="module")
def quadruped(tmp_path_factory):
    """(scene, execution, {(entity, static): {column: values}}, file) of the pronking quadruped
    dropped pitched by 0.3 rad, over 0.12 s: its flight and first landing, the joints moving."""
    scene = load_scene("quadruped_pronk", overrides=["integrator.t_final=0.12", "initial.state.pitch=0.3"])
    ex = scene.simulate()
    assert len(ex.transitions) >= 1
    path = write_rrd(ex, scene, tmp_path_factory.mktemp("rrd") / "quadruped.rrd")
    chunks: dict[tuple[str, bool], dict[str, list]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        found = chunks.setdefault((chunk.entity_path, chunk.is_static), {})
        for name in batch.schema.names:
            if name != "sim_time":  # nanoseconds, which pyarrow will not turn into timedeltas
                found.setdefault(name, []).extend(batch.column(name).to_pylist())
    return scene, ex, chunks, path


def _urdf(scene):
    return scene.model.info["urdf"]["file"]


def test_every_link_with_visuals_has_the_loaders_static_geometry(quadruped):
    scene, _, chunks, _ = quadruped
    tree = UrdfTree.from_file_path(_urdf(scene))
    links = [tree.root_link().name] + [joint.child_link for joint in tree.joints()]
    for link in links:
        paths = tree.get_visual_geometry_paths(link)
        assert paths, f"{link} has no visual in the URDF"
        for path in (f"/world/robot{path}" for path in paths):
            static = chunks[(path, True)]
            assert static["CoordinateFrame:frame"] == [[link]], path
            assert any(static.get(component) for component in GEOMETRY), f"{path} has no geometry"
            assert (path, False) not in chunks, f"{path} is logged again over time"


def test_every_movable_joint_and_the_root_have_a_transform_per_sample(quadruped):
    scene, ex, chunks, _ = quadruped
    model, _ = load_model(_urdf(scene))
    tree = UrdfTree.from_file_path(_urdf(scene))
    samples = len(execution_trace(ex).times)
    frames = {"root": (WORLD_FRAME, "body")}
    for j in range(2, model.njoints):  # Pinocchio's joints after the universe and the planar root
        joint = tree.get_joint_by_name(model.names[j])
        frames[joint.name] = (joint.parent_link, joint.child_link)
    assert len(frames) == 5
    for name, (parent, child) in frames.items():
        moving = chunks[(f"/world/robot/joints/{name}", False)]
        assert sorted(moving["sample"]) == list(range(samples)), name
        assert len(moving["Transform3D:translation"]) == len(moving["Transform3D:quaternion"]) == samples
        assert all(frame == [parent] for frame in moving["Transform3D:parent_frame"]), name
        assert all(frame == [child] for frame in moving["Transform3D:child_frame"]), name


def _edges(chunks, sample: int) -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """child frame -> (parent frame, translation (3,), quaternion xyzw (4,)) at ``sample``: the
    loader's static joint frames, overridden by the transforms logged at that sample."""
    edges = {}
    static = chunks[("/tf_static", True)]
    logged = [(static, None)] + [(cols, sample) for (path, is_static), cols in chunks.items() if not is_static]
    for columns, at in logged:
        if "Transform3D:child_frame" not in columns:
            continue
        for i, (child, parent) in enumerate(
            zip(columns["Transform3D:child_frame"], columns["Transform3D:parent_frame"], strict=True)
        ):
            if at is not None and columns["sample"][i] != at:
                continue
            translation = np.array(columns["Transform3D:translation"][i][0], dtype=float)
            quaternion = np.array(columns["Transform3D:quaternion"][i][0], dtype=float)
            edges[child[0]] = (parent[0], translation, quaternion)
    return edges


def _world_position(edges, frame: str) -> np.ndarray:
    """The origin of ``frame`` in the world's frame, composed up the frame tree."""
    point = np.zeros(3)
    while frame != WORLD_FRAME:
        parent, translation, (qx, qy, qz, qw) = edges[frame]
        rotation = pin.Quaternion(qw, qx, qy, qz).normalized().matrix()
        point = rotation @ point + translation
        frame = parent
    return point


def test_feet_composed_from_the_recorded_transforms_are_where_pinocchio_puts_them(quadruped):
    scene, ex, chunks, _ = quadruped
    model, names = load_model(_urdf(scene))
    data = model.createData()
    trace = execution_trace(ex)
    rows_of = {mode: rows for mode, (rows, _) in trace.blocks.items()}
    checked = 0
    for sample in np.linspace(0, len(trace.times) - 1, 7).astype(int).tolist():
        mode = trace.mode_names[trace.mode_index[sample]]
        _, states = trace.blocks[mode]
        state = states[int(np.searchsorted(rows_of[mode], sample))]
        coordinates = list(ex.state_names[mode])
        q = np.array([state[coordinates.index(name)] for name in names])
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        edges = _edges(chunks, sample)
        for foot in ("hind_foot", "front_foot"):
            expected = data.oMf[model.getFrameId(foot)].translation
            # Rerun stores translations and quaternions in float32 (relative rounding 6e-8):
            # over four frames of at most 0.6 m lever and 0.6 m height that is some 3e-7 m.
            np.testing.assert_allclose(_world_position(edges, foot), expected, atol=1e-6, err_msg=f"{foot}@{sample}")
            checked += 1
    assert checked == 14


def test_replay_draws_each_link_from_its_frame_to_its_joints_where_pinocchio_puts_them(quadruped):
    scene, _, _, path = quadruped
    model, names = load_model(_urdf(scene))
    data = model.createData()
    recording = read_rrd(path)
    robot = recording["frames"]
    assert robot is not None and len(robot) >= 2
    assert sorted(robot.parts) == sorted(frame.name for frame in model.frames if frame.type == pin.FrameType.BODY)
    for i, row in enumerate(recording["frame_rows"].tolist()):
        mode = recording["modes"][row]
        state = [recording["series"][name][1][np.searchsorted(recording["series_rows"][name], row)] for name in names]
        pin.forwardKinematics(model, data, np.array(state))
        pin.updateFramePlacements(model, data)
        for link in ("body", "hind_thigh", "hind_foot", "front_shank"):
            origin = data.oMf[model.getFrameId(link)].translation[[0, 2]]
            np.testing.assert_allclose(robot.parts[link][i][0], origin, atol=1e-6, err_msg=f"{link}@{row} in {mode}")
        hind_knee = data.oMi[model.getJointId("hind_knee")].translation[[0, 2]]
        np.testing.assert_allclose(robot.parts["hind_thigh"][i][1], hind_knee, atol=1e-6)
