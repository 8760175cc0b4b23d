"""Step-size rules: fixed nominal steps (paper 000 Fig. 12: every step starts from h) or error
control by the method's embedded pair, h then being the initial and largest step.

A rule is asked three things by the loop: the trial length of the next step
(``h_prop``, capped by ``h_max``), whether a trial step inside the relaxed domain passes
(``judge``), and what to carry to the next step once one is accepted (``keep``). Error control
also restarts each new mode at the standard starting step (``restart``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..methods import Tableau
from ..methods.stepper import error_estimator, error_norm
from .rules import (
    kept_proposal,
    proposed_step,
    rejected_step,
    restarted_step,
    scaled_rms,
    starting_guess,
    starting_step,
)


class FixedStep:
    """Every step starts from the nominal h (s); only landings shorten it."""

    adaptive = False

    def __init__(self, h: float) -> None:
        self.h_max = h
        self.h_prop = h

    def judge(
        self, hk: float, stages: tuple[np.ndarray, ...], x: np.ndarray, x_new: np.ndarray, rejected: bool
    ) -> tuple[bool, float]:
        """Every step passes; the proposal stays h."""
        return True, self.h_max

    def keep(self, proposal: float, shortened: bool, rejected: bool) -> None:
        """Nothing to carry: the next step starts from h again."""

    def settings(self) -> dict[str, Any]:
        return {"rtol": None, "atol": None}


class ErrorControl:
    """Steps controlled by the local error estimate of an embedded pair: a step passes when the
    RMS norm of its estimate scaled by atol + rtol |x| is at most 1 (Hairer, Norsett and Wanner I,
    Sec. II.4; scipy's solve_ivp). ``h`` (s) is the initial and largest step."""

    adaptive = True

    def __init__(self, tableau: Tableau, h: float, rtol: float, atol: float) -> None:
        self.h_max = h
        self.h_prop = h
        self.rtol, self.atol = rtol, atol
        if tableau.error_order is None:
            raise SimulationError(
                f"method '{tableau.name}' has an embedded error estimate but no error_order: "
                f"error control needs it for its step exponent"
            )
        self.exponent = -1.0 / (min(tableau.order, tableau.error_order) + 1)
        self._estimate = error_estimator(tableau)
        self._blended = tableau.b_err_low is not None

    def error(self, hk: float, stages: tuple[np.ndarray, ...], x: np.ndarray, x_new: np.ndarray) -> float:
        """The scaled RMS norm of the step's local error estimate."""
        err, err_low = self._estimate(hk, stages)
        return error_norm(
            err.tolist(),
            err_low.tolist() if err_low is not None else (),
            x.tolist(),
            x_new.tolist(),
            self.rtol,
            self.atol,
            self._blended,
        )

    def judge(
        self, hk: float, stages: tuple[np.ndarray, ...], x: np.ndarray, x_new: np.ndarray, rejected: bool
    ) -> tuple[bool, float]:
        """(True, proposal for the next step) when the step passes the error test, else
        (False, the shorter step to retry)."""
        err = self.error(hk, stages, x, x_new)
        if err > 1.0:
            return False, rejected_step(hk, err, self.exponent)
        return True, proposed_step(hk, err, self.exponent, rejected)

    def keep(self, proposal: float, shortened: bool, rejected: bool) -> None:
        """Carry the proposal of an accepted step (see ``rules.kept_proposal``)."""
        self.h_prop = kept_proposal(self.h_prop, proposal, shortened, rejected)

    def restart(self, f: Callable[[float, np.ndarray], np.ndarray], t: float, x: np.ndarray, k0: np.ndarray) -> None:
        """A new mode's flow (a stance after a touchdown) may want a much shorter step than the
        one the previous mode ended with, which was tuned to another field: start it at the
        smaller of that and the standard starting step, as an event-driven integrator does at
        every restart; for one field evaluation a tolerance then buys the accuracy it buys
        solve_ivp."""
        self.h_prop = restarted_step(self.h_prop, self.starting_step(f, t, x, k0))

    def starting_step(
        self, f: Callable[[float, np.ndarray], np.ndarray], t: float, x: np.ndarray, k0: np.ndarray
    ) -> float:
        """The starting step size of Hairer, Norsett and Wanner (I, Sec. II.4): a step whose
        estimated local error is about 1% of the tolerance, from f at x and at one explicit Euler
        step away (one evaluation of ``f(t, x)``). On any failure the current proposal stands.
        The norms are ``rules.scaled_rms``, which the compiled kernel sums the same way."""
        rtol, atol, xs = self.rtol, self.atol, x.tolist()
        d1 = scaled_rms(k0.tolist(), xs, rtol, atol)
        h0 = starting_guess(scaled_rms(xs, xs, rtol, atol), d1, self.h_max)
        try:
            f1 = f(t + h0, x + h0 * k0)
        except Exception:
            return self.h_prop  # the steps themselves will meet it and report it properly
        d2 = scaled_rms((f1 - k0).tolist(), xs, rtol, atol) / h0
        if not math.isfinite(d2):
            return self.h_prop
        return starting_step(h0, d1, d2, self.exponent)

    def settings(self) -> dict[str, Any]:
        return {"rtol": self.rtol, "atol": self.atol}


def rms(v: np.ndarray) -> float:
    """Root mean square of a scaled vector (the norms of Hairer's codes)."""
    return math.sqrt(float(np.dot(v, v)) / len(v))
