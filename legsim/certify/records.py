"""What a certification reports: each certified transition, each refinement level, the certificate."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

REASONS = ("grazing", "intersecting_guards", "zeno", "refinement_limit", "t_final")


@dataclass
class CertifiedTransition:
    """The verdict on one transition of the computed execution.

    Attributes
    ----------
    index: position in the execution (0-based).
    name, source, target: the transition.
    time: computed event time t_e (s); for a near miss, the time of closest approach.
    taken: whether the computed trajectory takes it (False for a near miss).
    certified: Proposition 2 holds at step ``h``.
    reason: None when certified, else one of ``REASONS``.
    h: the step (s) of the level that decided.
    window: (first, last) time the cone meets the guard (s): the true switching time lies
        within it when certified.
    radius: the bound B at the event (state units); entry_radius: b0 of the visit.
    guards_met: names of the transitions whose guards the cone meets before leaving the domain.
    detail: a sentence saying why.
    """

    index: int
    name: str
    source: str
    target: str
    time: float
    taken: bool
    certified: bool
    reason: str | None
    h: float
    window: tuple[float, float]
    radius: float
    entry_radius: float
    guards_met: list[str]
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the items of ``legsim certify --json``)."""
        return {
            "index": self.index,
            "name": self.name,
            "source": self.source,
            "target": self.target,
            "time": _num(self.time),
            "taken": self.taken,
            "certified": self.certified,
            "reason": self.reason,
            "h": self.h,
            "window": [_num(self.window[0]), _num(self.window[1])],
            "radius": _num(self.radius),
            "entry_radius": _num(self.entry_radius),
            "guards_met": list(self.guards_met),
            "detail": self.detail,
        }


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


@dataclass
class Level:
    """One refinement level of Algorithm 1: its step, the transitions it certified and the
    failure that stopped it (kind, index, separation and bound), if any."""

    h: float
    certified: int
    failure: str | None = None
    index: int | None = None
    separation: float = math.nan
    bound: float = math.nan


@dataclass
class Certificate:
    """The outcome of ``certify``: the transitions (certified ones, then at most one refused),
    the refinement levels tried and the settings. ``complete`` is False when the last level
    stopped at its transition budget (``max_transitions``) before t_final; ``message`` then
    says where."""

    transitions: list[CertifiedTransition]
    levels: list[Level]
    settings: dict[str, Any] = field(default_factory=dict)
    end_time: float = math.nan
    complete: bool = True
    message: str = ""

    @property
    def certified(self) -> bool:
        """True when every transition of the execution up to t_final is certified (so never
        when the transition budget ran out before t_final)."""
        return self.complete and all(tr.certified for tr in self.transitions)

    def to_list(self) -> list[dict[str, Any]]:
        """The per-transition verdicts as JSON-ready dicts."""
        return [tr.to_dict() for tr in self.transitions]

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: settings, levels, verdicts."""
        return {
            **self.settings,
            "certified": self.certified,
            "complete": self.complete,
            "message": self.message,
            "end_time": _num(self.end_time),
            "levels": [
                {"h": lv.h, "certified": lv.certified, "failure": lv.failure, "index": lv.index} for lv in self.levels
            ],
            "transitions": self.to_list(),
        }


@dataclass
class _Visit:
    kind: str  # "end", "certified", "zeno", "intersecting_guards", "grazing", "t_final", "non_finite"
    record: CertifiedTransition | None = None
    separation: float = math.nan
    bound: float = math.nan
    next_state: tuple[str, np.ndarray, float, float] | None = None
    end_time: float = math.nan
