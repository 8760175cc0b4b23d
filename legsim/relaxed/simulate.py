"""``simulate``: check the arguments, turn them into the integrator's parts, run the loop."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..arguments import count, positive
from ..control import Bound, ControlLaw, bind
from ..errors import ContractError, LegsimError, ModelError, SimulationError
from ..execution import Execution, RunSoFar
from ..hybrid import HybridSystem
from ..methods import Tableau, get_method
from ..methods.builtin import ADAPTIVE_DEFAULTS, SCIPY_NAMES
from .adapt import input_entries
from .driver import Options, drive
from .parts import Aim, Dense, ErrorControl, FixedStep, Halve
from .resolution import state_scale, strip_at_scale
from .watches import check as check_watches

#: Landing rules of ``simulate(landing=...)``.
LANDINGS = ("halve", "aim", "dense")

#: Default step budget. A run stores every step (t, x, dx), so steps bound its memory and time:
#: 1e7 steps of an 8-dimensional robot are ~1.4 GB and minutes of Python. A run that means to be
#: longer raises it.
MAX_STEPS = 10_000_000


def simulate(
    system: HybridSystem,
    x0: Any,
    mode: str,
    t_final: float,
    h: float,
    eps: float,
    method: str | Tableau = "rk4",
    control: Any = None,
    *,
    t0: float = 0.0,
    max_transitions: int = 100_000,
    max_halvings: int = 64,
    progress: Callable[[float, float, float], None] | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    landing: str | Halve | Aim | Dense = "halve",
    step_size: FixedStep | ErrorControl | None = None,
    max_steps: int = MAX_STEPS,
    continuation: bool = True,
    zeno_window: float | None = None,
    t_eval: Any = None,
    python: bool = False,
    watches: Any = (),
    until: Callable[[RunSoFar], bool] | None = None,
) -> Execution:
    """Simulate ``system`` from ``(mode, x0)`` at time ``t0`` to ``t_final`` with the relaxed
    hybrid integrator.

    Parameters
    ----------
    system: the hybrid system.
    x0: initial state, shape (n_mode,); it must lie in the relaxed domain of ``mode``.
    mode: initial mode name.
    t_final: end time (s), > t0.
    h: nominal step size (s), > 0; each step starts from h and is shortened as needed. With
        error control, the initial and largest step.
    eps: strip width (guard units), > 0.
    method: a Runge-Kutta method name (``euler``, ``rk2``, ``heun``, ``rk4``, ``bs32``,
        ``dopri5``, ``dop853``; case-insensitive) or a ``Tableau``. scipy's spellings ``"RK45"``,
        ``"RK23"`` and ``"DOP853"`` imply error control as in ``solve_ivp``: without rtol/atol
        they take scipy's defaults, rtol = 1e-3, atol = 1e-6.
    control: optional ``control(t, x) -> u``, evaluated at every stage, or a
        ``legsim.control.Controller`` (told the mode, reset at every mode entry, and evaluated at
        every stage or held over each step); u is passed to the fields as their third argument
        (None without control).
    t0: start time (s).
    max_transitions: transition budget; reaching it ends the run with status
        ``max_transitions``.
    max_halvings: most halvings of one step before the run ends with ``halving_exhausted``.
    progress: optional ``progress(t, t0, t_final)`` called about five times a second.
    rtol, atol: with either given, the step size inside modes is error-controlled by the
        method's embedded pair (``bs32``, ``dopri5`` or ``dop853``), h being the initial and
        largest step (unlike solve_ivp, h always caps the step: it is also the step the relaxed
        landing starts from); the guards keep their relaxed treatment (a step that would leave
        the relaxed domain is shortened until it lands inside it). Without them every step starts
        from h. One given alone sets the other to a thousandth of it.
    landing: how a step that would leave the relaxed domain is shortened: ``"halve"`` (paper 000
        Fig. 12, step 3); ``"aim"``, which retries with the step length at which the failed
        step's own interpolant reaches the middle of the strip (at most three aims, then
        halving); or ``"dense"`` (methods with a continuous extension: bs32, dopri5, dop853, a
        ``Tableau`` with ``dense``), which lands on the failed step's own dense output once it
        passes the error test, so no step is retried (aiming as a fallback). Or the rule as an
        object (``legsim.relaxed.Halve()``, ``Aim()``, ``Dense()``); any other is refused by name.
    step_size: a step-size rule object (``legsim.relaxed.FixedStep()`` or
        ``ErrorControl(rtol, atol)``) instead of h's fixed steps or rtol/atol; h still gives the
        largest step. Any other object is refused by name.
    max_steps: step budget (default ``MAX_STEPS``, 1e7): a run whose nominal steps
        (t_final - t0) / h exceed it is refused before it starts, and one that takes that many
        accepted steps (error control may take more than nominal) ends with status ``max_steps``.
    continuation: when the crossings of a transition accumulate (a Zeno point ahead), take the
        ``Continuation`` the transition names (an impact's rest in its constrained mode), as the
        bridge's contacts and stops and the analytic ball and oscillator declare; False keeps the
        plain relaxed semantics. Either way an accumulation without continuation is reported in
        ``Execution.warnings``.
    zeno_window: flights (s) between crossings of one transition shorter than this, and shrinking,
        count as accumulating (``legsim.relaxed.zeno``); default h + eps.
    python: run the loop as plain Python, the model's and controller's compiled functions too
        (their ``py_func``), instead of the compiled kernel: the same source step by step, to
        read or debug (slower). A model calling the native library needs its compiled functions.
    t_eval: optional times (s), increasing, in [t0, t_final]: the execution's mode and state
        there, in ``Execution.evaluated`` (a ``Samples``; the cubic Hermite interpolant of the
        steps, the held point inside strips). Times past the end of a run that stopped early are
        left out.
    watches: conditions on the run's states, checked at its stored points and the middle of each
        step (``legsim.relaxed.Watch``): a fall that ends the run (status ``fell``), a state
        reported by a warning, a time measured into a counter (``legsim.relaxed.watches``).
    until: optional ``until(so_far) -> bool`` on the run computed so far (a
        ``legsim.execution.RunSoFar``), asked each time the loop hands its points back (at most
        every ``STOP_CHECK_STEPS`` steps or transitions): once true, the run ends there with
        status ``finished``, a message saying so, and ``t_end`` the time reached. Its execution
        is then the beginning of the run to t_final, every point but its last one as that run's
        (a return map ends its runs soon after their return this way).

    Returns
    -------
    Execution
        with ``status`` one of ``finished``, ``max_transitions``, ``max_steps``,
        ``halving_exhausted``, ``non_finite``, ``reset_outside_domain``, ``model_breakdown``,
        ``stalled``, ``fell`` (a stop watch) and a message naming mode, time and state.

    Raises
    ------
    SimulationError
        for invalid arguments (h, eps, t_final, x0, mode, method, control, landing, tolerances).
    ModelError
        when the model's field, guard or reset misbehaves on the initial state.
    """
    if not isinstance(system, HybridSystem):
        raise SimulationError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    h, eps = positive("h", h), positive("eps", eps)
    t0, t_final = _times(t0, t_final, h)
    tableau = get_method(method)
    if method in SCIPY_NAMES and rtol is None and atol is None and step_size is None:
        rtol, atol = ADAPTIVE_DEFAULTS
    law = control if isinstance(control, ControlLaw) else None
    control = None if law is not None else _bound_control(control)
    rule = _step_rule(step_size, tableau, h, rtol, atol)
    _check_flags(continuation=continuation, python=python)
    options = Options(
        tableau=tableau,
        h=h,
        eps=eps,
        landing=landing_part(landing, tableau),
        rtol=rule[0],
        atol=rule[1],
        t0=t0,
        t_final=t_final,
        max_transitions=count("max_transitions", max_transitions, 0),
        max_halvings=count("max_halvings", max_halvings, 1),
        max_steps=_check_step_budget(max_steps, t0, t_final, h),
        continuation=bool(continuation),
        zeno_window=h + eps if zeno_window is None else positive("zeno_window", zeno_window),
        hold=law.hold if law is not None else isinstance(control, Bound) and control.hold,
        progress=_check_progress(progress),
        python=bool(python),
        watches=check_watches(watches),
        until=_check_until(until),
    )
    return _run(system, mode, x0, control, law, options, _eval_times(t_eval, t0, t_final))


def _run(
    system: HybridSystem, mode: str, x0: Any, control: Any, law: ControlLaw | None, options: Options,
    times: np.ndarray | None,
) -> Execution:  # fmt: skip
    """The run of checked arguments from (mode, x0), sampled at ``times`` (s) when given. It
    holds the system's turn: the model may keep scratch of its own (a robot's Pinocchio data),
    so runs of one system take turns."""
    with system.turn():
        x, memory = _initial_state(system, mode, x0, options.t0, options.eps, control, law)
        execution = drive(system, mode, x, control, law, options, memory)
    if times is not None:
        execution.evaluated = execution.sample(times[times <= execution.t_end])
    return execution


def _check_progress(progress: Any) -> Any:
    """``progress`` itself: a callable progress(t, t0, t_final), or None."""
    if progress is not None and not callable(progress):
        raise SimulationError(
            f"progress must be callable progress(t, t0, t_final) or None, got {type(progress).__name__} {progress!r}"
        )
    return progress


def _check_until(until: Any) -> Any:
    """``until`` itself: a callable until(so_far) -> bool, or None."""
    if until is not None and not callable(until):
        raise SimulationError(f"until must be callable until(so_far) -> bool or None, got {type(until).__name__}")
    return until


def _check_flags(**flags: Any) -> None:
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise SimulationError(f"{name} must be True or False, got {type(value).__name__} {value!r}")


def _step_rule(
    step_size: Any, tableau: Tableau, h: float, rtol: float | None, atol: float | None
) -> tuple[float | None, float | None]:
    """(rtol, atol) of the run's step-size rule, given as a rule object or as tolerances (not
    both: one of them would be dropped)."""
    if step_size is None:
        return step_size_rule(tableau, h, rtol, atol)
    if rtol is not None or atol is not None:
        raise SimulationError(
            f"give either step_size or rtol/atol, not both (got step_size={step_size!r}, rtol={rtol!r}, atol={atol!r})"
        )
    return _step_size_part(step_size, tableau, h)


def _bound_control(control: Any) -> Any:
    """What the loop calls as ``u(t, x)``: the control itself, or a Controller bound to the mode."""
    if control is not None and not callable(control):
        raise SimulationError(
            f"control must be callable control(t, x) -> u or None, got {type(control).__name__}; "
            f"a legsim.control.Controller also does"
        )
    return bind(control)


def landing_part(landing: Any, tableau: Tableau) -> str:
    """The name of the landing rule ``landing`` names (or of the built-in rule object given);
    the loop runs the built-in rules only, so any other object is refused by name."""
    if isinstance(landing, str):
        if landing not in LANDINGS:
            raise SimulationError(f"landing must be one of {', '.join(map(repr, LANDINGS))}, got {landing!r}")
        name = landing
    elif type(landing) in (Halve, Aim, Dense):
        name = landing.name
    else:
        raise SimulationError(
            f"landing {type(landing).__name__} is not one of the loop's landing rules: give 'halve', 'aim' or "
            f"'dense' (or legsim.relaxed.Halve(), Aim(), Dense()); the loop runs no other rule"
        )
    if name == "dense" and tableau.dense is None:
        raise SimulationError(
            f"landing 'dense' needs a method with a continuous extension (bs32, dopri5, dop853, or a Tableau with "
            f"dense output); method '{tableau.name}' has none: use landing 'aim'"
        )
    return name


def _step_size_part(rule: Any, tableau: Tableau, h: float) -> tuple[float | None, float | None]:
    """(rtol, atol) of a built-in step-size rule object ((None, None): fixed steps); any other
    object is refused by name."""
    if type(rule) is FixedStep:
        return None, None
    if type(rule) is ErrorControl:
        if rule.rtol is None and rule.atol is None:  # would mean fixed steps: say FixedStep()
            raise SimulationError(
                f"step_size {rule!r} gives no tolerance: error control needs rtol or atol (for fixed steps give "
                f"FixedStep())"
            )
        return step_size_rule(tableau, h, rule.rtol, rule.atol)
    raise SimulationError(
        f"step_size {type(rule).__name__} is not one of the loop's step-size rules: give h (fixed steps) or "
        f"rtol/atol (error control), or legsim.relaxed.FixedStep() or ErrorControl(rtol, atol)"
    )


def step_size_rule(
    tableau: Tableau, h: float, rtol: float | None, atol: float | None
) -> tuple[float | None, float | None]:
    """(rtol, atol) of error control when rtol or atol is given (the other then a thousandth of
    it); (None, None): fixed steps of h."""
    if rtol is None and atol is None:
        return None, None
    if not tableau.embedded:
        raise SimulationError(
            f"rtol/atol need a method with an embedded error estimate (bs32, dopri5, dop853), got '{tableau.name}'"
        )
    if tableau.error_order is None:
        raise SimulationError(
            f"method '{tableau.name}' has an embedded error estimate but no error_order: "
            f"error control needs it for its step exponent"
        )
    if rtol is None:  # atol given
        atol = positive("atol", atol)
        return 1e-3 * atol, atol
    rtol = positive("rtol", rtol)
    atol = 1e-3 * rtol if atol is None else positive("atol", atol)
    return rtol, atol


def _number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float, np.floating, np.integer))


def _times(t0: Any, t_final: Any, h: float) -> tuple[float, float]:
    if not _number(t0) or not math.isfinite(t0):
        raise SimulationError(f"t0 must be a finite number, got {t0!r}")
    if not _number(t_final):
        raise SimulationError(f"t_final must be a number, got {type(t_final).__name__} {t_final!r}")
    t0, t_final = float(t0), float(t_final)
    if not math.isfinite(t_final) or t_final <= t0:
        raise SimulationError(f"t_final must be finite and > t0 = {t0}, got {t_final}")
    scale = max(abs(t0), abs(t_final))
    if scale + h == scale:
        raise SimulationError(
            f"h = {h:g} s is below the time resolution at t = {scale:g} s (float64 times are "
            f"{float(np.spacing(scale)):.3g} s apart there): no step could advance time; shift t0 towards 0 or raise h"
        )
    return t0, t_final


def _eval_times(t_eval: Any, t0: float, t_final: float) -> np.ndarray | None:
    if t_eval is None:
        return None
    try:
        times = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SimulationError(f"t_eval must be a sequence of times (s): {exc}") from exc
    if times.ndim > 1:
        raise SimulationError(f"t_eval must be a sequence of times (s), got an array of shape {times.shape}")
    times = times.reshape(-1)
    if times.size and (
        not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0) or times[0] < t0 or times[-1] > t_final
    ):
        raise SimulationError(f"t_eval must be finite, strictly increasing times in [t0, t_final] = [{t0}, {t_final}]")
    return times


def _check_step_budget(max_steps: Any, t0: float, t_final: float, h: float) -> int:
    budget = count("max_steps", max_steps, 1)
    nominal = (t_final - t0) / h
    if nominal > budget:
        raise SimulationError(
            f"t_final - t0 = {t_final - t0:g} s at h = {h:g} s is {nominal:.3g} steps, more than "
            f"max_steps = {budget}; every step is stored, so check t_final and h, or raise "
            f"max_steps if the run is meant to be that long"
        )
    return budget


def _initial_state(
    system: HybridSystem, mode: Any, x0: Any, t0: float, eps: float, control: Any, law: ControlLaw | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """(the plant's state, the controller's memory or None for its initial one) from x0: the
    plant's state, or with a controller that keeps memory the plant's state followed by the
    memory. The plant's state is checked finite and in the relaxed domain, with the mode's field,
    guards and resets evaluated once on it."""
    if not isinstance(mode, str) or not _is_mode(system, mode):
        raise SimulationError(f"unknown initial mode {mode!r}; modes: {sorted(system.modes)}")
    dim = system.mode(mode).dim
    memory_names = _memory_names(control, law)
    try:
        x = np.array(x0, dtype=float).reshape(-1) if np.ndim(x0) <= 1 else None
    except (TypeError, ValueError) as exc:
        raise SimulationError(f"x0 must be a numeric vector of length {dim} for mode '{mode}': {exc}") from exc
    if x is None or x.shape not in ((dim,), (dim + len(memory_names),)):
        extra = f", or ({dim + len(memory_names)},) with the controller's memory {memory_names}" if memory_names else ""
        raise SimulationError(
            f"x0 has shape {np.shape(x0)}, expected ({dim},){extra} for mode '{mode}' "
            f"with coordinates {system.state_names(mode)}"
        )
    scale = state_scale(x)  # nan or inf where x is not finite
    if not math.isfinite(scale):
        raise SimulationError(f"x0 must be finite, got {x} in mode '{mode}'")
    x, memory = (x[:dim], x[dim:]) if x.shape[0] > dim else (x, None)
    _check_resolution(eps, state_scale(x) if memory is not None else scale, mode)
    u0 = _initial_input(system, mode, t0, x, control, law, memory)
    _check_outputs_once(system, mode, x, t0, u0, control)
    gvals = system.guard_values(mode, x, t0, u0)
    if gvals.size and gvals.min() < -eps:
        worst = int(np.argmin(gvals))
        raise SimulationError(
            f"x0 lies past the guard of transition {system.outgoing(mode)[worst].name} by "
            f"{-gvals[worst]:.3g} > eps = {eps:g} (guard units); start inside the domain of '{mode}'"
        )
    return x, memory


def _check_outputs_once(system: HybridSystem, mode: str, x: np.ndarray, t0: float, u0: Any, control: Any) -> None:
    """``system.check_state`` on the initial state: the mode's field, guards and resets evaluated
    once, so that a model's type and shape errors name their mode or transition before the run.
    Done on the first run of a system in a mode under a controller, whose functions do not
    change; every later run's state is still checked finite, of the mode's shape and in its
    domain (``_initial_state``)."""
    checked: dict[str, Any] = system.run_scratch.setdefault("outputs_checked", {})
    if mode in checked and checked[mode] is control:
        return
    system.check_state(mode, x, t=t0, u=u0, label="x0")
    checked[mode] = control


def _check_resolution(eps: float, scale: float, mode: str) -> None:
    """Refuse a strip thinner than float64 can resolve at the initial state's scale (its
    ``state_scale``): no step could land in it, and the run would only crawl towards the first
    guard."""
    thinnest = strip_at_scale(scale)
    if eps < thinnest:
        raise SimulationError(
            f"eps = {eps:g} is thinner than float64 resolves at the scale of the initial state in mode '{mode}' "
            f"(|x| up to {scale - 1.0:.3g}, values {float(np.spacing(scale)):.3g} apart there): no step could land "
            f"in a strip; give eps >= {thinnest:.3g} in guard units"
        )


def _memory_names(control: Any, law: ControlLaw | None) -> tuple[str, ...]:
    """The memory entries a run's state ends with: a ``ControlLaw``'s."""
    return () if law is None else law.memory_names


def _initial_input(
    system: HybridSystem,
    mode: str,
    t0: float,
    x: np.ndarray,
    control: Any,
    law: ControlLaw | None,
    memory: np.ndarray | None,
) -> Any:
    """The control at (t0, x0), before the controller enters the mode (the run enters it when it
    starts)."""
    try:
        if law is not None:
            return law.input_at(mode, t0, x, memory)
        if isinstance(control, Bound):
            value = control.controller(mode, t0, x)
        else:
            value = None if control is None else control(t0, x)
    except LegsimError:
        raise
    except Exception as exc:
        raise SimulationError(f"control(t0, x0) failed at t0={t0}: {type(exc).__name__}: {exc}") from exc
    functions = system.mode(mode).functions
    if functions is not None and functions.inputs and (value is not None or control is not None):
        try:
            input_entries(value, functions.inputs, control)
        except ContractError as exc:
            raise ModelError(f"{system.name}: {exc} (mode '{mode}', t0={t0})") from exc
    return value


def _is_mode(system: HybridSystem, mode: str) -> bool:
    try:
        system.mode(mode)
    except ModelError:
        return False
    return True
