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
