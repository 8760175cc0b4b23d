"""Accumulating transitions (Zeno points): where the relaxed execution stops being guaranteed.

The relaxed execution converges to the hybrid one up to a Zeno time (paper 000, Thm. 26); past
it the strips hold the state while time runs, which is an artefact, not motion. The rule that
detects an accumulation is written once (``rules.accumulating``): the flight since the previous
crossing of the same transition, with no other transition between, is shorter than the window
(by default h + eps: shorter than the integrator can resolve) and shorter than the flight
before it. At such a crossing:

* a transition that names a ``Continuation`` (an impact's plastic impact into the resting or
  sticking mode) takes it instead, provided its reset image lies in its target's domain (the
  constraint would push); the model then says what happens next;
* otherwise the run keeps its relaxed semantics and the execution carries a warning naming the
  transition, when the accumulation began, the estimated accumulation time, the transitions and
  strip time since, and the remedy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..execution import RunWarning
from .rules import accumulating


@dataclass
class _Episode:
    """Crossings of one transition accumulating without a continuation, since ``start``."""

    mode: str
    transition: str
    start: float
    transitions_before: int
    strip_time_before: float
    estimate: float
    remedy: str


class ZenoWatch:
    """Follows the chain of crossings of one transition, for the accumulation rule and the
    warnings. ``window`` (s): flights shorter than this may accumulate; ``continues``: whether a
    transition's continuation is taken when they do (``simulate(continuation=...)``)."""

    def __init__(self, window: float, continues: bool) -> None:
        self.window = window
        self.continues = continues
        self._chain: tuple[str, str] | None = None
        self._last_exit = -math.inf
        self._flight = math.inf
        self._episode: _Episode | None = None
        self.episodes: list[tuple[_Episode, int, float, float]] = []

    def crossing(self, mode: str, name: str, tc: float) -> bool:
        """A crossing of transition ``name`` of ``mode`` at time tc: True when the crossings of
        this transition accumulate (``rules.accumulating``)."""
        if self._chain != (mode, name):
            return False
        return accumulating(self._flight, tc - self._last_exit, self.window)

    def crossed(self, run, mode: str, name: str, tc: float, exit_time: float, accumulates: bool,
                continued: bool, has_continuation: bool = False) -> None:
        """Record the crossing of ``name`` (its strip left at ``exit_time``): the chain goes on or
        restarts, and an accumulation without continuation opens an episode for the warnings."""
        flight = tc - self._last_exit if self._chain == (mode, name) else math.inf
        if self._chain != (mode, name) or continued:
            self._close(run, tc)
        if accumulates and not continued and self._episode is None:
            ratio = flight / self._flight if self._flight > 0.0 else 1.0
            estimate = exit_time + flight * ratio / (1.0 - ratio) if ratio < 1.0 else exit_time
            remedy = ("run with continuation (the default: simulate(continuation=True), integrator.continuation = "
                      "true), which takes the transition's continuation there" if has_continuation else
                      "give the transition a continuation (legsim.Continuation: the constrained mode entered when its "
                      "crossings accumulate)")
            self._episode = _Episode(mode, name, tc, len(run.transitions) - 1, run.strip_time - (exit_time - tc),
                                     estimate, remedy)
        self._chain = None if continued else (mode, name)
        self._last_exit, self._flight = exit_time, flight

    def _close(self, run, t: float) -> None:
        episode = self._episode
        if episode is not None:
            self.episodes.append((episode, len(run.transitions) - 1 - episode.transitions_before,
                                  run.strip_time - episode.strip_time_before, t))
            self._episode = None

    def warnings(self, run, t_end: float) -> list[RunWarning]:
        """One warning per accumulation that no continuation resolved."""
        if self._episode is not None:
            self.episodes.append((self._episode, len(run.transitions) - self._episode.transitions_before,
                                  run.strip_time - self._episode.strip_time_before, t_end))
            self._episode = None
        return [_accumulation_warning(*entry) for entry in self.episodes]


def _accumulation_warning(episode: _Episode, transitions: int, strip_time: float, until: float) -> RunWarning:
    message = (f"transition {episode.transition} in mode '{episode.mode}' accumulates from t={episode.start:.6g} s "
               f"(a Zeno point near t={episode.estimate:.6g} s): {transitions} transitions and {strip_time:.3g} s "
               f"held in its strip until t={until:.6g} s. Past an accumulation point the relaxed execution holds "
               f"the state in the strip instead of moving it (paper 000, Thm. 26), so the result there is not the "
               f"hybrid system's. Remedy: {episode.remedy}, or end the run before t={episode.estimate:.6g} s.")
    return RunWarning("accumulation", message, episode.start,
                      {"transition": episode.transition, "mode": episode.mode, "accumulation_time": episode.estimate,
                       "transitions_since": transitions, "strip_time_since": strip_time})


#: Share of a run's time held in strips above which the run says so.
STRIP_HOLD_SHARE = 0.01


def strip_hold_warning(strip_time: float, t0: float, t_end: float, already: list[RunWarning]) -> RunWarning | None:
    """A warning when the state was held in strips for more than 1% of the run and no
    accumulation warning explains it."""
    span = t_end - t0
    if span <= 0.0 or strip_time <= STRIP_HOLD_SHARE * span or any(w.kind == "accumulation" for w in already):
        return None
    message = (f"the state was held in strips for {strip_time:.3g} s of the run's {span:.3g} s "
               f"({100.0 * strip_time / span:.1f}%): each hold delays the execution by up to eps, so the result "
               f"is off by that much; a smaller eps (strip width) shortens the holds")
    return RunWarning("strip_hold", message, t0, {"strip_time": strip_time, "share": strip_time / span})
