"""The stress suite's table: the invariants by letter, the case's own checks without their run
labels, and every failed check spelled out under the table."""

from legsim import stress


def _checks(*names, passed=True):
    return [stress.Check(n, passed) for n in names]


def test_invariant_summary_letters_then_own_checks_without_run_labels():
    checks = _checks("status", "finite", "time increasing", "in relaxed domain", "resets in target domain",
                     "energy non-increasing", "transition bound", "converges (d = 1e-06)", "converges (d = 0)",
                     "released where eq. (31) changes sign")
    assert stress.invariant_summary(checks) == "SFTDREB + converges; released where eq. (31) changes sign"
    assert stress.invariant_summary(_checks("status", "finite")) == "SF"


def test_table_has_a_row_per_case_and_spells_out_failures():
    good = stress.CaseResult("good_case", "zeno", outcome="finished", transitions=3, steps=40, wall_time=0.5)
    good.add(_checks("status", "finite"))
    bad = stress.CaseResult("bad_case", "extremes", outcome="x" * 100)
    bad.add(stress.Check("impossible", False, "1 > 2"))
    lines = stress.format_table([good, bad]).splitlines()
    assert lines[0].split() == ["case", "outcome", "trans.", "steps", "wall", "s", "invariants", "checked",
                                "verdict"]
    row = next(line for line in lines if line.startswith("good_case"))
    assert row.split()[-6:] == ["finished", "3", "40", "0.50", "SF", "pass"]
    assert "..." in next(line for line in lines if line.startswith("bad_case"))  # a long outcome is cut
    assert "1 of 2 cases passed" in lines and "FAIL bad_case: impossible: 1 > 2" in lines
