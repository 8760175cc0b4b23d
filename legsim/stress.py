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
this module never imports ``robots`` or Pinocchio itself.
"""

from __future__ import annotations

import math
import re
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from .builders import Model, get_builder
from .execution import Execution
from .hybrid import HybridSystem, Mode, Transition
from .relaxed import simulate

# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------


@dataclass
class Check:
    """One invariant checked on a case: its name, whether it held, and the numbers behind it."""

    name: str
    passed: bool
    detail: str = ""

    def __post_init__(self) -> None:
        self.passed = bool(self.passed)  # numpy booleans are not JSON


@dataclass
class CaseResult:
    """What one case did and what was checked.

    Attributes
    ----------
    name, group: the case's name and group (zeno, grazing, simultaneous, resting, extremes).
    outcome: one line saying what happened (status, final mode, the behaviour of interest).
    transitions, steps: of the case's main run.
    wall_time: seconds for the whole case (all its runs and checks).
    checks: the invariants checked; the case passes when all hold and it did not crash.
    numbers: measured numbers worth reporting (errors, drifts, costs).
    error: the exception text when the case itself crashed.
    """

    name: str
    group: str
    outcome: str = ""
    transitions: int = 0
    steps: int = 0
    wall_time: float = 0.0
    checks: list[Check] = field(default_factory=list)
    numbers: dict[str, float] = field(default_factory=dict)
    error: str | None = None

    @property
    def passed(self) -> bool:
        return self.error is None and bool(self.checks) and all(c.passed for c in self.checks)

    @property
    def failures(self) -> list[str]:
        """Descriptions of what failed (empty when the case passed)."""
        out = [f"{c.name}: {c.detail}" for c in self.checks if not c.passed]
        if self.error is not None:
            out.append(f"crashed: {self.error}")
        if not self.checks and self.error is None:
            out.append("no invariant was checked")
        return out

    def add(self, check: Check | Iterable[Check]) -> None:
        if isinstance(check, Check):
            self.checks.append(check)
        else:
            self.checks.extend(check)

    def main_run(self, ex: Execution) -> None:
        """Record the transitions and steps of the case's main run."""
        self.transitions = len(ex.transitions)
        self.steps = ex.steps

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``legsim stress --json``)."""
        return {
            "name": self.name, "group": self.group, "passed": self.passed, "outcome": self.outcome,
            "transitions": self.transitions, "steps": self.steps, "wall_time_s": self.wall_time,
            "invariants": [c.name for c in self.checks],
            "checks": [{"name": c.name, "passed": c.passed, "detail": c.detail} for c in self.checks],
            "numbers": {k: _json_number(v) for k, v in self.numbers.items()},
            "error": self.error,
        }


def _json_number(v: Any) -> Any:
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    v = float(v)
    return v if math.isfinite(v) else str(v)


@dataclass(frozen=True)
class Case:
    """A stress case: ``run(quick) -> CaseResult``."""

    name: str
    group: str
    description: str
    run: Callable[[bool], CaseResult]


CASES: list[Case] = []
GROUPS = ("zeno", "grazing", "simultaneous", "resting", "extremes")


def case(name: str, group: str, description: str):
    """Register a case function ``fn(result, quick)`` that fills the given result."""
    if group not in GROUPS:
        raise ValueError(f"unknown group {group!r}")

    def register(fn: Callable[[CaseResult, bool], None]) -> Callable[[CaseResult, bool], None]:
        def run(quick: bool) -> CaseResult:
            result = CaseResult(name, group)
            start = time.perf_counter()
            try:
                fn(result, quick)
            except Exception as exc:  # a crash is a failed case with its reason, not a crashed suite
                result.error = f"{type(exc).__name__}: {exc}"
                result.numbers["traceback"] = traceback.format_exc(limit=3)[-600:]
            result.wall_time = time.perf_counter() - start
            return result

        CASES.append(Case(name, group, description, run))
        return fn

    return register


def select(names: Sequence[str] | None = None) -> list[Case]:
    """The cases named by ``names`` (all cases when None or empty), in group order: a name
    selects the case of that exact name, else the group of that name, else every case whose name
    contains it."""
    ordered = sorted(CASES, key=lambda c: GROUPS.index(c.group))  # stable: registration order within a group
    if not names:
        return ordered

    def matches(n: str, c: Case) -> bool:
        if any(n == other.name for other in CASES):
            return n == c.name
        if n in GROUPS:
            return n == c.group
        return n in c.name

    return [c for c in ordered if any(matches(n, c) for n in names)]


def run_suite(quick: bool = True, names: Sequence[str] | None = None,
              progress: Callable[[Case, CaseResult], None] | None = None) -> list[CaseResult]:
    """Run the selected cases (quick or full form) in order; ``progress(case, result)`` after each."""
    out = []
    for c in select(names):
        result = c.run(quick)
        out.append(result)
        if progress is not None:
            progress(c, result)
    return out


def format_table(results: Sequence[CaseResult]) -> str:
    """The table ``legsim stress`` prints: one row per case, then the failures spelled out."""
    header = ("case", "outcome", "trans.", "steps", "wall s", "invariants checked", "verdict")
    rows = []
    for r in results:
        rows.append((r.name, r.outcome, str(r.transitions), str(r.steps), f"{r.wall_time:.2f}",
                     invariant_summary(r.checks), "pass" if r.passed else "FAIL"))
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(header)]
    widths[1] = min(widths[1], 64)
    widths[5] = min(widths[5], 64)

    def line(cells):
        out = []
        for i, cell in enumerate(cells):
            text = cell if len(cell) <= widths[i] else cell[:widths[i] - 3] + "..."
            out.append(text.rjust(widths[i]) if i in (2, 3, 4) else text.ljust(widths[i]))
        return "  ".join(out).rstrip()

    lines = [line(header), line(["-" * w for w in widths])]
    lines.extend(line(row) for row in rows)
    failed = [r for r in results if not r.passed]
    lines.append("")
    lines.append("invariants: " + ", ".join(f"{k} {v}" for k, v in GENERIC.items())
                 + "; then the case's own checks (see --json for all of them with their numbers)")
    lines.append(f"{len(results) - len(failed)} of {len(results)} cases passed")
    for r in failed:
        for f in r.failures:
            lines.append(f"FAIL {r.name}: {f}")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# invariants
# ---------------------------------------------------------------------------------------------

#: One-letter codes of the execution invariants in the table.
GENERIC = {"S": "status", "F": "finite", "T": "time increasing", "D": "in relaxed domain",
           "R": "resets in target domain", "E": "energy", "B": "transition bound"}


def invariant_summary(checks: Sequence[Check]) -> str:
    """``SFTDREB + own checks``: the execution invariants by letter, then the case's own."""
    names = list(dict.fromkeys(c.name for c in checks))
    letters = "".join(k for k, v in GENERIC.items()
                      if any(n == v or (k == "E" and n.startswith("energy ")) for n in names))
    own = [n for n in names if n not in GENERIC.values() and not n.startswith("energy ")]
    # drop a run's label, "converges (d = 1e-06)" -> "converges"; keep "eq. (31)"
    own = list(dict.fromkeys(re.sub(r" \((?=[^()]*[=#])[^()]*\)$", "", n) for n in own))
    return letters + (" + " + "; ".join(own) if own else "")


def _control_at(control, t, x):
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
                problems.append(f"strip {i} ({strip.name}) runs from {strip.time!r} to {strip.exit_time!r} "
                                f"after the segment ended at {prev!r}")
            prev = strip.exit_time
    if ex.status == "finished" and abs(ex.t_end - ex.t_final) > 1e-9 * max(1.0, abs(ex.t_final)):
        problems.append(f"finished at {ex.t_end!r} instead of t_final {ex.t_final!r}")
    ok = not problems
    return Check("time increasing", ok, "monotone" if ok else "; ".join(problems[:3]))


def check_domain(system: HybridSystem, ex: Execution, eps: float, control=None, stride: int = 1,
                 tol: float | None = None) -> Check:
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


def check_resets(system: HybridSystem, ex: Execution, eps: float, control=None, tol: float | None = None,
                 rtol: float = 1e-12) -> Check:
    """Each strip point lies in the relaxed domain of its source; each reset image equals the
    reset of the strip point and lies in the relaxed domain of its target."""
    tol = 1e-9 * eps if tol is None else tol
    problems = []
    for k, tr in enumerate(ex.transitions):
        transition = system.outgoing(tr.source)[tr.index]
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


def energies(system: HybridSystem, ex: Execution, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(times, energies) at every ``stride``-th segment point and every segment's ends (J)."""
    ts, es = [], []
    for seg in ex.segments:
        idx = sorted(set(range(0, len(seg.t), max(1, stride))) | {len(seg.t) - 1})
        for i in idx:
            ts.append(float(seg.t[i]))
            es.append(float(system.energy(seg.mode, seg.x[i])))
    return np.array(ts), np.array(es)


def check_energy(system: HybridSystem, ex: Execution, kind: str, tol: float, stride: int = 1) -> Check:
    """``kind="conservative"``: |E - E(0)| <= tol everywhere; ``"dissipative"``: E never rises
    more than tol above its lowest earlier value. Transitions are included (resets)."""
    ts, es = energies(system, ex, stride)
    if kind == "conservative":
        drift = float(np.max(np.abs(es - es[0])))
        ok = drift <= tol
        return Check("energy conserved", ok, f"max |E - E0| = {drift:.3g} J {'<=' if ok else '>'} {tol:.3g} J")
    if kind == "dissipative":
        rise = float(np.max(es - np.minimum.accumulate(es)))
        ok = rise <= tol
        return Check("energy non-increasing", ok,
                     f"largest rise {rise:.3g} J {'<=' if ok else '>'} {tol:.3g} J; E {es[0]:.6g} -> {es[-1]:.6g} J")
    raise ValueError(f"energy kind must be 'conservative' or 'dissipative', got {kind!r}")


def check_transition_bound(ex: Execution, bound: float, why: str) -> Check:
    """At most ``bound`` transitions (derived by the case: ``why``), and the run did not stop on
    its transition budget."""
    n = len(ex.transitions)
    ok = n <= bound and ex.status != "max_transitions"
    detail = f"{n} <= {bound:.6g} ({why})" if ok else f"{n} transitions (status {ex.status}) vs bound {bound:.6g} ({why})"
    return Check("transition bound", ok, detail)


def check_status(ex: Execution, expected: str | Sequence[str] = "finished") -> Check:
    """The run ended as expected."""
    allowed = (expected,) if isinstance(expected, str) else tuple(expected)
    ok = ex.status in allowed
    return Check("status", ok, f"{ex.status} at t = {ex.t_end:.6g}" + ("" if ok else f": {ex.message}"))


def execution_checks(system: HybridSystem, ex: Execution, eps: float, *, control=None,
                     status: str | Sequence[str] = "finished", energy: str | None = None,
                     energy_tol: float = 0.0, bound: float | None = None, bound_why: str = "",
                     stride: int = 1, strict_time: bool = True) -> list[Check]:
    """The invariants every case checks on a run (see the module docstring)."""
    checks = [check_status(ex, status), check_finite(ex), check_time(ex, strict_time),
              check_domain(system, ex, eps, control, stride), check_resets(system, ex, eps, control)]
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


def slope(xs: Sequence[float], ys: Sequence[float]) -> float:
    """Least-squares slope of log(ys) against log(xs) (a convergence order)."""
    lx, ly = np.log(np.asarray(xs, dtype=float)), np.log(np.asarray(ys, dtype=float))
    return float(np.polyfit(lx, ly, 1)[0])


def check_order(name: str, xs: Sequence[float], errors: Sequence[float], low: float, high: float,
                label: str = "h") -> Check:
    """The errors shrink with the fitted order in [low, high] as ``xs`` shrink."""
    errors = [float(e) for e in errors]
    if min(errors) <= 0 or not all(math.isfinite(e) for e in errors):
        return Check(name, False, f"errors {errors} must be positive and finite to fit an order")
    p = slope(xs, errors)
    ok = low <= p <= high
    pairs = ", ".join(f"{x:g}: {e:.3g}" for x, e in zip(xs, errors))
    return Check(name, ok, f"order {p:.2f} {'in' if ok else 'outside'} [{low}, {high}] ({label} -> error: {pairs})")


def build(robot: str, parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """A model built by a registered builder, as a scene would build it."""
    return get_builder(robot).make(parameters or {}, effects or {})


def _state(model: Model, mode: str, values: dict[str, float] | None = None) -> np.ndarray:
    names = model.system.state_names(mode)
    merged = {**model.initial_state, **(values or {})}
    return np.array([float(merged[n]) for n in names])


# ---------------------------------------------------------------------------------------------
# Zeno: the bouncing ball
# ---------------------------------------------------------------------------------------------


def ball_flight_checks(ex: Execution, g: float, eps: float, resolved: float) -> Check:
    """Free fall is a cubic in time, which RK4 and the Hermite crossing reproduce to rounding:
    every flight of the relaxed execution (from a strip exit to the next crossing) must last
    exactly 2 w / g for its take-off speed w, whatever the holds in the strips. Flights shorter
    than ``resolved`` (s) are skipped: they start from a strip point whose height (|z| <= 1e-9
    eps) is comparable to the flight itself."""
    worst, count = 0.0, 0
    for a, b in zip(ex.transitions[:-1], ex.transitions[1:]):
        z0, w = a.state_after
        flight = b.time - a.exit_time
        expected = (w + math.sqrt(max(w * w + 2.0 * g * z0, 0.0))) / g
        if expected < resolved or w <= 0:
            continue
        count += 1
        # the crossing is located to 1e-9 eps in height, i.e. to 1e-9 eps / w in time, at each end
        worst = max(worst, abs(flight - expected) / (1e-9 + 4e-9 * eps / w))
    ok = count > 0 and worst <= 1.0
    return Check("flights exact", ok, f"{count} flights equal 2 w/g to the crossing tolerance (worst ratio {worst:.2g})"
                 if ok else f"{count} flights checked, worst error {worst:.3g} x (1e-9 s + 4e-9 eps/w)")


def ball_rest_check(ex: Execution, c: float, g: float, eps: float, t_from: float, t_to: float) -> Check:
    """After its Zeno time the ball rests on the floor: between t_from and t_to its height stays
    in [-eps, eps c^2/(1 - c^2)] and its speed below sqrt(2 g eps/(1 - c^2)). (Resting, every
    cycle takes off from the strip point with w = c v, v^2 <= w^2 + 2 g eps: the fixed point of
    w^2 = c^2 (w^2 + 2 g eps) bounds the apex w^2/(2 g) and the speed.)"""
    times = np.linspace(t_from, t_to, 400)
    states = np.array(ex.sample(times).states)
    z_hi = eps * c * c / (1.0 - c * c) if c < 1 else math.inf
    v_hi = math.sqrt(2.0 * g * eps / (1.0 - c * c)) if c < 1 else math.inf
    slack = 1e-9 * eps
    z_min, z_max, v_max = float(states[:, 0].min()), float(states[:, 0].max()), float(np.abs(states[:, 1]).max())
    ok = z_min >= -eps - slack and z_max <= z_hi + slack and v_max <= v_hi + slack
    return Check("rests on the floor", ok,
                 f"t in [{t_from:.3g}, {t_to:.3g}] s: z in [{z_min:.2g}, {z_max:.2g}] within [-eps, {z_hi:.2g}] m, "
                 f"|zd| <= {v_max:.2g} <= {v_hi:.2g} m/s" if ok else
                 f"t in [{t_from:.3g}, {t_to:.3g}] s: z in [{z_min:.3g}, {z_max:.3g}] vs [-eps, {z_hi:.3g}] m, "
                 f"|zd| up to {v_max:.3g} vs {v_hi:.3g} m/s")


def _zeno_ball(result: CaseResult, quick: bool, c: float) -> None:
    g, z0 = 9.81, 1.0
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    system = model.system
    T = 2.0 * ref.zeno_time
    h, eps = 1e-3, 1e-4
    floor = min(step_floor(h, eps, accel=g), eps * (1 - 1e-9))
    bound = (T - ref.first_impact) / floor + 1
    ex = simulate(system, [z0, 0.0], "flight", T, h, eps, max_transitions=int(2 * bound) + 10)
    result.main_run(ex)
    result.add(execution_checks(system, ex, eps, energy="dissipative", energy_tol=1e-9, bound=bound,
                                bound_why=f"(T - t1)/{floor:.3g} s: a step or a strip per transition"))
    result.add(ball_flight_checks(ex, g, eps, resolved=4 * h))
    result.add(ball_rest_check(ex, c, g, eps, 1.5 * ref.zeno_time, T))
    # Convergence: the relaxed impacts lag the exact ones by the strips they held; the lag of a
    # late impact before the Zeno time shrinks like h + eps.
    k = 6
    levels = [(2e-3, 2e-4), (1e-3, 1e-4), (5e-4, 5e-5)] + ([] if quick else [(2.5e-4, 2.5e-5), (1.25e-4, 1.25e-5)])
    lags = []
    t_k = float(ref.impact_time(k))
    for hh, ee in levels:
        run = simulate(system, [z0, 0.0], "flight", t_k + 0.5 * (ref.zeno_time - t_k), hh, ee)
        lags.append(run.transitions[k - 1].time - t_k)
    result.add(check_order(f"impact {k} lag -> 0", [lv[0] for lv in levels], lags, 0.7, 1.3, "h (eps = h/10)"))
    after = sum(tr.time > ref.zeno_time for tr in ex.transitions)
    result.numbers.update({"zeno_time": ref.zeno_time, "transitions_after_zeno": after,
                           "lag_impact6_h1e-3": lags[1]})
    z_end = ex.final_state
    result.outcome = (f"{ex.status}; {len(ex.transitions) - after} impacts before t_zeno = {ref.zeno_time:.4g} s, "
                      f"rests (z = {z_end[0]:.1g} m) to {T:.3g} s")


@case("zeno_ball_c0.5", "zeno", "bouncing ball, c = 0.5, through and past its Zeno time (to twice it)")
def _zeno_ball_half(result: CaseResult, quick: bool) -> None:
    _zeno_ball(result, quick, 0.5)


@case("zeno_ball_c0.8", "zeno", "bouncing ball, c = 0.8, through and past its Zeno time (to twice it)")
def _zeno_ball_08(result: CaseResult, quick: bool) -> None:
    _zeno_ball(result, quick, 0.8)


@case("zeno_ball_c0.8_continued", "zeno", "bouncing ball, c = 0.8, Zeno continuation: the plain bounces, then rest")
def _zeno_ball_continued(result: CaseResult, quick: bool) -> None:
    g, z0, c, h, eps = 9.81, 1.0, 0.8, 1e-3, 1e-4
    window = h + eps
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}, "zeno": {"window": window}})
    plain_model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    T = 2.0 * ref.zeno_time
    # the exact impacts leave at c^k v1 and the continuation keeps those with c^k v1 >= g window / 2
    bound = math.log(c * ref.impact_speed / (0.5 * g * window)) / math.log(1.0 / c) + 3
    start = time.perf_counter()
    ex = simulate(model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=1000)
    cost = time.perf_counter() - start
    result.main_run(ex)
    result.add(execution_checks(model.system, ex, eps, energy="dissipative", energy_tol=1e-9, bound=bound,
                                bound_why="log(c v1/w_th)/log(1/c) + 2 bounces and the rest"))
    result.add(ball_flight_checks(ex, g, eps, resolved=4 * h))
    start = time.perf_counter()
    plain = simulate(plain_model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=10 ** 6)
    plain_cost = time.perf_counter() - start
    kept = ex.transitions[:-1]
    same = [a.exit_time for a in kept] == [b.exit_time for b in plain.transitions[:len(kept)]]
    rests = ex.final_mode == "rest" and ex.transitions[-1].name == "rest"
    v = abs(float(ex.transitions[-1].state_before[1]))
    t_rest = ex.transitions[-1].time
    early = 2 * c * v / (g * (1 - c))
    ok = same and rests and ref.zeno_time - early - 1e-12 <= t_rest <= ref.zeno_time + len(kept) * window
    result.add(Check("plain bounces, then rest", ok,
                     f"{len(kept)} bounces identical to the plain run's, rest at {t_rest:.5g} s (t_zeno "
                     f"{ref.zeno_time:.5g} s; the skipped tail is {early:.2g} s)"))
    result.numbers.update({"transitions_plain": len(plain.transitions), "wall_s": cost, "wall_s_plain": plain_cost})
    result.outcome = (f"{ex.status} in '{ex.final_mode}'; {len(ex.transitions)} transitions vs "
                      f"{len(plain.transitions)} plain ({cost:.2g} s vs {plain_cost:.2g} s)")


# ---------------------------------------------------------------------------------------------
# Zeno: the double pendulum with a stop (paper 003 Fig. 2c)
# ---------------------------------------------------------------------------------------------


def _pendulum(c: float, window: float | None) -> tuple[Model, np.ndarray]:
    effects: dict[str, Any] = {"stop": {"restitution": c}}
    if window is not None:
        effects["zeno"] = {"window": window}
    model = build("double_pendulum", {}, effects)
    return model, _state(model, "unconstrained")


def flight_ratios(ex: Execution, n: int) -> list[float]:
    """Ratios of successive flights (strip exit to next crossing) of the first n+1 bounces."""
    flights = [b.time - a.exit_time for a, b in zip(ex.transitions[:-1], ex.transitions[1:])
               if a.source == a.target]
    # The first flight follows the first impact, before which the motion was not a bounce.
    return [b / a for a, b in zip(flights[1:n + 1], flights[2:n + 2])]


def max_guard_accel(system: HybridSystem, ex: Execution, coordinate: int, stride: int = 1) -> float:
    """Largest |d^2 q/dt^2| of a coordinate (index in the state's velocity block) over the run."""
    best = 0.0
    for seg in ex.segments:
        field = system.mode(seg.mode).field
        for x, t in zip(seg.x[::stride], seg.t[::stride]):
            best = max(best, abs(float(np.asarray(field(t, x, None))[coordinate])))
    return best


@case("zeno_double_pendulum_c0.5", "zeno",
      "double pendulum, stop c = 0.5 (paper 003 Fig. 2c), plain relaxed: impacts accumulate, the run carries on")
def _zeno_pendulum_plain(result: CaseResult, quick: bool) -> None:
    h, eps, c = 1e-3, 1e-3, 0.5
    T = 2.5 if quick else 5.0
    model, x0 = _pendulum(c, None)
    system = model.system
    ex = simulate(system, x0, "unconstrained", T, h, eps, max_transitions=10 ** 6)
    result.main_run(ex)
    a_max = 2.0 * max_guard_accel(system, ex, 3)  # theta2'' measured on the run, with a factor 2 of slack
    floor = min(step_floor(h, eps, accel=a_max), eps * (1 - 1e-9))
    bound = T / floor + 1
    result.add(execution_checks(system, ex, eps, energy="dissipative", energy_tol=1e-7, bound=bound,
                                bound_why=f"T/{floor:.3g} s, |theta2''| <= {a_max:.3g} rad/s^2"))
    ratios = flight_ratios(ex, 6)
    ok = len(ratios) == 6 and all(abs(r - c) <= 0.02 for r in ratios)
    result.add(Check("flights shrink by c", ok, "ratios " + ", ".join(f"{r:.3f}" for r in ratios)))
    # Where the flights are shorter than one step the stop chatters: theta2 stays in the strip's
    # band (the ball's bound with the largest acceleration).
    short = [tr.time for a, tr in zip(ex.transitions[:-1], ex.transitions[1:]) if tr.time - a.exit_time < h]
    t_chatter = short[0] if short else T
    times = np.linspace(t_chatter, T, 300)
    th2 = np.array([s[1] for s in ex.sample(times).states])
    hi = eps * c * c / (1 - c * c)
    ok = short != [] and th2.min() >= -eps * (1 + 1e-9) and th2.max() <= hi * (1 + 1e-9)
    result.add(Check("stop chatters in its strip", ok,
                     f"from {t_chatter:.4g} s theta2 in [{th2.min():.2g}, {th2.max():.2g}] within [-eps, {hi:.2g}] rad"))
    # The finding: while the stop chatters every step crosses at its start, and the relaxed
    # algorithm holds the whole state at the strip point: link 1 stops swinging.
    th1 = np.array([s[0] for s in ex.sample(times).states])
    frozen = float(np.ptp(th1))
    result.numbers.update({"chatter_from": t_chatter, "theta1_range_while_chattering": frozen,
                           "transitions": len(ex.transitions)})
    result.outcome = (f"{ex.status}; {len(ex.transitions) - len(short)} resolved impacts, chatters from "
                      f"{t_chatter:.3g} s; whole state held (theta1 range {frozen:.1g} rad)")


@case("zeno_double_pendulum_c0.5_continued", "zeno",
      "double pendulum, stop c = 0.5, Zeno continuation: rests in the constrained mode, released where eq. (31) changes sign")
def _zeno_pendulum_continued(result: CaseResult, quick: bool) -> None:
    h, eps, c = 1e-3, 1e-3, 0.5
    T = 2.5 if quick else 5.0
    model, x0 = _pendulum(c, h + eps)
    system = model.system
    ex = simulate(system, x0, "unconstrained", T, h, eps, max_transitions=1000)
    result.main_run(ex)
    rests = [tr for tr in ex.transitions if tr.name == "rest_stop"]
    releases = [tr for tr in ex.transitions if tr.name == "release_stop"]
    # Bound: in each accumulation (the impacts since the last release) the impacts that press
    # link 2 onto the stop (free theta2'' < 0, acceleration a_n = -theta2'') leave with speeds
    # falling by c, from w1 = c max|theta2'| to the threshold a_n window / 2 at the least a_n:
    # at most log(w1/w_th)/log(1/c) + 2 of them. Impacts pulling away end long flights and are
    # counted as they come, as are the rests and releases.
    free = system.mode("unconstrained").field
    bound, groups, pressing = 0.0, [[]], []
    for tr in ex.transitions:
        if tr.name == "bounce_stop" and -float(free(tr.time, tr.state_before, None)[3]) > 0:
            groups[-1].append(tr)
        else:
            bound += 1
        if tr.name == "release_stop":
            groups.append([])
    for grp in groups:
        if grp:
            w1 = c * max(abs(float(tr.state_before[3])) for tr in grp)
            a_n = min(-float(free(tr.time, tr.state_before, None)[3]) for tr in grp)
            bound += math.log(max(w1 / (0.5 * a_n * (h + eps)), 1.0)) / math.log(1.0 / c) + 2
            pressing.append(len(grp))
    result.add(execution_checks(system, ex, eps, energy="dissipative", energy_tol=1e-7, bound=bound,
                                bound_why=f"pressing impacts per accumulation {pressing} <= log(w1/w_th)/log(1/c) + 2"))
    # The stop torque of the straight rigid pendulum (theta2 = 0) is m2 L2 g sin(theta1) (1 - L (m1 L1 +
    # m2 L)/(m1 L1^2 + m2 L^2)) with L = L1 + L2: with unit masses and lengths -0.2 g sin(theta1), so
    # the release is exactly where theta1 crosses zero.
    th1 = [abs(float(tr.state_before[0])) for tr in releases]
    ok = len(releases) >= 1 and max(th1) <= 1e-6
    result.add(Check("released where eq. (31) changes sign", ok,
                     f"{len(releases)} release(s) at |theta1| <= {max(th1, default=math.nan):.2g} rad (closed form 0)"))
    # Between each rest and the next release the pendulum is in its constrained mode.
    ends = [tr.time for tr in rests]
    spans = [(r.exit_time, next((q.time for q in releases if q.time > r.time), ex.t_end)) for r in rests]
    modes = [set(ex.sample(np.linspace(a, b, 50, endpoint=False)).modes) for a, b in spans if b > a]
    ok = bool(rests) and all(m == {"constrained"} for m in modes)
    result.add(Check("rests in the constrained mode", ok,
                     "constrained on " + ", ".join(f"[{a:.4g}, {b:.4g}]" for a, b in spans) + " s"))
    # Cost and agreement with the plain relaxed run up to the accumulation.
    plain = simulate(_pendulum(c, None)[0].system, x0, "unconstrained",
                     ends[0] - 0.05, h, eps, max_transitions=10 ** 6)
    gap = float(np.max(np.abs(plain.final_state - ex.sample([plain.t_end]).states[0])))
    result.add(Check("agrees with plain run before resting", gap <= 1e-9,
                     f"|x_plain - x_continued| = {gap:.2g} at t = {plain.t_end:.4g} s"))
    # Convergence: the rest and release times converge as h = eps shrinks (successive differences
    # shrink at least like h^0.5; the number of resolved flights grows like log(1/h)).
    levels = [4e-3, 2e-3, 1e-3] if quick else [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]
    times = []
    for hh in levels:
        m_l, _ = _pendulum(c, 2 * hh)
        run = simulate(m_l.system, x0, "unconstrained", 2.5, hh, hh, max_transitions=1000)
        times.append(next(tr.time for tr in run.transitions if tr.name == "release_stop"))
    diffs = [abs(a - b) for a, b in zip(times[:-1], times[1:])]
    result.add(check_order("release time converges", levels[:-1], diffs, 0.5, 1.5, "h = eps"))
    result.numbers.update({"rest_time": ends[0], "release_times": ", ".join(f"{tr.time:.6g}" for tr in releases)})
    result.outcome = (f"{ex.status} in '{ex.final_mode}'; rests at {ends[0]:.4g} s, released at "
                      f"{', '.join(f'{tr.time:.4g}' for tr in releases)} s")


# ---------------------------------------------------------------------------------------------
# Zeno: the two-tank system (paper 004 Sec. IV-D)
# ---------------------------------------------------------------------------------------------


def _two_tanks_run(h: float, eps: float, T: float, method: str = "rk4"):
    model = build("two_tanks")
    ref = model.reference
    x0 = _state(model, "q1")
    rate = max(abs(ref.w - ref.v1), ref.v1, ref.v2, abs(ref.w - ref.v2))
    floor = min(step_floor(h, eps, rate=rate), eps * (1 - 1e-9))
    bound = T / floor + 1
    ex = simulate(model.system, x0, "q1", T, h, eps, method=method, max_transitions=int(2 * bound) + 10)
    return model, ref, x0, ex, bound, floor, rate


def tank_switch_checks(ex: Execution, ref: Any, x0: np.ndarray, count: int) -> Check:
    """Constant fields are integrated exactly and the guards are linear, so the relaxed execution
    is the exact one with pauses: its k-th strip point is the exact k-th switching state, and its
    k-th crossing time the exact one plus the strip time held before it."""
    times, _ = ref.switching_times("q1", x0, count)
    worst_x, worst_t, held = 0.0, 0.0, 0.0
    x = np.array(x0, dtype=float)
    flows = {"q1": np.array([ref.w - ref.v1, -ref.v2]), "q2": np.array([-ref.v1, ref.w - ref.v2])}
    t_prev, mode = 0.0, "q1"
    n = min(count, len(ex.transitions))
    for k in range(n):
        x = x + (times[k] - t_prev) * flows[mode]
        if mode == "q1":
            x[1] = ref.r2
        else:
            x[0] = ref.r1
        tr = ex.transitions[k]
        worst_x = max(worst_x, float(np.max(np.abs(tr.state_before - x))))
        worst_t = max(worst_t, abs(tr.time - (times[k] + held)))
        held += tr.exit_time - tr.time
        t_prev, mode = times[k], tr.target
    ok = n == count and worst_x <= 1e-9 and worst_t <= 1e-9
    return Check("switches exact", ok, f"first {n} strip points = exact switching states to {worst_x:.2g} m, "
                                       f"crossing times = exact + held strips to {worst_t:.2g} s")


@case("zeno_two_tanks", "zeno", "two tanks, one switched inflow (paper 004 Sec. IV-D): through its Zeno time 8 s to 10 s")
def _zeno_two_tanks(result: CaseResult, quick: bool) -> None:
    h, eps, T = 0.01, 1e-3, 10.0
    model, ref, x0, ex, bound, floor, rate = _two_tanks_run(h, eps, T)
    result.main_run(ex)
    result.add(execution_checks(model.system, ex, eps, bound=bound,
                                bound_why=f"T/{floor:.3g} s: each transition costs a step, the levels move at "
                                          f"<= {rate:g} m/s"))
    result.add(tank_switch_checks(ex, ref, x0, 24))
    # The total excess level falls at v1 + v2 - w while the flow runs and is frozen in the strips,
    # so the relaxed excess never falls below the exact one, which reaches zero at the Zeno time.
    t_zeno = ref.zeno_time(x0)
    times = np.linspace(0.0, T, 501)
    states = np.array(ex.sample(times).states)
    excess = states.sum(axis=1) - ref.r1 - ref.r2
    exact = np.maximum((x0.sum() - ref.r1 - ref.r2) - (ref.v1 + ref.v2 - ref.w) * times, 0.0)
    late = times >= t_zeno + 0.5 * (T - t_zeno)
    lo = float(states[late].min() - min(ref.r1, ref.r2))
    hi = float(np.abs(excess[late]).max())
    ok = bool(np.all(excess >= exact - 1e-9)) and lo >= -eps * (1 + 1e-9) and hi <= 2 * eps
    result.add(Check("levels at their thresholds after t_zeno", ok,
                     f"excess >= exact everywhere; for t >= {times[late][0]:.3g} s levels >= threshold - {-lo:.2g} m, "
                     f"|excess| <= {hi:.2g} m <= 2 eps"))
    # Convergence: the excess left at the Zeno time is the flow lost while held in strips, O(eps).
    levels = [4e-3, 2e-3, 1e-3] if quick else [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]
    left = []
    for ee in levels:
        _, _, _, run, _, _, _ = _two_tanks_run(h, ee, t_zeno)
        left.append(float(run.final_state.sum() - ref.r1 - ref.r2))
    result.add(check_order("excess at t_zeno -> 0", levels, left, 0.8, 1.2, "eps"))
    after = sum(tr.time > t_zeno for tr in ex.transitions)
    result.numbers.update({"zeno_time": t_zeno, "transitions_after_zeno": after})
    result.outcome = (f"{ex.status}; {len(ex.transitions) - after} switches before t_zeno = {t_zeno:g} s, levels held "
                      f"at the thresholds to {T:g} s")


# ---------------------------------------------------------------------------------------------
# Grazing: the circular flow and the plane x1 = 1 (paper 004 Sec. IV-D, Fig. 1)
# ---------------------------------------------------------------------------------------------


def _grazing(result: CaseResult, quick: bool, offsets: Sequence[float], label: str) -> None:
    """The circle of radius 1 + d through (0, 1 + d) touches (d = 0), misses (d < 0) or cuts
    (d > 0) the plane x1 = 1 near t = pi/2; the exact execution switches twice (d > 0: out and
    back, for 2 sqrt(2 d) s) or never. Resets are the identity, so whatever the relaxed execution
    does near the plane its *state* must stay on the circle: the only errors are RK4's and the
    holds in strips (the state stands still for at most h + eps per transition).

    Steps longer than the excursion step over it (no switch, RK4's error); steps that resolve it
    pay the holds, first order in h + eps. Each offset is run on refinements of one kind: with
    d = 1e-6 (an excursion of 2.8e-3 s), h from 1e-2 down with eps = h/10."""
    omega, wall, T = 1.0, 1.0, 3.0
    model = build("circular_flow", {"omega": omega, "wall": wall})
    system = model.system
    main = None
    worst_state, worst_mode, counts = 0.0, 0.0, []
    for d in offsets:
        x0 = np.array([0.0, wall + d])
        ref = model.reference.with_initial("inside", x0)
        resolving = d >= 1e-7
        if resolving:
            hs = [1e-2, 3e-3, 1e-3] + ([] if quick else [3e-4])
        else:
            hs = [0.1, 0.03, 0.01] + ([] if quick else [0.003])
        errs, switched = [], []
        for h in hs:
            eps = h / 10 if resolving else 1e-3
            ex = simulate(system, x0, "inside", T, h, eps, max_transitions=100)
            main = main or ex
            # at most two switches (T < 2 pi / omega): the circle meets a line twice
            result.add(execution_checks(system, ex, eps, bound=2, bound_why="a circle meets a line twice"))
            counts.append(len(ex.transitions))
            switched.append(len(ex.transitions) > 0)
            times = np.linspace(0.0, ex.t_end, 601)
            got = ex.sample(times)
            want = ref.sample(times)
            held = sum(tr.exit_time - tr.time for tr in ex.transitions)
            rk4 = (omega * h) ** 4 / 120.0 * omega * T * (wall + abs(d)) / h  # global error of RK4 on a rotation
            # a hold lasts at most h + eps, and there are at most two switches
            allowed = rk4 + omega * (wall + abs(d)) * min(held, 2 * (h + eps)) + 1e-12
            err = float(np.max(np.abs(np.array(got.states) - np.array(want.states))))
            errs.append(err)
            worst_state = max(worst_state, err / allowed)
            # modes may differ only where the exact state is within the state error of the plane
            near = [abs(float(s[0]) - wall) for s, a, b in zip(want.states, got.modes, want.modes) if a != b]
            worst_mode = max([worst_mode] + [n / (err + abs(d) + 1e-15) for n in near])
        result.numbers[f"error_d{d:g}"] = ", ".join(f"h={h:g}: {e:.2g}" for h, e in zip(hs, errs))
        if all(switched):
            result.add(check_order(f"converges (d = {d:g})", hs, errs, 0.7, 1.3, "h, eps = h/10"))
        elif not any(switched):
            result.add(check_order(f"converges (d = {d:g})", hs, errs, 3.5, 4.5, "h, eps = 1e-3"))
        else:
            result.add(Check(f"converges (d = {d:g})", False,
                             f"some refinements switch and others do not: {dict(zip(hs, switched))}"))
    result.add(Check("state on the circle", worst_state <= 1.0,
                     f"state error <= RK4 bound + two holds x speed (worst ratio {worst_state:.2g})"))
    result.add(Check("modes differ only at the plane", worst_mode <= 1.0 + 1e-9,
                     f"where the relaxed and exact modes differ the exact x1 is within the state error + |d| of "
                     f"the plane (worst ratio {worst_mode:.2g})"))
    result.main_run(main)
    result.outcome = f"{label}; switches per run {counts}"


@case("grazing_tangent", "grazing", "circular flow from (0, 1): touches x1 = 1 at t = pi/2 without crossing")
def _grazing_tangent(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [0.0], "touches")


@case("grazing_inside", "grazing", "circular flow a tiny distance inside tangency (radius 1 - 1e-9, 1 - 1e-6)")
def _grazing_inside(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [-1e-9, -1e-6], "misses")


@case("grazing_outside", "grazing", "circular flow a tiny distance beyond tangency (radius 1 + 1e-9, 1 + 1e-6): two switches")
def _grazing_outside(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [1e-9, 1e-6], "cuts")


# ---------------------------------------------------------------------------------------------
# Simultaneous guards
# ---------------------------------------------------------------------------------------------


def _pronk(params: dict[str, Any] | None = None) -> Model:
    return build("pronk", params or {})


def _slip_twin(pronk_params: dict[str, Any] | None = None) -> Model:
    """The SLIP with the pronk's two legs merged (k doubled): its execution is the symmetric
    pronk's eps -> 0 limit (paper 000 Sec. V-C)."""
    p = {"m": 1.0, "k": 30.0, "l": 1.0, "g": 9.81, "psi": math.pi / 5, **(pronk_params or {})}
    return build("slip", {"m": p["m"], "k": 2 * p["k"], "l": p["l"], "g": p["g"], "psi": p["psi"]})


def pair_checks(ex: Execution, h: float) -> Check:
    """Touchdowns and liftoffs of the two legs come in pairs, the second crossed in the step
    after the first's strip (its crossing time is that strip's exit, within one step h)."""
    trs = ex.transitions
    worst, pairs = 0.0, 0
    ok = len(trs) % 2 == 0 and len(trs) > 0
    for a, b in zip(trs[0::2], trs[1::2]):
        kind_a, kind_b = a.name.split("_")[0], b.name.split("_")[0]
        if kind_a != kind_b or a.name == b.name:
            ok = False
            break
        pairs += 1
        worst = max(worst, b.time - a.exit_time)
    ok = ok and 0.0 <= worst <= h
    return Check("both legs in the same step", ok,
                 f"{pairs} pairs; second crossing <= {worst:.2g} s after the first strip's exit (h = {h:g} s)")


@case("simultaneous_pronk", "simultaneous",
      "symmetric pronk (paper 000 Fig. 17 left): both feet touch down and lift off together")
def _simultaneous_pronk(result: CaseResult, quick: bool) -> None:
    h, eps, T = 1e-3, 1e-2, 2.0
    model = _pronk()
    x0 = _state(model, "aerial")
    slip = _slip_twin()
    limit = simulate(slip.system, x0[[0, 1, 3, 4]], "flight", T, h, 1e-9)
    bound = 2 * len(limit.transitions) + 4
    ex = simulate(model.system, x0, "aerial", T, h, eps, max_transitions=10 * bound)
    result.main_run(ex)
    result.add(execution_checks(model.system, ex, eps, energy="conservative", energy_tol=1e-6, bound=bound,
                                bound_why="two per SLIP transition + 4 (the SLIP twin's "
                                          f"{len(limit.transitions)} in {T:g} s)"))
    result.add(pair_checks(ex, h))
    theta = max(float(np.max(np.abs(seg.x[:, 2]))) for seg in ex.segments)
    result.add(Check("pitch stays zero", theta <= 1e-10, f"max |theta| = {theta:.2g} rad"))
    # Convergence to the SLIP twin as eps shrinks (h fixed, small): paper 000's pronk is the
    # eps -> 0 limit of the relaxed execution.
    hh, T2 = 2.5e-4, 0.5
    ref = simulate(slip.system, x0[[0, 1, 3, 4]], "flight", T2, hh, 1e-9).final_state
    levels = [2e-2, 1e-2, 5e-3] + ([] if quick else [2.5e-3])
    dist = []
    for ee in levels:
        run = simulate(model.system, x0, "aerial", T2, hh, ee)
        dist.append(float(np.linalg.norm(run.final_state[[0, 1, 3, 4]] - ref[:4])))
    result.add(check_order("distance to the SLIP limit -> 0", levels, dist, 0.8, 1.2, "eps (h = 2.5e-4)"))
    E = energies(model.system, ex)[1]
    result.numbers.update({"energy_drift": float(np.max(np.abs(E - E[0]))), "max_theta": theta})
    result.outcome = f"{ex.status}; {len(ex.transitions) // 2} pairs of simultaneous transitions, |theta| <= {theta:.0g}"


@case("simultaneous_runner_random_pitch", "simultaneous",
      "pronk from random pitches |theta0| <= 1e-7: both feet reach the ground in the same step")
def _simultaneous_random_pitch(result: CaseResult, quick: bool) -> None:
    h, eps, T = 1e-3, 1e-2, 0.95  # one hop: touchdowns, liftoffs, and the next flight
    model = _pronk()
    x0 = _state(model, "aerial")
    rng = np.random.default_rng(7)
    n = 4 if quick else 12
    pitches = rng.uniform(-1e-7, 1e-7, n)
    pitches[0], pitches[1] = abs(pitches[0]), -abs(pitches[1])  # both signs, always
    finals, firsts, main = [], [], None
    for th in pitches:
        x = x0.copy()
        x[2] = th
        ex = simulate(model.system, x, "aerial", T, h, eps, max_transitions=40)
        main = main or ex
        result.add(execution_checks(model.system, ex, eps, energy="conservative", energy_tol=1e-6, bound=4,
                                    bound_why="one hop: two touchdowns, two liftoffs"))
        result.add(pair_checks(ex, h))
        finals.append(ex.final_state[:6])
        firsts.append(ex.transitions[0].name if ex.transitions else "")
    # theta > 0 pitches the nose (the right hip) down: the right foot is lower and lands first.
    expected = ["touchdown_right" if th > 0 else "touchdown_left" for th in pitches]
    result.add(Check("the lower foot lands first", firsts == expected,
                     f"{sum(a == b for a, b in zip(firsts, expected))}/{len(pitches)} as the sign of theta0 says"))
    # Continuity through the corner: whichever foot is taken first, the states after the hop
    # differ by O(|theta_i - theta_j|), with the sensitivity measured at a pitch 100 times larger.
    x = x0.copy()
    x[2] = 1e-5
    far = simulate(model.system, x, "aerial", T, h, eps).final_state[:6]
    lipschitz = float(np.max(np.abs(far - finals[0]))) / abs(1e-5 - pitches[0])
    worst = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            worst = max(worst, float(np.max(np.abs(finals[i] - finals[j]))) /
                        (10 * lipschitz * abs(pitches[i] - pitches[j]) + 1e-12))
    result.add(Check("continuous through the corner", worst <= 1.0,
                     f"|x_i - x_j| <= 10 L |theta_i - theta_j| + 1e-12, L = {lipschitz:.3g} from theta0 = 1e-5 "
                     f"(worst ratio {worst:.2g})"))
    # The symmetric start (exactly on the corner) is the limit of its pitched neighbours at every
    # h and eps: its second leg's guard is within rounding of zero when its mode is entered,
    # which counts as on the guard, so the crossing is found by the next step exactly as for a
    # pitch of 1e-9 (no O(h) jump decided by the last bits of the strip point).
    levels = [(1e-3, 1e-2), (5e-4, 5e-3), (2.5e-4, 2.5e-3)] + ([] if quick else [(1.25e-4, 1.25e-3)])
    ratios = []
    for hh, ee in levels:
        sym = simulate(model.system, x0, "aerial", T, hh, ee).final_state[:6]
        x = x0.copy()
        x[2] = pitches[0]
        jump = float(np.max(np.abs(simulate(model.system, x, "aerial", T, hh, ee).final_state[:6] - sym)))
        ratios.append(jump / (10 * lipschitz * abs(pitches[0]) + 1e-12))
    result.add(Check("the corner is the limit of its neighbours", max(ratios) <= 1.0,
                     f"|x(theta0 = 0) - x(theta0 = {pitches[0]:.2g})| <= 10 L |theta0| + 1e-12 at h = "
                     f"{', '.join(f'{lv[0]:g}' for lv in levels)} (eps = 10 h); worst ratio {max(ratios):.2g}"))
    result.main_run(main)
    result.numbers.update({"pitches": ", ".join(f"{p:.2g}" for p in pitches), "lipschitz": lipschitz,
                           "corner_ratio_worst": max(ratios)})
    result.outcome = f"{len(pitches)} pitches: first touchdown follows the sign of theta0; pairs within one step"


@case("simultaneous_digital_control", "simultaneous",
      "digital control (paper 000 Fig. 1): both thresholds at t = ln 2; neighbours take 0->2->3 and 0->1->3")
def _simultaneous_digital(result: CaseResult, quick: bool) -> None:
    model = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    ref0 = model.reference
    T, delta = 3.0, 1e-6
    starts = {"x": np.array([-1.0, -1.0]), "y_delta": np.array([-1.0 - delta, -1.0]),
              "z_delta": np.array([-1.0, -1.0 - delta])}
    paths = {}
    main = None
    levels = [(1e-2, 1e-4), (5e-3, 5e-5), (2.5e-3, 2.5e-5)] + ([] if quick else [(1.25e-3, 1.25e-5)])
    errors = []
    for label, x0 in starts.items():
        ref = ref0.with_initial("0", x0)
        for k, (h, eps) in enumerate(levels):
            ex = simulate(model.system, x0, "0", T, h, eps, max_transitions=10)
            main = main or ex
            result.add(execution_checks(model.system, ex, eps, bound=2,
                                        bound_why="each threshold is crossed once; mode 3 has no guard"))
            if k == 0:
                paths[label] = "->".join(ex.mode_sequence)
            # Autonomous fields and identity resets: the relaxed execution is the exact one
            # paused in its strips, so its state at T is the exact state at T minus the time held.
            held = sum(tr.exit_time - tr.time for tr in ex.transitions)
            warp = float(np.max(np.abs(ex.final_state - ref.state(T - held))))
            result.add(Check(f"exact up to the holds ({label}, h={h:g})", warp <= 1e-9,
                             f"|x(T) - x_exact(T - held)| = {warp:.2g} (held {held:.3g} s)"))
            if label == "x":
                errors.append(float(np.max(np.abs(ex.final_state - ref.state(T)))))
    ok = paths == {"x": "0->1->3", "y_delta": "0->2->3", "z_delta": "0->1->3"}
    result.add(Check("paths", ok, f"{paths} (x takes the first listed guard on the tie; y crosses xi2 first)"))
    t_cross = [tr.time for tr in main.transitions]
    ok = abs(t_cross[0] - math.log(2.0)) <= 1e-9 and t_cross[1] == main.transitions[0].exit_time
    result.add(Check("both thresholds at ln 2", ok,
                     f"first crossing at {t_cross[0]:.12g} s (ln 2 = {math.log(2):.12g}), the second at the "
                     f"first strip's exit"))
    result.add(check_order("x(T) -> exact", [lv[0] for lv in levels], errors, 0.8, 1.2, "h (eps = h/100)"))
    result.main_run(main)
    result.outcome = f"paths {paths['x']} (x), {paths['y_delta']} (y), {paths['z_delta']} (z)"


# ---------------------------------------------------------------------------------------------
# Resting contact: a ball that comes to rest on the floor and is lifted off by a growing force
# ---------------------------------------------------------------------------------------------


def lifted_ball(c: float, lift_rate: float, g: float = 9.81, mass: float = 1.0,
                window: float | None = None) -> tuple[HybridSystem, Callable[[float, np.ndarray], float]]:
    """A ball on a floor (restitution c) pulled up by the force ``u(t) = lift_rate t`` (N), and
    its control. Modes ``flight`` (z, zd) with field (zd, u/m - g) and ``rest`` (z, zd) with
    field 0, held on the floor while the floor pushes. Guards (eps in metres in flight, N at
    rest):

    * ``bounce`` (c > 0, flight -> flight): ``max(z, zd)``, reset (z, -c zd);
    * ``land`` (flight -> rest): the floor guard when the impact ends at rest: for c = 0 a
      plastic impact after which the floor pushes (m g - u > 0), for c > 0 with Zeno
      continuation (``window``) an impact whose rebound c v0 would fly shorter than the window
      (c v0 < a window / 2, a = g - u/m the acceleration pressing the ball on the floor);
      reset (z, 0);
    * ``graze`` (c = 0, flight -> flight): a plastic impact while the floor would pull (the lift
      exceeds the weight), reset (z, 0);
    * ``release`` (rest -> flight): the floor force ``m g - u(t)`` (N) on (t, x, u), so the
      crossing is located on the force's own time dependence.

    The release is at t* = m g / lift_rate exactly; after a release at t_e the flight is the
    cubic z(t) = (r/m)((t - t*)^3 - (t_e - t*)^3)/6 - (r/m)(t_e - t*)^2 (t - t_e)/2, r = lift_rate,
    which RK4 integrates exactly.
    """
    def control(t: float, x: np.ndarray) -> float:
        return lift_rate * t

    def flight(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([x[1], (0.0 if u is None else u) / mass - g])

    def rest(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.zeros(2)

    def floor_gap(x: np.ndarray) -> float:
        return x[0] if x[0] > x[1] else x[1]

    def accumulating(t: float, x: np.ndarray, u: float) -> bool:
        a = g - u / mass  # acceleration pressing the ball on the floor
        if c == 0.0:
            return a > 0.0
        if window is None or a <= 0.0:
            return False
        v0 = math.sqrt(max(x[1] * x[1] - 2.0 * a * max(-x[0], 0.0), 0.0))  # approach speed back at z = 0
        return c * v0 < 0.5 * a * window

    def branch(stays: bool):
        def guard(t: float, x: np.ndarray, u: float) -> float:
            base = floor_gap(x)
            if base >= 0.0:
                return base
            return base if accumulating(t, x, u) == stays else -base
        return guard

    def stop(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], 0.0])

    transitions = [Transition("flight", "rest", branch(True), stop, name="land", guard_args="t,x,u")]
    if c > 0.0:
        transitions.append(Transition("flight", "flight", branch(False), lambda x: np.array([x[0], -c * x[1]]),
                                      name="bounce", guard_args="t,x,u"))
    else:
        transitions.append(Transition("flight", "flight", branch(False), stop, name="graze", guard_args="t,x,u"))
    transitions.append(Transition("rest", "flight", lambda t, x, u: mass * g - u, name="release", guard_args="t,x,u"))

    def energy(mode: str, x: np.ndarray) -> float:
        return mass * (g * float(x[0]) + 0.5 * float(x[1]) ** 2)

    system = HybridSystem({"flight": Mode(2, flight, ("z", "zd")), "rest": Mode(2, rest, ("z", "zd"))},
                          transitions, name=f"lifted ball c={c:g}", energy=energy)
    return system, control


def _resting(result: CaseResult, quick: bool, c: float, window: bool) -> None:
    g, m, rate, z0 = 9.81, 1.0, 3.0, 0.5
    h, eps = 1e-3, 1e-4
    t_star = m * g / rate
    T = t_star + 1.0
    system, control = lifted_ball(c, rate, g, m, (h + eps) if window else None)
    ex = simulate(system, [z0, 0.0], "flight", T, h, eps, control=control, max_transitions=10 ** 6)
    result.main_run(ex)
    v1 = math.sqrt(2 * g * z0)
    if c == 0.0:
        bound, why = 2, "a plastic landing and a release"
    elif window:
        # the impacts before resting leave at c^k v1 and last while c^k v1 >= a window / 2, with the
        # least pressing acceleration a = g - rate t over the accumulation (before t* / 2 here)
        a_lo = g - rate * (0.5 * t_star)
        bound = math.log(c * v1 / (0.5 * a_lo * (h + eps))) / math.log(1.0 / c) + 2 + 2
        why = "log(c v1/w_th)/log(1/c) + 2 bounces, a landing, a release"
    else:
        floor = min(step_floor(h, eps, accel=g), eps * (1 - 1e-9))
        bound, why = T / floor + 1, f"T/{floor:.3g} s"
    result.add(execution_checks(system, ex, eps, control=control, energy=None, bound=bound, bound_why=why))
    releases = [tr for tr in ex.transitions if tr.name == "release"]
    if c == 0.0 or window:
        # Rests, then the release is located on the force's zero crossing, t* = m g / r, and the
        # flight after it is the exact cubic from the strip exit.
        ok = len(releases) == 1 and abs(releases[0].time - t_star) <= 1e-9
        result.add(Check("released at t* = m g / r", ok,
                         f"release at {releases[0].time if releases else math.nan:.12g} s, t* = {t_star:.12g} s"))
        if releases:
            te = releases[0].exit_time
            times = np.linspace(te, T, 50)
            z = np.array([s[0] for s in ex.sample(times).states])
            k = rate / m
            exact = k * ((times - t_star) ** 3 - (te - t_star) ** 3) / 6 - k * (te - t_star) ** 2 * (times - te) / 2
            err = float(np.max(np.abs(z - exact)))
            result.add(Check("flight after release exact", err <= 1e-9, f"|z - cubic| <= {err:.2g} m"))
        lands = [tr for tr in ex.transitions if tr.name == "land"]
        span = (lands[0].exit_time, releases[0].time) if lands and releases else (0.0, 0.0)
        modes = set(ex.sample(np.linspace(*span, 100, endpoint=False)).modes) if span[1] > span[0] else set()
        result.add(Check("rests on the floor", modes == {"rest"},
                         f"mode rest on [{span[0]:.4g}, {span[1]:.4g}] s"))
    else:
        # Plain relaxed: the ball chatters on the floor until the lift nearly cancels its weight,
        # then flies off along the exact cubic, shifted by the time d of its last impact from t*
        # and started with that impact's rebound w: |z(T) - cubic| <= w (T - t*) + k (T - t*)^2 |d|/2.
        last_tr = ex.transitions[-1] if ex.transitions else None
        last = last_tr.exit_time if last_tr else 0.0
        w = abs(float(last_tr.state_after[1])) if last_tr else 0.0
        z_end = float(ex.final_state[0])
        k = rate / m
        exact_end = k * (T - t_star) ** 3 / 6
        lag = last - t_star
        allowed = w * (T - t_star) + k * (T - t_star) ** 2 * abs(lag) / 2 + 1e-9
        ok = abs(lag) <= 2 * (h + eps) and abs(z_end - exact_end) <= allowed
        result.add(Check("lifts off at t*", ok,
                         f"last impact's strip exit {lag:+.2g} s from t* = {t_star:.6g} s (within 2 (h + eps)), "
                         f"z(T) = {z_end:.6g} m vs the cubic's {exact_end:.6g} (allowed {allowed:.2g})"))
        result.numbers["lift_lag"] = lag
    result.numbers["transitions"] = len(ex.transitions)
    # The plain run has no release transition: it leaves the floor when its last strip exit
    # is not followed by another impact.
    if releases:
        how = f"released at {releases[0].time:.6g} s"
    elif ex.transitions:
        how = f"lifts off at {ex.transitions[-1].exit_time:.6g} s (last strip exit)"
    else:
        how = "no impact"
    result.outcome = f"{ex.status}; {len(ex.transitions)} transitions, {how}"


@case("resting_ball_c0", "resting", "ball, plastic floor (c = 0): rests, then a lift u = 3 t N releases it at t* = m g / 3")
def _resting_plastic(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.0, False)


@case("resting_ball_c0.2", "resting", "ball, c = 0.2, plain relaxed: chatters on the floor until the lift exceeds its weight")
def _resting_chatter(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.2, False)


@case("resting_ball_c0.2_continued", "resting",
      "ball, c = 0.2, Zeno continuation: rests after the accumulation, released at t* exactly")
def _resting_continued(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.2, True)


# ---------------------------------------------------------------------------------------------
# Extremes
# ---------------------------------------------------------------------------------------------


def ball_hold_check(ex: Execution, eps: float) -> Check:
    """Each bounce's strip lasts at most eps (1 + 1/v): the landing point lies at most eps past the
    floor, reached in at most eps/v after the crossing at speed v (gravity only speeds it up), and
    the strip itself is eps - depth."""
    worst = 0.0
    for tr in ex.transitions:
        v = abs(float(tr.state_before[1]))
        if v > 0:
            worst = max(worst, (tr.exit_time - tr.time) / (eps * (1.0 + 1.0 / v)))
    ok = worst <= 1.0 + 1e-9
    return Check("holds <= eps (1 + 1/v)", ok, f"worst hold / bound = {worst:.3g}")


@case("extreme_eps", "extremes", "bouncing ball with eps = 1e-12 ... 1e-1 (to 0.95 t_zeno; with Zeno continuation to 2 t_zeno)")
def _extreme_eps(result: CaseResult, quick: bool) -> None:
    g, c, z0, h = 9.81, 0.5, 1.0, 1e-3
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    epss = [1e-12, 1e-9, 1e-6, 1e-3, 1e-1] if quick else [1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 1e-1]
    lags, halvings, main = [], {}, None
    T1 = 0.95 * ref.zeno_time
    for eps in epss:
        # plain relaxed, short of the Zeno time (past it every bounce costs a step or a strip:
        # (t - t_zeno) / min(h, eps, sqrt(eps/g)) transitions, 1e7 at eps = 1e-12)
        n_max = int(T1 / min(step_floor(h, eps, accel=g), eps * (1 - 1e-9))) + 1
        ex = simulate(model.system, [z0, 0.0], "flight", T1, h, eps, max_transitions=min(n_max, 10 ** 6))
        main = main or ex
        n_exact = int(ref.impact_count(T1))
        result.add(execution_checks(model.system, ex, eps, energy="dissipative", energy_tol=1e-9, bound=n_exact,
                                    bound_why=f"no more than the {n_exact} exact impacts before 0.95 t_zeno"))
        if eps < 0.05:  # a 0.1 m strip delays the impacts past 0.95 t_zeno; the flights stay exact
            result.add(ball_flight_checks(ex, g, eps, resolved=0.0))
        result.add(ball_hold_check(ex, eps))
        lags.append(ex.transitions[0].exit_time - ref.first_impact)
        halvings[eps] = ex.halvings / max(len(ex.transitions), 1)
        # through the Zeno time with continuation: the same ball in the model with a resting mode
        system, control = lifted_ball(c, 0.0, g, 1.0, window=h + eps)
        T2 = 2.0 * ref.zeno_time
        ex2 = simulate(system, [z0, 0.0], "flight", T2, h, eps, control=control, max_transitions=1000)
        bound = math.log(c * ref.impact_speed / (0.5 * g * (h + eps))) / math.log(1.0 / c) + 3
        result.add(execution_checks(system, ex2, eps, control=control, energy="dissipative", energy_tol=1e-9,
                                    bound=bound, bound_why="log(c v1/w_th)/log(1/c) + 2 bounces and a landing"))
        ok = ex2.final_mode == "rest" and abs(float(ex2.final_state[0])) <= 1e-9
        result.add(Check(f"rests past t_zeno (eps={eps:g})", ok, f"final mode {ex2.final_mode}, z = {ex2.final_state[0]:.2g} m"))
    result.add(check_order("first impact's strip exit -> t1", epss[1:-1], lags[1:-1], 0.9, 1.1, "eps"))
    result.main_run(main)
    result.numbers.update({f"halvings_per_impact_eps{e:g}": v for e, v in halvings.items()})
    result.outcome = (f"eps {epss[0]:g} .. {epss[-1]:g}: first impact held {lags[0]:.2g} .. {lags[-1]:.2g} s; "
                      f"{halvings[epss[0]]:.0f} halvings per impact at eps = {epss[0]:g}")


@case("extreme_large_h", "extremes", "h longer than the time between events: ball (h = 0.25, 1 s), two tanks (h = 2 s), digital control (h = 1 s)")
def _extreme_large_h(result: CaseResult, quick: bool) -> None:
    g, c, z0, eps = 9.81, 0.5, 1.0, 1e-3
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    T = 2.0 * ref.zeno_time
    main = None
    for h in ([0.25, 1.0] if quick else [0.1, 0.25, 0.5, 1.0]):
        floor = min(step_floor(h, eps, accel=g), eps * (1 - 1e-9))
        bound = (T - ref.first_impact) / floor + 1
        ex = simulate(model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=int(2 * bound) + 10)
        main = main or ex
        result.add(execution_checks(model.system, ex, eps, energy="dissipative", energy_tol=1e-9, bound=bound,
                                    bound_why=f"(T - t1)/{floor:.3g} s"))
        # flights under 1 ms start at the guard's corner z = zd = 0, where the crossing tolerance
        # (1e-9 eps in guard units) is one on zd, not on time
        result.add(ball_flight_checks(ex, g, eps, resolved=1e-3))
        result.add(ball_rest_check(ex, c, g, eps, 1.5 * ref.zeno_time, T))
    # two tanks: dwell times 2, 1, 0.5, ... s against h = 2 s
    tanks = build("two_tanks")
    tref = tanks.reference
    x0 = _state(tanks, "q1")
    for h in ([2.0] if quick else [2.0, 5.0]):
        ex = simulate(tanks.system, x0, "q1", 10.0, h, eps, max_transitions=10 ** 5)
        rate = max(abs(tref.w - tref.v1), tref.v1, tref.v2, abs(tref.w - tref.v2))
        floor = min(step_floor(h, eps, rate=rate), eps * (1 - 1e-9))
        result.add(execution_checks(tanks.system, ex, eps, bound=10.0 / floor + 1, bound_why=f"T/{floor:.3g} s"))
        result.add(tank_switch_checks(ex, tref, x0, 20))
    # digital control: both thresholds at ln 2 inside the first step of 1 s
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    x0 = np.array([-1.0, -1.0])
    ex = simulate(dc.system, x0, "0", 3.0, 1.0, 1e-4)
    result.add(execution_checks(dc.system, ex, 1e-4, bound=2, bound_why="each threshold once"))
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    warp = float(np.max(np.abs(ex.final_state - dc.reference.state(3.0 - held))))
    # RK4 on a relaxation at rate 1 with h = 1: |e^-1 - (1 - 1 + 1/2 - 1/6 + 1/24)| = 7.1e-3 per
    # step and unit amplitude; 3 steps, amplitudes <= 2
    result.add(Check("digital control exact up to holds and RK4", warp <= 3 * 2 * 7.2e-3,
                     f"|x(T) - x_exact(T - held)| = {warp:.2g} <= {3 * 2 * 7.2e-3:.2g}; path {'->'.join(ex.mode_sequence)}"))
    result.main_run(main)
    result.outcome = "ball rests after t_zeno; tank switches exact; digital path " + "->".join(ex.mode_sequence)


def hop_period(g: float, k: float, m: float, l: float, apex: float) -> tuple[float, float]:
    """(stance time, hop period) of a vertical hopper (SLIP with psi = 0) from apex height z0:
    ballistic flights and a harmonic stance about z_eq = l - m g / k at omega = sqrt(k/m)."""
    v = math.sqrt(2.0 * g * (apex - l))
    omega = math.sqrt(k / m)
    d = m * g / k  # the spring's static compression: the touchdown point is d above z_eq
    stance = (math.pi + 2.0 * math.atan(d * omega / v)) / omega
    return stance, 2.0 * v / g + stance


@case("extreme_stiff_legs", "extremes", "stiff leg (k = 1e5 N/m, stance 10 ms): vertical hopping SLIP, RK4 at omega h = 0.3 ... 0.08")
def _extreme_stiff(result: CaseResult, quick: bool) -> None:
    k, m, l, g, z0 = 1e5, 1.0, 1.0, 9.81, 1.1
    model = build("slip", {"k": k, "m": m, "l": l, "g": g, "psi": 0.0})
    x0 = _state(model, "flight", {"x": 0.0, "z": z0, "xd": 0.0, "zd": 0.0})
    stance, period = hop_period(g, k, m, l, z0)
    T = 2.0 if quick else 10.0
    eps = 1e-7  # m: the leg compresses by v/omega = 4.4 mm
    hs = [1e-3, 5e-4, 2.5e-4]
    drifts, period_errs, main = [], [], None
    for h in hs:
        ex = simulate(model.system, x0, "flight", T, h, eps, max_transitions=1000)
        main = main or ex
        hops = T / period
        result.add(execution_checks(model.system, ex, eps, energy="conservative", energy_tol=1e-2, bound=2 * hops + 2,
                                    bound_why=f"two per hop, hop {period:.4g} s (closed form)"))
        E = energies(model.system, ex)[1]
        drifts.append(float(np.max(np.abs(E - E[0]))))
        lifts = [tr.time for tr in ex.transitions if tr.name.startswith("liftoff")]
        # lifts are one period apart, up to the holds (h + eps each, two per hop)
        spacing = np.diff(lifts)
        period_errs.append(float(np.max(np.abs(spacing - period))) if len(spacing) else math.inf)
        ok = len(spacing) >= 1 and period_errs[-1] <= 2 * (h + eps) + 1e-6
        result.add(Check(f"hop period (h={h:g})", ok,
                         f"liftoffs {period:.6g} s apart (closed form) to {period_errs[-1]:.2g} s <= 2 (h + eps)"))
    # RK4 on a harmonic stance: |R(i omega h)| = 1 - (omega h)^6/144, an energy loss of (omega h)^6/72
    # per step, so (omega h)^5 per stance: order 5 (the flights are exact)
    result.add(check_order("energy drift order", hs, drifts, 4.5, 5.5, "h"))
    result.main_run(main)
    result.numbers.update({"stance_s": stance, "period_s": period,
                           "energy_drift": ", ".join(f"h={h:g}: {d:.2g} J" for h, d in zip(hs, drifts))})
    result.outcome = f"{main.status}; {len(main.transitions)} transitions, stance {stance * 1e3:.3g} ms, drift {drifts[0]:.2g} J at h = 1e-3"


#: The stable pronking gait used for the long horizon: k = 200 N/m per leg (dimensionless leg
#: stiffness k l/(m g) = 41 for the pair), apex z = 1 m, xd = 6 m/s, and the touchdown angle that
#: makes it periodic, found with
#: ``legsim orbit pronk_orbit --set robot.parameters.k=200 --set initial.state.xd=6
#: --set initial.state.z=1.0 --set robot.parameters.psi=0.36`` (multipliers 1 (energy),
#: 0.50 and 0.79 (pitch): stable). The paper's gait (k = 30, z = 1.1 m, xd = 3.4 m/s) has the
#: multiplier 5.86 per stride: it falls after some fifteen strides whatever the integrator.
STABLE_PRONK = {"params": {"k": 200.0, "psi": 0.36039485704763646}, "apex": {"z": 1.0, "xd": 6.0}}
PAPER_SLIP_PSI = 0.6251999313731675  # `legsim orbit slip_orbit`: the paper's apex made periodic, multiplier 5.86


def apex_heights(ex: Execution) -> list[tuple[float, float]]:
    """(time, z) of the apexes (zd changing sign from + to -) in the aerial segments of a runner
    whose coordinates are (x, z, ..., xd, zd, ...) with zd at index n + 1 (n = half the q, v block)."""
    out = []
    for seg in ex.segments:
        if seg.mode not in ("aerial", "flight") or len(seg.t) < 3:
            continue
        n = seg.x.shape[1] // 2
        zd = seg.x[:, n + 1]
        for i in np.nonzero((zd[:-1] > 0) & (zd[1:] <= 0))[0]:
            # the apex on the step's Hermite interpolant, to first order in the step
            s = zd[i] / (zd[i] - zd[i + 1])
            out.append((float(seg.t[i] + s * (seg.t[i + 1] - seg.t[i])), float(seg.x[i, 1] + s * (seg.x[i + 1, 1] - seg.x[i, 1]))))
    return out


@case("extreme_long_horizon", "extremes",
      "conservative runner for 1e3 s (20 s quick): a stable passive pronk; the paper's unstable gait falls after ~15 s")
def _extreme_long(result: CaseResult, quick: bool) -> None:
    h, eps = 1e-3, 1e-4
    T = 20.0 if quick else 1000.0
    model = _pronk(STABLE_PRONK["params"])
    x0 = _state(model, "aerial", STABLE_PRONK["apex"])
    stride = 1 if quick else 20  # checks on every 20th point over 1e6 steps keep the case to minutes
    # energy drift over the first 5 s, extrapolated linearly (RK4 drifts, it is not symplectic)
    short = simulate(model.system, x0, "aerial", 5.0, h, eps)
    E5 = energies(model.system, short)[1]
    d5 = float(np.max(np.abs(E5 - E5[0])))
    period = 0.34892597063684405  # the orbit's period from the same `legsim orbit` run
    bound_e = 2.0 * d5 * T / 5.0 + 1e-12
    ex = simulate(model.system, x0, "aerial", T, h, eps, max_transitions=int(5 * T / period) + 10)
    result.main_run(ex)
    result.add(execution_checks(model.system, ex, eps, energy="conservative", energy_tol=bound_e,
                                bound=4 * (T / period + 1), bound_why=f"4 per stride of {period:.4g} s", stride=stride))
    jumps = max(abs(model.system.energy(tr.target, tr.state_after) - model.system.energy(tr.source, tr.state_before))
                for tr in ex.transitions)
    result.add(Check("energy kept by every transition", jumps <= 1e-9, f"largest change at a transition {jumps:.2g} J"))
    apexes = apex_heights(ex)
    last_z = apexes[-1][1] if apexes else math.nan
    # every stride holds four strips of at most h + eps each: the relaxed strides are that much longer
    least = T / (period + 4 * (h + eps)) - 2
    ok = len(apexes) >= least and abs(last_z - STABLE_PRONK["apex"]["z"]) <= 1e-3
    result.add(Check("stays on the gait", ok, f"{len(apexes)} apexes (>= {least:.0f}), the last at z = {last_z:.6f} m "
                                              f"(start 1 m)"))
    ts, es = energies(model.system, ex, stride)
    drift = float(np.max(np.abs(es - es[0])))
    result.numbers.update({"energy_drift_J": drift, "energy_drift_bound_J": bound_e, "strides": len(apexes)})
    # The paper's gait: unstable, multiplier 5.86 per stride of 0.916 s. A perturbation of the
    # size of one stride's integration error (< 1e-6 at h = 1e-3, eps = 1e-2) needs
    # ln(1e5)/ln(5.86) = 6.5 strides to reach 0.1: it must survive at least 6 strides, then fall
    # with an honest status.
    slip = build("slip", {"psi": PAPER_SLIP_PSI})
    paper = simulate(slip.system, _state(slip, "flight"), "flight", 1000.0 if not quick else 60.0, h, 1e-2,
                     max_transitions=10 ** 5)
    falls = ("model_breakdown", "halving_exhausted", "reset_outside_domain")
    result.add(execution_checks(slip.system, paper, 1e-2, status=falls, energy="conservative", energy_tol=1e-6))
    strides = sum(tr.name.startswith("liftoff") for tr in paper.transitions)
    result.add(Check("paper gait survives >= 6 strides", strides >= 6,
                     f"{strides} strides, fell at t = {paper.t_end:.4g} s ({paper.status})"))
    result.numbers.update({"paper_gait_survives_s": paper.t_end, "paper_gait_end": paper.status})
    result.outcome = (f"stable pronk {ex.status} at {ex.t_end:g} s, {len(apexes)} strides, |dE| <= {drift:.2g} J; "
                      f"paper SLIP gait falls at {paper.t_end:.3g} s")


@case("extreme_on_guard", "extremes", "initial states exactly on a guard (and one inside a strip)")
def _extreme_on_guard(result: CaseResult, quick: bool) -> None:
    g, c, h, eps = 9.81, 0.5, 1e-3, 1e-4
    ball = build("bouncing_ball", {"g": g}, {"floor": {"restitution": c}})

    def run(system, x0, mode, T, *, eps=eps, bound, why, control=None, energy=None):
        ex = simulate(system, x0, mode, T, h, eps, control=control, max_transitions=int(2 * bound) + 10)
        result.add(execution_checks(system, ex, eps, control=control, bound=bound, bound_why=why,
                                    energy=energy, energy_tol=1e-9))
        return ex

    floor = min(step_floor(h, eps, accel=g), eps * (1 - 1e-9))
    # at rest exactly on the floor: the corner z = zd = 0 of the guard max(z, zd); stays at rest
    ex = run(ball.system, [0.0, 0.0], "flight", 0.5, bound=0.5 / floor + 1, why=f"T/{floor:.3g} s", energy="dissipative")
    result.add(ball_rest_check(ex, c, g, eps, 0.0, 0.5))
    main = ex
    # on the floor moving down: bounces at t = 0 exactly, then flies 2 c v / g
    ex = run(ball.system, [0.0, -1.0], "flight", 0.15, bound=3, why="a bounce at 0, one at 2 c/g", energy="dissipative")
    first = ex.transitions[0] if ex.transitions else None
    ok = first is not None and first.time == 0.0 and np.allclose(first.state_after, [0.0, c], atol=1e-15)
    result.add(Check("bounces at t0", ok, f"first transition at {first.time if first else math.nan} s -> "
                                          f"{first.state_after.tolist() if first else None}"))
    result.add(ball_flight_checks(ex, g, eps, resolved=0.0))
    # on the floor moving up: no transition at t = 0, lands at 2 v / g exactly
    ex = run(ball.system, [0.0, 1.0], "flight", 0.25, bound=1, why="one landing", energy="dissipative")
    ok = len(ex.transitions) == 1 and abs(ex.transitions[0].time - 2.0 / g) <= 1e-12
    result.add(Check("leaves the guard", ok, f"lands at {ex.transitions[0].time if ex.transitions else math.nan:.15g} s, "
                                             f"2 v/g = {2 / g:.15g}"))
    # inside the strip (half of eps below the floor, moving down): crosses at t0, held eps/2
    ex = run(ball.system, [-0.5 * eps, -1.0], "flight", 0.15, bound=3, why="a bounce at 0, one at 2 c/g")
    first = ex.transitions[0] if ex.transitions else None
    ok = first is not None and first.time == 0.0 and abs(first.exit_time - 0.5 * eps) <= 1e-15
    result.add(Check("starts in the strip", ok, f"crossed at {first.time if first else math.nan}, held to "
                                                f"{first.exit_time if first else math.nan:.3g} s (eps/2 = {eps / 2:g})"))
    # two tanks with tank 2 exactly at its threshold: switches at once, then exact
    tanks = build("two_tanks")
    x0 = np.array([1.0, 0.0])
    ex = run(tanks.system, x0, "q1", 3.0, bound=3.0 / min(step_floor(h, eps, rate=0.5), eps) + 1, why="T/floor")
    ok = bool(ex.transitions) and ex.transitions[0].time == 0.0 and ex.transitions[0].target == "q2"
    result.add(Check("tank switches at t0", ok, f"first switch at {ex.transitions[0].time if ex.transitions else None}"))
    result.add(tank_switch_checks(ex, tanks.reference, x0, 2))
    # the circle started on the plane, tangent to it: never crosses
    circle = build("circular_flow")
    ex = run(circle.system, [1.0, 0.0], "inside", 3.0, bound=0, why="tangent at t0, inside after")
    err = float(np.max(np.abs(ex.final_state - circle.reference.state(np.array([1.0, 0.0]), 3.0))))
    result.add(Check("circle from the plane", err <= 1e-9, f"no switch, |x(3) - exact| = {err:.2g}"))
    # the digital controller at the corner (0, 0) of its two guards: both crossed at t0
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    ex = run(dc.system, [0.0, 0.0], "0", 1.0, bound=2, why="each threshold once")
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    warp = float(np.max(np.abs(ex.final_state - dc.reference.with_initial("0", [0.0, 0.0]).state(1.0 - held))))
    ok = ex.mode_sequence == ["0", "1", "3"] and ex.transitions[0].time == 0.0 and warp <= 1e-9
    result.add(Check("corner at t0", ok, f"path {'->'.join(ex.mode_sequence)}, first at {ex.transitions[0].time} s, "
                                         f"exact up to holds to {warp:.2g}"))
    result.main_run(main)
    result.outcome = "ball at rest / moving in / out / inside the strip; tanks; circle; digital corner"


@case("extreme_corner", "extremes", "states near the corner of two guards: digital control within 1e-9 of the corner")
def _extreme_corner(result: CaseResult, quick: bool) -> None:
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    rng = np.random.default_rng(3)
    n = 6 if quick else 40
    h, eps, T = 1e-2, 1e-6, 1.5
    finals, main, agree = [], None, 0
    for k in range(n):
        d = rng.uniform(0.0, 1e-9, 2)
        x0 = np.array([-1.0, -1.0]) - d
        ex = simulate(dc.system, x0, "0", T, h, eps, max_transitions=10)
        main = main or ex
        result.add(execution_checks(dc.system, ex, eps, bound=2, bound_why="each threshold once"))
        ref = dc.reference.with_initial("0", x0)
        held = sum(tr.exit_time - tr.time for tr in ex.transitions)
        warp = float(np.max(np.abs(ex.final_state - ref.state(T - held))))
        # the quantity with the smaller offset crosses first: xi1 first means 0 -> 1 -> 3
        expected = ["0", "1", "3"] if d[0] < d[1] else ["0", "2", "3"]
        agree += ex.mode_sequence == expected
        result.add(Check(f"exact up to holds (#{k})", warp <= 1e-9, f"|x(T) - x_exact(T - held)| = {warp:.2g}"))
        finals.append(ex.final_state)
    result.add(Check("first crossing = the closer threshold", agree == n, f"{agree}/{n} paths as the offsets say"))
    spread = float(np.max(np.ptp(np.array(finals), axis=0)))
    # every execution is the exact one paused for its two strips (eps - depth + the landing step
    # each, < 2 (h + eps)), so the final states differ by at most the speed times that
    ok = spread <= 2 * (h + eps) * 2.0
    result.add(Check("paths meet again", ok, f"final states within {spread:.2g} of each other (<= 2 (h + eps) x speed 2)"))
    result.main_run(main)
    result.outcome = f"{n} starts within 1e-9 of the corner: both paths, final spread {spread:.2g}"


@case("zeno_oscillator_ex2", "zeno",
      "forced oscillator with a stop, paper 000 Table I Example 2: sticks, leaves, chatters (Zeno) and sticks again")
def _zeno_oscillator(result: CaseResult, quick: bool) -> None:
    _oscillator_ex2(result, quick, continued=False)


@case("zeno_oscillator_ex2_continued", "zeno",
      "Example 2 with Zeno continuation: sticks and releases as the exact execution does, at a fraction of the cost")
def _zeno_oscillator_continued(result: CaseResult, quick: bool) -> None:
    _oscillator_ex2(result, quick, continued=True)


def _oscillator_model(continued: bool, window: float = 0.0) -> Model:
    effects: dict[str, Any] = {"stop": {"position": -0.8, "restitution": 0.5}, "damping": {"a": 0.95},
                               "forcing": {"amplitude": 1.0, "frequency": 1.0}}
    if continued:
        effects["zeno"] = {"window": window}
    return build("oscillator", {"omega": 1.0, "mass": 1.0, "x0": -0.8, "xd0": 0.0}, effects)


def _oscillator_ex2(result: CaseResult, quick: bool, continued: bool) -> None:
    h, eps = 1e-2, 1e-5
    T = 4.0 * math.pi
    model = _oscillator_model(continued, h + eps)
    ref = model.reference
    c_ex2 = 0.5
    x_max, U, omega, a = -0.8, 1.0, 1.0, 0.95
    system = model.system
    start = time.perf_counter()
    ex = simulate(system, [x_max, 0.0], "free", T, h, eps, control=model.control, max_transitions=10 ** 6)
    cost = time.perf_counter() - start
    result.main_run(ex)
    if continued:
        # the exact impacts the continuation may still bounce (rebound c v at least F window / 4,
        # half the threshold for the approach-speed estimate), plus a stick and a release per
        # exact sticking phase and the first stick
        speeds = ref.impact_speeds(T)
        forces = ref.free_acceleration(ref.impact_times(T))
        bouncing = int(np.sum(c_ex2 * speeds >= forces * (h + eps) / 4.0))
        phases = len(ref.sticking_intervals(T))
        bound, why = bouncing + 2 * phases + 2, (f"{bouncing} exact impacts with rebound >= F window/4, a stick and "
                                                 f"a release per sticking phase ({phases})")
    else:
        # the stop's guard accelerates at most at |U|/m + omega^2 max|x| + 2 a max|xd|
        xs = np.concatenate([s.x for s in ex.segments])
        acc = U + omega ** 2 * float(np.max(np.abs(xs[:, 0]))) + 2 * a * float(np.max(np.abs(xs[:, 1])))
        floor = min(step_floor(h, eps, accel=acc), eps * (1 - 1e-9))
        bound, why = T / floor + 1, f"T/{floor:.3g} s, guard acceleration <= {acc:.3g} m/s^2"
    result.add(execution_checks(system, ex, eps, control=model.control, bound=bound, bound_why=why))
    # position error at the step points against the exact execution (paper 000 eq. (30))
    ts = ex.step_times()
    xs = np.concatenate([s.x[:, 0] for s in ex.segments])
    rho = float(np.max(np.abs(xs - ref.position(ts))))
    # during the exact sticking phases the relaxed mass stays on the stop: within the strip past it
    # and below eps c^2/(1 - c^2) off it once the chatter has settled (the ball's bound)
    c = 0.5
    band = eps * c * c / (1 - c * c)
    worst = 0.0
    for s0, s1 in ref.sticking_intervals(T):
        lo = s0 + (0.0 if s0 == 0.0 else 0.05)
        tt = np.linspace(lo, min(s1, T) - 0.05, 200)
        xx = np.array([st[0] for st in ex.sample(tt).states])
        worst = max(worst, float(np.max(xx - x_max)) / eps, float(np.max(x_max - xx)) / band)
    result.add(Check("on the stop while the exact mass sticks", worst <= 1.0 + 1e-9,
                     f"x within [x_max - eps c^2/(1-c^2), x_max + eps] on the exact sticking phases "
                     f"(worst ratio {worst:.3g})"))
    result.numbers.update({"rho_hat": rho, "wall_s": cost, "transitions": len(ex.transitions)})
    if continued:
        # sticks and releases as the reference does: the releases where F = u/m - omega^2 x_max
        # changes sign (closed form), the sticks at most the skipped tail (window/(1 - c)) early
        # and one transition's lag (h + eps) late
        sticks = [tr for tr in ex.transitions if tr.name == "stick"]
        releases = [tr for tr in ex.transitions if tr.name == "release"]
        exact = ref.sticking_intervals(T)
        starts = [s0 for s0, _ in exact]
        ends = [s1 for _, s1 in exact if s1 < T]
        rel_err = max((abs(a.time - b) for a, b in zip(releases, ends)), default=math.inf)
        ok = len(releases) == len(ends) and rel_err <= 1e-9
        result.add(Check("released where F changes sign", ok,
                         f"{len(releases)} releases at the exact times {', '.join(f'{e:.9g}' for e in ends)} to "
                         f"{rel_err:.2g} s"))
        lo, hi = (h + eps) / (1 - c_ex2) + (h + eps), (h + eps)
        errs = [a.time - b for a, b in zip(sticks, starts)]
        ok = len(sticks) == len(starts) and all(-lo <= e <= hi for e in errs)
        result.add(Check("sticks where the impacts accumulate", ok,
                         f"stick times - exact: {', '.join(f'{e:+.3g}' for e in errs)} s within "
                         f"[-{lo:.3g}, {hi:.3g}]"))
        plain_model = _oscillator_model(False)
        start = time.perf_counter()
        plain = simulate(plain_model.system, [x_max, 0.0], "free", T, h, eps, control=plain_model.control,
                         max_transitions=10 ** 6)
        plain_cost = time.perf_counter() - start
        t_p = plain.step_times()
        rho_plain = float(np.max(np.abs(np.concatenate([s.x[:, 0] for s in plain.segments]) - ref.position(t_p))))
        ok = rho <= 2.0 * rho_plain and 10 * len(ex.transitions) <= len(plain.transitions)
        result.add(Check("as accurate at a fraction of the cost", ok,
                         f"rho_hat {rho:.3g} m vs {rho_plain:.3g} m without; transitions {len(ex.transitions)} vs "
                         f"{len(plain.transitions)}; {cost:.3g} s vs {plain_cost:.3g} s"))
        result.numbers.update({"rho_hat_plain": rho_plain, "wall_s_plain": plain_cost,
                               "transitions_plain": len(plain.transitions)})
    levels = [(1e-2, 1e-3), (1e-2, 1e-4), (1e-2, 1e-5)] + ([] if quick else [(1e-2, 1e-6)])
    errs = []
    for hh, ee in levels:
        m_l = _oscillator_model(continued, hh + ee)
        run = simulate(m_l.system, [x_max, 0.0], "free", T, hh, ee, control=m_l.control, max_transitions=10 ** 6)
        t_r = run.step_times()
        errs.append(float(np.max(np.abs(np.concatenate([s.x[:, 0] for s in run.segments]) - ref.position(t_r)))))
    result.add(check_order("rho_hat -> 0", [lv[1] for lv in levels], errs, 0.5, 1.2, "eps (h = 1e-2)"))
    result.outcome = (f"{ex.status}; {len(ex.transitions)} transitions, rho_hat = {rho:.2g} m, "
                      f"{cost:.2g} s")
