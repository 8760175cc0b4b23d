"""Controller parameters are held to the scene's rules before anything runs (legsim.builders'
``Param`` checks, legsim.scene.controller): numbers finite, lists of one kind and bounded, file
parameters inside the scene's folder; and a plug-in that fails in ``make``, ``reset`` or its
input is an error naming the controller, never an internal error."""

from __future__ import annotations

import re

import numpy as np
import pytest

from helpers.reliability import run_cli
from legsim.builders import MAX_LIST_ITEMS, Param
from legsim.control import Controller, ControllerSpec
from legsim.errors import SceneError
from legsim.scene import bundled_dir, load_scene

STAND = (bundled_dir() / "quadruped_stand.toml").read_text()
SHORT = ["--set", "integrator.t_final=0.02", "--quiet"]


def stand_with(folder, controller: str, parameters: str = ""):
    """The standing quadruped's scene in ``folder`` (with its URDF), its ``[controller]`` section
    naming ``controller`` with ``parameters`` (TOML lines)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "quadruped.urdf").write_text((bundled_dir() / "quadruped.urdf").read_text())
    head, tail = STAND[: STAND.index("[controller]")], STAND[STAND.index("[initial]") :]
    scene = folder / "stand.toml"
    scene.write_text(f'{head}[controller]\nname = "{controller}"\n[controller.parameters]\n{parameters}\n\n{tail}')
    return scene


@pytest.mark.parametrize(
    "value, message",
    [
        ("[nan, 1.0, 0.5, -1.0]", r"controller.parameters.targets\[0\]: must be finite, got nan"),
        ("[0.0, inf, 0.5, -1.0]", r"controller.parameters.targets\[1\]: must be finite, got inf"),
        ('["a", 1.0, 0.5, -1.0]', r"controller.parameters.targets: expected a list of one kind, got numbers, strings"),
        ("[0.1, 0.2]", r"controller.parameters.targets: expected 4 numbers \(one per actuated joint\)"),
        ("[[1], [2], [3], [4]]", r"controller.parameters.targets: expected 4 numbers"),
        ("nan", r"controller.parameters.targets: expected a list, got nan"),
        (f"[{', '.join(['0.0'] * (MAX_LIST_ITEMS + 1))}]", rf"{MAX_LIST_ITEMS + 1} items, more than the"),
    ],
)
def test_joint_pd_targets_of_the_wrong_type_shape_or_range_are_refused_by_name(value, message, capsys):
    # [nan, ...] ran until the field was not finite (exit 3); ["a", ...] was an internal error.
    path = bundled_dir() / "quadruped_stand.toml"
    code, _, err = run_cli("run", "quadruped_stand", *SHORT, "--set", f"controller.parameters.targets={value}")
    assert code == 2
    assert err.startswith(f"legsim: error: {path}: ")
    assert len(err.splitlines()) == 1
    assert re.search(message, err), err
    assert "(controller 'joint_pd')" in err  # the field alone does not say which controller reads it


def test_parameters_that_are_no_table_are_refused():
    # A false-like value (0, "", []) was taken for no parameters at all (found by the fuzzer).
    for value in ("0", '""', "[]", "false"):
        with pytest.raises(SceneError, match=r"controller.parameters: expected a table of parameters, got"):
            load_scene("quadruped_stand", [f"controller.parameters={value}"])


def test_a_number_inside_a_table_of_a_list_parameter_must_be_finite():
    contacts = '[{ name = "hind", frame = "hind_foot", friction = nan }]'
    with pytest.raises(SceneError, match=r"robot.parameters.contacts\[0\].friction: must be finite, got nan"):
        load_scene("quadruped_stand", [f"robot.parameters.contacts={contacts}"])


def test_a_list_of_the_defaults_kind_is_required_when_the_default_has_items():
    param = Param([1.0, 2.0], "two numbers")
    assert param.check([3, 4.5], "p") == [3, 4.5]
    with pytest.raises(SceneError, match=r"^p: expected a list of numbers, got strings: \['a'\]$"):
        param.check(["a"], "p")


class Faulty(Controller):
    """A plug-in that fails where it is told to."""

    memory_names = ()

    def __init__(self, where: str) -> None:
        self.where = where

    def reset(self, mode, t, x):
        if self.where == "reset":
            raise ZeroDivisionError("the plug-in's own bug")

    def __call__(self, mode, t, x):
        if self.where == "call" and t > 0.005:  # past the check of the initial state
            raise KeyError("gain")
        return np.zeros(4)


def faulty_spec(where: str) -> ControllerSpec:
    def make(model, params):
        if where == "make":
            raise ValueError("could not convert string to float: 'a'")
        return Faulty(where)

    return ControllerSpec("faulty", "fails", {"file": Param("", "a file", path=True)}, make)


@pytest.mark.parametrize(
    "where, message",
    [
        ("make", r"controller 'faulty' could not be made from its parameters .*ValueError: could not convert"),
        ("reset", r"controller Faulty: reset in mode 'flight' at t=0 failed: ZeroDivisionError: the plug-in's own bug"),
        ("call", r"controller Faulty: its input in mode 'flight' at t=0.00[0-9]+ failed: KeyError: 'gain'"),
    ],
)
def test_a_plugin_that_raises_is_an_error_naming_it_not_an_internal_error(where, message, monkeypatch, tmp_path):
    monkeypatch.setattr("legsim.scene.controller.get_controller", lambda name: faulty_spec(where))
    code, _, err = run_cli("run", stand_with(tmp_path, "faulty"), *SHORT)
    assert code == 2, err
    assert "internal error" not in err and len(err.splitlines()) == 1
    assert re.search(message, err), err


def test_a_controllers_file_parameter_lies_inside_the_scenes_folder(monkeypatch, tmp_path):
    monkeypatch.setattr("legsim.scene.controller.get_controller", lambda name: faulty_spec("none"))
    (tmp_path / "outside.txt").write_text("a user's file")
    folder = tmp_path / "scene"
    scene = stand_with(folder, "faulty", 'file = "../outside.txt"')
    with pytest.raises(
        SceneError, match=r"controller.parameters.file: '../outside.txt' lies outside the scene's folder"
    ):
        load_scene(scene)
    (folder / "gains.txt").write_text("1 2 3")
    assert isinstance(load_scene(stand_with(folder, "faulty", 'file = "gains.txt"')).controller, Faulty)
