"""The bundled scenes (scenarios/*.toml): each one loads and validates, and `legsim scenes`
lists it; the analytic ones run through `legsim run --json` to their closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import builders
from legsim.scene import bundled_dir, load_scene, scene_info

FILES = sorted(bundled_dir().glob("*.toml"))


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_bundled_scene_loads_and_validates(path):
    info = scene_info(path)
    assert "error" not in info
    # `legsim scenes` shows the description on one line: it must exist and be one line.
    assert info["description"].strip() and "\n" not in info["description"]
    assert info["robot"] in builders.available()
    scene = load_scene(path.stem)  # by name, as a user would
    assert scene.path.resolve() == path.resolve() and scene.name == path.stem
    assert scene.robot == info["robot"]
    x0 = scene.initial_state
    assert x0.shape == (len(scene.state_names),) and np.all(np.isfinite(x0))
    # The loader rejects an initial state past a guard by more than eps; a bundled scene
    # should start inside its domain (all guards >= -eps).
    gvals = scene.model.system.guard_values(scene.initial_mode, x0)
    assert np.all(gvals >= -scene.integrator["eps"])


def test_the_pronk_does_what_its_description_says():
    # Both feet land and lift at one instant; the integrator crosses one foot's guard, then the
    # other's at once: a one-leg stance held for one strip hold, which the run prints.
    scene = load_scene("pronk")
    assert "so it prints aerial -> left -> both" in scene.description and "under 1 us" in scene.description
    ex = scene.simulate()
    assert ex.mode_sequence[:3] == ["aerial", "left", "both"]
    for before, after in zip(ex.transitions, ex.transitions[1:], strict=False):
        if before.target in ("left", "right"):
            assert after.source == before.target and after.time - before.time < 1e-6
    theta = np.concatenate([seg.x[:, ex.state_names[seg.mode].index("theta")] for seg in ex.segments])
    assert np.max(np.abs(theta)) < 1e-12
