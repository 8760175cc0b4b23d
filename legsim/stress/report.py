"""The stress suite's table (``legsim stress`` prints it): one row per case with its outcome,
cost and the invariants it checked, then every failed check spelled out."""

from __future__ import annotations

import re
from typing import Sequence

from .framework import CaseResult, Check
from .invariants import GENERIC


def format_table(results: Sequence[CaseResult]) -> str:
    """The table ``legsim stress`` prints: one row per case, then the failures spelled out."""
    header = ("case", "outcome", "trans.", "steps", "wall s", "invariants checked", "verdict")
    rows = []
    for r in results:
        rows.append((r.name, r.outcome, str(r.transitions), str(r.steps), f"{r.wall_time:.2f}",
                     invariant_summary(r.checks), "pass" if r.passed else "FAIL"))
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(header)]
    widths[1] = min(widths[1], 64)
    widths[5] = min(widths[5], 64)

    def line(cells):
        out = []
        for i, cell in enumerate(cells):
            text = cell if len(cell) <= widths[i] else cell[:widths[i] - 3] + "..."
            out.append(text.rjust(widths[i]) if i in (2, 3, 4) else text.ljust(widths[i]))
        return "  ".join(out).rstrip()

    lines = [line(header), line(["-" * w for w in widths])]
    lines.extend(line(row) for row in rows)
    failed = [r for r in results if not r.passed]
    lines.append("")
    lines.append("invariants: " + ", ".join(f"{k} {v}" for k, v in GENERIC.items())
                 + "; then the case's own checks (see --json for all of them with their numbers)")
    lines.append(f"{len(results) - len(failed)} of {len(results)} cases passed")
    for r in failed:
        for f in r.failures:
            lines.append(f"FAIL {r.name}: {f}")
    return "\n".join(lines)


def invariant_summary(checks: Sequence[Check]) -> str:
    """``SFTDREB + own checks``: the execution invariants by letter, then the case's own."""
    names = list(dict.fromkeys(c.name for c in checks))
    letters = "".join(k for k, v in GENERIC.items()
                      if any(n == v or (k == "E" and n.startswith("energy ")) for n in names))
    own = [n for n in names if n not in GENERIC.values() and not n.startswith("energy ")]
    # drop a run's label, "converges (d = 1e-06)" -> "converges"; keep "eq. (31)"
    own = list(dict.fromkeys(re.sub(r" \((?=[^()]*[=#])[^()]*\)$", "", n) for n in own))
    return letters + (" + " + "; ".join(own) if own else "")
