"""Compiled step loops: a mode's flow between guards run by a numba kernel.

A mode may carry a *compiled twin* (``Mode(..., compiled=CompiledMode(...))``, see ``twin``).
When the run has no control (compiled twins take none), lands by halving or aiming, and no guard
depends on (t, u), the relaxed loop hands each visit of the mode to the kernel (``visit``). The
kernel (``kernel``) is plain Python compiled by numba, calling the same decision rules as the
Python loop (``legsim.relaxed.rules``), generated and cached per twin (``generate``). Both paths
give the same execution, to the bit for the built-in methods but DOP853 (whose long rows the
Python stepper combines by matrix products: the same steps and transitions, to rounding).
A kernel evaluates all guards of a mode at once and counts ``n_guards`` guard evaluations per
call, where the Python loop counts one per guard it calls (the same count for one guard).
"""

from . import jit as _jit  # registers the compiled loop with legsim.relaxed
from .jit import model_function
from .generate import cache_dir, get_kernel, plan_for
from .twin import CompiledMode, without_compiled
from .visit import enter_compiled, run_visit_compiled

__all__ = [
    "CompiledMode",
    "cache_dir",
    "enter_compiled",
    "get_kernel",
    "plan_for",
    "run_visit_compiled",
    "model_function",
    "without_compiled",
]
