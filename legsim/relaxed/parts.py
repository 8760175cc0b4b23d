"""The parts a run is composed of, as data: a step-size rule and a landing rule.

``simulate`` takes them by name (h, rtol/atol, ``landing="aim"``) or as these objects; either way
the one loop (``legsim.relaxed.loop``) runs the rule they name with their parameters, compiled or
not. Any other object is refused by name: the loop never guesses what a custom part means.

* Step-size rules: ``FixedStep`` (every step starts from h, paper 000 Fig. 12) and
  ``ErrorControl`` (steps controlled by the method's embedded pair, h the first and largest).
* Landing rules: ``Halve`` (the paper's rule), ``Aim`` (retry at the step where the failed step's
  interpolant reaches the strip's middle) and ``Dense`` (land on the failed step's own
  continuous extension; methods that have one).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FixedStep:
    """Every step starts from the nominal step h of ``simulate``."""


@dataclass(frozen=True)
class ErrorControl:
    """Steps controlled by the local error estimate of an embedded pair: a step passes when the
    RMS norm of its estimate scaled by ``atol + rtol |x|`` is at most 1 (Hairer, Norsett and
    Wanner I, Sec. II.4; scipy's solve_ivp). Tolerances are relative (1) and absolute (the
    state's units)."""

    rtol: float
    atol: float


@dataclass(frozen=True)
class Halve:
    """Halve a step that ends past a strip (paper 000 Fig. 12, step 3)."""

    name = "halve"


@dataclass(frozen=True)
class Aim:
    """Aim the retry at the middle of the deepest strip along the failed step's interpolant."""

    name = "aim"


@dataclass(frozen=True)
class Dense:
    """Land on the failed step's own continuous extension."""

    name = "dense"
