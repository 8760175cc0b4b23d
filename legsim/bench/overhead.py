"""What the relaxed integrator costs beyond the model: steps per second, the shares of time in
fields, guards and resets, the overhead per step in units of one field evaluation, and the
evaluations a transition costs with halving and with aiming.

Method: a run's time minus (evaluations x the cost of one evaluation measured alone), per step.
Times are CPU times of this process (``time.process_time``), not wall-clock times: on a
machine shared with other jobs the wall clock also counts the time this process waits for a
core, which can double a short measurement; CPU time counts the work. Evaluations are the
run's own counters; one evaluation's cost is timed in a loop of the same kind as the caller's
(a numba loop for the compiled kernel, a Python loop for the interpreted loop, which calls
the same compiled model functions from Python), so the overhead is
what the integrator adds around the model.
"""

from __future__ import annotations

import json
import math
import time
import timeit
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

from ..control import ControlLaw
from ..hybrid import HybridSystem
from ..model import ModeFunctions
from ..relaxed import driver, simulate
from ..systems import bouncing_ball
from ..systems import oscillator as osc
from ..tables import render_table
from .cases import BenchError


# The loops that take model functions as arguments are compiled in each process, not cached:
# numba's cache keys them by the argument functions' types, and an entry made for a function
# whose source later changed cannot be loaded again ("underlying object has vanished").
@numba.njit
def _loop_field(control, pc, field, p, x, n):
    u, m, dx = np.zeros(1), np.zeros(0), np.empty(x.shape[0])
    acc = 0.0
    t = 0.0
    for _ in range(n):
        control(t, x, m, pc, u)
        field(t, x, u, p, dx)
        acc += dx[1]
        t += 1e-9
    return acc


@numba.njit
def _loop_guards(guards, p, x, n):
    u, g = np.zeros(1), np.empty(1)
    acc = 0.0
    for _ in range(n):
        guards(0.0, x, u, p, g)
        acc += g[0]
        x[1] += 1e-300
    return acc


@numba.njit
def _loop_resets(reset, p, x, n):
    u, out = np.zeros(1), np.empty(x.shape[0])
    acc = 0.0
    for _ in range(n):
        reset(0, 0.0, x, u, p, out)
        acc += out[1]
        x[1] += 1e-300
    return acc


@numba.njit(cache=True)
def _loop_empty(p, x, n):
    acc = 0.0
    t = 0.0
    for _ in range(n):
        acc += x[1] + t
        t += 1e-9
    return acc


def _best(fn: Callable[[], Any], repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.process_time()
        fn()
        times.append(time.process_time() - start)
    return min(times)


def compiled_costs(system: HybridSystem, law: ControlLaw, x: np.ndarray, n: int = 2_000_000) -> dict[str, float]:
    """Seconds per call of mode ``free``'s field (with the forcing law evaluated before it, as the
    loop does), guards and reset, called from compiled code."""
    x = np.array(x, dtype=float)
    functions = _functions(system)
    p, pc = functions.params, law.params_for(osc.MODE)
    # compile each loop before it is timed
    _loop_field(law.control, pc, functions.field, p, x.copy(), 10)
    _loop_empty(p, x.copy(), 10)
    empty = _best(lambda: _loop_empty(p, x.copy(), n))
    out = {"field": (_best(lambda: _loop_field(law.control, pc, functions.field, p, x.copy(), n)) - empty) / n}
    if functions.guards is not None:
        _loop_guards(functions.guards, p, x.copy(), 10)
        out["guards"] = (_best(lambda: _loop_guards(functions.guards, p, x.copy(), n)) - empty) / n
        _loop_resets(functions.reset, p, x.copy(), 10)
        out["reset"] = (_best(lambda: _loop_resets(functions.reset, p, x.copy(), n)) - empty) / n
    else:
        out["guards"], out["reset"] = 0.0, math.nan
    return out


def _functions(system: HybridSystem) -> ModeFunctions:
    """The model functions of the oscillator's mode (BenchError when it has none)."""
    functions = system.mode(osc.MODE).functions
    if functions is None:
        raise BenchError(f"{system.name}: mode {osc.MODE!r} is not written as model functions")
    return functions


def python_costs(system: HybridSystem, law: ControlLaw, x: np.ndarray, n: int = 50_000) -> dict[str, float]:
    """Seconds per call of mode ``free``'s field (with the forcing law), guards and reset as the
    interpreted loop calls them: the same compiled functions, from Python."""
    x = np.array(x, dtype=float)
    functions = _functions(system)
    p, pc = functions.params, law.params_for(osc.MODE)
    u, m, dx, g, out = np.zeros(1), np.zeros(0), np.empty(2), np.empty(1), np.empty(2)

    def field() -> None:
        law.control(0.0, x, m, pc, u)
        functions.field(0.0, x, u, p, dx)

    clock = time.process_time
    cost = {"field": min(timeit.repeat(field, number=n, repeat=3, timer=clock)) / n}
    guards, reset = functions.guards, functions.reset
    if guards is None or reset is None:
        raise BenchError(f"{system.name}: mode {osc.MODE!r} has no compiled guards and reset to time")
    cost["guards"] = min(timeit.repeat(lambda: guards(0.0, x, u, p, g), number=n, repeat=3, timer=clock)) / n
    cost["reset"] = min(timeit.repeat(lambda: reset(0, 0.0, x, u, p, out), number=n, repeat=3, timer=clock)) / n
    return cost


def callable_costs(system: HybridSystem, mode: str, x: np.ndarray, n: int = 50_000) -> dict[str, float]:
    """Seconds per call of a mode's Python field, first guard and first reset, from Python."""
    x = np.array(x, dtype=float)
    field = system.mode(mode).field
    tr = system.outgoing(mode)[0] if system.outgoing(mode) else None
    clock = time.process_time
    cost = {"field": min(timeit.repeat(lambda: field(0.0, x, None), number=n, repeat=3, timer=clock)) / n}
    cost["guards"] = cost["reset"] = 0.0
    if tr is not None:
        cost["guards"] = min(timeit.repeat(lambda: tr.guard_value(x), number=n, repeat=3, timer=clock)) / n
        reset = tr.reset if tr.reset is not None else np.copy
        cost["reset"] = min(timeit.repeat(lambda: reset(x), number=n, repeat=3, timer=clock)) / n
    return cost


def interpreted(run: Callable[..., Any]) -> Callable[..., Any]:
    """``run`` with the relaxed loop interpreted (the compiled kernel set aside while it runs)."""

    def wrapped(*args: Any, **kw: Any) -> Any:
        kernel, driver.KERNEL = driver.KERNEL, None
        try:
            return run(*args, **kw)
        finally:
            driver.KERNEL = kernel

    return wrapped


def example(name: str) -> tuple[HybridSystem, ControlLaw, np.ndarray, float]:
    """Table I example ``ex1`` or ``ex2``: (system, forcing law, initial state, t_max)."""
    p = osc.EXAMPLES[name]
    system = osc.make_system(p["omega"], p["a"], p["x_max"], p["c"], p["mass"])
    return system, osc.forcing(p["amplitude"], p["frequency"]), np.array([p["x0"], p["xd0"]]), float(p["t_max"])


def measure_run(
    system,
    x0,
    mode: str,
    t_final: float,
    h: float,
    eps: float,
    method: str,
    costs: dict[str, float] | Callable[[], dict[str, float]],
    repeats: int = 3,
    run: Callable[..., Any] = simulate,
    **kw,
) -> dict[str, Any]:
    """Time one run (``run``: ``simulate``, or ``interpreted(simulate)``) and split its time.
    ``costs`` (seconds per evaluation) may be a function that measures them: it is then called
    before every repeat, and for each quantity the smallest time over the repeats is kept, run
    and evaluations alike, so that a burst of other load on the machine disturbs neither side of
    the difference."""
    run(system, x0, mode, min(t_final, 0.1), h, eps, method, **kw)
    walls = []
    measured: list[dict[str, float]] = []
    ex = None
    for _ in range(repeats):
        if callable(costs):
            measured.append(costs())
        start = time.process_time()
        ex = run(system, x0, mode, t_final, h, eps, method, **kw)
        walls.append(time.process_time() - start)
    if callable(costs):
        costs = {k: min(m[k] for m in measured) for k in measured[0]}
    assert ex is not None  # repeats >= 1 runs
    wall = min(walls)
    c = ex.counters
    steps = max(int(c["steps"]), 1)
    t_field = c["field_evals"] * costs["field"]
    t_guard = c["guard_evals"] * costs["guards"]
    t_reset = c["reset_evals"] * (0.0 if math.isnan(costs["reset"]) else costs["reset"])
    rest = wall - t_field - t_guard - t_reset
    return {
        "method": method,
        "h": h,
        "eps": eps,
        "status": ex.status,
        "wall_s": wall,
        "steps": int(c["steps"]),
        "halvings": int(c["halvings"]),
        "field_evals": int(c["field_evals"]),
        "guard_evals": int(c["guard_evals"]),
        "reset_evals": int(c["reset_evals"]),
        "transitions": int(c["transitions"]),
        "steps_per_s": c["steps"] / wall,
        "ns_per_step": 1e9 * wall / steps,
        "cost_field_s": costs["field"],
        "clock": "process CPU time",
        "share_field": t_field / wall,
        "share_guards": t_guard / wall,
        "share_resets": t_reset / wall,
        "overhead_per_step_in_fields": rest / steps / costs["field"],
    }


def landing_costs(
    system,
    x0,
    mode,
    t_final,
    h,
    eps,
    method="rk4",
    landings=("halve", "aim"),
    tol: float | None = None,
    control: Any = None,
) -> dict[str, dict[str, float]]:
    """Per transition: extra trial steps and evaluations spent landing in the strips, for each
    landing rule (error-controlled with rtol = atol = ``tol`` when given), under ``control``. Extra field evaluations
    are those beyond the accepted steps' own (error rejections included)."""
    from ..methods import get_method

    tab = get_method(method)
    per_step = tab.stages - 1 + (0 if tab.fsal else 1)
    out = {}
    for landing in landings:
        ex = simulate(
            system,
            x0,
            mode,
            t_final,
            h,
            eps,
            method,
            control,
            landing=landing,
            max_transitions=1_000_000,
            rtol=tol,
            atol=tol,
        )
        c = ex.counters
        n = max(int(c["transitions"]), 1)
        out[landing] = {
            "transitions": int(c["transitions"]),
            "trial_steps_per_transition": c["halvings"] / n,
            "extra_field_evals_per_transition": (c["field_evals"] - per_step * c["steps"]) / n,
            "guard_evals_per_transition": c["guard_evals"] / n - c["steps"] / n,
        }
    return out


def collect(quick: bool = False) -> dict[str, Any]:
    """All measurements: the oscillator of Example 1 at h = 1e-3, eps = 1e-6 (paper 000 Table I),
    compiled and interpreted loop over the same model functions, euler/rk2/rk4; and landing costs
    on three cases."""
    system, law, x0, t_max = example("ex1")
    t_final = t_max / (4 if quick else 1)  # long runs: the fixed cost of a call (~0.5 ms) must not count per step
    probe = np.array([1.0, 2.0])
    n_c, n_p = (100_000, 2_000) if quick else (300_000, 20_000)
    free = osc.make_system(2.5, 0.05, None, 0.9, 1.0)
    compiled_cost = lambda: compiled_costs(system, law, probe, n_c)  # noqa: E731
    free_cost = lambda: compiled_costs(free, law, probe, n_c)  # noqa: E731
    python_cost = lambda: python_costs(system, law, probe, n_p)  # noqa: E731
    result: dict[str, Any] = {
        "case": f"oscillator Ex.1, t in [0, {t_final:.4g}] s, h = 1e-3, eps = 1e-6",
        "cost_compiled_s": compiled_cost(),
        "cost_python_s": python_cost(),
        "compiled": [],
        "compiled_no_stop": [],
        "python": [],
    }
    repeats = 3 if quick else 9
    python_repeats = max(3, repeats // 3)
    for method in ("euler", "rk2", "rk4"):
        args = (x0, "free", t_final, 1e-3, 1e-6, method)
        result["compiled"].append(measure_run(system, *args, compiled_cost, repeats, control=law))
        result["compiled_no_stop"].append(measure_run(free, *args, free_cost, repeats, control=law))
        result["python"].append(
            measure_run(system, *args, python_cost, python_repeats, interpreted(simulate), control=law)
        )
    ex2, law2, x2, t2 = example("ex2")
    ball = bouncing_ball.make_system(9.81, 0.8)
    result["landing"] = {
        "oscillator Ex.1 (h=1e-2, eps=1e-6)": landing_costs(system, x0, "free", t_final, 1e-2, 1e-6, control=law),
        "oscillator Ex.2 (h=1e-2, eps=1e-6)": landing_costs(
            ex2, x2, "free", t2 / (4 if quick else 1), 1e-2, 1e-6, control=law2
        ),
        "bouncing ball c=0.8 (h=1e-2, eps=1e-6, 3 s)": landing_costs(
            ball, np.array([1.0, 0.0]), "flight", 3.0, 1e-2, 1e-6
        ),
    }
    # Error-controlled pairs: a retried step at the aim, or the landing on the failed step's own
    # dense output (no retried step).
    result["landing_pairs"] = {
        "oscillator Ex.1 (h=0.1, eps=1e-6)": landing_costs(
            system, x0, "free", t_final, 0.1, 1e-6, "dopri5", ("aim", "dense"), 1e-8, law
        ),
        "bouncing ball c=0.8 (h=0.1, eps=1e-6, 3 s)": landing_costs(
            ball, np.array([1.0, 0.0]), "flight", 3.0, 0.1, 1e-6, "dopri5", ("aim", "dense"), 1e-8
        ),
    }
    return result


#: The report's rows: (label, key of the measurements).
PATHS = (("compiled", "compiled"), ("compiled, no stop", "compiled_no_stop"), ("interpreted", "python"))


def format_report(r: dict[str, Any], width: int | None = None) -> str:
    """The measurements as text; the table at most ``width`` characters wide (``legsim.tables``)."""
    lines = [f"# integrator overhead: {r['case']}"]
    cc, cp = r["cost_compiled_s"], r["cost_python_s"]
    lines.append(
        "costs of one evaluation measured alongside each run, the least disturbed of the repeats kept: "
        "a row's overhead is in its own field cost (column 'field ns'); before the runs:"
    )
    lines.append(
        f"one evaluation, compiled (from numba): field {cc['field'] * 1e9:.1f} ns, guard "
        f"{cc['guards'] * 1e9:.1f} ns, reset {cc['reset'] * 1e9:.1f} ns"
    )
    lines.append(
        f"one evaluation, interpreted loop (the same functions from Python): field {cp['field'] * 1e9:.0f} ns, guard "
        f"{cp['guards'] * 1e9:.0f} ns, reset {cp['reset'] * 1e9:.0f} ns"
    )
    head = ("path", "method", "steps/s", "ns/step", "field", "guard", "reset", "field ns", "overhead/step", "trans")
    rows = [
        (
            label,
            m["method"],
            f"{m['steps_per_s']:.3g}",
            f"{m['ns_per_step']:.0f}",
            f"{100 * m['share_field']:.0f}%",
            f"{100 * m['share_guards']:.0f}%",
            f"{100 * m['share_resets']:.1f}%",
            f"{m['cost_field_s'] * 1e9:.1f}",
            f"{m['overhead_per_step_in_fields']:.2f} f-ev",
            str(m["transitions"]),
        )
        for label, key in PATHS
        for m in r[key]
    ]
    lines.append(render_table(head, rows, right=range(2, 10), whole=range(10), width=width))
    lines.append("")
    lines.append(
        "landing in a strip, per transition (rk4): trial steps, extra field evaluations, guard "
        "evaluations beyond one per step"
    )
    lines.append(_landing_table(r["landing"], width))
    lines.append("")
    lines.append(
        "landing in a strip, per transition (dopri5, rtol = atol = 1e-8): the same, aimed retry against "
        "the failed step's dense output"
    )
    lines.append(_landing_table(r.get("landing_pairs", {}), width))
    rk4 = next(m for m in r["compiled"] if m["method"] == "rk4")
    target = rk4["overhead_per_step_in_fields"]
    lines.append("")
    lines.append(
        f"target: integrator overhead per step <= 2 field evaluations (compiled rk4, with the stop): "
        f"{target:.2f}: {'MET' if target <= 2 else 'MISSED'}"
    )
    return "\n".join(lines)


def _landing_table(costs: dict[str, dict[str, dict[str, Any]]], width: int | None) -> str:
    """case -> landing -> its costs per transition, as a table."""
    head = ("case", "landing", "trial steps", "extra field evals", "guard evals", "transitions")
    rows = [
        (
            case,
            landing,
            f"{v['trial_steps_per_transition']:.2f}",
            f"{v['extra_field_evals_per_transition']:.2f}",
            f"{v['guard_evals_per_transition']:.2f}",
            str(v["transitions"]),
        )
        for case, d in costs.items()
        for landing, v in d.items()
    ]
    return render_table(head, rows, right=range(2, 6), whole=range(1, 6), width=width)


def main(quick: bool = False, as_json: bool = False, fmt: str = "text") -> int:
    """``legsim bench overhead``: the report as text, or as JSON (``--json`` or ``--format
    json``); BenchError for a format this report has no form in (csv, markdown)."""
    if fmt not in ("text", "json"):
        raise BenchError(f"legsim bench overhead prints text or json, not {fmt!r} (--format text|json)")
    r = collect(quick)
    print(json.dumps(r, indent=1) if as_json or fmt == "json" else format_report(r))
    return 0
