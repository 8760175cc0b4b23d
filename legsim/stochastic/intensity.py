"""Transition functions and intensities of the stochastic approximation (paper 004 Sec. IV-B):
the fraction of the error ball past each guard, read as a hazard or a derivative intensity."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..arguments import check_start, check_t_final, positive
from ..bounds import LocalErrorEstimator, ModeFlow, StepSamples, ball_fraction_past, check_steps
from ..errors import SimulationError
from ..hybrid import HybridSystem
from ..methods import Tableau

ControlFn = Callable[[float, np.ndarray], Any]
INTENSITIES = ("hazard", "derivative")

#: Most executions of one ensemble: each is kept in memory, and one takes milliseconds to
#: seconds, so more is a typo rather than a Monte Carlo run to start.
MAX_SAMPLES = 1_000_000

# -log(1 - pi) with 1 - pi floored here: a hazard of 690 is certain switching (e^-690 ~ 1e-300).
_TINY = 1e-300


def cumulative(pi: np.ndarray, form: str) -> np.ndarray:
    if form == "hazard":
        return -np.log(np.maximum(1.0 - pi, _TINY))
    return pi


#: Default ``hazard_cap``: the most hazard one visit gains per error-ball radius its state moves
#: relative to a guard.
HAZARD_CAP = 16.0


def check_hazard_cap(hazard_cap: float) -> float:
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


def capped_gain(
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


def distance_ratio(d: np.ndarray, r: Any) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(d, dtype=float) / r


def check_form(intensity: str) -> str:
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
    form = check_form(intensity)
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
    cum = cumulative(pi, form)
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
