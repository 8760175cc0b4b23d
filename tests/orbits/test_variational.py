"""The compiled variational equation against the Python path's analytic field Jacobians."""

import numpy as np
import pytest
from legsim.robots import compass_gait

from helpers.orbit_systems import hopf_reset
from legsim.orbits import OrbitProblem, Section, jacobian_saltation, jacobians, return_map, variational
from legsim.orbits.variational import compiled_sensitivity


@pytest.fixture(scope="module")
def compass_return():
    model = compass_gait.make({})
    assert all(model.system.mode(name).compiled is not None for name in model.system.modes)
    prob = OrbitProblem(model.system, Section.after("heel_strike"), h=2e-3, eps=1e-6, t_max=3.0, cyclic=["foot_x"])
    ret = return_map(prob, np.array([-0.27, 0.54, 1.09, -0.72, 0.0]))
    return prob, ret


def python_path_jacobian(prob, ret, monkeypatch):
    """The saltation Jacobian with every segment on the Python path: the compass gait's modes
    carry an analytic ``Mode.jacobian``, so this reference has no finite differences inside."""
    with monkeypatch.context() as m:
        m.setattr(jacobians, "compiled_sensitivity", lambda *args, **kwargs: None)
        return jacobian_saltation(prob, ret)


def test_compiled_saltation_jacobian_matches_the_analytic_python_path(compass_return, monkeypatch):
    prob, ret = compass_return
    reference = python_path_jacobian(prob, ret, monkeypatch)
    scale = np.max(np.abs(reference))
    # Central differences of the twin's field, relative ~1e-10 per stage (measured 1e-11 over
    # the whole return).
    assert np.max(np.abs(jacobian_saltation(prob, ret) - reference)) < 1e-9 * scale


def test_newton_jacobian_is_accurate_enough_for_a_newton_step(compass_return, monkeypatch):
    prob, ret = compass_return
    reference = python_path_jacobian(prob, ret, monkeypatch)
    error = np.max(np.abs(jacobian_saltation(prob, ret, newton=True) - reference)) / np.max(np.abs(reference))
    # Forward differences and interpolated field Jacobians: ~1e-6 relative (measured 1.5e-6),
    # so a Newton step from a residual r leaves ~1e-6 r; not the converged orbit's Jacobian.
    assert 1e-9 < error < 1e-5


def test_a_segment_cut_inside_a_step_matches_the_python_product(compass_return, monkeypatch):
    # A crossing section cuts the last segment's last step at t_stop: the cut step's derivative.
    prob, ret = compass_return
    system, _ = prob.instantiate(ret.parameters)
    seg = ret.execution.segments[0]
    t_stop = 0.5 * (seg.t[len(seg.t) // 2] + seg.t[len(seg.t) // 2 + 1])
    compiled = compiled_sensitivity(system.mode(seg.mode), prob.tableau, seg, t_stop)
    monkeypatch.setattr(jacobians, "compiled_sensitivity", lambda *args, **kwargs: None)
    python = jacobians._segment_sensitivity(system, None, prob.tableau, seg, t_stop, False)
    assert compiled is not None
    assert np.max(np.abs(compiled - python)) < 1e-9 * np.max(np.abs(python))


def test_a_mode_without_a_compiled_twin_is_left_to_the_python_path():
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0)
    ret = return_map(prob, np.array([-0.35, -0.55]))
    seg = ret.execution.segments[0]
    mode = prob.system.mode(seg.mode)
    assert mode.compiled is None
    assert compiled_sensitivity(mode, prob.tableau, seg) is None


def test_an_unwritable_kernel_cache_leaves_the_product_to_the_python_path(compass_return, monkeypatch, tmp_path):
    prob, ret = compass_return
    reference = python_path_jacobian(prob, ret, monkeypatch)
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.setenv("LEGSIM_CACHE_DIR", str(blocker / "kernels"))
    monkeypatch.setattr(variational, "_MODULES", {})
    system, _ = prob.instantiate(ret.parameters)
    seg = ret.execution.segments[0]
    assert compiled_sensitivity(system.mode(seg.mode), prob.tableau, seg) is None
    # The Python path (analytic field Jacobians) gives the same Jacobian, bit for bit.
    assert np.array_equal(jacobian_saltation(prob, ret), reference)
