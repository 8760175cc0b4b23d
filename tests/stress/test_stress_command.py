"""``legsim stress``: table, JSON, selection, exit codes."""

import json

from legsim import stress
from legsim.cli import main


def test_json_lists_name_and_passed_and_exits_zero_when_all_pass(capsys):
    code = main(["stress", "--quick", "--json", "--case", "extreme_on_guard", "--case", "resting_ball_c0"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert [r["name"] for r in out] == ["resting_ball_c0", "extreme_on_guard"]  # group order
    for r in out:
        assert r["passed"] is True and r["transitions"] >= 2 and r["steps"] > 0 and r["wall_time_s"] > 0
        assert {"status", "finite", "time increasing", "in relaxed domain"} <= set(r["invariants"])
        assert all(c["passed"] for c in r["checks"])


def test_table_names_the_failed_check_and_exits_one(capsys, scratch_cases):
    @stress.case("always_failing", "extremes", "a check that cannot hold")
    def _fails(result, quick):
        result.add(stress.Check("impossible", False, "1 > 2"))

    code = main(["stress", "--quick", "--case", "always_failing"])
    out = capsys.readouterr().out
    assert code == 1
    assert "always_failing" in out and "FAIL" in out and "FAIL always_failing: impossible: 1 > 2" in out
    assert "0 of 1 cases passed" in out


def test_list_and_unknown_selection(capsys):
    assert main(["stress", "--list", "--case", "zeno"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert listed and all(" zeno " in line for line in listed)
    assert main(["stress", "--case", "no_such_case"]) == 2
    err = capsys.readouterr().err
    assert "no stress case matches ['no_such_case']" in err and "zeno_ball_c0.5" in err
