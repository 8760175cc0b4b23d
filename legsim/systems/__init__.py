"""Analytic benchmark systems, each with an exact (closed-form) reference execution.

=====================  ================================================================
module                 system
=====================  ================================================================
``bouncing_ball``      ball on a floor with restitution: closed-form impacts, Zeno time
``oscillator``         forced linear oscillator with a stop (paper 000 Sec. V-B, Table I):
                       exact solution between impacts, sticking, Zeno accumulation
``digital_control``    two thresholds, four modes, simultaneous crossing (paper 000 Fig. 1)
=====================  ================================================================

Each module exposes ``make_system(**params) -> HybridSystem``, a reference class whose
``sample(times)`` returns ``legsim.execution.Samples`` like ``Execution.sample`` (so a metric
can compare a run with it) and whose ``with_initial(mode, x, t0)`` re-targets it to another
initial state, and ``BUILDER`` (a ``legsim.builders.Builder``) for scenes. Modules are imported
on demand, so importing ``legsim.systems`` costs nothing.
"""

__all__ = ["bouncing_ball", "digital_control", "oscillator"]
