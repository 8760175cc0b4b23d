"""A stop signal is not lost when it lands in a finalizer, where Python swallows its exception
(legsim.interrupts): the sweep engine raises it again before its next batch, and a run at its
next progress report."""

from __future__ import annotations

import os
import signal
import sys

import pytest

from helpers.compiled_models import two_balls
from legsim import simulate
from legsim.errors import Terminated
from legsim.interrupts import raise_if_stopped, stop_on_signals
from legsim.relaxed import driver
from legsim.sweep.engine import Engine


class SignalledInFinalizer:
    """An object whose finalizer receives ``signum``: the handler's exception is raised inside
    ``__del__``, and Python prints it as ignored and goes on."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        os.kill(os.getpid(), self.signum)
        sum(range(1000))  # the handler runs at the next bytecode, still inside the finalizer


class FailingFinalizer:
    def __del__(self) -> None:
        raise ValueError("a finalizer's own failure")


@pytest.mark.parametrize(("signum", "raised"), [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_swallowed_by_a_finalizer_is_raised_at_the_next_check_and_not_printed(signum, raised, monkeypatch):
    reported: list[BaseException | None] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: reported.append(unraisable.exc_value))
    with stop_on_signals():
        FailingFinalizer()  # reported as before: only the stop signal's exception is quiet
        SignalledInFinalizer(signum)  # dropped at once: its finalizer swallows the exception
        with pytest.raises(raised) as caught:
            raise_if_stopped()
    assert isinstance(caught.value, Terminated) == (signum == signal.SIGTERM)
    assert [type(exc) for exc in reported] == [ValueError]


def test_outside_the_block_nothing_is_pending_and_the_handlers_are_restored():
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with stop_on_signals(), pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        sum(range(1000))
    raise_if_stopped()  # nothing pending once the block has ended
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_the_sweep_engine_stops_before_the_next_batch_after_a_swallowed_sigterm():
    batches: list[list[int]] = []

    def on_done(batch: list[int], results: object) -> None:
        batches.append(batch)
        if len(batches) == 1:
            SignalledInFinalizer(signal.SIGTERM)

    with stop_on_signals(), Engine(in_process=True, batch_size=1) as engine, pytest.raises(Terminated):
        engine.run(lambda common, batch: batch, None, range(5), on_done)
    assert batches == [[0]]


def test_a_long_run_ends_at_its_next_progress_report_after_a_swallowed_sigterm(monkeypatch):
    monkeypatch.setattr(driver, "PROGRESS_INTERVAL", 0.0)  # every hand-back reports
    reports: list[float] = []

    def progress(t: float, t0: float, t_final: float) -> None:
        reports.append(t)
        if len(reports) == 1:
            SignalledInFinalizer(signal.SIGTERM)

    with stop_on_signals(), pytest.raises(Terminated):
        simulate(two_balls(), [1.0, 1.0, 0.0, 0.0], "falling", 3.0, 1e-5, 1e-6, progress=progress)
    assert len(reports) == 1 and reports[0] < 3.0
