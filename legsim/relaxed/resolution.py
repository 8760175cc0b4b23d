"""The thinnest strip float64 resolves at a state's scale, written once: ``simulate`` refuses a
thinner eps before the run, and a run that ends without landing in a strip says whether eps was
below it at the state where it ended."""

from __future__ import annotations

import numpy as np

#: A strip must hold this many float64 spacings of the state's scale for a step to land in it.
RESOLVED_SPACINGS = 16.0


def state_scale(x: np.ndarray) -> float:
    """1 + max |x_i| (1 for an empty state): the magnitude float64 must resolve eps next to."""
    return 1.0 + float(np.max(np.abs(x))) if np.size(x) else 1.0


def thinnest_strip(x: np.ndarray) -> float:
    """The thinnest eps (guard units) a step can land in next to the state x:
    ``RESOLVED_SPACINGS`` float64 spacings at ``state_scale(x)``."""
    return RESOLVED_SPACINGS * float(np.spacing(state_scale(x)))
