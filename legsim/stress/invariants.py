"""The invariants every stress case checks on its runs, each a function of an execution that
returns a ``Check`` (see the package docstring for the list), with the bounds and fits the cases
derive their checks from: ``step_floor`` (the shortest accepted step near a guard, which bounds
the number of transitions) and ``check_order`` (a fitted convergence order).

Every check can fail: tests/stress/test_invariants.py breaks a good execution for each of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..execution import Execution
from ..hybrid import HybridSystem
from .framework import Check

#: The control of a run, ``u(t, x)``, or None for a run without one.
Control = Callable[[float, np.ndarray], Any] | None

#: One-letter codes of the execution invariants in the table.
GENERIC = {
    "S": "status",
    "F": "finite",
    "T": "time increasing",
    "D": "in relaxed domain",
    "R": "resets in target domain",
    "E": "energy",
    "B": "transition bound",
}


def _control_at(control: Control, t: float, x: np.ndarray) -> Any:
    return None if control is None else control(t, x)


def check_finite(ex: Execution) -> Check:
    """Every stored state, derivative, strip point and reset image is finite."""
    bad = []
    for i, seg in enumerate(ex.segments):
        if not (np.all(np.isfinite(seg.x)) and np.all(np.isfinite(seg.dx)) and np.all(np.isfinite(seg.t))):
            bad.append(f"segment {i} ({seg.mode})")
    for k, tr in enumerate(ex.transitions):
        if not (np.all(np.isfinite(tr.state_before)) and np.all(np.isfinite(tr.state_after))):
            bad.append(f"transition {k} ({tr.name})")
    ok = not bad and ex.status != "non_finite"
    return Check("finite", ok, "all states finite" if ok else f"non-finite in {bad[:3]} (status {ex.status})")


def check_time(ex: Execution, strict: bool = True) -> Check:
    """Time strictly increasing inside every segment (``strict=False``: never decreasing), never
    going back between the pieces (segment end <= strip entry <= strip exit <= next segment
    start), and reaching t_end."""
    problems = []
    prev = ex.t0
    for i, seg in enumerate(ex.segments):
        steps = np.diff(seg.t)
        if len(seg.t) > 1 and not (np.all(steps > 0) if strict else np.all(steps >= 0)):
            problems.append(f"segment {i} ({seg.mode}) has {'non-increasing' if strict else 'decreasing'} times")
        if seg.t[0] < prev - 1e-12 * max(1.0, abs(prev)):
            problems.append(f"segment {i} starts at {seg.t[0]!r} before {prev!r}")
        prev = seg.t[-1]
        if i < len(ex.strips):
            strip = ex.strips[i]
            if strip.time < prev - 1e-12 * max(1.0, abs(prev)) or strip.exit_time < strip.time:
                problems.append(
                    f"strip {i} ({strip.name}) runs from {strip.time!r} to {strip.exit_time!r} "
                    f"after the segment ended at {prev!r}"
                )
            prev = strip.exit_time
    if ex.status == "finished" and abs(ex.t_end - ex.t_final) > 1e-9 * max(1.0, abs(ex.t_final)):
        problems.append(f"finished at {ex.t_end!r} instead of t_final {ex.t_final!r}")
    ok = not problems
    return Check("time increasing", ok, "monotone" if ok else "; ".join(problems[:3]))


def check_domain(
    system: HybridSystem, ex: Execution, eps: float, control: Control = None, stride: int = 1, tol: float | None = None
) -> Check:
    """No computed state lies past a guard of its mode by more than eps (plus ``tol``, default
    1e-9 eps: the crossing search's tolerance); every ``stride``-th segment point is checked,
    and every last point of a segment (the strip point of a crossing) always is."""
    tol = 1e-9 * eps if tol is None else tol
    worst = (0.0, "")
    checked = 0
    for seg in ex.segments:
        trs = system.outgoing(seg.mode)
        if not trs:
            continue
        idx = list(range(0, len(seg.t), max(1, stride)))
        if idx[-1] != len(seg.t) - 1:
            idx.append(len(seg.t) - 1)
        for i in idx:
            t, x = float(seg.t[i]), seg.x[i]
            u = _control_at(control, t, x)
            for tr in trs:
                g = tr.guard_value(x, t, u)
                checked += 1
                if g < worst[0]:
                    worst = (g, f"{tr.name} in mode '{seg.mode}' at t={t:.9g}")
    ok = worst[0] >= -eps - tol
    where = f" ({worst[1]})" if worst[1] else ""
    detail = f"lowest guard {worst[0]:.3g} >= -eps = {-eps:.3g}{where}, {checked} guard values"
    if stride > 1:
        detail += f" (every {stride}th point)"
    return Check("in relaxed domain", ok, detail if ok else f"lowest guard {worst[0]:.3g} < -eps = {-eps:.3g}{where}")


def check_resets(
    system: HybridSystem,
    ex: Execution,
    eps: float,
    control: Control = None,
    tol: float | None = None,
    rtol: float = 1e-12,
) -> Check:
    """Each strip point lies in the relaxed domain of its source; each reset image equals the
    reset of the strip point and lies in the relaxed domain of its target."""
    tol = 1e-9 * eps if tol is None else tol
    problems = []
    for k, tr in enumerate(ex.transitions):
        transition = system.taken(tr.source, tr.index, tr.name)
        u_before = _control_at(control, tr.time, tr.state_before)
        g_src = system.guard_values(tr.source, tr.state_before, tr.time, u_before)
        if g_src.size and g_src.min() < -eps - tol:
            problems.append(f"#{k} {tr.name}: strip point past a guard of '{tr.source}' by {-g_src.min():.3g}")
        image = tr.state_before.copy() if transition.reset is None else np.asarray(transition.reset(tr.state_before))
        scale = 1.0 + float(np.max(np.abs(image))) if image.size else 1.0
        if image.shape != tr.state_after.shape or np.max(np.abs(image - tr.state_after)) > rtol * scale:
            problems.append(f"#{k} {tr.name}: recorded image {tr.state_after.tolist()} != reset {image.tolist()}")
        u_after = _control_at(control, tr.exit_time, tr.state_after)
        g_tgt = system.guard_values(tr.target, tr.state_after, tr.exit_time, u_after)
        if g_tgt.size and g_tgt.min() < -eps - tol:
            problems.append(f"#{k} {tr.name}: reset image past a guard of '{tr.target}' by {-g_tgt.min():.3g}")
        if len(problems) >= 3:
            break
    ok = not problems and ex.status != "reset_outside_domain"
    if ok:
        return Check("resets in target domain", True, f"{len(ex.transitions)} strip points and reset images")
    return Check("resets in target domain", False, "; ".join(problems) or ex.message)


def energy_of(system: HybridSystem) -> Callable[[str, np.ndarray], float]:
    """The system's ``energy(mode, x)`` (J); a case that checks energy needs one."""
    energy = system.energy
    if energy is None:
        raise ValueError(f"{system.name}: the model defines no energy function to check")
    return energy


def energies(system: HybridSystem, ex: Execution, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(times, energies) at every ``stride``-th segment point and every segment's ends (J)."""
    energy = energy_of(system)
    ts, es = [], []
    for seg in ex.segments:
        idx = sorted(set(range(0, len(seg.t), max(1, stride))) | {len(seg.t) - 1})
        for i in idx:
            ts.append(float(seg.t[i]))
            es.append(float(energy(seg.mode, seg.x[i])))
    return np.array(ts), np.array(es)


def check_energy(system: HybridSystem, ex: Execution, kind: str, tol: float, stride: int = 1) -> Check:
    """``kind="conservative"``: |E - E(0)| <= tol everywhere; ``"dissipative"``: E never rises
    more than tol above its lowest earlier value. Transitions are included (resets)."""
    _ts, es = energies(system, ex, stride)
    if kind == "conservative":
        drift = float(np.max(np.abs(es - es[0])))
        ok = drift <= tol
        return Check("energy conserved", ok, f"max |E - E0| = {drift:.3g} J {'<=' if ok else '>'} {tol:.3g} J")
    if kind == "dissipative":
        rise = float(np.max(es - np.minimum.accumulate(es)))
        ok = rise <= tol
        return Check(
            "energy non-increasing",
            ok,
            f"largest rise {rise:.3g} J {'<=' if ok else '>'} {tol:.3g} J; E {es[0]:.6g} -> {es[-1]:.6g} J",
        )
    raise ValueError(f"energy kind must be 'conservative' or 'dissipative', got {kind!r}")


def check_transition_bound(ex: Execution, bound: float, why: str) -> Check:
    """At most ``bound`` transitions (derived by the case: ``why``), and the run did not stop on
    its transition budget."""
    n = len(ex.transitions)
    ok = n <= bound and ex.status != "max_transitions"
    detail = (
        f"{n} <= {bound:.6g} ({why})" if ok else f"{n} transitions (status {ex.status}) vs bound {bound:.6g} ({why})"
    )
    return Check("transition bound", ok, detail)


def first_accumulating_crossing(ex: Execution, name: str, window: float, after: float = -math.inf) -> int | None:
    """Index of the first crossing of transition ``name`` later than ``after`` (s) that ends a
    flight (from the previous crossing of ``name``'s strip exit, whatever happened between) no
    longer than ``window`` (s) and shorter than the flight before: where the accumulation rule
    (``legsim.relaxed.rules.accumulating``) fires, read off the execution's records. None when
    there is none."""
    previous_flight, last_exit = math.inf, None
    for k, record in enumerate(ex.transitions):
        if record.name != name:
            continue
        if last_exit is not None:
            flight = record.time - last_exit
            if record.time > after and flight <= window and flight < previous_flight:
                return k
            previous_flight = flight
        last_exit = record.exit_time
    return None


def check_accumulation(ex: Execution, expected: Sequence[tuple[str, float, float]]) -> Check:
    """The run's accumulation warnings (``Execution.warnings`` of kind ``accumulation``) are one
    per ``(transition, earliest, latest)`` expected, in order, each beginning in [earliest,
    latest] (s)."""
    found = [(w.details.get("transition"), w.time) for w in ex.warnings if w.kind == "accumulation"]
    ok = len(found) == len(expected) and all(
        name == want and lo <= t <= hi for (name, t), (want, lo, hi) in zip(found, expected, strict=True)
    )
    seen = ", ".join(f"{name} from {t:.9g} s" for name, t in found) or "none"
    wanted = ", ".join(f"{name} from [{lo:.9g}, {hi:.9g}] s" for name, lo, hi in expected) or "none"
    return Check("accumulation reported", ok, f"warnings: {seen}; expected: {wanted}")


def check_status(ex: Execution, expected: str | Sequence[str] = "finished") -> Check:
    """The run ended as expected."""
    allowed = (expected,) if isinstance(expected, str) else tuple(expected)
    ok = ex.status in allowed
    return Check("status", ok, f"{ex.status} at t = {ex.t_end:.6g}" + ("" if ok else f": {ex.message}"))


def execution_checks(
    system: HybridSystem,
    ex: Execution,
    eps: float,
    *,
    control: Control = None,
    status: str | Sequence[str] = "finished",
    energy: str | None = None,
    energy_tol: float = 0.0,
    bound: float | None = None,
    bound_why: str = "",
    stride: int = 1,
    strict_time: bool = True,
) -> list[Check]:
    """The invariants every case checks on a run (see the module docstring)."""
    checks = [
        check_status(ex, status),
        check_finite(ex),
        check_time(ex, strict_time),
        check_domain(system, ex, eps, control, stride),
        check_resets(system, ex, eps, control),
    ]
    if energy is not None:
        checks.append(check_energy(system, ex, energy, energy_tol, stride))
    if bound is not None:
        checks.append(check_transition_bound(ex, bound, bound_why))
    return checks


def step_floor(h: float, eps: float, rate: float | None = None, accel: float | None = None) -> float:
    """A floor under the length of every accepted step (s) near a guard that moves at most at
    ``rate`` (guard units/s) or accelerates away from rest at most at ``accel`` (units/s^2):
    a step of length s moves the guard by at most rate*s (or accel*s^2/2), so every step of
    length <= eps/rate (or sqrt(2 eps/accel)) lands in the relaxed domain and halving never goes
    below half of that. Every transition costs at least one accepted step, which bounds the
    number of transitions by (time span) / floor."""
    floor = h
    if rate is not None and rate > 0:
        floor = min(floor, 0.5 * eps / rate)
    if accel is not None and accel > 0:
        floor = min(floor, 0.5 * math.sqrt(2.0 * eps / accel))
    return floor


def transition_floor(h: float, eps: float, rate: float | None = None, accel: float | None = None) -> float:
    """A floor under the time (s) every transition costs: an accepted step (``step_floor``) or a
    strip, counted as eps (less 1e-9 of it for rounding). The usual transition bound is
    (time span) / transition_floor + 1."""
    return min(step_floor(h, eps, rate=rate, accel=accel), eps * (1 - 1e-9))


def slope(xs: Sequence[float], ys: Sequence[float]) -> float:
    """Least-squares slope of log(ys) against log(xs) (a convergence order)."""
    lx, ly = np.log(np.asarray(xs, dtype=float)), np.log(np.asarray(ys, dtype=float))
    return float(np.polyfit(lx, ly, 1)[0])


def check_order(
    name: str, xs: Sequence[float], errors: Sequence[float], low: float, high: float, label: str = "h"
) -> Check:
    """The errors shrink with the fitted order in [low, high] as ``xs`` shrink."""
    errors = [float(e) for e in errors]
    if min(errors) <= 0 or not all(math.isfinite(e) for e in errors):
        return Check(name, False, f"errors {errors} must be positive and finite to fit an order")
    p = slope(xs, errors)
    ok = low <= p <= high
    pairs = ", ".join(f"{x:g}: {e:.3g}" for x, e in zip(xs, errors, strict=True))
    return Check(name, ok, f"order {p:.2f} {'in' if ok else 'outside'} [{low}, {high}] ({label} -> error: {pairs})")
