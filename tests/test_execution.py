"""The Execution: save/load round trip, dense sampling (continuous, O(h^4) between steps) and the
hold of the state inside relaxation strips."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import Execution, SimulationError, load_execution, run_summary, save_execution, simulate
from legsim.systems import bouncing_ball as bb
from legsim.systems import oscillator as osc
from legsim.systems.oscillator import EXAMPLES, OscillatorReference


@pytest.fixture(scope="module")
def ball_run() -> Execution:
    # The plain relaxed run: past the Zeno time the ball chatters in its strips.
    return simulate(bb.make_system(), [1.0, 0.0], "flight", 2.0, 1e-2, 1e-3, continuation=False)


@pytest.fixture(scope="module")
def sticking_run() -> Execution:
    E = EXAMPLES["ex2"]
    system = osc.make_system(E["omega"], E["a"], E["x_max"], E["c"])
    return simulate(
        system,
        [E["x0"], E["xd0"]],
        "free",
        6.0,
        1e-2,
        1e-3,
        "rk2",
        osc.forcing(E["amplitude"], E["frequency"]),
        continuation=False,
    )


def assert_same_execution(a: Execution, b: Execution) -> None:
    assert (a.status, a.message, a.t0, a.t_end, a.t_final) == (b.status, b.message, b.t0, b.t_end, b.t_final)
    assert a.counters == b.counters and a.settings == b.settings
    assert a.state_names == b.state_names and a.system_name == b.system_name
    assert a.final_in_strip == b.final_in_strip and a.final_mode == b.final_mode
    np.testing.assert_array_equal(a.final_state, b.final_state)
    assert len(a.segments) == len(b.segments)
    for s, r in zip(a.segments, b.segments, strict=True):
        assert s.mode == r.mode
        for name in ("t", "x", "dx"):
            np.testing.assert_array_equal(getattr(s, name), getattr(r, name))
    assert [(s.mode, s.name, s.time, s.exit_time) for s in a.strips] == [
        (s.mode, s.name, s.time, s.exit_time) for s in b.strips
    ]
    for s, r in zip(a.strips, b.strips, strict=True):
        np.testing.assert_array_equal(s.state, r.state)
    assert len(a.transitions) == len(b.transitions)
    for s, r in zip(a.transitions, b.transitions, strict=True):
        assert (s.name, s.source, s.target, s.index, s.time, s.landing_time, s.exit_time, s.depth) == (
            r.name,
            r.source,
            r.target,
            r.index,
            r.time,
            r.landing_time,
            r.exit_time,
            r.depth,
        )
        np.testing.assert_array_equal(s.state_before, r.state_before)
        np.testing.assert_array_equal(s.state_after, r.state_after)


@pytest.mark.parametrize("run", ["ball_run", "sticking_run"])
def test_save_load_round_trip(run, request, tmp_path):
    ex = request.getfixturevalue(run)
    path = save_execution(ex, tmp_path / "deep" / "run.npz")
    assert path.exists()
    assert [p.name for p in path.parent.iterdir()] == ["run.npz"]  # no temporary left behind
    loaded = load_execution(path)
    assert_same_execution(ex, loaded)
    ts = np.linspace(ex.t0, ex.t_end, 997)
    a, b = ex.sample(ts), loaded.sample(ts)
    assert a.modes == b.modes
    np.testing.assert_array_equal(a.in_strip, b.in_strip)
    np.testing.assert_array_equal(a.stack(), b.stack())


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(SimulationError, match=r"nothing.npz: no such execution file"):
        load_execution(tmp_path / "nothing.npz")
    bad = tmp_path / "bad.npz"
    bad.write_text("not numpy")
    with pytest.raises(SimulationError, match=r"bad.npz: not a legsim execution file"):
        load_execution(bad)


def test_run_ending_inside_a_strip(tmp_path):
    ref = bb.BouncingBallReference()
    # The first strip holds for at least eps / v = 1e-2 / 4.43 s after the crossing.
    ex = simulate(bb.make_system(), [1.0, 0.0], "flight", ref.first_impact + 1e-3, 1e-3, 1e-2)
    assert ex.status == "finished" and ex.final_in_strip
    assert ex.transitions == [] and len(ex.strips) == 1
    np.testing.assert_allclose(ex.final_state, [0.0, -ref.impact_speed], atol=1e-9)  # the held q
    assert_same_execution(ex, load_execution(save_execution(ex, tmp_path / "strip.npz")))


def test_sample_is_continuous_between_transitions(sticking_run):
    ex = sticking_run
    ts = np.linspace(ex.t0, ex.t_end, 60001)
    s = ex.sample(ts)
    x = s.stack()
    dt = ts[1] - ts[0]
    # Jumps only where a reset happens between two samples; elsewhere |dx| <= max|f| dt.
    f_max = max(np.abs(seg.dx).max(axis=0).max() for seg in ex.segments)
    jumps = np.abs(np.diff(x, axis=0)).max(axis=1) > 1.5 * f_max * dt
    exits = np.array([tr.exit_time for tr in ex.transitions])
    assert jumps.sum() >= 8  # the big impacts of the chatter show as jumps
    for i in np.nonzero(jumps)[0]:
        assert np.any((exits > ts[i]) & (exits <= ts[i + 1]))
    # Samples at the stored points are the stored states.
    seg = max(ex.segments, key=lambda g: len(g.t))
    got = ex.sample(seg.t[1:-1]).stack()
    np.testing.assert_array_equal(got, seg.x[1:-1])


def test_dense_output_is_fourth_order_between_steps():
    # The interpolation defect alone: at each step's midpoint, the sample against the exact flow
    # started from the step's own left point. Cubic Hermite interpolation leaves O(h^4) there
    # (linear interpolation, paper 000 Fig. 12 step 9, would leave O(h^2)).
    E = EXAMPLES["ex1"]
    system = osc.make_system(E["omega"], E["a"], None, E["c"])  # no stop: one smooth segment
    defects = []
    hs = [4e-2, 2e-2, 1e-2]
    for h in hs:
        ex = simulate(
            system, [E["x0"], E["xd0"]], "free", 1.0, h, 1e-3, "rk4", osc.forcing(E["amplitude"], E["frequency"])
        )
        seg = ex.segments[0]
        worst = 0.0
        for t_left, x_left, t_right in zip(seg.t[:-1:5], seg.x[:-1:5], seg.t[1::5], strict=True):
            local = OscillatorReference(
                E["omega"], E["a"], None, E["c"], 1.0, E["amplitude"], E["frequency"], x_left[0], x_left[1], t0=t_left
            )
            mid = 0.5 * (t_left + t_right)
            worst = max(worst, np.abs(ex.sample([mid]).stack()[0] - local.state(mid)).max())
        defects.append(worst)
    assert np.polyfit(np.log(hs), np.log(defects), 1)[0] == pytest.approx(4.0, abs=0.3)


def test_sample_rejects_times_outside_the_run(ball_run):
    with pytest.raises(SimulationError, match=r"sample times must lie in \[0.0, 2.0\]"):
        ball_run.sample([2.5])
    with pytest.raises(SimulationError, match=r"sample times must be finite"):
        ball_run.sample([np.nan])
    with pytest.raises(SimulationError, match=r"sample times must be a 1-d sequence"):
        ball_run.sample(np.zeros((2, 2)))


def test_summary_counts(ball_run):
    summary = run_summary(ball_run)
    assert summary["transitions"] == len(ball_run.transitions)
    assert summary["mode_sequence"] == ["flight"] * (len(ball_run.transitions) + 1)
    assert summary["reset_evals"] == len(ball_run.transitions)
    assert summary["final_in_strip"] == ball_run.final_in_strip
    assert summary["strip_time"] == pytest.approx(sum(s.exit_time - s.time for s in ball_run.strips))


def test_filled_records_equal_the_records_their_constructors_make(ball_run):
    # The drain builds segments, strips and transitions with ``filled`` (every field at once);
    # each must equal, field for field, the record its dataclass constructor makes, and stay
    # frozen. The ball's run has all three kinds.
    from dataclasses import FrozenInstanceError, asdict, fields

    from legsim.execution import Segment, Strip, TransitionRecord, filled

    for records, cls in (
        (ball_run.segments, Segment),
        (ball_run.strips, Strip),
        (ball_run.transitions, TransitionRecord),
    ):
        assert records, f"the run has no {cls.__name__}"
        for record in records[:3]:
            values = {f.name: getattr(record, f.name) for f in fields(cls)}
            made, constructed = filled(cls, **values), cls(**values)
            assert type(made) is cls
            assert {k: repr(v) for k, v in asdict(made).items()} == {k: repr(v) for k, v in asdict(constructed).items()}
            with pytest.raises(FrozenInstanceError):
                made.time = 0.0  # type: ignore[misc]
