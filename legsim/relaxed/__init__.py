"""The relaxed hybrid integrator (paper 000, Fig. 12), composed of parts.

* ``simulate``: the public entry point; checks its arguments and builds the parts.
* ``integrate``: the loop of Fig. 12, nothing else.
* ``step_size``: fixed h, or error control by an embedded pair (``FixedStep``, ``ErrorControl``).
* ``landing``: how a step past a strip is shortened (``Halve``, ``Aim``, ``Dense``).
* ``strip``: locating q on a step's interpolant, holding it for eps - tau, the reset at q.
* ``entry``: entering a mode (a state already in a strip, the starting step, the short step to a
  simultaneous strip).
* ``rules``: the numeric decisions, plain functions the Python loop calls and the compiled
  kernel compiles from the same source.
* ``run``, ``outcomes``, ``messages``: the run's workspace, what the parts return, the messages
  of a run's ends.
"""

from .landing import Aim, Dense, Halve
from .simulate import LANDINGS, simulate
from .step_size import ErrorControl, FixedStep
from .strip import crossing_on_step, hermite, hermite_slope

__all__ = [
    "LANDINGS",
    "Aim",
    "Dense",
    "ErrorControl",
    "FixedStep",
    "Halve",
    "crossing_on_step",
    "hermite",
    "hermite_slope",
    "simulate",
]
