"""An event's outcome with friction is chosen under the input the controller applies after it
(``legsim.relaxed.crossing.previewed_choice``), asked at the step's landing point, where the
event's guard is past and its outcome decided (at q, on the guard to within rounding, it is
not). Asked at q, the choice could contradict the entered mode's forces under the controller's
input there, and the run would stop with ``reset_outside_domain``."""

from __future__ import annotations

from legsim.scene import load_scene


def test_quadruped_run_passes_a_graze_during_a_slip_reversal_at_eps_1e_4():
    """Near t = 1.0617 s (eps = 1e-4, h = 1e-3) the hind foot lands while the front foot's slip
    reverses; asked at q, the chosen outcome (front slipping in -x) contradicted the front's +x
    slip velocity and the run stopped there."""
    scene = load_scene("quadruped_run", ["integrator.t_final=1.2", "integrator.eps=1e-4", "integrator.h=1e-3"])
    execution = scene.simulate()
    assert execution.status == "finished", execution.message
    assert execution.counters["python_steps"] == 0
    assert any(1.06 < tr.time < 1.07 and "_hind" in tr.name for tr in execution.transitions)
