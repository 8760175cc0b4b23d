"""Reading scene files within bounds: the size and nesting a scene may have, and files that are
no scene (a FIFO, a device) refused without reading them."""

import os

import pytest

from helpers.scenes import TINY_SCENE, register_tiny, write_scene
from legsim.errors import SceneError
from legsim.scene import load_scene, read_toml
from legsim.scene.files import MAX_SCENE_BYTES, MAX_SCENE_DEPTH, parse_override


def nested_table(depth: int) -> str:
    """A TOML value holding tables nested ``depth`` deep (the value itself is level 1)."""
    return "{ a = " * depth + "1" + " }" * depth


def test_nesting_up_to_the_bound_reads_and_one_more_level_is_refused(tmp_path):
    # [robot.parameters] is level 1 and 2 of the document; the value adds the rest.
    ok = write_scene(tmp_path, f"[robot.parameters]\nx = {nested_table(MAX_SCENE_DEPTH - 2)}\n", name="ok")
    assert read_toml(ok)["robot"]["parameters"]["x"]["a"]
    deep = write_scene(tmp_path, f"[robot.parameters]\nx = {nested_table(MAX_SCENE_DEPTH - 1)}\n", name="deep")
    with pytest.raises(SceneError, match=rf"^{deep}: nested more than {MAX_SCENE_DEPTH} levels deep"):
        read_toml(deep)


def test_a_file_larger_than_the_bound_is_refused_unread(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text("#" * MAX_SCENE_BYTES + "\n")
    with pytest.raises(SceneError, match=rf"^{path}: larger than {MAX_SCENE_BYTES} bytes"):
        read_toml(path)


def test_a_fifo_in_the_scene_folder_is_refused_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    with pytest.raises(SceneError, match=r"pipe\.toml: not a scene file \(it is a FIFO\)$"):
        read_toml(fifo)


def test_an_override_nested_too_deep_is_a_scene_error(tmp_path, monkeypatch):
    register_tiny(monkeypatch)
    with pytest.raises(SceneError, match=r"^--set robot\.x: the value is nested more than"):
        parse_override(f"robot.x={nested_table(600)}")
    # Dotted keys nest without any bracket: measured after the overrides are applied.
    path = write_scene(tmp_path, TINY_SCENE)
    with pytest.raises(SceneError, match=rf"^{path}: nested more than {MAX_SCENE_DEPTH} levels deep"):
        load_scene(path, ["robot.parameters." + ".".join(["a"] * 40) + "=1"])
