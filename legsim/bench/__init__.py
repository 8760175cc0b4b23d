"""Benchmarks: work-precision sweeps against the baselines, and the integrator's overhead.

``run_case(name, quick=..., out=...)`` runs one work-precision case (``CASE_NAMES``) and
returns its rows, Pareto front and targets; ``legsim bench work-precision`` is its command.
``legsim.bench.overhead`` measures the integrator's cost per step beyond the model's own.
"""

from .cases import CASE_NAMES, BenchError, Case, RunSpec, Target, make_case
from .work_precision import COLUMNS, BenchResult, Row, evaluate_targets, mark_pareto, run_case

__all__ = ["CASE_NAMES", "COLUMNS", "BenchError", "BenchResult", "Case", "Row", "RunSpec", "Target",
           "evaluate_targets", "make_case", "mark_pareto", "run_case"]
