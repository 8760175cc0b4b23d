"""``legsim bench robots``: the robots on the compiled path against ``solve_ivp`` with events.

Cases: the compass gait and the rimless wheel with Drake's default parameters (its examples'
``CompassGaitParams`` and ``RimlessWheelParams``), started on their limit cycles; the pronking
runner and the double pendulum with a plastic stop of the bundled scenes. The error of a run is
that of its transitions, as the issue measures it: the largest difference, over the
transitions, of the transition time (s) and of the post-impact state (the reset image, in the
state's units) to a reference run (``solve_ivp`` DOP853 with events at rtol = atol = 1e-12);
transitions at the same instant count as one event (``events``), and a run with another number
of events has error inf.

The families: ``relaxed`` runs with the robots' compiled twins (aimed landing, the compiled
path), ``relaxed-python`` the Python path's best configuration (DOP853, dense landing), and
``solve_ivp`` (RK45 and DOP853 over tolerances and largest steps). For each error level the
fastest run of each family below it is compared; ratios are measured in one run, so they hold
on a shared machine to within its noise. ``cost_report`` gives the limit: a compiled field
evaluation all-in against a bare C++ ``aba`` on the same model, and the share of a run spent
outside it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..builders import get_builder
from ..errors import LegsimError
from ..progress import counting
from .cases import BenchError, RunSpec
from .work_precision import Row, _timed, format_table, mark_pareto, plot_rows, write_csv

CASES = ("compass-gait", "rimless-wheel", "pronk", "double-pendulum")
LEVELS = (1e-4, 1e-6, 1e-8)
#: solve_ivp tolerance of the reference runs.
REFERENCE_TOL = 1e-12
#: Drake's example parameters: compass gait slope 0.0525 rad; rimless wheel 8 spokes, slope 0.08 rad.
DRAKE_COMPASS_SLOPE = 0.0525
DRAKE_RIMLESS = {"spokes": 8, "slope": 0.08}


@dataclass
class RobotCase:
    """A robot, its start and horizon, and the reference its runs are measured against."""

    name: str
    description: str
    system: Any
    mode: str
    x0: np.ndarray
    t_final: float
    reference: Any

    def error(self, execution: Any) -> float:
        """Largest difference of event times (s) and post-event states to the reference's (inf
        when the runs have different numbers of events or a state of another size)."""
        if execution.status != "finished":
            return math.inf
        ours, ref = events(execution), events(self.reference)
        if len(ours) != len(ref):
            return math.inf
        worst = 0.0
        for (ta, xa), (tb, xb) in zip(ours, ref, strict=True):
            if xa.shape != xb.shape:
                return math.inf
            worst = max(worst, abs(ta - tb), float(np.max(np.abs(xa - xb))))
        return worst


#: Transitions closer in time than this (s) form one event: simultaneous ones (a release and a
#: graze, the pronk's two feet), which a relaxed run crosses one strip hold (about eps) apart
#: and rounding orders; the physical events of these cases are over 0.2 s apart.
EVENT_GAP = 1e-3


def events(execution: Any) -> list[tuple[float, np.ndarray]]:
    """The execution's events: its transitions with the chains of simultaneous ones merged
    (``EVENT_GAP``), each as (time of its first transition, state after its last)."""
    out: list[tuple[float, np.ndarray]] = []
    last = -math.inf
    for tr in execution.transitions:
        state = np.asarray(tr.state_after, dtype=float)
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
    if name == "compass-gait":
        model = _builder("compass_gait").make({"slope": math.degrees(DRAKE_COMPASS_SLOPE)}, {})
        x0 = np.array([model.initial_state[n] for n in model.system.state_names("stance")])
        x0 = _on_limit_cycle(model.system, x0, 30.0)
        return model.system, x0, 10.0 if quick else 40.0, "compass gait, Drake's parameters (slope 0.0525 rad)"
    params = {"spokes": DRAKE_RIMLESS["spokes"], "slope": math.degrees(DRAKE_RIMLESS["slope"])}
    model = _builder("rimless_wheel").make(params, {})
    alpha = math.pi / params["spokes"]
    c = math.cos(2 * alpha)  # point mass: thetad+ = c thetad-
    k = 4 * 9.81 * math.sin(alpha) * math.sin(DRAKE_RIMLESS["slope"])
    x0 = np.array([-alpha, math.sqrt(c * c * k / (1 - c * c)), 0.0])  # the closed-form rolling cycle
    return model.system, x0, 10.0 if quick else 40.0, "rimless wheel, Drake's parameters (8 spokes, slope 0.08 rad)"


def make_robot_case(name: str, quick: bool = False) -> RobotCase:
    """The case called ``name`` (one of ``CASES``) with its reference run."""
    from ..baselines import simulate_events

    if name in ("compass-gait", "rimless-wheel"):
        system, x0, t_final, description = _walker(name, quick)
        mode = "stance"
    elif name == "pronk":
        model = _builder("pronk").make()
        system, mode, t_final = model.system, model.initial_mode, 0.5 if quick else 2.0
        description = "pronking runner of paper 000 Sec. V-C"
    elif name == "double-pendulum":
        model = _builder("double_pendulum").make(None, {"gravity": True, "stop": {"restitution": 0.0}})
        system, mode, t_final = model.system, model.initial_mode, 1.0 if quick else 5.0
        description = "double pendulum with a plastic stop, paper 003 Fig. 2b"
    else:
        raise BenchError(f"unknown robot case {name!r}; choose one of {', '.join(CASES)}")
    if name in ("pronk", "double-pendulum"):
        x0 = np.array([model.initial_state[n] for n in system.state_names(mode)])
    reference = simulate_events(
        system,
        x0,
        mode,
        t_final,
        method="DOP853",
        rtol=REFERENCE_TOL,
        atol=REFERENCE_TOL,
        max_step=0.02,
        max_transitions=100_000,
    )
    if reference.status != "finished":
        raise BenchError(f"case {name}: the reference run did not finish ({reference.status}: {reference.message})")
    return RobotCase(name, f"{description}, t in [0, {t_final:g}] s", system, mode, x0, t_final, reference)


def sweep(quick: bool) -> list[RunSpec]:
    """The runs of every case: compiled relaxed (rk4 over h; dopri5 and dop853 over tolerances,
    aimed landing), the Python path's dense-landing DOP853, and solve_ivp over tolerances."""
    tols = (1e-4, 1e-6, 1e-8) if quick else (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
    runs = [
        RunSpec("relaxed", "relaxed-rk4", h, 1e-10, landing="aim")
        for h in ((1e-2, 2e-3) if quick else (2e-2, 1e-2, 5e-3, 2e-3, 1e-3))
    ]
    for method in ("dopri5", "dop853"):
        runs += [RunSpec("relaxed", f"relaxed-{method}", 0.1, min(1e-6, 1e-2 * tol), tol, "aim") for tol in tols]
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


def _reported_wall(result: Any, measured_s: float) -> float:
    """The integration time solve_ivp reports (s): it leaves out the assembly of legsim's Execution."""
    return float(result.counters["wall_time_s"])


def _measured_wall(result: Any, measured_s: float) -> float:
    """The wall time measured around the call (s)."""
    return measured_s


def run_one(case: RobotCase, spec: RunSpec, repeats: int) -> Row:
    """One run of ``case`` timed (median of repeats) and measured."""
    from ..baselines import simulate_events
    from ..relaxed import simulate

    if spec.kind == "solve_ivp":

        def call() -> Any:
            return simulate_events(
                case.system,
                case.x0,
                case.mode,
                case.t_final,
                method=spec.method[10:],
                rtol=spec.tol,
                atol=spec.tol,
                max_step=spec.max_step,
                max_transitions=100_000,
            )

        wall_of: Callable[[Any, float], float] = _reported_wall
    else:
        # The same system on both relaxed families: dense landing runs the Python loop.
        system = case.system
        tol = None if math.isnan(spec.tol) else spec.tol

        def call() -> Any:
            return simulate(
                system,
                case.x0,
                case.mode,
                case.t_final,
                spec.h,
                spec.eps,
                spec.method.split("-")[1],
                landing=spec.landing,
                max_transitions=100_000,
                rtol=tol,
                atol=tol,
            )

        wall_of = _measured_wall
    ex, wall, n = _timed(call, repeats, wall_of)
    c = ex.counters
    return Row(
        case.name,
        spec.method,
        spec.kind,
        spec.h,
        spec.eps,
        spec.tol,
        spec.max_step,
        spec.landing,
        case.error(ex),
        math.nan,
        wall,
        n,
        int(c["steps"]),
        int(c.get("halvings", 0)),
        int(c["field_evals"]),
        int(c["guard_evals"]),
        int(c["transitions"]),
        str(ex.status),
    )


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
    """Each level's fastest run per family."""
    out = []
    for level in levels:
        best: dict[str, Row | None] = {}
        for family in ("relaxed", "relaxed-python", "solve_ivp"):
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
            )
            if r is not None
        ]
        lines.append(f"error <= {res.level:g}: " + "; ".join(parts) + ("; " + ", ".join(ratios) if ratios else ""))
    return "\n".join(lines)


def cost_report(case: RobotCase, rows: list[Row]) -> dict[str, float]:
    """The limit: seconds per call of a bare C++ ABA on the case's model, of the compiled
    field all-in (called from compiled code) and of the Python field; and, for the fastest
    compiled run below 1e-6, the share of its wall time outside ABA (1 - field evaluations x
    bare ABA / wall time)."""
    from .. import _native
    from .overhead import compiled_costs, python_costs

    twin = case.system.mode_data(case.mode).mode.compiled
    if twin is None:
        return {}
    n = int(case.system.mode_data(case.mode).mode.dim)
    x = np.ascontiguousarray(case.x0, dtype=float)
    nv = (n - 1) // 2 if case.name in ("compass-gait", "rimless-wheel") else n // 2
    aba = _native.time_aba(int(twin.params[0]), x[:nv], x[nv : 2 * nv], np.zeros(nv), 200_000)
    compiled = compiled_costs(twin, x, 200_000)
    python = python_costs(case.system, case.mode, x, 20_000)
    out = {
        "aba_s": aba,
        "field_s": compiled["field"],
        "guards_s": compiled["guards"],
        "reset_s": compiled["reset"],
        "python_field_s": python["field"],
        "field_over_aba": compiled["field"] / aba,
    }
    best = at_levels(rows, (1e-6,))[0].best["relaxed"]
    if best is not None:
        out["outside_aba_share"] = 1.0 - best.field_evals * aba / best.wall_s
    return out


def format_costs(costs: dict[str, float]) -> str:
    if not costs:
        return "cost: the model has no compiled twin (native library unavailable)"
    text = (
        f"cost per call: bare C++ aba {1e6 * costs['aba_s']:.3g} us; compiled field all-in "
        f"{1e6 * costs['field_s']:.3g} us ({costs['field_over_aba']:.2f}x aba); "
        f"guards {1e6 * costs['guards_s']:.3g} us; reset {1e6 * costs['reset_s']:.3g} us; "
        f"Python field {1e6 * costs['python_field_s']:.3g} us"
    )
    if "outside_aba_share" in costs:
        text += f"; fastest compiled run at 1e-6: {100 * costs['outside_aba_share']:.0f}% of its time outside aba"
    return text


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
    specs = sweep(quick)
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
    cases: list[str], *, quick: bool, out: str, repeats: int, figure: bool, log: Callable[[str], None] | None
) -> int:
    """The command: every case's table, levels and costs."""
    from .. import _native

    print(f"# native library: {_native.status()}")
    for name in cases:
        case, rows, csv_path, fig_path = run_case(name, quick=quick, out=out, repeats=repeats, figure=figure, log=log)
        print(f"# {case.name}: {case.description}")
        print(format_table(rows))
        print(format_levels(at_levels(rows)))
        print(format_costs(cost_report(case, rows)))
        print(f"wrote {csv_path}" + (f" and {fig_path}" if fig_path else ""))
        print()
    return 0
