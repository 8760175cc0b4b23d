"""The relaxed hybrid integrator's loop (paper 000, Fig. 12; paper 003, Definition 14 for Euler).

Each guard is thickened into a strip ``-eps <= guard < 0``. Inside a mode any Runge-Kutta method
takes steps; a trial step that would leave the relaxed domain is shortened until it lands in it;
a step that lands in a strip crosses it: q is located on the step's interpolant, the state held
there for the rest of the strip, eps - tau, and the reset applied at q::

    while t < t_final:
        trial = step(t, x, h)                       # method, step-size rule
        while trial leaves the relaxed domain:      # landing rule: halve | aim | dense
            trial = shorten(trial)
        if trial lands in a strip:                  # strip: locate q, hold eps - tau, reset at q
            mode, x, t = cross(trial)
        else:
            t, x = trial.t1, trial.x1

The parts are small objects with one interface each: the method's stepper (``methods``), the
step-size rule (``step_size``), the landing rule (``landing``), the strip crossing (``strip``)
and mode entry (``entry``); the numeric decisions they share with the compiled kernel are the
functions of ``rules``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from math import isfinite
from typing import Any

import numpy as np

from ..control import Bound
from ..errors import ContractError, LegsimError, ModelBreakdown, ModelError
from ..execution import Execution, Status
from ..hybrid import ModeData
from ..methods.stepper import field_value
from . import messages
from .entry import enter_mode
from .outcomes import NOT_REACHED, Ended, Entered, Landing, Outcome, Trial
from .rules import finish_tolerance, shortening_exhausted, trial_length
from .run import PROGRESS_STEPS, ModeVisit, Run
from .strip import cross_landing, hermite_landing


def integrate(run: Run, mode: str, x: np.ndarray, t: float) -> Execution:
    """Run from (mode, x) at time t to ``run.t_final``, or until the run ends otherwise."""
    outcome: Outcome = Entered(mode, x, t)
    while isinstance(outcome, Entered):
        mode, x, t = outcome.mode, outcome.x, outcome.t
        try:
            if not outcome.python_entry and run.control is None and runs_compiled(run, run.system.mode_data(mode)):
                from ..compiled import enter_compiled  # numba is imported only by systems that use it

                outcome = enter_compiled(run, mode, x, t)
                continue
            visit = enter_mode(run, mode, x, t)
            outcome = visit if not isinstance(visit, ModeVisit) else run_visit(run, visit)
        except ModelBreakdown as exc:  # raised while entering a mode or crossing a strip
            outcome = Ended(Status.MODEL_BREAKDOWN, f"{exc} (mode '{mode}', t={t:.17g})", t)
        except ContractError as exc:
            raise ModelError(f"{run.system.name}: {exc} in mode '{mode}' entered at t={t:.17g}") from exc
    return run.execution(outcome)


def runs_compiled(run: Run, data: ModeData) -> bool:
    """Whether the compiled kernel runs this run's visits of the mode: the mode has a twin that
    computes the run's control (``control_writer``) and whose guards take x alone (or compute
    the control themselves), and the run lands without a dense extension (which the kernel
    does not evaluate). Without control its entries are the kernel's too
    (``compiled.enter_compiled``); with one, Python enters every mode, resetting the controller."""
    twin = data.mode.compiled
    if twin is None or run.landing.lands_on_extension or control_writer(run.control, twin) is None:
        return False
    return twin.controls is not None or all(tr.guard_args == "x" for tr in data.transitions)


def control_writer(control: Any, twin: Any) -> Callable[[np.ndarray], None] | None:
    """How the twin gets a run's ``control`` (as the run calls it: a ``Bound`` controller, a
    control function, or None) (``CompiledMode.controls``): a function that writes
    the control's values into the twin's parameters at each entry (doing nothing for a run
    without control and a twin without controls), or None when the twin cannot compute the
    run's control: a held controller (sampled once per step, which the kernel does not do), or
    a controller or control function the twin does not know."""
    if control is None:
        return _write_nothing if twin.controls is None else twin.controls(None)
    if twin.controls is None or (isinstance(control, Bound) and control.hold):
        return None
    source = control_source(control)
    try:
        return twin.controls(source)
    except LegsimError:
        raise
    except Exception as exc:  # a controller's compiled_record failed: name it, not a traceback
        raise ModelError(
            f"the compiled twin could not take the control {type(source).__name__}: {type(exc).__name__}: {exc}"
        ) from exc


def control_source(control: Any) -> Any:
    """What a twin computes for the run's ``control``: the bound controller's input source
    (``Controller.input_source``), or the plain control function itself."""
    return control.controller.input_source if isinstance(control, Bound) else control


def _write_nothing(params: np.ndarray) -> None:
    """The twin of a run without control has nothing to write."""


def run_visit(run: Run, visit: ModeVisit, *, python: bool = False) -> Outcome:
    """Step through one mode visit until a transition or the end of the run (with ``python``,
    in this loop even when the mode has a compiled twin)."""
    if not python and runs_compiled(run, visit.data):
        from ..compiled import run_visit_compiled  # numba is imported only by systems that use it

        return run_visit_compiled(run, visit)
    finish_tol = finish_tolerance(run.t_final)
    try:
        while True:
            remaining = run.t_final - visit.t
            if remaining <= finish_tol:
                return run.end_visit(visit, Ended(Status.FINISHED, "", run.t_final if remaining > 0 else visit.t))
            if run.steps >= run.max_steps:
                return run.end_visit(visit, out_of_steps(run, visit))
            step = take_step(run, visit, remaining)
            if type(step) is Trial:
                if step.gmin >= 0.0:
                    _advance(run, visit, step)
                    continue
                step = _landing(run, visit, step)
            if type(step) is Ended:
                return run.end_visit(visit, step)
            return cross_landing(run, visit, step)
    except ModelBreakdown as exc:
        return run.end_visit(
            visit, Ended(Status.MODEL_BREAKDOWN, messages.model_breakdown(exc, visit.name, visit.t), visit.t)
        )
    except ContractError as exc:
        raise ModelError(
            f"{run.system.name}: {exc} in the step from t={visit.t:.17g} in mode '{visit.name}' (x={visit.x.tolist()})"
        ) from exc
    except LegsimError:
        raise
    except Exception as exc:
        # A model's callable failed mid-run: name where, rather than leak a numpy traceback.
        raise ModelError(
            f"{run.system.name}: evaluating mode '{visit.name}' failed in the step from "
            f"t={visit.t:.17g} (x={visit.x.tolist()}): {type(exc).__name__}: {exc}"
        ) from exc


def take_step(run: Run, visit: ModeVisit, remaining: float) -> Trial | Landing | Ended:
    """One accepted step from the visit's point: a trial inside the relaxed domain (possibly in
    a strip), a landing on the step's own dense output, or the end of the run when no shortened
    step lands (the step's length: the step-size rule's, the landing rule's when it leaves the
    relaxed domain)."""
    step_size, landing = run.step_size, run.landing
    hk = trial_length(step_size.h_prop, step_size.h_max, remaining)
    last = hk == remaining
    shortened = aims = broke = 0
    rejected = False
    while True:
        trial = _attempt(run, visit, hk, last)
        if trial.failure is None:
            if trial.gmin != trial.gmin:
                bad = messages.first_nonfinite(visit.guard_values(trial.t1, trial.x1))
                assert bad is not None, "gmin is nan: one of the guards is"
                return Ended(
                    Status.NON_FINITE,
                    messages.nan_guard(visit.name, visit.t + hk, trial.x1, visit.data.transitions[bad].name),
                    visit.t,
                )
            inside = trial.gmin >= -run.eps
            if inside or (landing.lands_on_extension and aims == 0):
                passed, hk_next = step_size.judge(hk, trial.stages, visit.x, trial.x1, rejected)
                if not passed:
                    run.error_rejections += 1
                    rejected, hk, last = True, hk_next, False
                    continue
                if inside:
                    step_size.keep(hk_next, shortened > 0, rejected)
                    run.halvings += shortened
                    run.steps += 1
                    return trial
                landed = landing.land(run, visit, trial)
                if isinstance(landed, Landing):
                    step_size.keep(hk_next, shortened > 0, rejected)
                    run.halvings += shortened + 1
                    run.steps += 1
                    return landed
                aims, shortened, hk, last = aims + 1, shortened + 1, landed * hk, False
                continue
        shortened += 1
        broke += trial.failure == "model_breakdown"
        if trial.failure is None:
            hk, aimed = landing.retry(run, visit, trial, aims)
            aims += aimed
        else:
            hk *= 0.5
        last = False
        if shortening_exhausted(shortened, run.max_halvings, visit.t, hk, broke):
            run.halvings += shortened
            return _exhausted(run, visit, trial, shortened)


def _attempt(run: Run, visit: ModeVisit, hk: float, last: bool) -> Trial:
    """A trial step of length hk and its guard values; a step whose state is not finite, or
    whose stages leave the model's range (ModelBreakdown: a runner's hip through the ground), has
    left the relaxed domain like one past a strip and is marked so, to be shortened."""
    t = visit.t
    t1 = run.t_final if last else t + hk
    run.field_evals += run.evals_per_step  # counted first: a trial that breaks down made at most these
    try:
        x1, stages = run.stepper(visit.field, t, visit.x, hk, visit.k0, run.control)
        # Exact and warning-free (a sum of squares would overflow for finite states above ~1e154).
        if not all(map(isfinite, x1.tolist())):
            return Trial(hk, t1, x1, failure="non_finite")
        single = visit.single_guard
        if single is not None:
            run.guard_evals += 1
            return Trial(hk, t1, x1, stages, None, float(single(t1, x1)))
        if not visit.guards:
            return Trial(hk, t1, x1, stages, [], 0.0)
        gvals = visit.guard_values(t1, x1)
        run.guard_evals += len(gvals)
        gmin = min(gvals)
        if gmin == gmin and math.isnan(sum(gvals)):
            gmin = math.nan  # min() keeps a nan only when it comes first
        return Trial(hk, t1, x1, stages, gvals, gmin)
    except ModelBreakdown as exc:
        return Trial(hk, t1, NOT_REACHED, failure="model_breakdown", breakdown=exc)


def _exhausted(run: Run, visit: ModeVisit, trial: Trial, shortened: int) -> Ended:
    """The end of a run whose step could not be shortened into the relaxed domain, by why the
    last trial left it."""
    t, x, name = visit.t, visit.x, visit.name
    if trial.failure == "non_finite":
        return Ended(Status.NON_FINITE, messages.non_finite_step(name, t, x, trial.hk), t)
    if trial.failure == "model_breakdown":
        return Ended(Status.MODEL_BREAKDOWN, messages.model_breakdown(trial.breakdown, name, t, trial.hk), t)
    gvals = trial.guard_values()
    e = min(range(len(gvals)), key=gvals.__getitem__)
    message = messages.halving_exhausted(name, t, x, shortened - 1, visit.data.transitions[e].name, run.eps)
    return Ended(Status.HALVING_EXHAUSTED, message, t)


def out_of_steps(run: Run, visit: ModeVisit) -> Ended:
    """The end of a run that used up its step budget."""
    return Ended(
        Status.MAX_STEPS,
        f"step budget max_steps={run.max_steps} used up at t={visit.t:.17g} in mode "
        f"'{visit.name}' (x={visit.x.tolist()})",
        visit.t,
    )


def _landing(run: Run, visit: ModeVisit, trial: Trial) -> Landing:
    """An accepted step that ended in a strip, with its cubic Hermite interpolant."""
    k1 = trial.stages[-1] if run.tableau.fsal else run.f(visit.field, trial.t1, trial.x1)
    return hermite_landing(visit.t, visit.x, visit.k0, trial.t1, trial.x1, k1, trial.guard_values())


def _advance(run: Run, visit: ModeVisit, trial: Trial) -> None:
    """Move the visit to the accepted step's end and store the point."""
    t, x = visit.t, visit.x = trial.t1, trial.x1
    visit.g_last = trial
    held = run.held_control
    if held is not None:  # a zero-order hold samples the controller at the step's start: f changes there
        held.step_from(t, x)
        k0 = run.f(visit.field, t, x)
    elif run.tableau.fsal:
        k0 = trial.stages[-1]
    else:
        run.field_evals += 1
        control = run.control
        k0 = visit.field(t, x, None if control is None else control(t, x))
        if k0.__class__ is not np.ndarray or k0.shape != x.shape:
            k0 = field_value(k0, x)
    visit.k0 = k0
    visit.buf.append(t, x, k0)
    if not run.steps & (PROGRESS_STEPS - 1):
        run.tick(t)
