"""The recording as a Rerun user meets it, read with Rerun's own reader (``rerun.chunk.RrdReader``),
not legsim's: each body's shape static and a transform per sample, the series named with their
units, and a blueprint that opens on the robot and views named by unit."""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from legsim.output.rrd import write_rrd
from legsim.output.trace import execution_trace
from legsim.scene import load_scene


@pytest.fixture(scope="module")
def pronk(tmp_path_factory):
    """(scene, execution, {(entity, static): {column: values}}, blueprint views) of the pronk
    over 0.6 s (aerial and stance phases)."""
    scene = load_scene("pronk", overrides=["integrator.t_final=0.6"])
    ex = scene.simulate()
    assert len(ex.transitions) >= 2
    path = write_rrd(ex, scene, tmp_path_factory.mktemp("rrd") / "pronk.rrd")
    reader = RrdReader(path)
    chunks: dict[tuple[str, bool], dict[str, list]] = {}
    for chunk in reader.stream():
        batch = chunk.to_record_batch()
        found = chunks.setdefault((chunk.entity_path, chunk.is_static), {})
        for name in batch.schema.names:
            if name != "sim_time":  # nanoseconds, which pyarrow will not turn into timedeltas
                found.setdefault(name, []).extend(batch.column(name).to_pylist())
    (blueprint,) = reader.blueprints()
    views = {}
    for chunk in reader.stream(store=blueprint):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:display_name" in batch.schema.names:
            (name,) = batch.column("ViewBlueprint:display_name").to_pylist()[-1]
            (kind,) = batch.column("ViewBlueprint:class_identifier").to_pylist()[-1]
            views[name] = kind
    return scene, ex, chunks, views


def test_every_body_is_a_static_shape_moved_by_a_transform_per_sample(pronk):
    scene, ex, chunks, _ = pronk
    first = ex.segments[0]
    bodies = scene.model.geometry(first.mode, first.x[0])
    samples = len(execution_trace(ex).times)
    for body in bodies:
        path = f"/world/robot/{body}"
        static = chunks[(path, True)]
        shape = static.get("LineStrips3D:strips") or static.get("Points3D:positions")
        assert shape and shape[0], f"{path} has no static shape"
        moving = chunks[(path, False)]
        assert "LineStrips3D:strips" not in moving and "Points3D:positions" not in moving
        assert sorted(moving["sample"]) == list(range(samples))
        assert len(moving["Transform3D:translation"]) == samples


def test_a_foot_translation_is_where_the_model_draws_it(pronk):
    scene, ex, chunks, _ = pronk
    moving = chunks[("/world/robot/foot_left", False)]
    trace = execution_trace(ex)
    mode = trace.modes[-1]
    state = trace.blocks[mode][1][-1]
    (point,) = scene.model.geometry(mode, state)["foot_left"]
    last = int(np.argmax(moving["sample"]))
    shape = chunks[("/world/robot/foot_left", True)]["Points3D:positions"][0][0]
    x, _, z = np.add(moving["Transform3D:translation"][last][0], shape)
    np.testing.assert_allclose([x, z], point, atol=1e-6)  # float32 storage


def test_series_are_named_with_their_units(pronk):
    _, ex, chunks, _ = pronk
    names = {
        path: column["SeriesLines:names"][0][0]
        for (path, static), column in chunks.items()
        if static and path.startswith("/state/")
    }
    for mode, coordinates in ex.state_names.items():
        for name, unit in zip(coordinates, ex.state_units[mode], strict=False):
            assert names[f"/state/{name}"] == f"{name} ({unit})"


def test_mode_is_a_state_band_and_events_are_text_logs_with_fields(pronk):
    _, ex, chunks, _ = pronk
    assert chunks[("/mode", False)]["StateChange:state"] == [[s.mode] for s in ex.segments]
    events = chunks[("/events/transitions", False)]
    assert [row[0] for row in events["edge"]] == [f"{t.source} -> {t.target}" for t in ex.transitions]
    assert np.array_equal(np.ravel(events["time"]), [t.time for t in ex.transitions])
    assert set(np.ravel(events["TextLog:level"])) == {"INFO"}


def test_the_blueprint_opens_on_the_robot_and_views_by_unit(pronk):
    *_, views = pronk
    assert views["robot"] == "3D"
    assert views["mode and strips"] == "StateTimeline"
    for title in ("positions (m)", "angles (rad)", "velocities (m/s)", "angular velocities (rad/s)"):
        assert views[title] == "TimeSeries"
