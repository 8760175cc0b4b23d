"""The ``[certify]`` and ``[stochastic]`` section readers (legsim.scene.certify and
legsim.scene.stochastic): defaults from ``[integrator]``, overrides, and errors naming the key."""

import pytest

from legsim.errors import SceneError
from legsim.scene import certify as certify_section
from legsim.scene import load_scene
from legsim.scene import stochastic as stochastic_section


@pytest.mark.parametrize("reader", [certify_section, stochastic_section])
def test_settings_default_to_the_integrator_and_take_overrides(reader):
    scene = load_scene("grazing")
    settings = reader.scene_settings(scene)
    assert (settings["h"], settings["method"], settings["t_final"]) == (0.1, "rk4", 3.0)
    assert settings["pair"] == "auto" and settings["floor"] == 0.0
    assert reader.scene_settings(scene, {"h": 0.05, "floor": None})["h"] == 0.05


def test_each_section_keeps_its_own_keys_and_values():
    scene = load_scene("grazing")
    assert certify_section.scene_settings(scene)["max_refinements"] == 3
    stochastic = stochastic_section.scene_settings(scene)
    assert (stochastic["samples"], stochastic["seed"]) == (200, 1)
    assert "alpha" in certify_section.section_schema(scene) and "alpha" not in stochastic


@pytest.mark.parametrize("section", ["certify", "stochastic"])
def test_t_final_before_t0_and_too_many_steps_are_named_by_their_keys(section):
    reader = {"certify": certify_section, "stochastic": stochastic_section}[section]
    scene = load_scene("grazing", overrides=["integrator.t0=5.0", "integrator.t_final=6.0", f"{section}.t_final=4.0"])
    with pytest.raises(SceneError, match=rf"grazing.toml: {section}.t_final: must be > t0 = 5.0"):
        reader.scene_settings(scene)
    scene = load_scene("grazing", overrides=[f"{section}.h=1e-9"])
    with pytest.raises(SceneError, match=rf"{section}.h / {section}.t_final: .* more than the limit"):
        reader.scene_settings(scene)
