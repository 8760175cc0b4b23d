"""``legsim bench robots``: the robots on the compiled path against ``solve_ivp`` with events.

Cases: the compass gait and the rimless wheel with Drake's default parameters (its examples'
``CompassGaitParams`` and ``RimlessWheelParams``), started on their limit cycles; the pronking
runner and the double pendulum with a plastic stop of the bundled scenes. The error of a run is
that of its transitions, as the issue measures it: the largest difference, over the
transitions, of the transition time (s) and of the post-impact state (the reset image, in the
state's units) to a reference run (``solve_ivp`` DOP853 with events at rtol = atol = 1e-12);
transitions at the same instant count as one event (``events``), and a run with another number
of events has error inf.

The families: ``relaxed`` runs on the compiled path (the robots' model functions in the kernel;
rk4 with aimed landing, dopri5 and dop853 with dense landing), ``relaxed-python`` the Python
path's best configuration before the kernel took dense landing (DOP853, dense landing), and
``solve_ivp`` (RK45 and DOP853 over tolerances and largest steps). For each error level the
fastest run of each family below it is compared; ratios are measured in one run, so they hold
on a shared machine to within its noise. ``cost_report`` gives the limit: a compiled field
evaluation all-in against a bare C++ ``aba`` on the same model, and the share of a run spent
outside it.

The controlled runners (``CONTROLLED``, run only when named: ``--case slip-raibert --case
pronk-raibert --case double-pendulum-pd --case quadruped-run``) are the bundled scenes' robots under
their scenes' controllers (``raibert_slip``, ``raibert_pronk``, the double pendulum's PD,
``raibert_runner``), every run with a controller made anew from the scene. Every robot and
controller is written as compiled model functions and ``ControlLaw``s
(``ControlledSweep.compiled``), so each case has the three families of the uncontrolled cases.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..builders import get_builder
from ..control import ControlLaw
from ..errors import LegsimError
from ..progress import counting
from ..tables import Table
from .cases import BenchError, RunSpec
from .names import ROBOT_CASES, ROBOT_CONTROLLED
from .rows import Row
from .work_precision import _timed, mark_pareto, plot_rows, rows_table, write_csv

CASES = ROBOT_CASES
CONTROLLED = ROBOT_CONTROLLED
ALL_CASES = CASES + CONTROLLED
LEVELS = (1e-4, 1e-6, 1e-8)
#: solve_ivp tolerance of the reference runs.
REFERENCE_TOL = 1e-12
#: Drake's example parameters: compass gait slope 0.0525 rad; rimless wheel 8 spokes, slope 0.08 rad.
DRAKE_COMPASS_SLOPE = 0.0525
DRAKE_RIMLESS = {"spokes": 8, "slope": 0.08}


@dataclass(frozen=True)
class ControlledSweep:
    """The knobs of a controlled case's sweep.

    scene: the bundled scene; t_final, t_quick: horizons (s) of the full and ``--quick`` runs;
    tols: rtol = atol of the error-controlled runs; h_largest: their initial and largest step
    (s); eps_floor: the narrowest strip of the adaptive runs (guard units; their strip is
    ``max(eps_floor, min(1e-6, 1e-2 tol))``); rk4_eps: the strip of the rk4 runs; rk4_steps:
    the fixed steps (s); max_repeats: a cap on the timed repeats (None: ``--repeats``);
    compiled: the scene's controller is a compiled ``ControlLaw``, so the rk4 and aimed runs take
    the compiled path (family ``relaxed``) and DOP853 with dense landing is the Python path's.
    """

    scene: str
    t_final: float
    t_quick: float
    tols: tuple[float, ...]
    h_largest: float
    eps_floor: float
    rk4_eps: float
    rk4_steps: tuple[float, ...]
    max_repeats: int | None = None
    compiled: bool = False


def _compiled_sweep(scene: str) -> ControlledSweep:
    """The sweep of a robot under a compiled scene controller: 5 s (1 s with
    ``--quick``), tolerances 1e-4 .. 1e-10 with steps up to 0.1 s and strips min(1e-6, 1e-2 tol)
    (no floor), rk4 at steps of 10 to 1 ms with a strip of 1e-10."""
    tols = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    return ControlledSweep(scene, 5.0, 1.0, tols, 0.1, 0.0, 1e-10, (1e-2, 5e-3, 2e-3, 1e-3), compiled=True)


#: The quadruped's case is one hop, to 0.45 s (touchdown, stance and liftoff, before the first
#: apex: docs/bench.md, "Why the quadruped runs one hop"). Its reset images sit past the force
#: guards by up to 1e-9 N of rounding (a strip of 1e-10 is crossed, 1e-9 holds them); the error
#: is then about 2 eps.
CONTROLLED_SWEEPS = {
    "slip-raibert": _compiled_sweep("slip_raibert"),
    # The pronk hopper and raibert_pronk are compiled model functions: 5 s, 16 hops.
    "pronk-raibert": _compiled_sweep("pronk_raibert"),
    # The double pendulum's shoulder PD (joint_pd, a ControlLaw): it lands on the stop
    # (a graze, then the impact that holds) and rests there.
    "double-pendulum-pd": _compiled_sweep("double_pendulum_pd"),
    "quadruped-run": ControlledSweep(
        "quadruped_run",
        0.45,
        0.2,
        (1e-4, 1e-6, 1e-8, 1e-10),
        0.02,
        1e-9,
        1e-8,
        (1e-3, 5e-4),
        max_repeats=1,
        compiled=True,
    ),
}


@dataclass
class RobotCase:
    """A robot, its start and horizon, and the reference its runs are measured against.

    new_control: makes the case's controller anew (a controller keeps state across
    transitions, so every run gets a fresh one); None for an uncontrolled case, whose runs take
    the compiled path. controlled: the ``ControlledSweep`` of a controlled case.
    """

    name: str
    description: str
    system: Any
    mode: str
    x0: np.ndarray
    t_final: float
    reference: Any
    new_control: Callable[[], Any] | None = None
    controlled: ControlledSweep | None = None
    #: ``bare_aba(q, v, tau, reps)``: seconds per bare C++ ABA call on the robot's model (its
    #: ``Model.info["bare_aba"]``), the floor of a field's cost; None when the robot gives none.
    bare_aba: Callable[..., float] | None = None

    def error(self, execution: Any) -> float:
        """Largest difference of event times (s) and post-event states to the reference's (inf
        when the runs have different numbers of events or a state of another size)."""
        if execution.status != "finished":
            return math.inf
        ours, ref = events(execution, self.system), events(self.reference, self.system)
        if len(ours) != len(ref):
            return math.inf
        worst = 0.0
        for (ta, xa), (tb, xb) in zip(ours, ref, strict=True):
            xa = xa[: xb.shape[0]]  # a ControlLaw's memory follows the plant's state in a relaxed run
            if xa.shape != xb.shape:
                return math.inf
            worst = max(worst, abs(ta - tb), float(np.max(np.abs(xa - xb))))
        return worst


#: Transitions closer in time than this (s) form one event: simultaneous ones (a release and a
#: graze, the pronk's two feet), which a relaxed run crosses one strip hold (about eps) apart
#: and rounding orders; the physical events of these cases are over 0.2 s apart.
EVENT_GAP = 1e-3


def events(execution: Any, system: Any = None) -> list[tuple[float, np.ndarray]]:
    """The execution's events: its transitions with the chains of simultaneous ones merged
    (``EVENT_GAP``), each as (time of its first transition, state after its last); with
    ``system``, the plant's state only (a controller's memory, which follows it in a relaxed
    run's states, left out)."""
    out: list[tuple[float, np.ndarray]] = []
    last = -math.inf
    for tr in execution.transitions:
        state = np.asarray(tr.state_after, dtype=float)
        if system is not None:
            state = state[: system.mode(tr.target).dim]
        if out and tr.time - last < EVENT_GAP:
            out[-1] = (out[-1][0], state)
        else:
            out.append((tr.time, state))
        last = tr.time
    return out


def _builder(name: str) -> Any:
    try:
        return get_builder(name)
    except LegsimError as exc:
        raise BenchError(f"robot {name} cannot be loaded ({exc}); install pinocchio (`pip install pin`)") from exc


def _on_limit_cycle(system: Any, x: np.ndarray, t: float) -> np.ndarray:
    """The post-impact state of a walker after t seconds from x (relaxed DOP853, tight
    tolerances): on the limit cycle to the contraction of the steps taken; foot_x set to 0."""
    from ..relaxed import simulate

    ex = simulate(system, x, "stance", t, 0.05, 1e-12, "dop853", rtol=1e-12, atol=1e-12, landing="aim")
    start = np.array(ex.transitions[-1].state_after, dtype=float)
    start[-1] = 0.0
    return start


def _walker(name: str, quick: bool) -> tuple[Any, np.ndarray, float, str]:
    """The walker's model (``legsim.builders.Model``), its state on the limit cycle, the horizon
    (s) and a description."""
    if name == "compass-gait":
        model = _builder("compass_gait").make({"slope": math.degrees(DRAKE_COMPASS_SLOPE)}, {})
        x0 = np.array([model.initial_state[n] for n in model.system.state_names("stance")])
        x0 = _on_limit_cycle(model.system, x0, 30.0)
        return model, x0, 10.0 if quick else 40.0, "compass gait, Drake's parameters (slope 0.0525 rad)"
    params = {"spokes": DRAKE_RIMLESS["spokes"], "slope": math.degrees(DRAKE_RIMLESS["slope"])}
    model = _builder("rimless_wheel").make(params, {})
    alpha = math.pi / params["spokes"]
    c = math.cos(2 * alpha)  # point mass: thetad+ = c thetad-
    k = 4 * 9.81 * math.sin(alpha) * math.sin(DRAKE_RIMLESS["slope"])
    x0 = np.array([-alpha, math.sqrt(c * c * k / (1 - c * c)), 0.0])  # the closed-form rolling cycle
    return model, x0, 10.0 if quick else 40.0, "rimless wheel, Drake's parameters (8 spokes, slope 0.08 rad)"


def _reference(name: str, system: Any, x0: np.ndarray, mode: str, t_final: float, control: Any) -> Any:
    """The reference run of case ``name``: solve_ivp DOP853 with events at ``REFERENCE_TOL``
    (largest step 0.02 s), under ``control`` (a fresh controller, or None); BenchError when it
    does not finish."""
    from ..baselines import simulate_events

    reference = simulate_events(
        system,
        x0,
        mode,
        t_final,
        method="DOP853",
        rtol=REFERENCE_TOL,
        atol=REFERENCE_TOL,
        control=control,
        max_step=0.02,
        max_transitions=100_000,
    )
    if reference.status != "finished":
        raise BenchError(f"case {name}: the reference run did not finish ({reference.status}: {reference.message})")
    return reference


def _controlled_case(name: str, quick: bool) -> RobotCase:
    """A controlled runner: its scene's robot, start and controller, and its reference run."""
    from ..scene import load_scene

    knobs = CONTROLLED_SWEEPS[name]
    try:
        scene = load_scene(knobs.scene)
    except LegsimError as exc:
        raise BenchError(f"case {name}: scene {knobs.scene} cannot be loaded ({exc})") from exc
    system, mode, x0 = scene.model.system, scene.initial_mode, scene.initial_state.copy()
    t_final = knobs.t_quick if quick else knobs.t_final
    reference = _reference(name, system, x0, mode, t_final, scene.control)
    # A [controller] section's, or the robot's own control (an effect such as the double pendulum's PD).
    controller = scene.data["controller"]["name"] if "controller" in scene.data else "(the robot's own)"
    description = f"scene {knobs.scene} under its controller {controller}, t in [0, {t_final:g}] s"

    def new_control() -> Any:
        return scene.control

    if knobs.compiled and not takes_compiled_path(system, new_control()):
        raise BenchError(
            f"case {name}: {system.name} under controller {controller} is not all compiled model functions (its "
            f"runs would take the Python path)"
        )
    return RobotCase(name, description, system, mode, x0, t_final, reference, new_control, knobs)


def takes_compiled_path(system: Any, control: Any) -> bool:
    """Whether runs of ``system`` under ``control`` take the compiled path: every mode built so
    far (a robot's bridge builds its modes as runs reach them) is written as compiled model
    functions, and the control is None or a compiled ``ControlLaw``."""

    if control is not None and not (isinstance(control, ControlLaw) and control.compiled):
        return False
    modes = [system.mode(name) for name in list(system.modes)]
    return all(mode.functions is not None and mode.functions.compiled for mode in modes)


def make_robot_case(name: str, quick: bool = False) -> RobotCase:
    """The case called ``name`` (one of ``ALL_CASES``) with its reference run."""
    if name in CONTROLLED:
        return _controlled_case(name, quick)
    if name in ("compass-gait", "rimless-wheel"):
        model, x0, t_final, description = _walker(name, quick)
        system, mode = model.system, "stance"
    elif name == "pronk":
        model = _builder("pronk").make()
        system, mode, t_final = model.system, model.initial_mode, 0.5 if quick else 2.0
        description = "pronking runner of paper 000 Sec. V-C"
    elif name == "double-pendulum":
        model = _builder("double_pendulum").make(None, {"gravity": True, "stop": {"restitution": 0.0}})
        system, mode, t_final = model.system, model.initial_mode, 1.0 if quick else 5.0
        description = "double pendulum with a plastic stop, paper 003 Fig. 2b"
    else:
        raise BenchError(f"unknown robot case {name!r}; choose one of {', '.join(ALL_CASES)}")
    if name in ("pronk", "double-pendulum"):
        x0 = np.array([model.initial_state[n] for n in system.state_names(mode)])
    reference = _reference(name, system, x0, mode, t_final, None)
    bare_aba = model.info.get("bare_aba")
    return RobotCase(
        name, f"{description}, t in [0, {t_final:g}] s", system, mode, x0, t_final, reference, bare_aba=bare_aba
    )


#: The largest steps (s) of the compiled error-controlled runs: at loose tolerances a walker's
#: swing (0.74 s for the compass gait) takes steps longer than 0.1 s.
LARGEST_STEPS = (0.1, 0.2)


def sweep(quick: bool) -> list[RunSpec]:
    """The runs of every case: compiled relaxed (rk4 over h with aimed landing; dopri5 and
    dop853 over tolerances and ``LARGEST_STEPS`` with dense landing, which lands on the trial
    step's own continuous extension instead of retrying it), the Python path's dense-landing
    DOP853, and solve_ivp over tolerances."""
    tols = (1e-4, 1e-6, 1e-8) if quick else (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
    runs = [
        RunSpec("relaxed", "relaxed-rk4", h, 1e-10, landing="aim")
        for h in ((1e-2, 2e-3) if quick else (2e-2, 1e-2, 5e-3, 2e-3, 1e-3))
    ]
    for method in ("dopri5", "dop853"):
        runs += [
            RunSpec("relaxed", f"relaxed-{method}", h, min(1e-6, 1e-2 * tol), tol, "dense")
            for h in LARGEST_STEPS
            for tol in tols
        ]
    runs += [
        RunSpec("relaxed-python", "relaxed-dop853-dense", 0.1, min(1e-6, 1e-2 * tol), tol, "dense")
        for tol in tols[:: 2 if quick else 3]
    ]
    for method in ("RK45", "DOP853"):
        runs += [
            RunSpec("solve_ivp", f"solve_ivp-{method}", tol=tol, landing="", max_step=step)
            for tol in tols
            for step in (math.inf, 0.1)
        ]
    return runs


def controlled_sweep(knobs: ControlledSweep, quick: bool) -> list[RunSpec]:
    """The runs of a controlled case: DOP853 with dense landing (the Python path) and dopri5
    with aimed landing over tolerances, rk4 over steps (the scenes' own method) -- the last two
    on the compiled path (family ``relaxed``) when ``knobs.compiled``, with dop853 aimed too,
    else on the Python path -- and solve_ivp RK45, DOP853 and LSODA over the same tolerances;
    ``--quick`` keeps every other tolerance and the largest rk4 step."""
    tols = knobs.tols[::2] if quick else knobs.tols
    family = "relaxed" if knobs.compiled else "relaxed-python"

    def eps(tol: float) -> float:
        return max(knobs.eps_floor, min(1e-6, 1e-2 * tol))

    runs = [
        RunSpec(family, "relaxed-rk4", h, knobs.rk4_eps, landing="aim") for h in knobs.rk4_steps[: 1 if quick else None]
    ]
    aimed = ("dopri5", "dop853") if knobs.compiled else ("dopri5",)
    for method, landing, kind in [("dop853", "dense", "relaxed-python")] + [(m, "aim", family) for m in aimed]:
        name = f"relaxed-{method}-dense" if landing == "dense" else f"relaxed-{method}"
        runs += [RunSpec(kind, name, knobs.h_largest, eps(tol), tol, landing) for tol in tols]
    runs += [
        RunSpec("solve_ivp", f"solve_ivp-{m}", tol=tol, landing="") for m in ("RK45", "DOP853", "LSODA") for tol in tols
    ]
    return runs


def case_sweep(case: RobotCase, quick: bool) -> list[RunSpec]:
    """The runs of ``case``: ``controlled_sweep`` for a controlled case, else ``sweep``."""
    return controlled_sweep(case.controlled, quick) if case.controlled is not None else sweep(quick)


def _reported_wall(result: Any, measured_s: float) -> float:
    """The integration time solve_ivp reports (s): it leaves out the assembly of legsim's Execution."""
    return float(result.counters["wall_time_s"])


def run_one(case: RobotCase, spec: RunSpec, repeats: int) -> Row:
    """One run of ``case`` timed (median of repeats, at most the case's ``max_repeats``) and
    measured. A controlled case's controller is made anew for every run, outside the time."""
    controller = _ControllerMaker(case)
    if spec.kind == "solve_ivp":
        call, wall_of = _solve_ivp_call(case, spec, controller), _reported_wall
    else:
        call = _relaxed_call(case, spec, controller)

        def wall_of(result: Any, measured_s: float) -> float:
            return measured_s - controller.seconds

    if case.controlled is not None and case.controlled.max_repeats is not None:
        repeats = min(repeats, case.controlled.max_repeats)
    ex, wall, n = _timed(call, repeats, wall_of)
    c = ex.counters
    return Row(
        case=case.name,
        method=spec.method,
        kind=spec.kind,
        h=spec.h,
        eps=spec.eps,
        tol=spec.tol,
        max_step=spec.max_step,
        landing=spec.landing,
        error=case.error(ex),
        rho=math.nan,
        wall_s=wall,
        repeats=n,
        steps=int(c["steps"]),
        halvings=int(c.get("halvings", 0)),
        field_evals=int(c["field_evals"]),
        guard_evals=int(c["guard_evals"]),
        transitions=int(c["transitions"]),
        status=str(ex.status),
    )


class _ControllerMaker:
    """Makes the case's controller for each run (None for an uncontrolled case) and keeps the
    last one's construction time (s), which the run's time leaves out."""

    def __init__(self, case: RobotCase) -> None:
        self.case, self.seconds = case, 0.0

    def __call__(self) -> Any:
        start = time.perf_counter()
        made = None if self.case.new_control is None else self.case.new_control()
        self.seconds = time.perf_counter() - start
        return made


def _solve_ivp_call(case: RobotCase, spec: RunSpec, controller: _ControllerMaker) -> Callable[[], Any]:
    """The event-driven baseline's run of the case at the spec's method and tolerance."""
    from ..baselines import simulate_events

    def call() -> Any:
        return simulate_events(
            case.system,
            case.x0,
            case.mode,
            case.t_final,
            method=spec.method[10:],
            rtol=spec.tol,
            atol=spec.tol,
            control=controller(),
            max_step=spec.max_step,
            max_transitions=100_000,
        )

    return call


def _relaxed_call(case: RobotCase, spec: RunSpec, controller: _ControllerMaker) -> Callable[[], Any]:
    """The relaxed run of the case at the spec's settings; the same system on both relaxed
    families, the ``relaxed-python`` one asking for the Python loop (``simulate(python=True)``)."""
    from ..relaxed import simulate

    tol = None if math.isnan(spec.tol) else spec.tol

    def call() -> Any:
        return simulate(
            case.system,
            case.x0,
            case.mode,
            case.t_final,
            spec.h,
            spec.eps,
            spec.method.split("-")[1],
            controller(),
            landing=spec.landing,
            max_transitions=100_000,
            rtol=tol,
            atol=tol,
            python=spec.kind == "relaxed-python",
        )

    return call


@dataclass
class LevelResult:
    """The fastest run of each family with error <= level (None when none reaches it)."""

    level: float
    best: dict[str, Row | None]

    def ratio(self, baseline: str, family: str = "relaxed") -> float | None:
        """Wall time of the baseline family's best over the family's best (> 1: family faster)."""
        a, b = self.best.get(baseline), self.best.get(family)
        return None if a is None or b is None else a.wall_s / b.wall_s


def at_levels(rows: list[Row], levels: tuple[float, ...] = LEVELS) -> list[LevelResult]:
    """Each level's fastest run per family that ran (a controlled case has no ``relaxed``)."""
    families = [f for f in ("relaxed", "relaxed-python", "solve_ivp") if any(r.kind == f for r in rows)]
    out = []
    for level in levels:
        best: dict[str, Row | None] = {}
        for family in families:
            ok = [r for r in rows if r.kind == family and r.error <= level]
            best[family] = min(ok, key=lambda r: r.wall_s) if ok else None
        out.append(LevelResult(level, best))
    return out


def format_levels(results: list[LevelResult]) -> str:
    """One line per level: each family's best (method, knob, time) and the ratios."""
    lines = []
    for res in results:
        parts = []
        for family, row in res.best.items():
            if row is None:
                parts.append(f"{family}: none")
                continue
            knob = f"h={row.h:g}" if math.isnan(row.tol) else f"tol={row.tol:g}"
            step = "" if math.isinf(row.max_step) or math.isnan(row.max_step) else f" max_step={row.max_step:g}"
            parts.append(f"{family}: {row.method} {knob}{step} {1e3 * row.wall_s:.3g} ms")
        ratios = [
            f"{name} {r:.3g}x"
            for name, r in (
                ("solve_ivp/relaxed", res.ratio("solve_ivp")),
                ("python/compiled", res.ratio("relaxed-python")),
                ("solve_ivp/python", None if "relaxed" in res.best else res.ratio("solve_ivp", "relaxed-python")),
            )
            if r is not None
        ]
        lines.append(f"error <= {res.level:g}: " + "; ".join(parts) + ("; " + ", ".join(ratios) if ratios else ""))
    return "\n".join(lines)


def cost_report(case: RobotCase, rows: list[Row]) -> dict[str, float]:
    """The limit: seconds per call of a bare C++ ABA on the case's model, of the mode's compiled
    field, guards and first reset called from compiled code, and of its field called from
    Python; and, for the fastest compiled run below 1e-6, the share of its wall time outside ABA
    (1 - field evaluations x bare ABA / wall time)."""
    from .overhead import callable_costs

    mode = case.system.mode(case.mode)
    functions = mode.functions
    if functions is None or not functions.compiled or case.controlled is not None or case.bare_aba is None:
        return {}
    x = np.ascontiguousarray(case.x0, dtype=float)
    nv = (mode.dim - 1) // 2 if case.name in ("compass-gait", "rimless-wheel") else mode.dim // 2
    aba = case.bare_aba(x[:nv], x[nv : 2 * nv], np.zeros(nv), 200_000)
    costs = model_function_costs(functions, mode.dim, len(case.system.outgoing(case.mode)), x, 200_000)
    python = callable_costs(case.system, case.mode, x, 20_000)
    out = {
        "aba_s": aba,
        "field_s": costs["field"],
        "guards_s": costs["guards"],
        "reset_s": costs["reset"],
        "python_field_s": python["field"],
        "field_over_aba": costs["field"] / aba,
    }
    best = at_levels(rows, (1e-6,))[0].best["relaxed"]
    if best is not None:
        out["outside_aba_share"] = 1.0 - best.field_evals * aba / best.wall_s
    return out


def model_function_costs(functions: Any, dim: int, guards: int, x: np.ndarray, n: int) -> dict[str, float]:
    """Seconds per call of a mode's compiled field, guards and first reset at x (the best of 3
    batches of n calls), each called from a compiled loop; successive calls alternate between x
    and x with its first coordinate moved by 1e-9, so that none is served by the native
    library's one-solve cache."""
    import numba

    @numba.njit
    def loop_state(fn, n, x, u, p, out):
        first = x[0]
        for i in range(n):
            x[0] = first + 1e-9 * (i & 1)
            fn(0.0, x, u, p, out)
        x[0] = first

    @numba.njit
    def loop_reset(fn, n, x, u, p, out):
        first = x[0]
        for i in range(n):
            x[0] = first + 1e-9 * (i & 1)
            fn(0, 0.0, x, u, p, out)
        x[0] = first

    p, u = np.array(functions.params), np.zeros(functions.inputs)
    out = np.empty(max(dim, guards, 1) + 16)
    timed = {"field": (loop_state, functions.field), "guards": (loop_state, functions.guards),
             "reset": (loop_reset, functions.reset)}  # fmt: skip
    costs = {}
    for name, (loop, fn) in timed.items():
        if fn is None or (name == "guards" and guards == 0):
            costs[name] = math.nan
            continue
        loop(fn, 1, x, u, p, out)
        best = math.inf
        for _ in range(3):
            start = time.perf_counter()
            loop(fn, n, x, u, p, out)
            best = min(best, time.perf_counter() - start)
        costs[name] = best / n
    return costs


def format_costs(costs: dict[str, float]) -> str:
    if not costs:
        return "cost: the mode is not written as compiled model functions, or the robot gives no bare ABA timer"
    text = (
        f"cost per call: bare C++ aba {1e6 * costs['aba_s']:.3g} us; compiled field all-in "
        f"{1e6 * costs['field_s']:.3g} us ({costs['field_over_aba']:.2f}x aba); "
        f"guards {1e6 * costs['guards_s']:.3g} us; reset {1e6 * costs['reset_s']:.3g} us; "
        f"Python field {1e6 * costs['python_field_s']:.3g} us"
    )
    if "outside_aba_share" in costs:
        text += f"; fastest compiled run at 1e-6: {100 * costs['outside_aba_share']:.0f}% of its time outside aba"
    return text


PYTHON_PATH_NOTE = (
    "controlled: every relaxed run takes legsim's Python path (the scene's controller is not a compiled "
    "ControlLaw), so there is no compiled family; ratios are solve_ivp / Python path"
)
COMPILED_PATH_NOTE = (
    "controlled, compiled path: the robot and its controller are compiled, so the relaxed family (rk4 and aimed "
    "landing) runs in the compiled kernel; relaxed-python is DOP853 with dense landing on the Python path"
)


def run_case(
    name: str,
    *,
    quick: bool,
    out: str | os.PathLike,
    repeats: int,
    figure: bool,
    log: Callable[[str], None] | None = None,
) -> tuple[RobotCase, list[Row], Path, Path | None]:
    """Sweep one case; write OUT/robots-NAME.csv (and .png)."""
    case = make_robot_case(name, quick)
    rows = []
    specs = case_sweep(case, quick)
    with counting(len(specs), name, enabled=log is not None) as advance:
        for spec in specs:
            run_one(case, spec, 1)  # warm: kernels loaded, caches filled
            rows.append(run_one(case, spec, repeats))
            if log is not None:
                r = rows[-1]
                log(f"{name}: {r.method} h={r.h:g} tol={r.tol:g} error {r.error:.2e} wall {1e3 * r.wall_s:.3g} ms")
            advance(1)
    mark_pareto(rows)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(rows, folder / f"robots-{name}.csv")
    fig_path = None
    if figure:
        fig_path = plot_rows(
            rows,
            folder / f"robots-{name}.png",
            f"{name}: work-precision",
            "error of transition times and post-impact states",
        )
    return case, rows, csv_path, fig_path


def main(
    cases: list[str],
    *,
    quick: bool,
    out: str,
    repeats: int,
    figure: bool,
    log: Callable[[str], None] | None,
    fmt: str = "text",
) -> int:
    """The command: every case's table, levels and costs, printed in the format ``fmt``
    (``legsim.tables.FORMATS``)."""
    from ..tables import print_report

    report: list[str | Table] = []
    for name in cases:
        case, rows, csv_path, fig_path = run_case(name, quick=quick, out=out, repeats=repeats, figure=figure, log=log)
        report.append(f"# {case.name}: {case.description}")
        if case.controlled is not None:
            report.append(COMPILED_PATH_NOTE if case.controlled.compiled else PYTHON_PATH_NOTE)
        report.append(replace(rows_table(rows), title=case.name))
        report.append(format_levels(at_levels(rows)))
        if case.controlled is None:
            report.append(format_costs(cost_report(case, rows)))
        report.append(f"wrote {csv_path}" + (f" and {fig_path}" if fig_path else ""))
        report.append("")
    print_report(report, fmt)
    return 0
