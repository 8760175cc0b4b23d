"""Sampled executions of the stochastic approximation (paper 004 Def. 4): each mode visit's
switch drawn from its guards' intensities, then the reset and the next visit."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from ..arguments import check_start, check_t_final, count, positive
from ..bounds import LocalErrorEstimator, ModeFlow, StepSamples, ball_fraction_past, check_steps, reset_lipschitz
from ..errors import ModelBreakdown
from ..hybrid import HybridSystem
from ..methods import Tableau
from .intensity import HAZARD_CAP, ControlFn, capped_gain, check_form, check_hazard_cap, cumulative, distance_ratio


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
    unresolved_from: the first time (s) the error ball was wider than the state itself
        (radius past max(1, |x|_inf), state units), None if never: from there on the ball holds
        the guards around it and the switches say nothing of the system (``wider_than_state``).
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
    unresolved_from: float | None = None

    @property
    def dwell_times(self) -> np.ndarray:
        """Duration of each completed visit (k,), s."""
        if not len(self.times):
            return np.zeros(0)
        starts = np.concatenate([[self.t0], self.times[:-1]])
        return self.times - starts


class Visit:
    """A mode visit's flow, shared by the samples that start it from the same state, with the
    cumulative hazard of each guard at the samples of each step, computed once."""

    def __init__(self, flow: ModeFlow, form: str, cap: float = HAZARD_CAP) -> None:
        self.flow = flow
        self.form = form
        self.cap = cap
        self.dim = flow.dim
        self._steps: list[tuple[StepSamples, np.ndarray, np.ndarray]] = []
        #: The first computed point whose ball is wider than the state, and how many points have
        #: been looked at (the flow's points only grow): found once for every sample.
        self._unresolved: float | None = None
        self._scanned = 0

    def unresolved_by(self, until: float) -> float | None:
        """The first time (s) up to ``until`` at which the flow's ball is wider than the state
        (``wider_than_state``), or None."""
        points = self.flow.points
        while self._unresolved is None and self._scanned < len(points):
            point = points[self._scanned]
            if wider_than_state(point.radius, point.x):
                self._unresolved = point.t
            self._scanned += 1
        return self._unresolved if self._unresolved is not None and self._unresolved <= until else None

    def step(self, n: int) -> tuple[StepSamples, np.ndarray, np.ndarray] | None:
        """Samples of step n, their cumulative hazards per guard (K, m) and the hazard gained
        over the step summed over guards from each sample on (K,), or None past the end."""
        while len(self._steps) <= n:
            samples = self.flow.step_samples(len(self._steps))
            if samples is None:
                return None
            pi = ball_fraction_past(samples.distance, samples.radius[:, None], self.dim).reshape(samples.distance.shape)
            cum = cumulative(pi, self.form)
            z = distance_ratio(samples.distance, samples.radius[:, None])
            gain = capped_gain(
                np.maximum(np.diff(cum, axis=0), 0.0), z[:-1], z[1:], pi[:-1], pi[1:], self.cap, self.form
            ).sum(axis=1)
            self._steps.append((samples, cum, np.concatenate([[0.0], np.cumsum(gain)])))
        return self._steps[n]


def _sample_visit(visit: Visit, rng: np.random.Generator) -> tuple[float, int, np.ndarray, float] | None:
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
    visit: Visit, n: int, samples: StepSamples, cum: np.ndarray, i: int, need: float, rng: np.random.Generator
) -> tuple[float, int, np.ndarray, float]:
    """The switch falls between samples i - 1 and i of step n, after a further hazard ``need``."""
    flow = visit.flow
    p0, p1 = flow.points[n], flow.points[n + 1]
    dt = p1.t - p0.t
    s_lo, s_hi = float(samples.s[i - 1]), float(samples.s[i])
    c_lo = cum[i - 1]

    def past(d: np.ndarray, r: Any) -> tuple[np.ndarray, np.ndarray]:
        """The fraction of the ball past each guard, and z = d / B."""
        return ball_fraction_past(d, r, visit.dim).reshape(-1), distance_ratio(d, r).reshape(-1)

    def past_at(s: float) -> tuple[np.ndarray, np.ndarray]:
        _, _, r, _, d = flow.on_step(n, s)
        return past(d, r)

    pi_lo, z_lo = past(samples.distance[i - 1], samples.radius[i - 1])

    def gained(s: float) -> float:
        # Capped as the pieces are (each guard's gain and its cap are non-decreasing in s, so is
        # their minimum), meeting the piece's own gain at sample i.
        pi, z = past_at(s)
        free = np.maximum(cumulative(pi, visit.form) - c_lo, 0.0)
        return float(capped_gain(free, z_lo, z, pi_lo, pi, visit.cap, visit.form).sum()) - need

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
    _first: Visit | None = None,
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
        Zeno behaviour (Theorem 2), see ``check_hazard_cap``.
    """
    x = check_start(system, mode, x0)
    h = positive("h", h)
    form = check_form(intensity)
    cap = check_hazard_cap(hazard_cap)
    t_final = check_t_final(t_final, t0)
    max_transitions = count("max_transitions", max_transitions, 0)
    check_steps(t_final - float(t0), h, "stochastic execution")
    generator = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    estimator = LocalErrorEstimator(method, pair, floor)

    def visit(mode: str, x: np.ndarray, t: float, b0: float) -> Visit:
        return Visit(ModeFlow(system, mode, x, t, h, estimator, control=control, b0=b0, t_end=t_final), form, cap)

    sampled = _SampledExecution(mode, x, float(t0), carry)
    return sampled.run(_first or visit(mode, x, float(t0), 0.0), visit, generator, max_transitions)


def ball_scale(x: np.ndarray) -> float:
    """The size an error ball around x is judged against: max(1, |x|_inf), state units. (Not
    ``relaxed.resolution.state_scale``, 1 + |x|_inf, float64's resolution next to x: at twice the
    unit circle's size a ball has already held its wall for a crossing the execution missed.)"""
    return max(1.0, float(np.max(np.abs(x)))) if x.size else 1.0


def wider_than_state(radius: float, x: np.ndarray) -> bool:
    """Whether an error ball of ``radius`` around x is wider than the state itself (``ball_scale``):
    it then holds every guard within the state's own size, and the switches it draws are noise."""
    return radius > ball_scale(x)


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
        self.unresolved_from: float | None = None

    def note_unresolved(self, visit: Visit, until: float) -> None:
        """The first time up to ``until`` (s) the visit's ball grew wider than the state, if this
        execution has none yet."""
        if self.unresolved_from is None:
            self.unresolved_from = visit.unresolved_by(until)

    def run(
        self,
        visit: Visit,
        next_visit: Callable[[str, np.ndarray, float, float], Visit],
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
                self.note_unresolved(visit, last.t)
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
            self.note_unresolved(visit, tau)
            self.widest = max(self.widest, radius)
            if self.unresolved_from is None and wider_than_state(radius, x_tau):
                self.unresolved_from = tau
            if tau <= self.t:
                # Def. 4 needs tau_{i+1} > tau_i. A switch at the very instant of the previous one
                # means the visits have shrunk below the resolution of the time (a ball at rounding
                # level cannot hold off an accumulation): going on would only repeat it.
                return self.end(x_tau.copy(), self.t, "stalled", self._stalled(radius, x_tau))
            tr = visit.flow.transitions[j]
            try:
                x_new = np.asarray(x_tau if tr.reset is None else tr.reset(x_tau), dtype=float)
            except ModelBreakdown as exc:
                return self.end(x_tau.copy(), tau, "model_breakdown", f"the reset of {tr.name} at t={tau:.6g}: {exc}")
            b0 = radius * reset_lipschitz(tr, x_tau, len(x_new)) if self.carry else 0.0
            self.switch(tau, tr.name, tr.target, x_new)
            visit = next_visit(tr.target, x_new, tau, b0)

    def _stalled(self, radius: float, x: np.ndarray) -> str:
        """Why the switching times stopped advancing: a ball too small to keep the switches
        apart, or one grown wider than the state (``wider_than_state``), which holds every guard
        at once, so each switch is drawn at the instant of the last."""
        head = (
            f"the switching times stopped advancing at t={self.t:.17g} after {len(self.times)} switches "
            f"(a visit shorter than the time resolution; error ball {radius:.3g})"
        )
        if wider_than_state(radius, x):
            return (
                f"{head}: the ball has grown wider than the state itself (|x|_inf {ball_scale(x):.3g}), so it "
                f"holds every guard and no longer tells the switches apart; its growth e^(L t) needs a "
                f"shorter run (t_final), a smaller step h or a smaller local error floor"
            )
        return f"{head}: the bound is too small to keep the switches apart, declare a larger local error floor"

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
            unresolved_from=self.unresolved_from,
        )
