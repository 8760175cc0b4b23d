"""meshcat animations without a browser: the keyframed boxes reproduce the polylines, the page
is self-contained, and a model without geometry is refused with a clear message."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
import umsgpack
from legsim.viz.meshcat_anim import _commands, _matrix, _segments, animation_html, camera_track, write_html

from helpers.models import ball_model, hopper_model
from legsim.errors import OutputError
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import Frames
from legsim.relaxed import simulate


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
        np.testing.assert_allclose(ends[[0, 2]].T, line[j : j + 2], atol=1e-12)
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
    moving = Frames(t, ["m"] * len(t), {"body": [box + np.array([3.0 * ti, 0.0]) for ti in t]})
    cam_x, _, _dist = camera_track(moving, follow=True)
    assert np.ptp(cam_x) > 4.0  # follows the 6 m of travel
    assert np.max(np.abs(cam_x - 3.0 * t)) < 0.5
    still = Frames(t, ["m"] * len(t), {"body": [box + np.array([0.05 * np.sin(ti), 0.0]) for ti in t]})
    cam_x, _, _ = camera_track(still, follow=True)
    assert np.ptp(cam_x) == 0.0


def test_default_camera_is_fixed_and_frames_the_whole_travel():
    from legsim.viz.meshcat_anim import view_half_width

    t = np.linspace(0.0, 2.0, 61)
    box = np.array([[-0.1, 0.0], [0.1, 0.0], [0.1, 0.2], [-0.1, 0.2]])
    moving = Frames(t, ["m"] * len(t), {"body": [box + np.array([3.0 * ti, 0.0]) for ti in t]})
    cam_x, _, dist = camera_track(moving)
    assert np.ptp(cam_x) == 0.0 and cam_x[0] == pytest.approx(3.0)
    # From x = -0.1 to 6.1 m: all of it in view.
    assert cam_x[0] - view_half_width(dist) <= -0.1 and cam_x[0] + view_half_width(dist) >= 6.1
    cmds = _commands(moving, 1.0)
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    assert "/meshcat" not in {a["path"] for a in anim["animations"]}  # the world does not move
    follow = _commands(moving, 1.0, camera="follow")
    (anim,) = [c for c in follow if c["type"] == "set_animation"]
    assert "/meshcat" in {a["path"] for a in anim["animations"]}
    with pytest.raises(OutputError, match=r"camera must be one of \['fixed', 'follow'\], got 'orbit'"):
        _commands(moving, 1.0, camera="orbit")


# -- the ground's ruler ---------------------------------------------------------------------------
def test_ruler_ticks_every_half_metre_labelled_every_metre_on_the_ground():
    from legsim.viz.meshcat_anim import ground_ruler

    slope = np.array([[-1.0, 0.1], [9.0, -0.9]])  # descending 0.1 per metre
    spacing, xs, zs, labelled = ground_ruler({"ground": slope}, -0.3, 2.2)
    assert spacing == 0.5
    np.testing.assert_allclose(xs, [0.0, 0.5, 1.0, 1.5, 2.0])
    np.testing.assert_allclose(zs, -0.1 * xs, atol=1e-15)  # on the slope
    assert xs[labelled].tolist() == [0.0, 1.0, 2.0]
    # Clipped to the ground's extent, and a floor counts as ground.
    _, xs, _, _ = ground_ruler({"floor": np.array([[1.2, 0.0], [2.6, 0.0]])}, -10.0, 10.0)
    np.testing.assert_allclose(xs, [1.5, 2.0, 2.5])
    # Long distances: coarser ticks, at most MAX_TICKS of them.
    from legsim.viz.meshcat_anim import MAX_TICKS

    spacing, xs, _, labelled = ground_ruler({"ground": np.array([[0.0, 0.0], [1000.0, 0.0]])}, 0.0, 1000.0)
    assert spacing == 10.0 and len(xs) <= MAX_TICKS + 1 and xs[labelled][:3].tolist() == [0.0, 20.0, 40.0]
    assert ground_ruler({"support": np.array([[-1.0, 0.0], [1.0, 0.0]])}, -1.0, 1.0) is None
    assert ground_ruler({"ground": np.array([[5.0, 0.0], [6.0, 0.0]])}, -1.0, 1.0) is None


def test_the_page_draws_ruler_ticks_and_labels_fixed_to_the_world():
    t = np.linspace(0.0, 2.0, 61)
    box = np.array([[-0.1, 0.0], [0.1, 0.0], [0.1, 0.2], [-0.1, 0.2]])
    ground = {"ground": np.array([[-2.0, 0.0], [15.0, 0.0]])}
    moving = Frames(t, ["m"] * len(t), {"body": [box + np.array([3.0 * ti, 0.0]) for ti in t]}, ground)
    cmds = _commands(moving, 1.0)
    ticks = [c for c in cmds if c["type"] == "set_transform" and "/ruler/tick/" in c["path"]]
    xs = sorted(np.array(c["matrix"]).reshape(4, 4).T[0, 3] for c in ticks)
    assert len(xs) >= 13 and np.allclose(np.diff(xs), 0.5) and min(xs) <= -0.1 and max(xs) >= 6.1
    labels = [
        c["object"]["textures"][0]["text"] for c in cmds if c["type"] == "set_object" and "/ruler/label/" in c["path"]
    ]
    assert {"0 m", "1 m", "2 m", "3 m", "4 m", "5 m", "6 m"} <= set(labels)
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    assert not [a for a in anim["animations"] if "/scenery/" in a["path"]]


# -- contact markers -----------------------------------------------------------------------------
def test_contact_rings_sit_on_the_footholds_while_the_contact_is_active():
    from legsim.viz.contacts import contact_frames

    from legsim.output.trace import frame_times, geometry_frames
    from legsim.scene import load_scene

    scene = load_scene("pronk", overrides=["integrator.t_final=1.0"])
    ex = scene.simulate()
    frames = geometry_frames(ex, scene.model, frame_times(ex, 30.0, 900))
    contacts = contact_frames(ex, scene.model, frames.times)
    assert sorted(contacts) == ["left", "right"]
    samples = ex.sample(frames.times)
    for i, (mode, x) in enumerate(zip(samples.modes, samples.states, strict=False)):
        names = ex.state_names[mode]
        for leg in ("left", "right"):
            point = contacts[leg][i]
            if f"{leg}_foot_x" in names:  # in stance: the foothold, on the ground
                assert point is not None and point.tolist() == [x[names.index(f"{leg}_foot_x")], 0.0]
            else:
                assert point is None
    page = animation_html(frames, contacts=contacts)
    (anim,) = [c for c in _decode(page) if c["type"] == "set_animation"]
    clip = {a["path"]: a["clip"] for a in anim["animations"]}["/meshcat/contacts/left"]
    tracks = {t["name"]: t for t in clip["tracks"]}
    # The ring jumps between footholds and appears or vanishes at once: no sliding between keys.
    assert tracks[".position"]["interpolation"] == tracks[".scale"]["interpolation"] == 2300
    shown = [k["value"][0] == 1.0 for k in tracks[".scale"]["keys"]]
    assert shown == [p is not None for p in contacts["left"]]
    on = [k["value"] for k, p in zip(tracks[".position"]["keys"], contacts["left"], strict=False) if p is not None]
    placed = [p for p in contacts["left"] if p is not None]
    assert all(v[0] == p[0] and v[2] == p[1] for v, p in zip(on, placed, strict=False))


def test_walkers_and_bridge_robots_mark_their_contacts():
    from legsim.viz.contacts import contact_frames

    from legsim.scene import load_scene

    found = {}
    for name in ("compass_gait", "rimless_wheel", "rod", "double_pendulum_plastic"):
        scene = load_scene(name)
        ex = scene.simulate()
        found[name] = contact_frames(ex, scene.model, np.array([ex.t0, ex.t_end]))
    # The walkers stand on their stance foot from the start, on the slope's line through 0.
    assert found["compass_gait"]["stance_foot"][0].tolist() == [0.0, 0.0]
    assert found["rimless_wheel"]["stance_spoke"][0].tolist() == [0.0, 0.0]
    end = found["compass_gait"]["stance_foot"][1]
    slope = np.radians(load_scene("compass_gait").parameters["slope"])
    assert end[0] > 1.0 and end[1] == pytest.approx(-np.tan(slope) * end[0], abs=1e-12)
    # The rod lands flat on both ends; the pendulum's stop is a joint, not a point on the ground.
    assert sorted(found["rod"]) == ["a", "b"] and found["rod"]["a"][0] is None
    assert abs(found["rod"]["a"][1][0] - found["rod"]["b"][1][0]) == pytest.approx(1.0)
    assert found["double_pendulum_plastic"] == {}


def test_a_page_from_a_recording_has_no_contact_rings(hopper_frames, tmp_path):
    model, ex, _ = hopper_frames
    data = read_rrd(write_rrd(ex, None, tmp_path / "h.rrd", model=model))
    cmds = _decode(write_html(None, None, tmp_path / "h.html", recording=data).read_text())
    assert not [c for c in cmds if "/contacts/" in c.get("path", "")]


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
    hidden = {
        c["path"] for c in cmds if c["type"] == "set_property" and c["property"] == "visible" and c["value"] is False
    }
    assert hidden == {"/Grid", "/Axes"}


def test_camera_stays_put_for_a_wide_oscillation():
    # A mass swinging over 20 m and ending where it started: a fixed camera frames it all.
    t = np.linspace(0.0, 10.0, 301)
    box = np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 1.0], [-0.5, 1.0]])
    swing = Frames(t, ["m"] * len(t), {"mass": [box + np.array([10.0 * np.sin(2.5 * ti), 0.0]) for ti in t]})
    cam_x, _, dist = camera_track(swing)
    assert np.ptp(cam_x) == 0.0
    # The whole swing (+-10.5 m) fits the view: half width <= distance * tan(fov/2) * aspect.
    from legsim.viz.meshcat_anim import ASSUMED_ASPECT, FOV_DEG

    assert dist * np.tan(np.radians(FOV_DEG / 2)) * ASSUMED_ASPECT >= 10.5


def test_legsim_run_and_replay_take_the_camera_option(tmp_path):
    from helpers.reliability import run_cli

    def moves_the_world(page):
        (anim,) = [c for c in _decode(page.read_text()) if c["type"] == "set_animation"]
        return "/meshcat" in {a["path"] for a in anim["animations"]}

    common = ["run", "pronk", "--quiet"]  # the whole run: two hops, 5.5 m of travel
    assert run_cli(*common, "--html", tmp_path / "fixed.html", "--rrd", tmp_path / "p.rrd")[0] == 0
    assert run_cli(*common, "--html", tmp_path / "follow.html", "--html-camera", "follow")[0] == 0
    assert not moves_the_world(tmp_path / "fixed.html") and moves_the_world(tmp_path / "follow.html")
    assert run_cli("replay", tmp_path / "p.rrd", "--html", tmp_path / "r.html", "--html-camera", "follow")[0] == 0
    assert moves_the_world(tmp_path / "r.html")
    code, _, err = run_cli(*common, "--html", tmp_path / "x.html", "--html-camera", "orbit")
    assert code == 2 and "--html-camera: invalid choice: 'orbit'" in err and not (tmp_path / "x.html").exists()
