"""The thinnest strip float64 resolves at a state's scale, written once: ``simulate`` refuses a
thinner eps before the run, and a run that ends without landing in a strip says whether eps was
below it at the state where it ended."""

from __future__ import annotations

import math

import numpy as np

#: A strip must hold this many float64 spacings of the state's scale for a step to land in it.
RESOLVED_SPACINGS = 16.0


def state_scale(x: np.ndarray) -> float:
    """1 + max |x_i| (1 for an empty state): the magnitude float64 must resolve eps next to; nan
    or inf where x is not finite."""
    x = np.asarray(x)
    return 1.0 + float(np.abs(x).max()) if x.size else 1.0


def thinnest_strip(x: np.ndarray) -> float:
    """The thinnest eps (guard units) a step can land in next to the state x:
    ``RESOLVED_SPACINGS`` float64 spacings at ``state_scale(x)``."""
    return strip_at_scale(state_scale(x))


def strip_at_scale(scale: float) -> float:
    """``thinnest_strip`` of a state whose ``state_scale`` is ``scale`` (>= 1): the spacing of
    float64 there is ``math.ulp(scale)``, as numpy's ``spacing``."""
    return RESOLVED_SPACINGS * math.ulp(scale)
