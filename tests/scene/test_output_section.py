"""A scene's [output] section: paths relative to the scene's folder, never out of it."""

import os

import pytest

from helpers.scenes import TINY_SCENE, register_tiny, write_scene
from legsim.errors import SceneError
from legsim.scene import load_scene


@pytest.fixture(autouse=True)
def tiny(monkeypatch):
    register_tiny(monkeypatch)


def scene_with(folder, **outputs):
    lines = "".join(f'{kind} = "{path}"\n' for kind, path in outputs.items())
    return write_scene(folder, TINY_SCENE + "\n[output]\n" + lines)


def test_outputs_resolve_against_the_scene_folder_or_out_dir(tmp_path, monkeypatch):
    path = scene_with(tmp_path, rrd="out/a.rrd", plot="a/../b.png", html="page.html")
    monkeypatch.chdir(tmp_path.parent)
    scene = load_scene(path)
    assert scene.output == {"rrd": "out/a.rrd", "html": "page.html", "plot": "a/../b.png"}
    assert scene.output_paths() == {
        "rrd": tmp_path / "out/a.rrd",
        "html": tmp_path / "page.html",
        "plot": tmp_path / "a/../b.png",
    }
    assert scene.output_paths(tmp_path / "elsewhere")["rrd"] == tmp_path / "elsewhere" / "out/a.rrd"


def test_a_bundled_scenes_outputs_land_in_the_current_folder_not_the_package(tmp_path, monkeypatch):
    """`legsim run grazing --set output.plot=g.png` wrote g.png into the installed package's
    scenarios folder (site-packages, for a pip install): a bundled scene's outputs resolve
    against the current folder instead."""
    monkeypatch.chdir(tmp_path)
    scene = load_scene("bouncing_ball", ["output.plot=g.png"])
    assert scene.output_paths() == {"plot": tmp_path / "g.png"}
    assert scene.output_paths(tmp_path / "elsewhere") == {"plot": tmp_path / "elsewhere" / "g.png"}


@pytest.mark.parametrize(
    "value, reason",
    [
        ("/tmp/a.png", "is an absolute path"),
        ("../a.png", "leaves the scene's folder"),
        ("a/../../a.png", "leaves the scene's folder"),
        ("..", "leaves the scene's folder"),
        (".", "leaves the scene's folder"),
        ("a\\u0000.png", "contains a NUL character"),
        ("", "expected a file path"),
    ],
)
def test_an_output_path_that_leaves_the_folder_is_a_scene_error(tmp_path, value, reason):
    path = scene_with(tmp_path, plot=value)
    with pytest.raises(SceneError, match=rf"^{path}: output\.plot: .*{reason}"):
        load_scene(path)


def test_a_link_out_of_the_folder_is_refused_when_resolved(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    folder = tmp_path / "scene"
    folder.mkdir()
    os.symlink(outside, folder / "link")
    os.symlink(folder, folder / "self")  # a link that stays inside is fine
    scene = load_scene(scene_with(folder, plot="link/a.png", rrd="self/a.rrd"))
    with pytest.raises(SceneError, match=rf"output\.plot: 'link/a\.png' leads out of {folder} to {outside}/a\.png"):
        scene.output_paths()
    scene.output.pop("plot")
    assert scene.output_paths() == {"rrd": folder / "self/a.rrd"}


def test_an_override_cannot_send_an_output_out_either(tmp_path):
    # --set is read as part of the scene; --plot FILE is how the user writes elsewhere.
    path = write_scene(tmp_path)
    with pytest.raises(SceneError, match=r"output\.plot: '/tmp/x\.png' is an absolute path; .*give --plot FILE"):
        load_scene(path, ['output.plot="/tmp/x.png"'])


def test_an_output_of_the_wrong_format_names_the_scene_file_and_its_field(tmp_path, capsys):
    from legsim.cli import main

    path = scene_with(tmp_path, plot="out/ball.toml")
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: output.plot = {tmp_path / 'out/ball.toml'}: unsupported format '.toml'" in err, err
    assert not (tmp_path / "out" / "ball.toml").exists()
