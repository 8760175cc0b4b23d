"""Baseline additions made for the benchmarks: dense output of the event-driven simulator."""

import numpy as np

from legsim.baselines import simulate_events
from legsim.systems.oscillator import OscillatorReference, make_system


def test_dense_output_samples_between_steps_at_the_method_accuracy():
    # Free damped oscillator (no stop): DOP853 at rtol 1e-11 takes long steps, between which the
    # cubic Hermite interpolation of a plain Execution is far less accurate than solve_ivp's own
    # interpolant. Both runs take the same steps.
    system = make_system(2.0, 0.1, None, 0.9)
    ref = OscillatorReference(2.0, 0.1, None, 0.9, 1.0, 0.0, 0.0, 1.0, 0.0)
    plain = simulate_events(system, [1.0, 0.0], "free", 10.0, method="DOP853", rtol=1e-11, atol=1e-12)
    dense = simulate_events(
        system, [1.0, 0.0], "free", 10.0, method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True
    )
    assert np.array_equal(plain.segments[0].t, dense.segments[0].t)
    steps = plain.segments[0].t
    mids = 0.5 * (steps[1:] + steps[:-1])
    err_plain = np.abs(plain.sample(mids).stack() - ref.states(mids)).max()
    err_dense = np.abs(dense.sample(mids).stack() - ref.states(mids)).max()
    assert err_dense < 1e-9  # the tolerance's order
    assert err_dense < 1e-2 * err_plain  # Hermite on steps of ~0.5 s is much worse
    # At the step points both are the computed states.
    assert np.allclose(dense.sample(steps).stack(), plain.segments[0].x, rtol=0, atol=1e-15)


def test_model_breakdown_inside_solve_ivp_ends_the_run_with_that_status():
    # solve_ivp evaluates the guard at its trial points; a model that breaks down there (as the
    # runner whose body goes through the ground) must end the run with a status, not a traceback.
    from legsim import HybridSystem, Mode, Transition
    from legsim.errors import ModelBreakdown

    def guard(x):
        if x[0] < -0.5:
            raise ModelBreakdown("fell through the floor")
        return x[0] + 10.0

    system = HybridSystem(
        {"m": Mode(1, lambda t, x, u: np.array([-1.0]))}, [Transition("m", "m", guard, lambda x: x.copy())]
    )
    ex = simulate_events(system, [1.0], "m", 10.0, method="RK45", rtol=1e-6, atol=1e-9)
    assert ex.status == "model_breakdown"
    assert "fell through the floor" in ex.message and "mode 'm'" in ex.message


def test_zero_speed_graze_at_a_release_does_not_loop():
    # Double pendulum, plastic stop: at the release (paper 003 eq. (31)) the link sits on the
    # stop at zero speed with zero free acceleration, so the graze guard reads 0 with a rate of
    # rounding size. Its plastic reset then maps the state to itself: firing it again and again
    # at that instant would exhaust the transition cap (it did at rtol 1e-12).
    from legsim.robots import double_pendulum as dp

    model = dp.make(None, {"gravity": True, "stop": {"restitution": 0.0, "position": 0.0}})
    x0 = np.array([dp.INITIAL_STATE[n] for n in dp.STATE_NAMES])
    ex = simulate_events(
        model.system,
        x0,
        "unconstrained",
        5.0,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        max_step=0.02,
        max_transitions=50,
    )
    assert ex.status == "finished"
    impacts = [tr.time for tr in ex.transitions if tr.name == "impact_stop"]
    releases = [tr.time for tr in ex.transitions if tr.name == "release_stop"]
    assert len(impacts) == 2 and len(releases) == 2
    # Each release follows its impact, after a constrained swing.
    assert impacts[0] < releases[0] < impacts[1] < releases[1]
    # Between them nothing fires more than twice at one instant.
    times = np.array([tr.time for tr in ex.transitions])
    assert max(np.sum(np.abs(times - t) < 1e-12) for t in times) <= 3
