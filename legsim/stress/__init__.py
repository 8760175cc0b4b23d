"""The stress suite: the hard cases of hybrid simulation, each run and checked against
invariants that can fail.

Hybrid simulators are known to fail on a short list of cases: they stall at Zeno points, miss or
double-count events where a trajectory grazes a guard, choose arbitrarily at simultaneous
impacts, chatter forever when a body comes to rest on a stop, and blow up with stiff springs.
Every case here runs one of them and checks what can go wrong:

* the **execution invariants** (``execution_checks``): finite states; time strictly increasing
  inside segments and never going back between pieces; every computed state inside the relaxed
  domain of its mode (no guard below -eps); every strip point in the relaxed domain of its source
  and every reset image in the relaxed domain of its target, equal to the reset of the strip
  point; the run reaching t_final (or the end the case expects);
* **energy**, where the system is conservative (drift bounded) or dissipative (never rising);
* a **bound on the number of transitions** that the case derives from the model (typically: every
  transition costs at least one accepted step, and no accepted step is shorter than the step
  that keeps a guard moving at its largest rate inside the strip), checked with the run's
  transition budget set above it, so that the budget never ends a run silently;
* the **qualitative outcome** (the ball rests on the floor after its Zeno time, the pendulum ends
  in its constrained mode, both feet land in the same step);
* **convergence** as h and eps shrink, against closed forms where there are some.

``CASES`` lists the cases (group, name, description); ``run_suite(quick=...)`` runs them and
returns ``CaseResult`` objects; ``format_table`` prints them as ``legsim stress`` does. The quick
form of every case is small enough for CI; the full form (``quick=False``) runs longer horizons
and more refinement levels. Robots are built through the ``legsim.builders`` entry points, so
this package never imports ``robots`` or Pinocchio itself.

======================  ======================================================================
module                  responsibility
======================  ======================================================================
``framework``           ``Check``, ``CaseResult``, ``Case``, the registry ``CASES`` and the
                        ``case`` decorator, ``select`` and ``run_suite``
``invariants``          the execution invariants every case checks, ``step_floor`` and
                        ``transition_floor`` (transition bounds), ``check_order`` (convergence),
                        ``check_accumulation`` (the run's accumulation warnings)
``report``              ``report`` and ``format_table``, the table ``legsim stress`` prints
``models``              the models the cases run (``build``, ``model_state``, ``lifted_ball``,
                        ``curved_floor_ball``)
``reference_checks``    checks against closed forms shared by several families (ball, tanks)
                        and where the accumulation rule continues the ball and the oscillator
``cases.zeno``          Zeno: the bouncing ball, the double pendulum, two tanks, the oscillator
``cases.continuation``  Zeno, past the accumulation: the curved-floor ball (no continuation:
                        a warning), the double pendulum converging with its continuation
``cases.grazing``       grazing: the circular flow near tangency
``cases.simultaneous``  simultaneous guards: the pronk, the digital controller
``cases.resting``       resting contact: the lifted ball
``cases.extremes``      extremes: eps, h, stiffness, horizon, starts on a guard or a corner
======================  ======================================================================
"""

from . import cases
from .cases.extremes import PAPER_SLIP_PSI, STABLE_PRONK, apex_heights, hop_period
from .cases.simultaneous import pair_checks
from .cases.zeno import flight_ratios, max_guard_accel, pressing_impact_bound, rho_hat
from .framework import CASES, GROUPS, Case, CaseResult, Check, case, run_suite, select
from .invariants import (
    GENERIC,
    check_accumulation,
    check_domain,
    check_energy,
    check_finite,
    check_order,
    check_resets,
    check_status,
    check_time,
    check_transition_bound,
    energies,
    execution_checks,
    first_accumulating_crossing,
    slope,
    step_floor,
    transition_floor,
)
from .models import build, curved_floor_ball, lifted_ball, model_state
from .reference_checks import (
    ball_flight_checks,
    ball_hold_check,
    ball_rest_check,
    ball_rest_crossing,
    oscillator_stick_sequence,
    tank_level_rate,
    tank_switch_checks,
)
from .report import format_table, invariant_summary, report

#: ``model_state`` under the name tests/test_property_runner.py calls it by.
_state = model_state

__all__ = [
    "CASES",
    "GENERIC",
    "GROUPS",
    "PAPER_SLIP_PSI",
    "STABLE_PRONK",
    "Case",
    "CaseResult",
    "Check",
    "apex_heights",
    "ball_flight_checks",
    "ball_hold_check",
    "ball_rest_check",
    "ball_rest_crossing",
    "build",
    "case",
    "cases",
    "check_accumulation",
    "check_domain",
    "check_energy",
    "check_finite",
    "check_order",
    "check_resets",
    "check_status",
    "check_time",
    "check_transition_bound",
    "curved_floor_ball",
    "energies",
    "execution_checks",
    "first_accumulating_crossing",
    "flight_ratios",
    "format_table",
    "hop_period",
    "invariant_summary",
    "lifted_ball",
    "max_guard_accel",
    "model_state",
    "oscillator_stick_sequence",
    "pair_checks",
    "pressing_impact_bound",
    "report",
    "rho_hat",
    "run_suite",
    "select",
    "slope",
    "step_floor",
    "tank_level_rate",
    "tank_switch_checks",
    "transition_floor",
]
