"""The stress suite's framework: a case passes only with checks and without a crash, a crash
is reported rather than raised, and cases are selected by name, group or part of a name."""

import pytest

from legsim import stress


def test_a_case_passes_only_with_checks_and_without_a_crash():
    r = stress.CaseResult("x", "zeno")
    assert not r.passed and r.failures == ["no invariant was checked"]
    r.add(stress.Check("a", True))
    assert r.passed
    r.error = "RuntimeError: boom"
    assert not r.passed and "crashed: RuntimeError: boom" in r.failures


def test_a_crashing_case_is_reported_not_raised(scratch_cases):
    @stress.case("crashing_case", "extremes", "raises")
    def _crash(result, quick):
        raise RuntimeError("boom")

    (result,) = stress.run_suite(True, ["crashing_case"])
    assert not result.passed and result.error == "RuntimeError: boom"
    table = stress.format_table([result])
    assert "FAIL" in table and "FAIL crashing_case: crashed: RuntimeError: boom" in table


def test_a_case_needs_a_known_group():
    with pytest.raises(ValueError, match="unknown group"):
        stress.case("x", "nogroup", "")


@pytest.mark.parametrize("group", ["zeno", "grazing", "simultaneous", "resting", "extremes"])
def test_every_group_has_cases(group):
    assert stress.select([group]), group


def test_select_by_exact_name_then_group_then_part_of_a_name():
    # an exact name selects that case only, not the cases whose names contain it
    assert [c.name for c in stress.select(["zeno_ball_c0.8"])] == ["zeno_ball_c0.8"]
    assert {c.group for c in stress.select(["grazing"])} == {"grazing"}
    assert [c.name for c in stress.select(["double_pendulum"])] == [
        "zeno_double_pendulum_c0.5",
        "zeno_double_pendulum_c0.5_continued",
        "zeno_double_pendulum_c0.5_converges",
    ]
    # in group order whatever the order asked for
    assert [c.group for c in stress.select(["extreme_corner", "zeno_two_tanks"])] == ["zeno", "extremes"]
    assert stress.select(["no_such_case"]) == []
