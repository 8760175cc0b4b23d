"""`legsim run` reports what a run cannot vouch for: the execution's warnings (an accumulation
without continuation, a long strip hold) as a `warnings` list in `--json` and one
`warning: ...` line each in the printed summary."""

from __future__ import annotations

import json

from legsim.cli import main
from legsim.scene import load_scene


def test_an_accumulation_without_continuation_reaches_the_json_and_the_summary(capsys):
    # The paper's relaxed execution of the ball: past its Zeno time it is held in the strip.
    argv = ["run", "bouncing_ball", "--set", "integrator.continuation=false"]
    assert main([*argv, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    direct = load_scene("bouncing_ball", overrides=["integrator.continuation=false"]).simulate()
    (warning,) = summary["warnings"]
    assert warning == json.loads(json.dumps(direct.warnings[0].as_dict()))
    assert warning["kind"] == "accumulation" and warning["transition"] == "bounce"
    # it began at the crossing from which its transitions are counted
    assert warning["time"] == direct.transitions[len(direct.transitions) - warning["transitions_since"]].time
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    printed = [line for line in lines if line.startswith("warning: ")]
    assert printed == [f"warning: {warning['message']}"]
    assert "transition bounce in mode 'flight' accumulates from t=1.35738 s" in printed[0]


def test_a_run_that_vouches_for_its_result_prints_no_warning(capsys):
    # By default the ball rests where its bounces accumulate: nothing to warn of.
    assert main(["run", "bouncing_ball", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == []
    assert main(["run", "bouncing_ball"]) == 0
    assert "warning:" not in capsys.readouterr().out


def test_a_long_strip_hold_is_printed_too(capsys):
    # The paper's eps = 1e-2 m: the pronk's eight strips hold the state for 3% of its 2 s.
    assert main(["run", "pronk_paper"]) == 0
    printed = [line for line in capsys.readouterr().out.splitlines() if line.startswith("warning: ")]
    assert len(printed) == 1 and "held in strips for" in printed[0] and "smaller eps" in printed[0]
