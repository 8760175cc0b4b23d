"""The sweep's error, in a leaf module: the spec and the measures both raise it."""

from __future__ import annotations

from ..errors import LegsimError


class SweepError(LegsimError):
    """A sweep is misdescribed (axes, measures, output folder); the message names the option."""
