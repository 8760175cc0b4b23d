"""Stochastic approximation of a hybrid system from its error bounds (paper 004, Section IV).

In a mode visit starting at ``(tau_i, xi_i)``, the numerical solution ``x_hat(t)`` (fixed step
h, flowing on past the guards: the domains of the stochastic system are all of R^n) is
surrounded by the ball of radius ``B(t)`` of Section III, which contains the true solution.
Reading the ball as a uniform distribution of the true state (Remark 2), the *transition
function* of transition j is the fraction of the ball past its guard,

    pi_j(t) = |ball(B(t), x_hat(t)) past g_j = 0| / |ball|,

exact for hyperplane guards (regularised incomplete beta function) and through the guard
linearised at x_hat otherwise (``legsim.bounds.ball_fraction_past``). Section IV-B4 turns the
transition functions into *intensities* by right derivatives, and a stochastic execution
(Def. 4) draws each switching time from the survival function ``S(t) = exp(-int lambda)`` and
the target from the transition kernel at that time.

Two readings of "intensity as right derivative" are offered (``intensity=``):

* ``"hazard"`` (default): lambda_j = (d/dt -log(1 - pi_j))^+, the right derivative of the
  cumulative hazard of pi_j. While pi_j rises, S = 1 - pi_j: the probability of having switched
  by t is exactly the fraction of the ball past the guard, so a ball wholly past a guard has
  switched with probability 1 and a trajectory whose ball reaches half-way past a guard
  (grazing) switches with probability 1/2 (paper 004 Fig. 1).
* ``"derivative"``: lambda_j = (d pi_j / dt)^+, the formula read literally. Then
  S = exp(-pi_j) while pi_j rises, so even a ball wholly past a guard leaves a probability
  e^-1 of never switching there, and a grazing pass switches with probability 1 - e^-1/2.

Both clip negative derivatives to 0 (intensities are non-negative, Def. 3): a ball moving
back out of a guard takes no probability back. The kernel chooses the target j with
probability proportional to pi_j at the switching time (Def. 4: "via P(tau_{i+1})").

Between the computed points B is interpolated linearly (Section III) and x_hat is the cubic
Hermite interpolant (see ``legsim.bounds.ModeFlow``); steps during which the ball may reach a
guard are sampled finely enough to split them where each pi_j turns (``ModeFlow.step_samples``),
so that pi_j is monotone between samples and its positive variation is exact; switching times
are found on the interpolant by a bracketed root search.

A visit that starts with its ball already past a guard (entered through a reset) takes that
guard only as the ball moves further past it: Def. 4 needs tau_{i+1} > tau_i. This is what
excludes Zeno behaviour (Theorem 2): for h > 0 the ball has a positive radius and each visit
must move it a positive distance.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq

from .arguments import check_start, check_t_final, count, positive
from .bounds import LocalErrorEstimator, ModeFlow, StepSamples, ball_fraction_past, check_steps, reset_lipschitz
from .errors import ModelBreakdown, SimulationError
from .hybrid import HybridSystem
from .methods import Tableau

ControlFn = Callable[[float, np.ndarray], Any]
INTENSITIES = ("hazard", "derivative")

#: Most executions of one ensemble: each is kept in memory, and one takes milliseconds to
#: seconds, so more is a typo rather than a Monte Carlo run to start.
MAX_SAMPLES = 1_000_000

# -log(1 - pi) with 1 - pi floored here: a hazard of 690 is certain switching (e^-690 ~ 1e-300).
_TINY = 1e-300


def _cumulative(pi: np.ndarray, form: str) -> np.ndarray:
    if form == "hazard":
        return -np.log(np.maximum(1.0 - pi, _TINY))
    return pi


#: Default ``hazard_cap``: the most hazard one visit gains per error-ball radius its state moves
#: relative to a guard.
HAZARD_CAP = 16.0


def _check_hazard_cap(hazard_cap: float) -> float:
    """Validate ``hazard_cap`` (dimensionless, > 0; inf for none).

    Theorem 2 (no Zeno behaviour for h > 0) rests on bounded intensities (paper 004, Remark 3).
    The hazard reading is not bounded: its rate d/dt -log(1 - pi) = pi' / (1 - pi) grows without
    limit as pi -> 1, so a visit that starts with its ball nearly all past its guard switches
    almost at once; without a cap, past the two tanks' Zeno time the visits shrink geometrically
    down to the resolution of time (an accumulation of the sampled executions themselves). The
    fraction past a guard is a function of z = d / B (signed distance over the ball's radius),
    so the cap is put in those units: a guard's hazard grows at most ``hazard_cap`` per unit of
    |dz|, the rate is then at most hazard_cap |dz/dt|, bounded for h > 0, and each passage of the
    ball through a guard allows a bounded number of switches. It binds only where pi'/(1 - pi)
    exceeds it, for the default 16 in the last ~1% of the probability (a disk: 1 - pi < 0.01),
    so grazing probabilities and switching times (Theorem 1) keep their values."""
    if (
        isinstance(hazard_cap, bool)
        or not isinstance(hazard_cap, (int, float, np.integer, np.floating))
        or not hazard_cap > 0.0
    ):
        raise SimulationError(f"hazard_cap must be a number > 0 (inf for no cap), got {hazard_cap!r}")
    return float(hazard_cap)


def _capped_gain(
    gain: np.ndarray,
    z_from: np.ndarray,
    z_to: np.ndarray,
    pi_from: np.ndarray,
    pi_to: np.ndarray,
    cap: float,
    form: str,
) -> np.ndarray:
    """Per-guard hazard gains limited to cap |z_to - z_from| (z = d / B; a zero radius makes z
    infinite and leaves the gain uncapped). In the hazard reading a ball wholly past its guard
    (pi = 1) has switched for certain: while it moves on further past, its uncapped rate is
    infinite, so it gains the cap's full cap |dz| (without this, a passage whose drawn hazard
    exceeds what the cap allowed before pi reached 1 would never switch)."""
    if cap == math.inf:
        return gain
    with np.errstate(invalid="ignore", divide="ignore"):
        dz = z_to - z_from
    if form == "hazard":
        gain = np.where((pi_from >= 1.0) & (pi_to >= 1.0) & (dz < 0.0), np.inf, gain)
    return np.minimum(gain, cap * np.where(np.isnan(dz), np.inf, np.abs(dz)))


def _ratio(d: np.ndarray, r: Any) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(d, dtype=float) / r


def _check_form(intensity: str) -> str:
    if intensity not in INTENSITIES:
        raise SimulationError(f"intensity must be one of {list(INTENSITIES)}, got {intensity!r}")
    return intensity


@dataclass(frozen=True)
class TransitionFunctions:
    """Transition functions of one mode visit, at the computed points.

    Attributes
    ----------
    mode: the mode; transitions, targets: names and target modes of its outgoing transitions (m).
    t: times (k,), s; x: numerical solution (k, n); radius: B(t) (k,).
    distance: signed distance to each linearised guard (k, m), positive inside.
    pi: transition functions pi_j(t) (k, m), the fraction of the ball past guard j.
    intensity: lambda_j on [t_n, t_{n+1}) (k, m), 1/s (the step's right derivative; 0 at the last).
    cumulative_hazard: int_{t0}^{t} sum_j lambda_j (k,).
    survival: S(t) = exp(-cumulative_hazard) (k,): the probability of no switch by t.
    form: "hazard" or "derivative" (see the module).
    """

    mode: str
    transitions: tuple[str, ...]
    targets: tuple[str, ...]
    t: np.ndarray
    x: np.ndarray
    radius: np.ndarray
    distance: np.ndarray
    pi: np.ndarray
    intensity: np.ndarray
    cumulative_hazard: np.ndarray
    survival: np.ndarray
    form: str

    @property
    def switching_probability(self) -> np.ndarray:
        """Probability of having left the mode by each time, 1 - S(t) (k,)."""
        return 1.0 - self.survival


def transition_functions(
    system: HybridSystem,
    mode: str,
    x0: Any,
    t_final: float,
    h: float,
    method: str | Tableau = "rk4",
    *,
    t0: float = 0.0,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    b0: float = 0.0,
    intensity: str = "hazard",
) -> TransitionFunctions:
    """pi_j(t), intensities and survival along one visit of ``mode`` from ``(t0, x0)`` to
    ``t_final`` (the numerical solution flows on past the guards).

    Parameters: as ``sample_execution``; ``b0`` is an initial uncertainty radius.
    """
    x = check_start(system, mode, x0)
    h = positive("h", h)
    form = _check_form(intensity)
    t_final = check_t_final(t_final, t0)
    check_steps(t_final - float(t0), h, "transition functions")
    flow = ModeFlow(
        system, mode, x, float(t0), h, LocalErrorEstimator(method, pair, floor), control=control, b0=b0, t_end=t_final
    )
    pieces: list[StepSamples] = []
    n = 0
    while True:
        samples = flow.step_samples(n)
        if samples is None:
            break
        pieces.append(samples)
        n += 1
    if not pieces:  # a flow of a single point (t_final reached at once, or a non-finite field)
        p = flow.point(0)
        if p is None:
            raise SimulationError(f"mode '{mode}': {flow.message}")
        pieces.append(
            StepSamples(np.zeros(1), np.array([p.t]), p.x[None], np.array([p.radius]), p.guard[None], p.distance[None])
        )
    # Consecutive steps share their end points: keep each once.
    keep = [pieces[0]] + [
        StepSamples(q.s[1:], q.t[1:], q.x[1:], q.radius[1:], q.guard[1:], q.distance[1:]) for q in pieces[1:]
    ]
    t = np.concatenate([q.t for q in keep])
    xs = np.concatenate([q.x for q in keep])
    radius = np.concatenate([q.radius for q in keep])
    m = len(flow.transitions)
    distance = np.concatenate([q.distance for q in keep]).reshape(len(t), m)
    pi = ball_fraction_past(distance, radius[:, None], flow.dim).reshape(len(t), m)
    cum = _cumulative(pi, form)
    incr = np.maximum(np.diff(cum, axis=0), 0.0)
    dt = np.diff(t)
    lam = np.zeros_like(pi)
    if len(dt):
        lam[:-1] = incr / np.maximum(dt, np.finfo(float).tiny)[:, None]
    hazard = np.concatenate([[0.0], np.cumsum(incr.sum(axis=1))])
    trs = flow.transitions
    return TransitionFunctions(
        mode,
        tuple(tr.name for tr in trs),
        tuple(tr.target for tr in trs),
        t,
        xs,
        radius,
        distance,
        pi,
        lam,
        hazard,
        np.exp(-hazard),
        form,
    )


# -- sampled stochastic executions ------------------------------------------------------------
@dataclass(frozen=True)
class StochasticExecution:
    """One sampled execution of the stochastic approximation (Def. 4).

    Attributes
    ----------
    times: switching times (k,), s, strictly increasing.
    modes: modes visited (k + 1).
    transitions: names of the transitions taken (k).
    states: state entering each visit (k + 1), after the reset.
    final_state: numerical state at t_end; t_end: end time (s).
    max_radius: the widest error ball met (at the switches and along the last visit), state
        units; 0 means the approximation was deterministic (the method is exact on the fields
        and no floor was declared).
    status: ``finished`` (t_final reached), ``max_transitions``, ``non_finite`` (a field or step
        that is not finite), ``model_breakdown`` (a model function raised ``ModelBreakdown``),
        ``bound_overflow`` (the error bound overflowed: the execution
        stops at the last time it was finite) or ``stalled`` (a switch fell at the instant of
        the previous one, in floating point: the ball is too small to keep switches apart, as
        with a bound at rounding level near a Zeno point); ``message`` says where.
    message: why it stopped, when not finished.
    t0: start time (s).
    """

    times: np.ndarray
    modes: list[str]
    transitions: list[str]
    states: list[np.ndarray]
    final_state: np.ndarray
    t_end: float
    status: str
    message: str = ""
    t0: float = 0.0
    max_radius: float = 0.0

    @property
    def dwell_times(self) -> np.ndarray:
        """Duration of each completed visit (k,), s."""
        if not len(self.times):
            return np.zeros(0)
        starts = np.concatenate([[self.t0], self.times[:-1]])
        return self.times - starts


class _Visit:
    """A mode visit's flow, shared by the samples that start it from the same state, with the
    cumulative hazard of each guard at the samples of each step, computed once."""

    def __init__(self, flow: ModeFlow, form: str, cap: float = HAZARD_CAP) -> None:
        self.flow = flow
        self.form = form
        self.cap = cap
        self.dim = flow.dim
        self._steps: list[tuple[StepSamples, np.ndarray, np.ndarray]] = []

    def step(self, n: int) -> tuple[StepSamples, np.ndarray, np.ndarray] | None:
        """Samples of step n, their cumulative hazards per guard (K, m) and the hazard gained
        over the step summed over guards from each sample on (K,), or None past the end."""
        while len(self._steps) <= n:
            samples = self.flow.step_samples(len(self._steps))
            if samples is None:
                return None
            pi = ball_fraction_past(samples.distance, samples.radius[:, None], self.dim).reshape(samples.distance.shape)
            cum = _cumulative(pi, self.form)
            z = _ratio(samples.distance, samples.radius[:, None])
            gain = _capped_gain(
                np.maximum(np.diff(cum, axis=0), 0.0), z[:-1], z[1:], pi[:-1], pi[1:], self.cap, self.form
            ).sum(axis=1)
            self._steps.append((samples, cum, np.concatenate([[0.0], np.cumsum(gain)])))
        return self._steps[n]


def _sample_visit(visit: _Visit, rng: np.random.Generator) -> tuple[float, int, np.ndarray, float] | None:
    """Draw the switching time and target of one visit: (tau, transition index, x_hat(tau),
    B(tau)), or None when the flow ends (t_end or non-finite) without a switch."""
    target = rng.exponential()
    level = 0.0
    n = 0
    while True:
        step = visit.step(n)
        if step is None:
            return None
        samples, cum, gained = step
        if level + gained[-1] >= target:
            i = int(np.searchsorted(gained, target - level, side="left"))  # gained[i-1] < need <= gained[i]
            return _switch_in_piece(visit, n, samples, cum, i, target - level - gained[i - 1], rng)
        level += float(gained[-1])
        n += 1


def _switch_in_piece(
    visit: _Visit, n: int, samples: StepSamples, cum: np.ndarray, i: int, need: float, rng: np.random.Generator
) -> tuple[float, int, np.ndarray, float]:
    """The switch falls between samples i - 1 and i of step n, after a further hazard ``need``."""
    flow = visit.flow
    p0, p1 = flow.points[n], flow.points[n + 1]
    dt = p1.t - p0.t
    s_lo, s_hi = float(samples.s[i - 1]), float(samples.s[i])
    c_lo = cum[i - 1]

    def past(d: np.ndarray, r: Any) -> tuple[np.ndarray, np.ndarray]:
        """The fraction of the ball past each guard, and z = d / B."""
        return ball_fraction_past(d, r, visit.dim).reshape(-1), _ratio(d, r).reshape(-1)

    def past_at(s: float) -> tuple[np.ndarray, np.ndarray]:
        _, _, r, _, d = flow.on_step(n, s)
        return past(d, r)

    pi_lo, z_lo = past(samples.distance[i - 1], samples.radius[i - 1])

    def gained(s: float) -> float:
        # Capped as the pieces are (each guard's gain and its cap are non-decreasing in s, so is
        # their minimum), meeting the piece's own gain at sample i.
        pi, z = past_at(s)
        free = np.maximum(_cumulative(pi, visit.form) - c_lo, 0.0)
        return float(_capped_gain(free, z_lo, z, pi_lo, pi, visit.cap, visit.form).sum()) - need

    # Between samples every pi_j is monotone, so gained is non-decreasing: one sign change.
    lo_val, hi_val = gained(s_lo), gained(s_hi)
    if lo_val >= 0.0:
        s = s_lo
    elif hi_val <= 0.0:
        s = s_hi
    else:
        s = brentq(gained, s_lo, s_hi, xtol=1e-15, rtol=8.9e-16)
    pi = past_at(s)[0]
    if pi.sum() <= 0.0:  # rounding at the bracket's end
        pi = past_at(s_hi)[0]
    if pi.sum() <= 0.0:
        pi = np.maximum(cum[i] - c_lo, 0.0)
    j = int(rng.choice(len(pi), p=pi / pi.sum())) if len(pi) > 1 else 0
    return p0.t + s * dt, j, flow.state(n, s), (1.0 - s) * p0.radius + s * p1.radius


def sample_execution(
    system: HybridSystem,
    mode: str,
    x0: Any,
    t_final: float,
    h: float,
    method: str | Tableau = "rk4",
    *,
    rng: np.random.Generator | int | None = None,
    t0: float = 0.0,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    intensity: str = "hazard",
    max_transitions: int = 1000,
    carry: bool = True,
    hazard_cap: float = HAZARD_CAP,
    _first: _Visit | None = None,
) -> StochasticExecution:
    """One stochastic execution of the approximation S_h of ``system`` (paper 004 Def. 4).

    Parameters
    ----------
    system, mode, x0: the hybrid system and the initial mode and state.
    t_final: end time (s); h: the fixed step (s) of the numerical solution in each visit.
    method: Runge-Kutta method of the numerical solution.
    rng: a numpy Generator or a seed.
    pair, floor: local error estimation (``legsim.bounds``): embedded pair, declared floor.
    control: optional control(t, x) -> u.
    intensity: ``"hazard"`` or ``"derivative"`` (see the module).
    max_transitions: most switches before the execution stops with status ``max_transitions``.
    carry: start each visit with the uncertainty inherited through the switch,
        ``b0 = sigma_max(DR) B(tau)`` (the computed state at the switch is only known to within
        B(tau)); False restarts every visit's bound at 0.
    hazard_cap: most hazard a visit gains per error-ball radius its state moves relative to a
        guard (``HAZARD_CAP``; ``math.inf`` for none): bounded intensities keep S_h free of
        Zeno behaviour (Theorem 2), see ``_check_hazard_cap``.
    """
    x = check_start(system, mode, x0)
    h = positive("h", h)
    form = _check_form(intensity)
    cap = _check_hazard_cap(hazard_cap)
    t_final = check_t_final(t_final, t0)
    max_transitions = count("max_transitions", max_transitions, 0)
    check_steps(t_final - float(t0), h, "stochastic execution")
    generator = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    estimator = LocalErrorEstimator(method, pair, floor)

    def visit(mode: str, x: np.ndarray, t: float, b0: float) -> _Visit:
        return _Visit(ModeFlow(system, mode, x, t, h, estimator, control=control, b0=b0, t_end=t_final), form, cap)

    sampled = _SampledExecution(mode, x, float(t0), carry)
    return sampled.run(_first or visit(mode, x, float(t0), 0.0), visit, generator, max_transitions)


class _SampledExecution:
    """A stochastic execution as it is drawn: the switches so far and the widest ball met."""

    def __init__(self, mode: str, x: np.ndarray, t0: float, carry: bool) -> None:
        self.t0 = t0
        self.t = t0  # time of the last switch (s)
        self.carry = carry
        self.times: list[float] = []
        self.modes = [mode]
        self.names: list[str] = []
        self.states = [x.copy()]
        self.widest = 0.0

    def run(
        self,
        visit: _Visit,
        next_visit: Callable[[str, np.ndarray, float, float], _Visit],
        rng: np.random.Generator,
        max_transitions: int,
    ) -> StochasticExecution:
        """Draw switches until the flow ends, the budget is used up or the switches stall;
        ``next_visit(mode, x, t, b0)`` starts the visit after a switch."""
        while True:
            drawn = _sample_visit(visit, rng)
            if drawn is None:
                flow = visit.flow
                last = flow.points[-1]
                self.widest = max([self.widest] + [p.radius for p in flow.points])
                return self.end(
                    last.x.copy(), last.t, "finished" if flow.status == "end" else flow.status, flow.message
                )
            if len(self.times) >= max_transitions:
                return self.end(
                    visit.flow.points[-1].x.copy(),
                    self.t,
                    "max_transitions",
                    f"transition budget max_transitions={max_transitions} used up at t={self.t:.17g}",
                )
            tau, j, x_tau, radius = drawn
            self.widest = max(self.widest, radius)
            if tau <= self.t:
                # Def. 4 needs tau_{i+1} > tau_i. A switch at the very instant of the previous one
                # means the visits have shrunk below the resolution of the time (a ball at rounding
                # level cannot hold off an accumulation): going on would only repeat it.
                return self.end(
                    x_tau.copy(),
                    self.t,
                    "stalled",
                    f"the switching times stopped advancing at t={self.t:.17g} after {len(self.times)} "
                    f"switches (a visit shorter than the time resolution; error ball {radius:.3g}): the "
                    f"bound is too small to keep the switches apart, declare a larger local error floor",
                )
            tr = visit.flow.transitions[j]
            try:
                x_new = np.asarray(x_tau if tr.reset is None else tr.reset(x_tau), dtype=float)
            except ModelBreakdown as exc:
                return self.end(x_tau.copy(), tau, "model_breakdown", f"the reset of {tr.name} at t={tau:.6g}: {exc}")
            b0 = radius * reset_lipschitz(tr, x_tau, len(x_new)) if self.carry else 0.0
            self.switch(tau, tr.name, tr.target, x_new)
            visit = next_visit(tr.target, x_new, tau, b0)

    def switch(self, tau: float, name: str, target: str, x_new: np.ndarray) -> None:
        self.times.append(tau)
        self.names.append(name)
        self.modes.append(target)
        self.states.append(x_new.copy())
        self.t = tau

    def end(self, final_state: np.ndarray, t_end: float, status: str, message: str) -> StochasticExecution:
        return StochasticExecution(
            np.array(self.times),
            self.modes,
            self.names,
            self.states,
            final_state,
            t_end,
            status,
            message,
            t0=self.t0,
            max_radius=self.widest,
        )


@dataclass
class Ensemble:
    """Monte Carlo ensemble of stochastic executions with the settings that made them."""

    executions: list[StochasticExecution]
    settings: dict[str, Any] = field(default_factory=dict)

    def switching_times(self, index: int) -> np.ndarray:
        """The ``index``-th switching time (0-based) of every execution that has one."""
        return np.array([e.times[index] for e in self.executions if len(e.times) > index])

    def summary(self, max_switches: int = 10, max_sequences: int = 10) -> dict[str, Any]:
        """JSON-ready summary: distribution of mode sequences and of switching times."""
        n = len(self.executions)
        counts = Counter(tuple(e.modes) for e in self.executions)
        sequences = [
            {"modes": list(seq), "transitions": len(seq) - 1, "count": c, "fraction": c / n}
            for seq, c in counts.most_common(max_sequences)
        ]
        per_sample = np.array([len(e.times) for e in self.executions])
        switches = []
        for i in range(int(per_sample.max(initial=0))):
            if i >= max_switches:
                break
            ts = self.switching_times(i)
            switches.append(
                {
                    "index": i + 1,
                    "count": len(ts),
                    "mean": float(ts.mean()),
                    "std": float(ts.std()),
                    "min": float(ts.min()),
                    "max": float(ts.max()),
                }
            )
        dwell = [e.dwell_times for e in self.executions if len(e.times)]
        min_dwell = float(min(d.min() for d in dwell)) if dwell else None
        statuses = Counter(e.status for e in self.executions)
        return {
            **self.settings,
            "samples": n,
            "distinct_sequences": len(counts),
            "sequences": sequences,
            "transitions_per_sample": {
                "mean": float(per_sample.mean()),
                "min": int(per_sample.min()),
                "max": int(per_sample.max()),
            },
            "switching_times": switches,
            "min_dwell_time": min_dwell,
            "max_radius": max((e.max_radius for e in self.executions), default=0.0),
            "statuses": dict(statuses),
        }


def sample_generator(seed: int | None, index: int) -> np.random.Generator:
    """The random generator of execution ``index`` of an ensemble seeded by ``seed``: child
    ``index`` of ``numpy.random.SeedSequence(seed)`` (independent streams, numpy's way of
    seeding parallel work). ``seed`` None draws fresh entropy: such an ensemble is not
    reproducible, and its executions are drawn from unrelated streams."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(index),)))


def sample_ensemble(
    system: HybridSystem,
    mode: str,
    x0: Any,
    t_final: float,
    h: float,
    method: str | Tableau = "rk4",
    *,
    samples: int = 100,
    seed: int | None = None,
    t0: float = 0.0,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    intensity: str = "hazard",
    max_transitions: int = 1000,
    carry: bool = True,
    hazard_cap: float = HAZARD_CAP,
    progress: Callable[[int, int], None] | None = None,
    indices: Sequence[int] | None = None,
) -> Ensemble:
    """``samples`` independent stochastic executions. Execution k draws from its own numpy
    Generator, ``sample_generator(seed, k)``, so that its draws do not depend on the executions
    before it: any subset (``indices``, e.g. one batch of a Monte Carlo run spread over
    processes, ``legsim.sweep.stochastic``) gives the same executions as the whole ensemble.
    The first visit's numerical flow is computed once and shared, as every sample starts it
    from the same state. ``samples`` is at most ``MAX_SAMPLES``; ``progress(done, total)``,
    when given, is called after each execution."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 1 <= samples <= MAX_SAMPLES:
        raise SimulationError(f"samples must be an integer in [1, {MAX_SAMPLES}], got {samples!r}")
    chosen = range(int(samples)) if indices is None else [int(k) for k in indices]
    if any(not 0 <= k < samples for k in chosen):
        raise SimulationError(f"indices must lie in [0, {samples}), got {list(chosen)[:10]}")
    x = check_start(system, mode, x0)
    h = positive("h", h)
    _check_form(intensity)
    cap = _check_hazard_cap(hazard_cap)
    t_final = check_t_final(t_final, t0)
    estimator = LocalErrorEstimator(method, pair, floor)
    first = _Visit(ModeFlow(system, mode, x, float(t0), h, estimator, control=control, t_end=t_final), intensity, cap)
    runs = []
    for done, k in enumerate(chosen, 1):
        runs.append(
            sample_execution(
                system,
                mode,
                x,
                t_final,
                h,
                method,
                rng=sample_generator(seed, k),
                t0=t0,
                pair=pair,
                control=control,
                floor=floor,
                intensity=intensity,
                max_transitions=max_transitions,
                carry=carry,
                hazard_cap=cap,
                _first=first,
            )
        )
        if progress is not None:
            progress(done, len(chosen))
    settings = {
        "system": system.name,
        "initial_mode": mode,
        "h": h,
        "method": estimator.method.name,
        "pair": estimator.pair.name,
        "floor": estimator.floor,
        "intensity": intensity,
        "carry": carry,
        "hazard_cap": cap,
        "t_final": t_final,
        "seed": seed,
    }
    return Ensemble(runs, settings)


__all__: Sequence[str] = (
    "INTENSITIES",
    "MAX_SAMPLES",
    "Ensemble",
    "StochasticExecution",
    "TransitionFunctions",
    "sample_ensemble",
    "sample_execution",
    "sample_generator",
    "transition_functions",
)
