"""Benchmarks: work-precision sweeps against the baselines, and the integrator's overhead.

``run_case(name, quick=..., out=...)`` runs one work-precision case (``CASE_NAMES``) and
returns its rows, Pareto front and targets' verdicts (``legsim.bench.targets``: MET, MISSED or
NOT COMPARABLE); ``legsim bench work-precision`` is its command.
``legsim.bench.overhead`` measures the integrator's cost per step beyond the model's own.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .cases import BenchError, Case, RunSpec, Target, make_case
    from .names import CASE_NAMES
    from .rows import COLUMNS, Row
    from .targets import MET, MISSED, NOT_COMPARABLE, TargetResult, evaluate_targets, extend_baselines, format_targets
    from .work_precision import BenchResult, mark_pareto, run_case

# Each name is imported from its module on first use: the command line imports
# ``legsim.bench.names`` at every start, which would otherwise import every bench with it.
_HOMES = {
    **dict.fromkeys(("BenchError", "Case", "RunSpec", "Target", "make_case"), ".cases"),
    "CASE_NAMES": ".names",
    **dict.fromkeys(
        ("MET", "MISSED", "NOT_COMPARABLE", "TargetResult", "evaluate_targets", "extend_baselines", "format_targets"),
        ".targets",
    ),
    **dict.fromkeys(("COLUMNS", "Row"), ".rows"),
    **dict.fromkeys(("BenchResult", "mark_pareto", "run_case"), ".work_precision"),
}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(home, __name__), name)


__all__ = [
    "CASE_NAMES",
    "COLUMNS",
    "MET",
    "MISSED",
    "NOT_COMPARABLE",
    "BenchError",
    "BenchResult",
    "Case",
    "Row",
    "RunSpec",
    "Target",
    "TargetResult",
    "evaluate_targets",
    "extend_baselines",
    "format_targets",
    "make_case",
    "mark_pareto",
    "run_case",
]
