"""The error every orbit computation raises when it fails or is set up wrongly."""

from __future__ import annotations

from typing import Any

from ..errors import LegsimError


class OrbitError(LegsimError, ValueError):
    """An orbit computation failed or was set up wrongly; the message says why (no return within
    the time limit, a failed simulation, a singular Jacobian, divergence, bad problem).

    ``status`` is the search outcome the failure stands for (one of ``STATUSES``, or
    ``"invalid"`` for a bad setting); ``key`` names the problem setting at fault, when there is
    one (e.g. ``"cyclic"``), so that a scene's error can name its ``[orbit]`` key.
    ``execution`` is the run that ended before returning, when there is one (its status says
    whether the model fell or the run failed)."""

    def __init__(self, message: str, status: str = "invalid", key: str | None = None, execution: Any = None) -> None:
        super().__init__(message)
        self.status = status
        self.key = key
        self.execution = execution
