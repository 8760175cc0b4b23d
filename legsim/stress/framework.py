"""The stress suite's framework: what a case reports (``Check``, ``CaseResult``), the registry of
cases (``Case``, ``CASES``, the ``case`` decorator) and running them (``select``, ``run_suite``).

A case is a function ``fn(result, quick)`` that runs its system and adds its checks to the
``CaseResult`` it is given; registering it with ``@case(name, group, description)`` wraps it so
that a crash becomes a failed case with its reason rather than a crashed suite.
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..execution import Execution


@dataclass
class Check:
    """One invariant checked on a case: its name, whether it held, and the numbers behind it."""

    name: str
    passed: bool
    detail: str = ""

    def __post_init__(self) -> None:
        self.passed = bool(self.passed)  # numpy booleans are not JSON


@dataclass
class CaseResult:
    """What one case did and what was checked.

    Attributes
    ----------
    name, group: the case's name and group (zeno, grazing, simultaneous, resting, extremes).
    outcome: one line saying what happened (status, final mode, the behaviour of interest).
    transitions, steps: of the case's main run.
    wall_time: seconds for the whole case (all its runs and checks).
    checks: the invariants checked; the case passes when all hold and it did not crash.
    numbers: measured numbers worth reporting (errors, drifts, costs), or their text where a
        number alone does not say it (a list of errors per step size, a crash's traceback).
    error: the exception text when the case itself crashed.
    """

    name: str
    group: str
    outcome: str = ""
    transitions: int = 0
    steps: int = 0
    wall_time: float = 0.0
    checks: list[Check] = field(default_factory=list)
    numbers: dict[str, float | str] = field(default_factory=dict)
    error: str | None = None

    @property
    def passed(self) -> bool:
        return self.error is None and bool(self.checks) and all(c.passed for c in self.checks)

    @property
    def failures(self) -> list[str]:
        """Descriptions of what failed (empty when the case passed)."""
        out = [f"{c.name}: {c.detail}" for c in self.checks if not c.passed]
        if self.error is not None:
            out.append(f"crashed: {self.error}")
        if not self.checks and self.error is None:
            out.append("no invariant was checked")
        return out

    def add(self, check: Check | Iterable[Check]) -> None:
        if isinstance(check, Check):
            self.checks.append(check)
        else:
            self.checks.extend(check)

    def main_run(self, ex: Execution) -> None:
        """Record the transitions and steps of the case's main run."""
        self.transitions = len(ex.transitions)
        self.steps = ex.steps

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``legsim stress --json``)."""
        return {
            "name": self.name,
            "group": self.group,
            "passed": self.passed,
            "outcome": self.outcome,
            "transitions": self.transitions,
            "steps": self.steps,
            "wall_time_s": self.wall_time,
            "invariants": [c.name for c in self.checks],
            "checks": [{"name": c.name, "passed": c.passed, "detail": c.detail} for c in self.checks],
            "numbers": {k: _json_number(v) for k, v in self.numbers.items()},
            "error": self.error,
        }


def _json_number(v: Any) -> Any:
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    v = float(v)
    return v if math.isfinite(v) else str(v)


@dataclass(frozen=True)
class Case:
    """A stress case: ``run(quick) -> CaseResult``."""

    name: str
    group: str
    description: str
    run: Callable[[bool], CaseResult]


CASES: list[Case] = []
GROUPS = ("zeno", "grazing", "simultaneous", "resting", "extremes")


def case(name: str, group: str, description: str):
    """Register a case function ``fn(result, quick)`` that fills the given result."""
    if group not in GROUPS:
        raise ValueError(f"unknown group {group!r}")

    def register(fn: Callable[[CaseResult, bool], None]) -> Callable[[CaseResult, bool], None]:
        def run(quick: bool) -> CaseResult:
            result = CaseResult(name, group)
            start = time.perf_counter()
            try:
                fn(result, quick)
            except Exception as exc:  # a crash is a failed case with its reason, not a crashed suite
                result.error = f"{type(exc).__name__}: {exc}"
                result.numbers["traceback"] = traceback.format_exc(limit=3)[-600:]
            result.wall_time = time.perf_counter() - start
            return result

        CASES.append(Case(name, group, description, run))
        return fn

    return register


def select(names: Sequence[str] | None = None) -> list[Case]:
    """The cases named by ``names`` (all cases when None or empty), in group order: a name
    selects the case of that exact name, else the group of that name, else every case whose name
    contains it."""
    ordered = sorted(CASES, key=lambda c: GROUPS.index(c.group))  # stable: registration order within a group
    if not names:
        return ordered

    def matches(n: str, c: Case) -> bool:
        if any(n == other.name for other in CASES):
            return n == c.name
        if n in GROUPS:
            return n == c.group
        return n in c.name

    return [c for c in ordered if any(matches(n, c) for n in names)]


def run_suite(
    quick: bool = True, names: Sequence[str] | None = None, progress: Callable[[Case, CaseResult], None] | None = None
) -> list[CaseResult]:
    """Run the selected cases (quick or full form) in order; ``progress(case, result)`` after each."""
    out = []
    for c in select(names):
        result = c.run(quick)
        out.append(result)
        if progress is not None:
            progress(c, result)
    return out
