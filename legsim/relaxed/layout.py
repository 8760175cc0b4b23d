"""Where the step loop keeps everything, by name: the one module that declares the slots of its
arrays (``legsim.relaxed.loop``).

The loop is written once, as plain Python over arrays and scalars, so that the same source runs
interpreted (a model of Python callables) and compiled by numba (a model of compiled functions,
``legsim.compiled``). Its state therefore lives in a few flat arrays rather than in objects, and
each array's slots are named here: a slot is a module-level integer, which numba reads as a
constant. Every argument list of the loop is built from the records of ``legsim.relaxed.tables``
and ``legsim.relaxed.workspace``, whose fields are the arrays below.

Units: times and step sizes in s, guard values in each guard's own units (eps in the same).
"""

from __future__ import annotations

# -- settings of a run (``Workspace.cf``, floats; ``Workspace.ci``, integers) ------------------
#: t_final (s), the largest step h (s), the strip width eps (guard units), the tolerances of
#: error control, the step-size exponent -1/(order + 1), the Zeno window (s), the start time (s).
S_T_FINAL, S_H_MAX, S_EPS, S_RTOL, S_ATOL, S_EXPONENT, S_WINDOW, S_T0 = range(8)
FLOAT_SETTINGS = 8
#: Error control on (1) or fixed steps (0); the landing rule (``LAND_*``); the budgets; whether a
#: transition's continuation is taken when its crossings accumulate; whether the control is held
#: over each step (zero-order hold); the controller's memory size; the most steps before the loop
#: hands back to report progress (0: never).
(
    S_ADAPTIVE,
    S_LANDING,
    S_MAX_HALVINGS,
    S_MAX_STEPS,
    S_MAX_TRANSITIONS,
    S_CONTINUES,
    S_HOLD,
    S_MEMORY,
    S_PROGRESS_STEPS,
) = range(9)
INT_SETTINGS = 9
LAND_HALVE, LAND_AIM, LAND_DENSE = range(3)

# -- the run's state (``Workspace.fs``, floats; ``Workspace.iv``, integers) ----------------------
#: The time of the current point (s); the step proposal carried to the next step (s); the time
#: held in strips so far (s); the length of the last trial step (s); the landing step's end (s),
#: its length (s) and, for a landing on a dense output, the fraction of the step it ends at; the
#: fraction s of q on the landing's curve when the landing rule located it; the time at the start of
#: the current stall window (``loop.STALL_WINDOW``).
F_T, F_H_PROP, F_STRIP_TIME, F_H_TRIED, F_LAND_T1, F_LAND_H, F_LAND_THETA, F_LAND_S, F_STALL_T = range(9)
FLOAT_STATE = 9
#: What the loop does next (``PHASE_*``); the current mode (a row of the mode table); the
#: counters (``COUNTERS`` names them for the execution); the points, transitions and visits
#: stored in the output buffers so far; the step counter at the last progress report; why the
#: run ended (``END_*``) and the transition or guard a message names; the source of the last
#: transition (-1 before the first); 1 when a model function said the state is past the model's
#: range (a Python model's ModelBreakdown); the landing step's curve (``CURVE_*``), the guard
#: whose crossing the landing rule located (-1: not located) and whether that search converged;
#: the halvings a step that ended the run took; the transition counter at the last progress report;
#: the steps and crossings in the current stall window; the accepted steps since a linearly implicit
#: method's Jacobian was evaluated (-1: it must be evaluated before the next step).
(
    I_PHASE,
    I_MODE,
    I_STEPS,
    I_HALVINGS,
    I_REJECTIONS,
    I_FIELD_EVALS,
    I_GUARD_EVALS,
    I_RESET_EVALS,
    I_TRANSITIONS,
    I_POINTS,
    I_RECORDS,
    I_VISITS,
    I_REPORTED,
    I_END,
    I_END_INDEX,
    I_LAST_SOURCE,
    I_BREAKDOWN,
    I_LAND_CURVE,
    I_LAND_E,
    I_LAND_CONVERGED,
    I_END_COUNT,
    I_REPORTED_TRANSITIONS,
    I_STALL_COUNT,
    I_JACOBIAN_AGE,
) = range(24)
INT_STATE = 24
#: The curve of a landing step: the cubic Hermite interpolant of its ends, or the method's
#: continuous extension (``F_LAND_THETA`` of the step); ``I_LAND_E`` >= 0 when q is located.
CURVE_HERMITE, CURVE_DENSE = range(2)
#: Counters the execution reports, by slot.
COUNTERS = (
    ("steps", I_STEPS),
    ("halvings", I_HALVINGS),
    ("error_rejections", I_REJECTIONS),
    ("field_evals", I_FIELD_EVALS),
    ("guard_evals", I_GUARD_EVALS),
    ("reset_evals", I_RESET_EVALS),
)

#: Phases: enter mode ``I_MODE`` at (F_T, x); step inside it; the run has ended.
PHASE_ENTER, PHASE_STEP, PHASE_ENDED = range(3)

#: Why the loop handed back to its driver: the run ended (``I_END`` says how); the mode to
#: enter has no row yet; an output buffer is full; a progress report is due.
RETURN_ENDED, RETURN_NEED_MODE, RETURN_FULL, RETURN_PROGRESS = range(4)

#: How a run ended (the driver turns each into an ``execution.Status`` and a message).
(
    END_FINISHED,
    END_MAX_TRANSITIONS,
    END_MAX_STEPS,
    END_HALVING_EXHAUSTED,
    END_NON_FINITE_STEP,
    END_BROKE_DOWN,
    END_GUARD_NAN,
    END_FIELD_AT_ENTRY,
    END_GUARD_AT_ENTRY,
    END_RESET_OUTSIDE,
    END_RESET_NON_FINITE,
    END_RESET_BROKE_DOWN,
    END_STALLED,
) = range(13)

# -- the mode table (``Tables.modes``, integers, one row per mode) ------------------------------
#: The plant's state dimension; the number of outgoing transitions (guards); the model functions
#: of the mode (indices into ``Tables.functions``; -1: none); the mode's parameters
#: ``P[M_P0:M_P1]`` and the controller's ``P[M_C0:M_C1]``; its first row in the transition
#: table; its joint outcomes (``Tables.joints`` rows ``M_J0 .. M_J0 + M_NJ``); whether its
#: transitions' targets have rows (1) or the driver must build them first (0); the row of the
#: Zeno history of its joint crossings; whether a nan from its functions means the state is past
#: the model's range (1: the step is shortened, as for a Python model's ModelBreakdown) or is
#: an error (0: a nan guard ends the run); whether its crossings are resolved with the input
#: applied after them (``ModeFunctions.previewed``); whether a guard that jumps past its strip
#: is crossed where it jumps (``ModeFunctions.crosses_jumps``).
(
    M_DIM,
    M_GUARDS,
    M_FIELD,
    M_GUARD_FN,
    M_RESET,
    M_JOINT,
    M_CONTROL,
    M_ENTER,
    M_P0,
    M_P1,
    M_C0,
    M_C1,
    M_T0,
    M_J0,
    M_NJ,
    M_READY,
    M_JOINT_HISTORY,
    M_NAN_BREAKS,
    M_PREVIEWED,
    M_CROSSES_JUMPS,
) = range(20)
MODE_FIELDS = 20

# -- the transition table (``Tables.transitions``, integers, one row per transition) -------------
#: The target mode's row; the continuation's target row (``NO_CONTINUATION`` when there is none).
T_TARGET, T_CONTINUATION = range(2)
TRANSITION_FIELDS = 2
NO_CONTINUATION = -1
#: The joint outcome table (``Tables.joints``): the target mode's row.
J_TARGET = 0
JOINT_FIELDS = 1

# -- the Zeno histories (``Workspace.history``, floats, one row per transition and per joint key) --
#: 1 once the transition was crossed (and not continued since); when its last crossing left the
#: strip (s); the flight that ended there (s).
H_SEEN, H_LAST_EXIT, H_FLIGHT = range(3)
HISTORY_FIELDS = 3

# -- the records of crossings (``Workspace.rec_f`` floats, ``rec_i`` integers, one row each) ----
#: Entry into the strip (s); the end of the step that landed there (s); the strip's exit (s);
#: the landing's depth tau (guard units).
R_TIME, R_LANDING, R_EXIT, R_DEPTH = range(4)
RECORD_FLOATS = 4
#: The source mode's row; the transition's index among its outgoing ones; the target's row; the
#: kind (``KIND_*``); the joint outcome (-1 otherwise); whether its crossings accumulate; the
#: state lengths before and after; the first two self-transitions crossed in the same step (-1:
#: fewer), whose order the driver checks (``simultaneous``); whether it has a continuation.
(
    R_SOURCE,
    R_INDEX,
    R_TARGET,
    R_KIND,
    R_JOINT,
    R_ACCUMULATES,
    R_DIM_BEFORE,
    R_DIM_AFTER,
    R_ORDER_A,
    R_ORDER_B,
    R_HAS_CONTINUATION,
) = range(11)
RECORD_INTS = 11
#: A transition; its continuation; a joint crossing; the strip of a run that ended inside it
#: (no reset: its exit is the run's end); a joint crossing resolved by its continuation (every
#: striker plastic, as its crossings accumulate).
KIND_PLAIN, KIND_CONTINUED, KIND_JOINT, KIND_CUT, KIND_JOINT_CONTINUED = range(5)

# -- the visits (``Workspace.visits``, integers, one row per mode visit) -------------------------
#: The mode's row; the first of its points in the point buffer.
V_MODE, V_FIRST = range(2)
VISIT_FIELDS = 2
