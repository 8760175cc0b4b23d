"""What the relaxed integrator costs beyond the model: steps per second, the shares of time in
fields, guards and resets, the overhead per step in units of one field evaluation, and the
evaluations a transition costs with halving and with aiming.

Method: a run's time minus (evaluations x the cost of one evaluation measured alone), per step.
Times are CPU times of this process (``time.process_time``), not wall-clock times: on a
machine shared with other jobs the wall clock also counts the time this process waits for a
core, which can double a short measurement; CPU time counts the work. Evaluations are the
run's own counters; one evaluation's cost is timed in a loop of the same kind as the caller's
(a numba loop for the compiled path, a Python loop for the Python path), so the overhead is
what the integrator adds around the model.
"""

from __future__ import annotations

import json
import math
import statistics
import time
import timeit
from collections.abc import Callable
from functools import partial
from typing import Any
from unittest.mock import patch

import numba
import numpy as np

from ..compiled import without_compiled
from ..relaxed import simulate
from ..systems.fast import make_bouncing_ball, make_oscillator, make_oscillator_example
from ..tables import render_table


# The loops that take a twin's functions as arguments are compiled in each process, not cached:
# numba's cache keys them by the argument functions' types, and an entry made for a function
# whose source later changed cannot be loaded again ("underlying object has vanished").
@numba.njit
def _loop_field(field, p, x, n):
    acc = 0.0
    t = 0.0
    for _ in range(n):
        acc += field(t, x, p)[1]
        t += 1e-9
    return acc


@numba.njit
def _loop_guards(guards, p, x, n):
    acc = 0.0
    for _ in range(n):
        acc += guards(x, p)[0]
        x[1] += 1e-300
    return acc


@numba.njit
def _loop_resets(resets, p, x, n):
    acc = 0.0
    for _ in range(n):
        acc += resets(x, p, 0)[1]
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


def compiled_costs(twin, x: np.ndarray, n: int = 2_000_000) -> dict[str, float]:
    """Seconds per call of the twin's field, guards and resets, called from compiled code."""
    x = np.array(x, dtype=float)
    p = twin.params
    # compile each loop before it is timed
    _loop_field(twin.field, p, x.copy(), 10)
    _loop_guards(twin.guards, p, x.copy(), 10)
    _loop_empty(p, x.copy(), 10)
    empty = _best(lambda: _loop_empty(p, x.copy(), n))
    out = {
        "field": (_best(lambda: _loop_field(twin.field, p, x.copy(), n)) - empty) / n,
        "guards": (_best(lambda: _loop_guards(twin.guards, p, x.copy(), n)) - empty) / n,
    }
    if twin.resets is not None:
        _loop_resets(twin.resets, p, x.copy(), 10)
        out["reset"] = (_best(lambda: _loop_resets(twin.resets, p, x.copy(), n)) - empty) / n
    else:
        out["reset"] = math.nan
    return out


def python_costs(system, mode: str, x: np.ndarray, n: int = 50_000) -> dict[str, float]:
    """Seconds per call of the Python field, first guard and first reset, from a Python loop."""
    x = np.array(x, dtype=float)
    field = system.mode(mode).field
    tr = system.outgoing(mode)[0] if system.outgoing(mode) else None
    number = n
    clock = time.process_time
    cost = {"field": min(timeit.repeat(lambda: field(0.0, x, None), number=number, repeat=3, timer=clock)) / number}
    if tr is not None:
        cost["guards"] = min(timeit.repeat(lambda: tr.guard_value(x), number=number, repeat=3, timer=clock)) / number
        cost["reset"] = min(timeit.repeat(lambda: tr.reset(x), number=number, repeat=3, timer=clock)) / number
    else:
        cost["guards"] = cost["reset"] = 0.0
    return cost


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
    **kw,
) -> dict[str, Any]:
    """Time one run and split its time. ``costs`` (seconds per evaluation) may be a function
    that measures them: it is then called before every repeat, and for each quantity the
    smallest time over the repeats is kept, run and evaluations alike, so that a burst of other
    load on the machine disturbs neither side of the difference."""
    simulate(system, x0, mode, min(t_final, 0.1), h, eps, method, **kw)
    walls = []
    measured: list[dict[str, float]] = []
    ex = None
    for _ in range(repeats):
        if callable(costs):
            measured.append(costs())
        start = time.process_time()
        ex = simulate(system, x0, mode, t_final, h, eps, method, **kw)
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
    system, x0, mode, t_final, h, eps, method="rk4", landings=("halve", "aim"), tol: float | None = None
) -> dict[str, dict[str, float]]:
    """Per transition: extra trial steps and evaluations spent landing in the strips, for each
    landing rule (error-controlled with rtol = atol = ``tol`` when given). Extra field evaluations
    are those beyond the accepted steps' own (error rejections included)."""
    from ..methods import get_method

    tab = get_method(method)
    per_step = tab.stages - 1 + (0 if tab.fsal else 1)
    out = {}
    for landing in landings:
        ex = simulate(
            system, x0, mode, t_final, h, eps, method, landing=landing, max_transitions=1_000_000, rtol=tol, atol=tol
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


def _unchecked_guard(run: Any, transition: Any) -> Callable[[float, np.ndarray], Any]:
    g, control = transition.guard, run.control
    if transition.guard_args == "x":
        return lambda t, x: g(x)
    return lambda t, x: g(t, x, None if control is None else control(t, x))


def contract_cost(system, x0: np.ndarray, t_final: float, method: str, repeats: int) -> float:
    """Median ratio of run times with the model-contract checks every evaluation runs (each
    stage's shape, each guard's type) to the same runs with them left out, interleaved pairs on
    the Python path (``system`` without compiled twins: the cheapest fields, where the checks'
    share is largest)."""
    import legsim.relaxed.run as run_module

    from ..methods.stepper import make_stepper

    def once() -> float:
        start = time.perf_counter()
        simulate(system, x0, "free", t_final, 1e-3, 1e-6, method, continuation=False)
        return time.perf_counter() - start

    def unchecked() -> float:
        with (
            patch.object(run_module.Run, "_guard_fn", _unchecked_guard),
            patch.object(run_module, "make_stepper", partial(make_stepper, checked=False)),
        ):
            return once()

    once(), unchecked()  # both steppers generated before anything is timed
    return statistics.median([once() / unchecked() for _ in range(repeats)])


def collect(quick: bool = False) -> dict[str, Any]:
    """All measurements: the oscillator of Example 1 at h = 1e-3, eps = 1e-6 (paper 000 Table I),
    compiled and Python paths, euler/rk2/rk4; and landing costs on three cases."""
    system, x0, t_max = make_oscillator_example("ex1")
    t_final = t_max / (4 if quick else 1)  # long runs: the fixed cost of a call (~0.5 ms) must not count per step
    twin = system.mode("free").compiled
    probe = np.array([1.0, 2.0])
    n_c, n_p = (100_000, 2_000) if quick else (300_000, 20_000)
    python_system = without_compiled(system)
    free = make_oscillator(2.5, 0.05, None, 0.9, 1.0, 20.0, 2.5)
    compiled_cost = lambda: compiled_costs(twin, probe, n_c)  # noqa: E731
    free_cost = lambda: dict(compiled_costs(twin, probe, n_c), guards=0.0)  # noqa: E731
    python_cost = lambda: python_costs(python_system, "free", probe, n_p)  # noqa: E731
    result: dict[str, Any] = {
        "case": f"oscillator Ex.1, t in [0, {t_final:.4g}] s, h = 1e-3, eps = 1e-6",
        "cost_compiled_s": compiled_cost(),
        "cost_python_s": python_cost(),
        "compiled": [],
        "compiled_no_stop": [],
        "python": [],
    }
    repeats = 3 if quick else 9
    for method in ("euler", "rk2", "rk4"):
        result["compiled"].append(measure_run(system, x0, "free", t_final, 1e-3, 1e-6, method, compiled_cost, repeats))
        result["compiled_no_stop"].append(
            measure_run(free, x0, "free", t_final, 1e-3, 1e-6, method, free_cost, repeats)
        )
        result["python"].append(
            measure_run(python_system, x0, "free", t_final, 1e-3, 1e-6, method, python_cost, max(3, repeats // 3))
        )
    result["contract"] = {
        method: contract_cost(python_system, x0, t_final / (4 if quick else 2), method, repeats)
        for method in ("euler", "rk4")
    }
    ex2, x2, t2 = make_oscillator_example("ex2")
    result["landing"] = {
        "oscillator Ex.1 (h=1e-2, eps=1e-6)": landing_costs(system, x0, "free", t_final, 1e-2, 1e-6),
        "oscillator Ex.2 (h=1e-2, eps=1e-6)": landing_costs(ex2, x2, "free", t2 / (4 if quick else 1), 1e-2, 1e-6),
        "bouncing ball c=0.8 (h=1e-2, eps=1e-6, 3 s)": landing_costs(
            make_bouncing_ball(9.81, 0.8), np.array([1.0, 0.0]), "flight", 3.0, 1e-2, 1e-6
        ),
    }
    # Error-controlled pairs: a retried step at the aim, or the landing on the failed step's own
    # dense output (no retried step). The dense landing runs the Python loop (the kernel aims).
    result["landing_pairs"] = {
        "oscillator Ex.1 (h=0.1, eps=1e-6)": landing_costs(
            system, x0, "free", t_final, 0.1, 1e-6, "dopri5", ("aim", "dense"), 1e-8
        ),
        "bouncing ball c=0.8 (h=0.1, eps=1e-6, 3 s)": landing_costs(
            make_bouncing_ball(9.81, 0.8),
            np.array([1.0, 0.0]),
            "flight",
            3.0,
            0.1,
            1e-6,
            "dopri5",
            ("aim", "dense"),
            1e-8,
        ),
    }
    return result


def format_report(r: dict[str, Any], width: int | None = None) -> str:
    """The measurements as text; the table at most ``width`` characters wide (``legsim.tables``)."""
    lines = [f"# integrator overhead: {r['case']}"]
    cc, cp = r["cost_compiled_s"], r["cost_python_s"]
    lines.append("costs of one evaluation measured alongside each run, the least disturbed of the repeats kept")
    lines.append(
        f"one evaluation, compiled (from numba): field {cc['field'] * 1e9:.1f} ns, guard "
        f"{cc['guards'] * 1e9:.1f} ns, reset {cc['reset'] * 1e9:.1f} ns"
    )
    lines.append(
        f"one evaluation, Python (from Python): field {cp['field'] * 1e9:.0f} ns, guard "
        f"{cp['guards'] * 1e9:.0f} ns, reset {cp['reset'] * 1e9:.0f} ns"
    )
    head = ("path", "method", "steps/s", "ns/step", "field", "guard", "reset", "overhead/step", "trans")
    rows = [
        (
            label,
            m["method"],
            f"{m['steps_per_s']:.3g}",
            f"{m['ns_per_step']:.0f}",
            f"{100 * m['share_field']:.0f}%",
            f"{100 * m['share_guards']:.0f}%",
            f"{100 * m['share_resets']:.1f}%",
            f"{m['overhead_per_step_in_fields']:.2f} f-ev",
            str(m["transitions"]),
        )
        for label, key in (("compiled", "compiled"), ("compiled, no stop", "compiled_no_stop"), ("python", "python"))
        for m in r[key]
    ]
    lines.append(render_table(head, rows, right=range(2, 9), whole=range(9), width=width))
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
    lines.append("")
    lines.append(
        "model-contract checks (each stage's shape, each guard's type) on the Python path: run time with "
        "/ without them, median of interleaved pairs: "
        + ", ".join(f"{method} {ratio:.3f}" for method, ratio in r["contract"].items())
        + f" (target <= 1.05: {'MET' if max(r['contract'].values()) <= 1.05 else 'MISSED'})"
    )
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


def main(quick: bool = False, as_json: bool = False) -> int:
    r = collect(quick)
    print(json.dumps(r, indent=1) if as_json else format_report(r))
    return 0
