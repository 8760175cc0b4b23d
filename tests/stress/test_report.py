"""The stress suite's table: the invariants by letter, the case's own checks without their run
labels, and every failed check spelled out under the table."""

from legsim import stress


def _checks(*names, passed=True):
    return [stress.Check(n, passed) for n in names]


def test_invariant_summary_letters_then_own_checks_without_run_labels():
    checks = _checks(
        "status",
        "finite",
        "time increasing",
        "in relaxed domain",
        "resets in target domain",
        "energy non-increasing",
        "transition bound",
        "converges (d = 1e-06)",
        "converges (d = 0)",
        "released where eq. (31) changes sign",
    )
    assert stress.invariant_summary(checks) == "SFTDREB + converges; released where eq. (31) changes sign"
    assert stress.invariant_summary(_checks("status", "finite")) == "SF"


def test_table_has_a_row_per_case_and_spells_out_failures():
    good = stress.CaseResult("good_case", "zeno", outcome="finished", transitions=3, steps=40, wall_time=0.5)
    good.add(_checks("status", "finite"))
    bad = stress.CaseResult("bad_case", "extremes", outcome="x" * 100)
    bad.add(stress.Check("impossible", False, "1 > 2"))
    lines = stress.format_table([good, bad], width=200).splitlines()
    assert lines[0].split() == ["case", "outcome", "trans.", "steps", "wall", "s", "invariants", "checked", "verdict"]
    row = next(line for line in lines if line.startswith("good_case"))
    assert row.split()[-6:] == ["finished", "3", "40", "0.50", "SF", "pass"]
    assert "x" * 100 in next(line for line in lines if line.startswith("bad_case"))  # a long outcome whole
    assert "1 of 2 cases passed" in lines and "FAIL bad_case: impossible: 1 > 2" in lines


def test_a_narrow_table_wraps_its_cells_at_spaces_and_keeps_every_character():
    # Long cells wrap inside their column at spaces: nothing is cut, no word is broken, and no
    # line is wider than asked unless the names, numbers and longest words need more.
    from helpers.tables import read_cells

    outcome = "diverged: " + " ".join(f"word{k}" for k in range(30)) + " " + "y" * 70
    results = []
    for name, text in (("first_case_with_a_long_name", outcome), ("second", "finished")):
        r = stress.CaseResult(name, "extremes", outcome=text, transitions=12345, steps=678901, wall_time=12.3456)
        r.add(
            _checks(
                "status",
                "finite",
                "time increasing",
                "converges (d = 1e-06)",
                "released where eq. (31) changes sign",
                "a check whose name is long enough to wrap",
            )
        )
        r.add(stress.Check("impossible", False, "the error 3.2e-4 is over the bound 1e-4 " * 4))
        results.append(r)
    for width in (60, 80, 100):
        text = stress.format_table(results, width=width)
        least = stress.report(results)[0].least_width()
        assert max(len(line) for line in text.splitlines()) <= max(width, least), text
        words = {word for r in results for cell in (r.name, r.outcome, *r.failures) for word in cell.split()}
        assert words <= set(text.split()), words - set(text.split())
        header, rows = read_cells(text, 7, key=6)
        assert header == ["case", "outcome", "trans.", "steps", "walls", "invariantschecked", "verdict"]
        expected = [
            [
                "".join(cell.split())
                for cell in (
                    r.name,
                    r.outcome,
                    str(r.transitions),
                    str(r.steps),
                    f"{r.wall_time:.2f}",
                    stress.invariant_summary(r.checks),
                    "FAIL",
                )
            ]
            for r in results
        ]
        assert rows == expected, text
        assert "..." not in text and "".join(text.split()).count("FAILfirst_case") == 1
