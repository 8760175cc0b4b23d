"""A progress bar on the simulated time, for long interactive runs (``rich.progress``).

``simulate(..., progress=bar)`` calls ``bar(t, t0, t_final)`` a few times a second once a run
has lasted a moment, so short runs never draw anything. The bar shows the fraction of the
simulated time done, the simulated time, the wall time elapsed and the estimated time left;
its columns have fixed widths, so the line does not jump as the numbers change. It is drawn on
one terminal line and erased by ``close()``; it is only ever created for a terminal, so pipes
and log files never receive control characters. Where stderr is not a terminal (a log file, a
pipe), ``ProgressLines`` writes a plain line every ``LINE_INTERVAL`` seconds instead, so a long
run still says that it runs.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

#: Characters of the bar itself; the other columns have fixed widths too.
BAR_WIDTH = 30


class ProgressBar:
    """``bar(t, t0, t_final)`` draws ``label ━━━━━━━━╺━━━━━  42%  t = 1.13 / 2.7 s  0:00:01 ETA 0:00:02``.

    Parameters
    ----------
    stream: where to draw (a terminal; default stderr).
    label: a short prefix, e.g. the scene's name.
    width: the console's width in characters; default: the terminal's.
    clock: the wall clock (s) the elapsed time and the estimate are measured with; default:
        a monotonic clock.
    """

    def __init__(
        self,
        stream: TextIO | None = None,
        label: str = "",
        width: int | None = None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        console = Console(file=stream if stream is not None else sys.stderr, width=width, highlight=False)
        columns = (
            TextColumn("{task.description}", markup=False),
            BarColumn(bar_width=BAR_WIDTH),
            TaskProgressColumn(),
            TextColumn("{task.fields[clock]}", markup=False),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
        )
        # Redrawn on each call rather than by a thread: simulate calls a few times a second.
        # Only stderr is routed above the bar: what a command prints on stdout stays there.
        self.progress = Progress(
            *columns, console=console, auto_refresh=False, transient=True, redirect_stdout=False, get_time=clock
        )
        self.task = self.progress.add_task(label, total=1.0, clock="")
        self.drawn = False

    @property
    def label(self) -> str:
        """The prefix of the bar; setting it starts a new phase (``legsim certify``'s refinement
        levels): the fraction, elapsed time and estimate start again."""
        return str(self.progress.tasks[0].description)

    @label.setter
    def label(self, text: str) -> None:
        self.progress.reset(self.task, total=1.0, description=text, clock="")

    def __call__(self, t: float, t0: float, t_final: float) -> None:
        """Show simulated time t (s) of [t0, t_final]."""
        span = t_final - t0
        done = 1.0 if span <= 0 else min(1.0, max(0.0, (t - t0) / span))
        self.progress.update(self.task, completed=done, clock=f"t = {t:<9.4g} / {t_final:.4g} s")
        if self.drawn:
            self.progress.refresh()
        else:
            self.progress.start()  # draws the first line
            self.drawn = True

    def close(self) -> None:
        """Erase the bar (only if it was drawn)."""
        if self.drawn:
            self.progress.stop()
            self.drawn = False


#: Wall-clock seconds between the lines of ``ProgressLines`` (the first that long after the start).
LINE_INTERVAL = 30.0


class ProgressLines:
    """``lines(t, t0, t_final)`` writes ``label: t = 1.13 / 2.7 s (42%), 0:00:30 elapsed`` on a
    line of its own every ``interval`` seconds of wall time, the first ``interval`` after it was
    made: a long run's word in a log file or a pipe, without a terminal's control characters. A
    run shorter than ``interval`` writes nothing. Same calls as ``ProgressBar``."""

    def __init__(
        self,
        stream: TextIO | None = None,
        label: str = "",
        interval: float = LINE_INTERVAL,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.interval, self.clock = interval, clock if clock is not None else time.monotonic
        self._label: str | None = None
        self.label = label

    @property
    def label(self) -> str:
        """The prefix of each line; setting a new one starts a new phase (the elapsed time starts again)."""
        return self._label or ""

    @label.setter
    def label(self, text: str) -> None:
        if text != self._label:
            self._label = text
            self.start = self.last = self.clock()

    def __call__(self, t: float, t0: float, t_final: float) -> None:
        """Write simulated time t (s) of [t0, t_final] when ``interval`` has passed since the last line."""
        now = self.clock()
        if now - self.last < self.interval:
            return
        self.last = now
        span = t_final - t0
        done = 1.0 if span <= 0 else min(1.0, max(0.0, (t - t0) / span))
        elapsed = int(now - self.start)
        clock = f"{elapsed // 3600}:{elapsed // 60 % 60:02d}:{elapsed % 60:02d}"
        self.stream.write(f"{self.label}: t = {t:.4g} / {t_final:.4g} s ({100 * done:.0f}%), {clock} elapsed\n")
        self.stream.flush()

    def close(self) -> None:
        """Nothing to erase: the lines stay in the log."""


@contextmanager
def counting(
    total: int,
    label: str,
    *,
    done: int = 0,
    enabled: bool = True,
    stream: TextIO | None = None,
    clock: Callable[[], float] | None = None,
) -> Iterator[Callable[[int], None]]:
    """``advance(n)`` counting ``n`` more of ``total`` items (the cases of ``legsim stress``,
    the tasks of a sweep, ``done`` of them already) on a bar with done / total, elapsed time
    and ETA, on ``stream`` (default stderr) when
    enabled and it is a terminal; a no-op otherwise. Lines printed to stderr meanwhile appear
    above the bar; the bar is erased at the end."""
    stream = stream if stream is not None else sys.stderr
    if not (enabled and _interactive(stream)):
        yield lambda n: None
        return
    columns = (
        TextColumn(label, markup=False),
        BarColumn(bar_width=BAR_WIDTH),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )
    with Progress(
        *columns, console=Console(file=stream, highlight=False), transient=True, redirect_stdout=False, get_time=clock
    ) as bar:
        task = bar.add_task(label, total=total, completed=done)
        yield lambda n: bar.advance(task, n)


def _interactive(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress_for(
    stream: TextIO | None = None, *, enabled: bool = True, label: str = ""
) -> ProgressBar | ProgressLines | None:
    """When enabled, a ProgressBar on ``stream`` (default stderr) if it is a terminal, else
    ProgressLines on it; None when not enabled."""
    stream = stream if stream is not None else sys.stderr
    if not enabled:
        return None
    return ProgressBar(stream, label) if _interactive(stream) else ProgressLines(stream, label)
