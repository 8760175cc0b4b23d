"""``legsim bench orbit``: ``legsim orbit SCENE`` against a plain scipy Newton iteration on the
step map, at the same fixed-point accuracy.

legsim's side is what the command runs: ``load_scene``, ``problem_from_scene`` and
``find_orbit`` with the scene's own settings (Gauss-Newton with the saltation Jacobian; the
result has the fixed point, the period and the Floquet multipliers). The baseline is the
strongest plain scipy code we know for the same question on the same model (the scene's
system, built by the same ``load_scene``, its Python callables: Pinocchio's ABA for a robot):
the step map is ``solve_ivp`` DOP853 with a terminal event per guard (direction -1), the reset
applied at the event, until the section's transition fires; Newton's method on the same
unknowns and equations as legsim's, with a forward-difference Jacobian (one step map per
unknown, relative step sqrt(tolerance): cheaper than central differences or the variational
equation through solve_ivp, and accurate enough for Newton), stopping at the scene's
``orbit.tol`` as ``find_orbit`` does. It stops at the fixed point; a second baseline also
computes the multipliers, as the command does (one more forward-difference Jacobian at the
fixed point: ~1e-5 accurate on the compass gait's complex pair, where legsim's saltation
Jacobian gives ~1e-7, so this baseline is favoured).

Accuracy: both fixed points are measured against a reference: the baseline at rtol = atol =
1e-12 iterated until its residual stops falling. The baseline's tolerance is the loosest of a
grid whose error is at most legsim's (so it is not slower for being more accurate than needed).
Times are medians of interleaved repeats in one process, after a warm-up call of each (kernels
loaded, caches filled); the ratio is baseline / legsim (>= 1: legsim no slower).
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from .cases import BenchError

#: The baseline's tolerances (rtol = atol), loosest first; it runs at the first reaching legsim's error.
TOLERANCES = (1e-8, 3e-9, 1e-9, 3e-10, 1e-10, 3e-11, 1e-11, 3e-12, 1e-12)
#: The reference's tolerance.
REFERENCE_TOL = 1e-12
#: Newton iterations allowed to the baseline.
MAX_ITERATIONS = 30


class _GuardEvent:
    """A solve_ivp event: a transition's guard crossing zero from above, which ends the solve."""

    terminal = True
    direction = -1.0

    def __init__(self, transition: Any) -> None:
        self.transition = transition

    def __call__(self, t: float, y: np.ndarray) -> float:
        return self.transition.guard_value(y, t)


class StepMap:
    """The step map of a scene's orbit problem by ``solve_ivp`` DOP853 with events: from a state
    just after the section's transition to the state just after it fires again. ``calls``
    counts step maps, ``field_evals`` the field evaluations."""

    def __init__(self, problem: Any, tol: float) -> None:
        if problem.section.kind != "transition" or problem.returns != 1:
            raise BenchError(
                f"bench orbit: the baseline's step map needs a section after a transition with "
                f"returns = 1, got section {problem.section.label}, returns {problem.returns}"
            )
        self.system, control = problem.instantiate(problem.parameters)
        if control is not None:
            raise BenchError("bench orbit: the baseline's step map runs passive systems only (no control)")
        self.transition, self.tol = problem.section.transition, tol
        self.mode, self.t_max = problem.bound.mode, problem.t_max
        self.calls = self.field_evals = 0
        self._pieces = {name: self._mode_pieces(name) for name in self.system.modes}

    def _mode_pieces(self, mode: str) -> tuple[Callable, list, list]:
        field = self.system.mode(mode).field
        transitions = self.system.outgoing(mode)
        events = [_GuardEvent(tr) for tr in transitions]
        return (lambda t, y: field(t, y, None)), transitions, events

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.calls += 1
        mode, t, y = self.mode, 0.0, np.asarray(x, dtype=float)
        while True:
            fun, transitions, events = self._pieces[mode]
            sol = solve_ivp(fun, (t, self.t_max), y, method="DOP853", rtol=self.tol, atol=self.tol, events=events)
            self.field_evals += sol.nfev
            if sol.status != 1:
                raise BenchError(
                    f"bench orbit: the baseline's step map found no {self.transition} within "
                    f"t_max = {self.t_max:g} s from {np.round(x, 8).tolist()} ({sol.message})"
                )
            assert sol.t_events is not None and sol.y_events is not None  # solve_ivp was given events
            t, e = min((float(te[0]), i) for i, te in enumerate(sol.t_events) if len(te))
            tr = transitions[e]
            y = np.asarray(tr.reset(sol.y_events[e][0]), dtype=float)
            mode = tr.target
            if tr.name == self.transition:
                return y


@dataclass
class NewtonResult:
    """The baseline's fixed point (n,), Newton iterations, step maps run, the final residual
    (max-norm of the periodicity rows), and the multipliers when asked for."""

    fixed_point: np.ndarray
    iterations: int
    step_maps: int
    residual: float
    multipliers: np.ndarray | None = None


def scipy_newton(
    problem: Any, guess: np.ndarray, tol: float, residual_tol: float, multipliers: bool = False
) -> NewtonResult:
    """Newton's method on P(x) - x over ``problem``'s unknowns (its periodic rows), P the
    ``StepMap`` at ``tol``, forward-difference Jacobian; stops at residual <= ``residual_tol``
    or when the residual stops falling. With ``multipliers``, the eigenvalues of the step map's
    Jacobian at the fixed point restricted to the unknowns, the one 0 of the section left out."""
    step_map = StepMap(problem, tol)
    rows, unknowns = problem.periodic_idx, problem.unknown_idx
    if rows != unknowns or problem.free or problem.extra_rows:
        raise BenchError(
            "bench orbit: the baseline solves periodicity of the unknown coordinates only "
            "(no free parameters, fixed periodic coordinates or extra equations)"
        )
    x = np.asarray(guess, dtype=float).copy()
    fd = math.sqrt(max(tol, np.finfo(float).eps))
    best = math.inf
    for it in range(MAX_ITERATIONS + 1):
        Px = step_map(x)
        F = Px[rows] - x[rows]
        res = float(np.max(np.abs(F)))
        if res <= residual_tol or res >= best or it == MAX_ITERATIONS:
            break
        best = res
        J = _jacobian(step_map, x, Px, unknowns, fd) - np.eye(len(unknowns))
        x[unknowns] -= np.linalg.solve(J, F)
    result = NewtonResult(x, it, step_map.calls, res)
    if multipliers:
        mu = np.linalg.eigvals(_jacobian(step_map, x, Px, unknowns, fd))
        result.multipliers = mu[np.argsort(-np.abs(mu), kind="stable")][:-1]
        result.step_maps = step_map.calls
    return result


def _jacobian(step_map: StepMap, x: np.ndarray, Px: np.ndarray, idx: list[int], rel: float) -> np.ndarray:
    """dP/dx on the coordinates ``idx`` by forward differences from P(x) = Px."""
    J = np.empty((len(idx), len(idx)))
    for col, j in enumerate(idx):
        y = x.copy()
        y[j] += rel * max(1.0, abs(x[j]))
        J[:, col] = (step_map(y)[idx] - Px[idx]) / (y[j] - x[j])
    return J


def interleaved(calls: dict[str, Callable[[], Any]], repeats: int) -> dict[str, float]:
    """Median wall time (s) of each call over ``repeats`` rounds, each round calling every one
    in turn, after one warm-up round."""
    for fn in calls.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in calls}
    for _ in range(repeats):
        for name, fn in calls.items():
            start = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - start)
    return {name: float(statistics.median(t)) for name, t in times.items()}


def tolerance_sweep(
    problem: Any, guess: np.ndarray, orbit_tol: float, reference: np.ndarray, log: Callable[[str], None]
) -> list[dict[str, Any]]:
    """One run of the baseline at each of ``TOLERANCES``: its fixed point's error (max-norm over
    the unknowns) against ``reference`` (n,), iterations, step maps, residual, wall time (s)."""
    idx = problem.unknown_idx
    sweep = []
    for tol_b in TOLERANCES:
        start = time.perf_counter()
        base = scipy_newton(problem, guess, tol_b, orbit_tol)
        wall = time.perf_counter() - start
        err = float(np.max(np.abs(base.fixed_point[idx] - reference[idx])))
        sweep.append(
            {
                "tol": tol_b,
                "error": err,
                "iterations": base.iterations,
                "step_maps": base.step_maps,
                "residual": base.residual,
                "wall_s": wall,
            }
        )
        log(f"scipy tol {tol_b:g}: error {err:.2e}, {base.step_maps} step maps, {1e3 * wall:.1f} ms")
    return sweep


def measure(
    scene_name: str = "compass_gait", repeats: int = 7, log: Callable[[str], None] | None = None
) -> dict[str, Any]:
    """Everything ``legsim bench orbit`` prints (the keys of its ``--json``). Besides the
    baseline at the loosest tolerance reaching legsim's error, the next looser one (less
    accurate than legsim) is timed too: the ratio at exactly equal error lies between the two."""
    from ..orbits import find_orbit
    from ..scene import load_scene
    from ..scene.orbit import problem_from_scene

    log = log or (lambda s: None)
    settings = problem_from_scene(load_scene(scene_name))
    problem, guess, tol = settings.problem, settings.guess, settings.solver.get("tol", 1e-9)

    def run_legsim() -> Any:
        st = problem_from_scene(load_scene(scene_name))
        return find_orbit(st.problem, st.guess, **st.solver)

    ours = run_legsim()
    if not ours.converged:
        raise BenchError(f"bench orbit: legsim found no orbit of {scene_name}: {ours.message}")
    reference = scipy_newton(problem, guess, REFERENCE_TOL, 0.0)
    idx = problem.unknown_idx
    error = float(np.max(np.abs(ours.fixed_point[idx] - reference.fixed_point[idx])))
    log(f"legsim error {error:.2e} against the reference (residual {reference.residual:.1e})")
    sweep = tolerance_sweep(problem, guess, tol, reference.fixed_point, log)
    at = next((i for i, row in enumerate(sweep) if row["error"] <= error and row["residual"] <= tol), None)
    if at is None:
        raise BenchError(
            f"bench orbit: the baseline reaches legsim's error {error:.2e} at no tolerance down to {TOLERANCES[-1]:g}"
        )
    chosen, looser = sweep[at], (sweep[at - 1] if at > 0 else None)

    def baseline(tol_b: float, multipliers: bool) -> Callable[[], Any]:
        def call() -> Any:
            st = problem_from_scene(load_scene(scene_name))  # the same set-up: the scene's model is built
            return scipy_newton(st.problem, st.guess, tol_b, tol, multipliers)

        return call

    calls = {
        "legsim": run_legsim,
        "scipy": baseline(chosen["tol"], False),
        "scipy_multipliers": baseline(chosen["tol"], True),
    }
    if looser is not None:
        calls["scipy_looser"] = baseline(looser["tol"], False)
    times = interleaved(calls, repeats)
    with_mu = baseline(chosen["tol"], True)()
    return {
        "scene": scene_name,
        "integrator": problem.integrator_settings,
        "orbit_tol": tol,
        "reference": {
            "tol": REFERENCE_TOL,
            "residual": reference.residual,
            "fixed_point": reference.fixed_point.tolist(),
        },
        "legsim": {
            "error": error,
            "iterations": ours.iterations,
            "simulations": ours.evaluations,
            "residual": ours.residual,
            "wall_s": times["legsim"],
            "multipliers": [[m.real, m.imag] for m in ours.multipliers],
        },
        "scipy": dict(
            chosen,
            wall_s=times["scipy"],
            wall_with_multipliers_s=times["scipy_multipliers"],
            multipliers=[[m.real, m.imag] for m in with_mu.multipliers],
        ),
        "scipy_looser": None
        if looser is None
        else dict(looser, wall_s=times["scipy_looser"], ratio=times["scipy_looser"] / times["legsim"]),
        "sweep": sweep,
        "repeats": repeats,
        "ratio": times["scipy"] / times["legsim"],
        "ratio_with_multipliers": times["scipy_multipliers"] / times["legsim"],
    }


def format_report(r: dict[str, Any]) -> str:
    """The human-readable report of ``measure``."""
    from ..orbits.problem import describe_integrator

    L, S = r["legsim"], r["scipy"]
    verdict = "MET" if r["ratio"] >= 1.0 else "MISSED"
    lines = [
        f"# orbit {r['scene']}: legsim orbit against scipy Newton on solve_ivp DOP853 + events",
        f"reference: scipy Newton at rtol = atol = {r['reference']['tol']:g}, residual "
        f"{r['reference']['residual']:.1e}",
        f"legsim ({describe_integrator(r['integrator'])}, tol {r['orbit_tol']:g}): error {L['error']:.2e}, "
        f"{L['iterations']} iterations, {L['simulations']} simulations, saltation Jacobian",
        "scipy tolerance sweep (rtol = atol; Newton with forward-difference Jacobian):",
    ]
    for row in r["sweep"]:
        lines.append(
            f"  tol {row['tol']:<7g} error {row['error']:.2e}  {row['iterations']} iterations, "
            f"{row['step_maps']} step maps, {1e3 * row['wall_s']:.1f} ms (one run)"
        )
    lines += [
        f"baseline: tol {S['tol']:g}, the loosest with error <= legsim's ({S['error']:.2e})",
        f"median of {r['repeats']} interleaved repeats (scene loaded and model built in each):",
        f"  legsim orbit (fixed point, period, multipliers)   {1e3 * L['wall_s']:8.1f} ms",
        f"  scipy Newton (fixed point)                        {1e3 * S['wall_s']:8.1f} ms",
        f"  scipy Newton (fixed point, multipliers)           {1e3 * S['wall_with_multipliers_s']:8.1f} ms",
        f"ratio scipy / legsim: {r['ratio']:.2f} (fixed point only), {r['ratio_with_multipliers']:.2f} "
        f"(with multipliers)",
        *(
            []
            if r["scipy_looser"] is None
            else [
                f"  (scipy at the next looser tol {r['scipy_looser']['tol']:g}, "
                f"error {r['scipy_looser']['error']:.2e} "
                f"> legsim's: {1e3 * r['scipy_looser']['wall_s']:.1f} ms, ratio {r['scipy_looser']['ratio']:.2f})"
            ]
        ),
        f"target: legsim orbit no slower than the scipy baseline at equal accuracy: {verdict}",
    ]
    return "\n".join(lines)


def main(
    scene_name: str = "compass_gait", repeats: int = 7, as_json: bool = False, log: Callable[[str], None] | None = None
) -> int:
    """``legsim bench orbit``: measure and print the report (or its JSON)."""
    import json

    r = measure(scene_name, repeats=repeats, log=log)
    print(json.dumps(r, indent=1) if as_json else format_report(r))
    return 0
