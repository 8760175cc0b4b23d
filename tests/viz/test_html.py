"""meshcat animations without a browser: the keyframed boxes reproduce the polylines, the page
is self-contained, and a model without geometry is refused with a clear message."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
import umsgpack
from helpers.models import ball_model, hopper_model

from legsim.errors import OutputError
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import Frames
from legsim.relaxed import simulate
from legsim.viz.meshcat_anim import _commands, _matrix, _segments, animation_html, camera_track, write_html


def test_segment_boxes_land_on_the_polyline():
    rng = np.random.default_rng(3)
    line = rng.normal(size=(6, 2))
    seg = _segments(line, 7)  # one more slot than segments: it stays absent
    assert seg[5:, 4].tolist() == [0.0, 0.0] and seg[:5, 4].tolist() == [1.0] * 5
    for j in range(5):
        mx, mz, length, phi, _, _ = seg[j]
        m = _matrix(mx, mz, length, phi)
        # The unit box's axis ends (-0.5, 0, 0) and (0.5, 0, 0) go to the segment's ends.
        ends = m @ np.array([[-0.5, 0, 0, 1], [0.5, 0, 0, 1]]).T
        np.testing.assert_allclose(ends[[0, 2]].T, line[j:j + 2], atol=1e-12)
        # and the box stays in the sagittal plane y = 0.
        np.testing.assert_allclose(ends[1], 0.0, atol=1e-15)


def _decode(page: str) -> list[dict]:
    packed = json.loads(re.search(r"var legsimCommands = (\[.*?\]);", page, re.S).group(1))
    return [umsgpack.unpackb(base64.b64decode(p)) for p in packed]


@pytest.fixture(scope="module")
def hopper_frames():
    from legsim.output.trace import frame_times, geometry_frames

    model = hopper_model()
    ex = simulate(model.system, np.array([0.5, 0.0]), "flight", 1.0, 1e-3, 2e-3)
    return model, ex, geometry_frames(ex, model, frame_times(ex, 30.0, 900))


def test_animation_keyframes_reproduce_the_frames(hopper_frames):
    _, _, frames = hopper_frames
    cmds = _decode(animation_html(frames))
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    # The leg is one segment: its keyframed position is the midpoint of the leg polyline.
    track = {t["name"]: t["keys"] for t in clips["/meshcat/robot/leg/0"]["tracks"]}
    assert [k["time"] for k in track[".position"]] == pytest.approx(frames.times - frames.times[0])
    for i in range(0, len(frames), 7):
        leg = frames.parts["leg"][i]
        mid = leg.mean(axis=0)
        assert track[".position"][i]["value"] == pytest.approx([mid[0], 0.0, mid[1]])
        assert track[".scale"][i]["value"][0] == pytest.approx(np.hypot(*(leg[1] - leg[0])))
    # The body circle has 12 segments, each keyframed.
    assert sum(p.startswith("/meshcat/robot/body/") for p in clips) == 12


def test_page_is_self_contained(hopper_frames):
    _, _, frames = hopper_frames
    page = animation_html(frames, title="hopper")
    assert "MeshCat.Viewer" in page and "<title>hopper</title>" in page
    # Nothing is fetched from elsewhere: no external scripts, styles or data.
    assert not re.search(r"""<(script|link|img)[^>]+(src|href)\s*=""", page)
    assert "fetch(" not in page.split("<script>", 2)[2]  # our own script fetches nothing


def test_camera_follows_a_travelling_robot_and_not_a_still_one():
    t = np.linspace(0.0, 2.0, 61)
    box = np.array([[-0.1, 0.0], [0.1, 0.0], [0.1, 0.2], [-0.1, 0.2]])
    moving = Frames(t, ["m"] * len(t), {"body": [box + [3.0 * ti, 0.0] for ti in t]})
    cam_x, _, dist = camera_track(moving)
    assert np.ptp(cam_x) > 4.0  # follows the 6 m of travel
    assert np.max(np.abs(cam_x - 3.0 * t)) < 0.5
    still = Frames(t, ["m"] * len(t), {"body": [box + [0.05 * np.sin(ti), 0.0] for ti in t]})
    cam_x, _, _ = camera_track(still)
    assert np.ptp(cam_x) == 0.0


def test_write_html_needs_geometry(tmp_path):
    model = ball_model()
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 0.5, 1e-3, 1e-3)
    with pytest.raises(OutputError, match=r"needs the robot's geometry, and ball defines none"):
        write_html(ex, None, tmp_path / "b.html", model=model)
    data = read_rrd(write_rrd(ex, None, tmp_path / "b.rrd", model=model))
    with pytest.raises(OutputError, match=r"recording of ball has none"):
        write_html(None, None, tmp_path / "b.html", recording=data)
    with pytest.raises(OutputError, match="pass a scene or model="):
        write_html(ex, None, tmp_path / "b.html")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.rrd"]


def test_html_from_recording_animates_the_recorded_frames(hopper_frames, tmp_path):
    model, ex, _ = hopper_frames
    data = read_rrd(write_rrd(ex, None, tmp_path / "h.rrd", model=model))
    path = write_html(None, None, tmp_path / "h.html", recording=data)
    cmds = _decode(path.read_text())
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    clip = {a["path"]: a["clip"] for a in anim["animations"]}["/meshcat/robot/leg/0"]
    keys = {t["name"]: t["keys"] for t in clip["tracks"]}[".position"]
    assert len(keys) == len(data["frames"])


def test_commands_hide_grid_and_axes(hopper_frames):
    _, _, frames = hopper_frames
    cmds = _commands(frames, 1.0)
    hidden = {c["path"] for c in cmds if c["type"] == "set_property" and c["property"] == "visible"
              and c["value"] is False}
    assert hidden == {"/Grid", "/Axes"}


def test_camera_stays_put_for_a_wide_oscillation():
    # A mass swinging over 20 m and ending where it started: a fixed camera frames it all.
    t = np.linspace(0.0, 10.0, 301)
    box = np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 1.0], [-0.5, 1.0]])
    swing = Frames(t, ["m"] * len(t), {"mass": [box + [10.0 * np.sin(2.5 * ti), 0.0] for ti in t]})
    cam_x, _, dist = camera_track(swing)
    assert np.ptp(cam_x) == 0.0
    # The whole swing (+-10.5 m) fits the view: half width <= distance * tan(fov/2) * aspect.
    from legsim.viz.meshcat_anim import ASSUMED_ASPECT, FOV_DEG

    assert 10.5 <= dist * np.tan(np.radians(FOV_DEG / 2)) * ASSUMED_ASPECT
