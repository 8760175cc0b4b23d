"""The models the stress cases run: the suite's own lifted ball, and models built through the
registered builders with their states by coordinate name."""

import numpy as np
import pytest

from legsim import simulate, stress


def test_the_lifted_ball_rests_and_is_released_at_the_force_zero():
    # the suite's own model: c = 0 lands plastically and leaves at m g / r exactly
    system, control = stress.lifted_ball(0.0, 4.0)
    ex = simulate(system, [0.2, 0.0], "flight", 3.0, 1e-2, 1e-4, control=control)
    assert [tr.name for tr in ex.transitions] == ["land", "release"]
    assert ex.transitions[1].time == pytest.approx(9.81 / 4.0, abs=1e-12)


def test_model_state_is_the_initial_state_with_overrides_by_name():
    model = stress.build("bouncing_ball", {"z0": 2.0})
    np.testing.assert_array_equal(stress.model_state(model, "flight"), [2.0, 0.0])
    np.testing.assert_array_equal(stress.model_state(model, "flight", {"zd": -1.5}), [2.0, -1.5])
