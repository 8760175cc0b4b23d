"""`legsim certify` and `legsim stochastic` on the bundled paper-004 scenes: JSON keys and values
against closed forms, exit codes and error messages."""

import json
import math
import re

import numpy as np
import pytest

from legsim.cli import main
from legsim.systems.two_tanks import TwoTankReference


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_certify_json_lists_verdicts_with_the_documented_keys(capsys):
    code, out, err = run_cli(capsys, "certify", "two_tanks", "--json", "--set", "certify.max_refinements=1")
    assert code == 3 and "not certified: zeno" in err
    verdicts = json.loads(out)
    assert isinstance(verdicts, list) and verdicts
    for v in verdicts:
        assert {"source", "target", "time", "certified", "reason"} <= set(v)
        assert v["reason"] in (None, "grazing", "intersecting_guards", "zeno", "refinement_limit")
    *done, last = verdicts
    assert last["reason"] == "zeno" and last["certified"] is False
    exact, modes = TwoTankReference(0.75, 0.5, 0.5).switching_times("q1", np.array([1.0, 1.0]), len(done))
    for v, t, target in zip(done, exact, modes, strict=True):
        assert v["certified"] is True and v["reason"] is None and v["target"] == target
        assert v["time"] == pytest.approx(t, abs=1e-9)


def test_certify_grazing_scene_refuses_with_grazing(capsys):
    code, out, _err = run_cli(capsys, "certify", "grazing", "--json", "--max-refinements", "1")
    assert code == 3
    (v,) = json.loads(out)
    assert (v["source"], v["target"], v["certified"], v["reason"], v["taken"]) == (
        "inside",
        "outside",
        False,
        "grazing",
        False,
    )
    assert v["time"] == pytest.approx(math.pi / 2, abs=1e-3)


def test_certify_transversal_crossing_succeeds_with_exit_code_zero(capsys):
    code, out, err = run_cli(capsys, "certify", "grazing", "--set", "initial.state.x2=1.5")
    assert code == 0 and err == ""
    assert "all transitions certified" in out
    assert out.count("certified") >= 3  # two crossings of the circle of radius 1.5 before t = 3 s


def test_stochastic_json_summarises_sequences_and_switching_times(capsys):
    code, out, _err = run_cli(capsys, "stochastic", "grazing", "--samples", "60", "--seed", "4", "--json")
    assert code == 0
    s = json.loads(out)
    assert s["samples"] == 60 and s["seed"] == 4
    assert sum(seq["count"] for seq in s["sequences"]) == 60
    # Half the ball past the plane at tangency: about half the executions switch (4 sigma).
    switched = 1 - sum(seq["fraction"] for seq in s["sequences"] if seq["transitions"] == 0)
    assert abs(switched - 0.49) < 4 * math.sqrt(0.25 / 60)
    assert abs(s["switching_times"][0]["mean"] - math.pi / 2) < 0.01
    assert s["deterministic"]["transitions"] == 0


def test_stochastic_two_tanks_text_output_and_seed_reproducibility(capsys):
    argv = ("stochastic", "two_tanks", "--samples", "3", "--set", "stochastic.t_final=6.0", "--json")
    code, first, _ = run_cli(capsys, *argv)
    code2, second, _ = run_cli(capsys, *argv)
    assert code == code2 == 0 and first == second
    s = json.loads(first)
    assert s["switching_times"][0]["mean"] == pytest.approx(2.0, abs=0.3)  # Euler, h = 0.02, floor 1
    # The relaxed execution is exact in each mode but holds each strip crossing for up to eps
    # (1e-3 here), which delays every later switch by as much.
    first_switch, second_switch = s["deterministic"]["switching_times"][:2]
    assert first_switch == pytest.approx(2.0, abs=1e-9)
    assert 5.0 <= second_switch <= 5.0 + 1e-3 + 1e-9
    code, out, _ = run_cli(capsys, "stochastic", "two_tanks", "--samples", "2", "--set", "stochastic.t_final=3.0")
    assert code == 0 and "switching times (s)" in out and "deterministic" in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (("stochastic", "no_such_scene"), "no_such_scene"),
        (("stochastic", "grazing", "--samples", "0"), "--samples must be an integer >= 1, got 0"),
        (("stochastic", "grazing", "--set", "stochastic.intensity=rate"), "stochastic.intensity"),
        (("stochastic", "grazing", "--set", "stochastic.bogus=1"), "unknown parameter(s) ['bogus']"),
        (("stochastic", "two_tanks", "--set", "stochastic.hazard_cap=0"), "stochastic.hazard_cap: 0.0 is out of range"),
        (("certify", "no_such_scene"), "no_such_scene"),
        (("certify", "grazing", "--set", "certify.alpha=1.0"), "certify.alpha"),
        (("certify", "grazing", "--max-refinements", "-1"), "--max-refinements must be an integer >= 0"),
        # Absurd sizes are refused up front rather than started (they would run for days).
        (("stochastic", "grazing", "--samples", "1000000000"), "stochastic.samples: 1000000000 is out of range"),
        (("stochastic", "grazing", "--set", "stochastic.h=1e-12"), "steps, more than the limit"),
        (("stochastic", "grazing", "--set", "stochastic.t_final=1e12"), "steps, more than the limit"),
        (("certify", "grazing", "--set", "certify.h=1e-12"), "certify.h / certify.t_final"),
    ],
)
def test_bad_input_exits_2_with_a_message(capsys, argv, message):
    code, _out, err = run_cli(capsys, *argv)
    assert code == 2
    assert message in err and "Traceback" not in err


def test_non_integer_samples_is_a_usage_error(capsys):
    code, _out, err = run_cli(capsys, "stochastic", "grazing", "--samples", "many")
    assert code == 2 and "invalid int value: 'many'" in err


def test_certify_with_a_used_up_transition_budget_exits_3_as_incomplete(capsys):
    code, out, err = run_cli(capsys, "certify", "two_tanks", "--set", "certify.max_transitions=3")
    assert code == 3
    assert sum(line.endswith("   certified") for line in out.splitlines()) == 3
    assert "all transitions certified" not in out
    assert "incomplete: stopped after max_transitions = 3" in out
    assert "legsim: certification incomplete" in err


def test_stochastic_reports_stalled_and_overflowing_executions(capsys):
    # Two tanks without a floor: the ball is rounding noise and the switches pile up at 8 s.
    code, out, err = run_cli(capsys, "stochastic", "two_tanks", "--samples", "2", "--set", "stochastic.floor=0")
    assert code == 3 and "statuses: stalled 2" in out
    stalled_at = float(re.search(r"stopped advancing at t=([0-9.e+-]+)", err).group(1))
    assert stalled_at == pytest.approx(8.0, abs=1e-9)  # the Zeno time, to the switches' rounding
    # A circle at omega = 50 rad/s over 20 s: B grows like e^(50 t) and overflows near 14 s
    # (709 / 50, less the local errors' own size). The execution stops there, with no switch at
    # a nan time after it.
    code, out, err = run_cli(
        capsys,
        "stochastic",
        "grazing",
        "--samples",
        "1",
        "--set",
        "robot.parameters.omega=50",
        "--set",
        "stochastic.h=0.01",
        "--set",
        "stochastic.t_final=20",
        "--json",
    )
    assert code == 3
    s = json.loads(out)
    assert s["statuses"] == {"bound_overflow": 1}
    t_overflow = float(re.search(r"overflowed at t=([0-9.]+)", err).group(1))
    # e^(50 t) overflows at 709 / 50 = 14.2 s after the visit's start, less ln(1 / B0) / 50 for
    # a first local error B0 between 1e-15 and 1 (0.7 .. 0 s), plus the visit's start (< 0.5 s).
    assert 13.0 < t_overflow < 14.7
    assert all(sw["max"] < t_overflow for sw in s["switching_times"])
    # Long before it overflows the ball is wider than the circle itself (measured from 0.14 s:
    # e^(50 t) times rk4's local errors at h = 0.01), which the run says as a warning, with when.
    unresolved = s["unresolved"]
    assert unresolved["executions"] == 1 and 0.0 < unresolved["earliest"] < t_overflow
    assert f"the earliest at t={unresolved['earliest']:.6g} s" in err and "wider than the state" in err
