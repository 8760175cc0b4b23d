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

from .ensemble import Ensemble, sample_ensemble, sample_generator
from .executions import StochasticExecution, sample_execution
from .intensity import HAZARD_CAP, INTENSITIES, MAX_SAMPLES, TransitionFunctions, transition_functions

__all__ = (
    "HAZARD_CAP",
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
