"""The fuzzers' outcome counts, printed after a run (the table of docs/reliability.md).

Run without xdist to see them: each worker of ``-n 2`` counts its own share and the
controller, which prints the summary, ran none."""

from helpers.reliability import OUTCOMES, outcome_table


def pytest_terminal_summary(terminalreporter):
    if OUTCOMES:
        terminalreporter.section("reliability fuzzers: outcomes")
        terminalreporter.write_line(outcome_table())
