"""Runs that start from the tables an earlier run of the system left, against runs that build
their tables anew, interleaved in one process.

A run's tables (``legsim.relaxed.tables``: the modes it made ready, their transitions, functions
and parameters) stay on the system for its next run under the same law (``kept_tables``). This
script times the robot bench's short cases (``legsim bench robots``: the pronk of paper 000 over
2 s, the double pendulum with a stop of paper 003 over 5 s, the compass gait over 40 s) at one
setting each, dopri5 with dense landing, both ways: rounds alternate the two, each round's time is
the best of its runs, and the median over rounds is printed with the ratio (> 1: the kept tables
are faster). Print ``uptime`` beside the numbers.

    .venv/bin/python benchmarks/kept_tables.py [--rounds 20] [--runs 20]
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from collections.abc import Iterator
from typing import Any

from legsim.bench import robots
from legsim.bench.cases import RunSpec
from legsim.relaxed import driver
from legsim.relaxed.tables import RunTables, kept_tables

CASES = ("pronk", "double-pendulum", "compass-gait")
SPEC = RunSpec("relaxed", "relaxed-dopri5", 0.2, 1e-7, 1e-5, "dense")


@contextlib.contextmanager
def new_tables(system: Any, control: Any, law: Any) -> Iterator[RunTables]:
    """The baseline: every run builds its tables."""
    yield RunTables(system, control, law)


def best_of(call: Any, runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=20, help="alternating rounds (default 20)")
    parser.add_argument("--runs", type=int, default=20, help="runs a round, the best taken (default 20)")
    args = parser.parse_args()
    for name in CASES:
        case = robots.make_robot_case(name, quick=False)
        call = robots._relaxed_call(case, SPEC, robots._ControllerMaker(case))
        best_of(call, 5)  # compiled code loaded, tables kept once
        times: dict[str, list[float]] = {"new": [], "kept": []}
        for _ in range(args.rounds):
            for label, tables in (("new", new_tables), ("kept", kept_tables)):
                driver.kept_tables = tables
                times[label].append(best_of(call, args.runs))
        driver.kept_tables = kept_tables
        new, kept = statistics.median(times["new"]), statistics.median(times["kept"])
        timing = f"new tables {1e3 * new:.3f} ms, kept {1e3 * kept:.3f} ms, ratio {new / kept:.3g}"
        print(f"{name} ({case.description}): {timing}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
