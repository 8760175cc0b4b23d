"""The stress suite's table (``legsim stress`` prints it): one row per case with its outcome,
cost and the invariants it checked, then every failed check spelled out."""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence

from ..tables import Table, render_report
from .framework import CaseResult, Check
from .invariants import GENERIC


def format_table(results: Sequence[CaseResult], width: int | None = None) -> str:
    """The table ``legsim stress`` prints, as text: long cells wrap within ``width`` characters
    where their words allow (None: one line per row), then the failures spelled out."""
    return render_report(report(results, width), "text", width)[0]


def report(results: Sequence[CaseResult], width: int | None = None) -> list[str | Table]:
    """``legsim stress``'s report (``legsim.tables.render_report``): one row per case with its
    outcome, cost and invariants, then notes: the invariants' letters, the count passed and
    every failed check, each note wrapped to ``width`` characters (None: not wrapped)."""
    header = ("case", "outcome", "trans.", "steps", "wall s", "invariants checked", "verdict")
    rows = [
        (
            r.name,
            r.outcome,
            str(r.transitions),
            str(r.steps),
            f"{r.wall_time:.2f}",
            invariant_summary(r.checks),
            "pass" if r.passed else "FAIL",
        )
        for r in results
    ]
    failed = [r for r in results if not r.passed]
    notes = [
        "invariants: "
        + ", ".join(f"{k} {v}" for k, v in GENERIC.items())
        + "; then the case's own checks (see --json for all of them with their numbers)",
        f"{len(results) - len(failed)} of {len(results)} cases passed",
    ]
    notes += [f"FAIL {r.name}: {f}" for r in failed for f in r.failures]
    if width is not None:
        notes = [
            textwrap.fill(note, width, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)
            for note in notes
        ]
    table = Table.of(header, rows, right=(2, 3, 4), whole=(0, 2, 3, 4, 6), title="stress cases")
    return [table, "", *notes]


def invariant_summary(checks: Sequence[Check]) -> str:
    """``SFTDREB + own checks``: the execution invariants by letter, then the case's own."""
    names = list(dict.fromkeys(c.name for c in checks))
    letters = "".join(
        k for k, v in GENERIC.items() if any(n == v or (k == "E" and n.startswith("energy ")) for n in names)
    )
    own = [n for n in names if n not in GENERIC.values() and not n.startswith("energy ")]
    # drop a run's label, "converges (d = 1e-06)" -> "converges"; keep "eq. (31)"
    own = list(dict.fromkeys(re.sub(r" \((?=[^()]*[=#])[^()]*\)$", "", n) for n in own))
    return letters + (" + " + "; ".join(own) if own else "")
