"""Accumulating transitions (Zeno points): where the relaxed execution stops being guaranteed.

The relaxed execution converges to the hybrid one up to a Zeno time (paper 000, Thm. 26); past
it the strips hold the state while time runs, which is an artefact, not motion. The rule that
detects an accumulation is written once (``rules.accumulating``): the flight since the previous
crossing of the same transition is shorter than the window (by default h + eps: shorter than the
integrator can resolve) and shorter than the flight before it. At such a crossing:

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
from .rules import accumulating, flight_since


@dataclass
class _Episode:
    """Crossings accumulating without a continuation, since ``start``: those of ``members``
    ((mode, transition) pairs, the first one first; a Zeno cycle through several modes has one
    member per transition of the cycle)."""

    members: list[tuple[str, str]]
    start: float
    transitions_before: int
    strip_time_before: float
    estimate: float
    remedy: str
    #: When the latest member crossing left its strip, and the run's transitions (that one
    #: included) and strip time then: where the episode ends when the run leaves it.
    last_exit: float = 0.0
    transitions_at_last: int = 0
    strip_time_at_last: float = 0.0

    def member_crossed(self, run, exit_time: float) -> None:
        self.last_exit = exit_time
        self.transitions_at_last = len(run.transitions)
        self.strip_time_at_last = run.strip_time


@dataclass
class _History:
    """The crossings of one transition so far: when the last left its strip and the flight that
    ended there."""

    last_exit: float
    flight: float = math.inf


class ZenoWatch:
    """Follows the crossings of each transition, for the accumulation rule and the warnings.
    ``window`` (s): flights shorter than this may accumulate; ``continues``: whether a
    transition's continuation is taken when they do (``simulate(continuation=...)``).

    A transition's flights are the times from one of its crossings to the next, whatever
    happens between: the cycle of a Zeno execution through several modes (two tanks filled in
    turn) accumulates like a single bouncing contact, and is one episode. An episode without
    continuation lasts until a flight of one of its transitions is longer than the window again
    (the execution left the accumulation: a released mass, a ball kicked up), one of them
    takes its continuation, or the run goes on for longer than the window without any of them
    (another transition crosses then, or the run ends): it then ends at its last crossing, so a
    graze repeated a few times and never again is not counted to the end of the run."""

    def __init__(self, window: float, continues: bool) -> None:
        self.window = window
        self.continues = continues
        self._histories: dict[tuple[str, str], _History] = {}
        self._open: _Episode | None = None
        self.episodes: list[tuple[_Episode, int, float, float]] = []

    def crossing(self, mode: str, name: str, tc: float) -> bool:
        """A crossing of transition ``name`` of ``mode`` at time tc: True when the crossings of
        this transition accumulate (``rules.accumulating``)."""
        history = self._histories.get((mode, name))
        return history is not None and accumulating(history.flight, tc - history.last_exit, self.window)

    def crossed(
        self,
        run,
        mode: str,
        name: str,
        tc: float,
        exit_time: float,
        accumulates: bool,
        continued: bool,
        has_continuation: bool = False,
    ) -> None:
        """Record the crossing of ``name`` (its strip left at ``exit_time``; ``continued`` when
        its continuation was taken): an accumulation without continuation opens an episode for
        the warnings or joins the open one, a long flight or a continuation closes it."""
        key = (mode, name)
        history = self._histories.get(key)
        flight = flight_since(history is not None, history.last_exit if history is not None else 0.0, tc)
        episode = self._open
        if episode is not None and key in episode.members and (continued or flight > self.window):
            self._close(run, tc, ending=True)
        elif episode is not None and key not in episode.members and tc - episode.last_exit > self.window:
            self._close_at_last()
        if continued:  # the model took over: a later crossing starts a new sequence
            self._histories.pop(key, None)
            return
        if history is None:
            history = self._histories[key] = _History(exit_time)
        if accumulates:
            if self._open is None:
                self._open = _open(run, key, tc, exit_time, flight, history.flight, has_continuation)
            elif key not in self._open.members:
                self._open.members.append(key)
        if self._open is not None and key in self._open.members:
            self._open.member_crossed(run, exit_time)
        history.last_exit, history.flight = exit_time, flight

    def history(self, mode: str, name: str) -> tuple[float, float] | None:
        """(when its last crossing left the strip (s), the flight that ended there (s)) of
        transition ``name`` of ``mode``, or None before its first crossing (or after a
        continuation): what the compiled kernel starts from."""
        history = self._histories.get((mode, name))
        return None if history is None else (history.last_exit, history.flight)

    def _close(self, run, t: float, ending: bool) -> None:
        episode = self._open
        assert episode is not None
        counted = len(run.transitions) - (1 if ending else 0) - episode.transitions_before
        self.episodes.append((episode, counted, run.strip_time - episode.strip_time_before, t))
        self._open = None

    def _close_at_last(self) -> None:
        """End the open episode at its last member crossing: the run left the accumulation."""
        episode = self._open
        assert episode is not None
        counted = episode.transitions_at_last - episode.transitions_before
        self.episodes.append(
            (episode, counted, episode.strip_time_at_last - episode.strip_time_before, episode.last_exit)
        )
        self._open = None

    def warnings(self, run, t_end: float) -> list[RunWarning]:
        """One warning per accumulation that no continuation resolved, in the order they began."""
        if self._open is not None and t_end - self._open.last_exit > self.window:
            self._close_at_last()
        if self._open is not None:
            self._close(run, t_end, ending=False)
        return [_accumulation_warning(*entry) for entry in self.episodes]


def _open(
    run, key: tuple[str, str], tc: float, exit_time: float, flight: float, previous: float, has_continuation: bool
) -> _Episode:
    """An episode from the crossing of ``key`` at tc, with the Zeno time extrapolated from its
    flights as a geometric series."""
    ratio = flight / previous if previous > 0.0 else 1.0
    estimate = exit_time + flight * ratio / (1.0 - ratio) if ratio < 1.0 else exit_time
    remedy = (
        "run with continuation (the default: simulate(continuation=True), integrator.continuation = true), "
        "which takes the transition's continuation there"
        if has_continuation
        else "give the transition a continuation (legsim.Continuation: the constrained mode entered when its "
        "crossings accumulate)"
    )
    return _Episode([key], tc, len(run.transitions) - 1, run.strip_time - (exit_time - tc), estimate, remedy)


def _accumulation_warning(episode: _Episode, transitions: int, strip_time: float, until: float) -> RunWarning:
    mode, name = episode.members[0]
    which = " and ".join(f"{n} in mode '{m}'" for m, n in episode.members)
    subject = f"transition {which} accumulates" if len(episode.members) == 1 else f"transitions {which} accumulate"
    message = (
        f"{subject} from t={episode.start:.6g} s (a Zeno point near t={episode.estimate:.6g} s): "
        f"{transitions} transition{'' if transitions == 1 else 's'} and {strip_time:.3g} s held in strips "
        f"until t={until:.6g} s. Past an "
        f"accumulation point the relaxed execution holds the state in the strip instead of moving it "
        f"(paper 000, Thm. 26), so the result there is not the hybrid system's. Remedy: {episode.remedy}, "
        f"or end the run before t={episode.estimate:.6g} s."
    )
    return RunWarning(
        "accumulation",
        message,
        episode.start,
        {
            "transition": name,
            "mode": mode,
            "transitions": [n for _, n in episode.members],
            "accumulation_time": episode.estimate,
            "transitions_since": transitions,
            "strip_time_since": strip_time,
        },
    )


#: A single flight under this share of the Zeno window is a re-crossing at once (a state already
#: resting on its guard), which takes its continuation without a warning.
RESTING_SHARE = 0.01


def unconfirmed_continuation(
    history: tuple[float, float] | None, mode: str, transition: str, continuation: str, tc: float, window: float
) -> RunWarning | None:
    """A warning when the continuation ``continuation`` of ``transition`` (of ``mode``) was taken
    at tc on the evidence of one flight alone (``history``: the transition's (last exit, flight
    before it), the flight before infinite): nothing showed the flights shrinking towards a Zeno
    point, so the motion may have gone on (a periodic event as frequent as the steps looks the
    same). Only a flight under ``RESTING_SHARE`` of the window passes without a word: a state
    that was already resting re-crosses at once."""
    if history is None or history[1] != math.inf:
        return None
    flight = tc - history[0]
    if flight <= RESTING_SHARE * window:
        return None
    message = (
        f"transition {transition} in mode '{mode}' was taken to accumulate at t={tc:.6g} s after a single "
        f"flight of {flight:.3g} s (no earlier flight to show the flights shrinking), and its continuation "
        f"{continuation} was taken there; within the window h + eps = {window:.3g} s one flight cannot tell a "
        f"Zeno point from motion that goes on (a periodic event as frequent as the steps), so the motion may "
        f"have gone on where the run rests. Remedy: a smaller h (or zeno_window) resolves such flights."
    )
    details = {"transition": transition, "mode": mode, "continuation": continuation, "flight": flight,
               "window": window}  # fmt: skip
    return RunWarning("unconfirmed_continuation", message, tc, details)


#: Share of a run's time held in strips above which the run says so.
STRIP_HOLD_SHARE = 0.01


def strip_hold_warning(strip_time: float, t0: float, t_end: float, already: list[RunWarning]) -> RunWarning | None:
    """A warning when the state was held in strips for more than 1% of the run and no
    accumulation warning explains it."""
    span = t_end - t0
    if span <= 0.0 or strip_time <= STRIP_HOLD_SHARE * span or any(w.kind == "accumulation" for w in already):
        return None
    message = (
        f"the state was held in strips for {strip_time:.3g} s of the run's {span:.3g} s "
        f"({100.0 * strip_time / span:.1f}%): each hold delays the execution by up to eps, so the result "
        f"is off by that much; a smaller eps (strip width) shortens the holds"
    )
    return RunWarning("strip_hold", message, t0, {"strip_time": strip_time, "share": strip_time / span})
