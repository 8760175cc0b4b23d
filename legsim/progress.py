"""A progress bar on the simulated time, for long interactive runs.

``simulate(..., progress=bar)`` calls ``bar(t, t0, t_final)`` a few times a second once a run
has lasted a moment, so short runs never draw anything. The bar is drawn on one terminal line
(carriage return, no newline) and erased by ``close()``; it is only ever created for a TTY,
so pipes and log files never receive control characters.
"""

from __future__ import annotations

import shutil
import sys
import time
from typing import TextIO


class ProgressBar:
    """``bar(t, t0, t_final)`` draws ``[#####-----]  42%  t = 1.13 / 2.7 s  0.8 s`` on ``stream``.

    Parameters
    ----------
    stream: where to draw (a terminal).
    label: a short prefix, e.g. the scene's name.
    width: bar width in characters; default: what fits the terminal.
    """

    def __init__(self, stream: TextIO | None = None, label: str = "", width: int | None = None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.width = width
        self.started = time.perf_counter()
        self.drawn = False
        self._last_len = 0

    def line(self, t: float, t0: float, t_final: float) -> str:
        """The text of the bar at simulated time t (s) of [t0, t_final]."""
        span = t_final - t0
        frac = 0.0 if span <= 0 else min(1.0, max(0.0, (t - t0) / span))
        tail = f" {frac * 100:5.1f}%  t = {t:.6g} / {t_final:.6g} s  {time.perf_counter() - self.started:.1f} s"
        head = f"{self.label} " if self.label else ""
        width = self.width
        if width is None:
            columns = shutil.get_terminal_size((80, 24)).columns
            width = max(10, min(50, columns - len(head) - len(tail) - 3))
        filled = int(round(frac * width))
        return f"{head}[{'#' * filled}{'-' * (width - filled)}]{tail}"

    def __call__(self, t: float, t0: float, t_final: float) -> None:
        text = self.line(t, t0, t_final)
        pad = " " * max(0, self._last_len - len(text))
        self.stream.write("\r" + text + pad)
        self.stream.flush()
        self._last_len = len(text)
        self.drawn = True

    def close(self) -> None:
        """Erase the bar (only if it was drawn), leaving the cursor at the line's start."""
        if self.drawn:
            self.stream.write("\r" + " " * self._last_len + "\r")
            self.stream.flush()
            self.drawn = False


def progress_for(stream: TextIO | None = None, *, enabled: bool = True, label: str = "") -> ProgressBar | None:
    """A ProgressBar on ``stream`` (default stderr) when enabled and the stream is a terminal, else None."""
    stream = stream if stream is not None else sys.stderr
    if not enabled:
        return None
    try:
        interactive = stream.isatty()
    except (AttributeError, ValueError):
        interactive = False
    return ProgressBar(stream, label) if interactive else None
