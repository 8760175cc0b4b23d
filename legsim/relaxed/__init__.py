"""The relaxed hybrid integrator (paper 000, Fig. 12): one loop, written once.

* ``simulate``: the public entry point; checks its arguments and runs the loop.
* ``loop``: the loop of Fig. 12, over the functions of ``entering`` (a mode's entry), ``stepping``
  (a step, error control, the landing rules), ``crossing`` (locating q, holding it for eps - tau,
  the reset at q, continuations, joint crossings), ``curve`` (a step's interpolant and where a
  guard meets it), ``stages`` (the Runge-Kutta step from a method's arrays) and ``evaluate`` (the
  closed loop's field, guards and resets); ``rules`` holds the scalar decisions. All are plain
  Python over the arrays ``layout`` names, run interpreted or compiled (``legsim.compiled``).
* ``driver``, ``tables``, ``workspace``, ``assemble``, ``adapt``: the Python around it (a run's
  tables and arrays, Python models' adapters, the execution).
* ``parts``: the step-size and landing rules as data.
* ``watches``: conditions checked on the stored points and the steps' middles (a fall, a state
  to report, a time to measure), by the driver.
"""

from .parts import Aim, Dense, ErrorControl, FixedStep, Halve
from .rules import crossing_on_step
from .simulate import LANDINGS, simulate
from .single import hermite, hermite_derivative
from .watches import Watch

__all__ = [
    "LANDINGS",
    "Aim",
    "Dense",
    "ErrorControl",
    "FixedStep",
    "Halve",
    "Watch",
    "crossing_on_step",
    "hermite",
    "hermite_derivative",
    "simulate",
]
