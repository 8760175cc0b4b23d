"""Benchmarks: work-precision sweeps against the baselines, and the integrator's overhead.

``run_case(name, quick=..., out=...)`` runs one work-precision case (``CASE_NAMES``) and
returns its rows, Pareto front and targets' verdicts (``legsim.bench.targets``: MET, MISSED or
NOT COMPARABLE); ``legsim bench work-precision`` is its command.
``legsim.bench.overhead`` measures the integrator's cost per step beyond the model's own.
"""

from .cases import CASE_NAMES, BenchError, Case, RunSpec, Target, make_case
from .targets import MET, MISSED, NOT_COMPARABLE, TargetResult, evaluate_targets, extend_baselines, format_targets
from .work_precision import COLUMNS, BenchResult, Row, mark_pareto, run_case

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
