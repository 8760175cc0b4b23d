"""One bench run's results as rows (a CSV row each) and the questions asked of them: the
fastest run of a kind within an error level, and a run's label."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

#: CSV columns, in order.
COLUMNS = (
    "case",
    "method",
    "kind",
    "h",
    "eps",
    "tol",
    "max_step",
    "landing",
    "error",
    "rho",
    "wall_s",
    "repeats",
    "steps",
    "halvings",
    "field_evals",
    "guard_evals",
    "transitions",
    "status",
    "pareto",
)


@dataclass
class Row:
    """One run's results (a CSV row)."""

    case: str
    method: str
    kind: str
    h: float
    eps: float
    tol: float
    max_step: float
    landing: str
    error: float
    rho: float
    wall_s: float
    repeats: int
    steps: int
    halvings: int
    field_evals: int
    guard_evals: int
    transitions: int
    status: str
    pareto: int = 0


def time_to_reach(rows: Iterable[Row], level: float, kind: str) -> Row | None:
    """The fastest run of ``kind`` with error <= level, or None."""
    ok = [r for r in rows if r.kind == kind and r.error <= level]
    return min(ok, key=lambda r: r.wall_s) if ok else None


def run_label(r: Row) -> str:
    """The run's method and settings, e.g. ``ps h=5e-06`` or ``solve_ivp-DOP853 tol=1e-08 max_step=0.05``."""
    parts = [r.method]
    if math.isfinite(r.h):
        parts.append(f"h={r.h:g}")
    if math.isfinite(r.eps):
        parts.append(f"eps={r.eps:g}")
    if math.isfinite(r.tol):
        parts.append(f"tol={r.tol:g}")
    if math.isfinite(r.max_step):
        parts.append(f"max_step={r.max_step:g}")
    return " ".join(parts)
