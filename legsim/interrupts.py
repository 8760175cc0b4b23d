"""Stopping on Ctrl-C (SIGINT) and SIGTERM, even when Python swallows the exception.

A signal's handler raises its exception in whatever the main thread runs at that moment. When
that is a finalizer (a ``__del__`` method or a weakref callback; Dask's futures release
themselves in one), Python prints "Exception ignored in ..." and carries on: a sweep would run to
its end and exit 0, as if no signal had come. So the handlers installed here also record the
signal, and loops that run for long call ``raise_if_stopped`` between their pieces of work (the
sweep engine before each batch, a run at each progress report), which raises the same exception
again; the swallowed one is not printed (the command's own one-line message follows).
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from .errors import Terminated

_received: int | None = None


def _exception(signum: int) -> KeyboardInterrupt:
    if signum == signal.SIGTERM:
        return Terminated(f"signal {signum}")
    return KeyboardInterrupt()


def _stop(signum: int, frame: object) -> None:
    global _received
    _received = signum
    raise _exception(signum)


def raise_if_stopped() -> None:
    """Raise ``KeyboardInterrupt`` (``Terminated`` for SIGTERM) if a signal asked to stop inside
    ``stop_on_signals``, whether or not its first exception was swallowed; otherwise nothing."""
    if _received is not None:
        raise _exception(_received)


@contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within the block, SIGINT raises ``KeyboardInterrupt`` and SIGTERM ``Terminated`` (a
    KeyboardInterrupt) in the main thread, so that every ``finally`` and ``except BaseException``
    runs (``write_atomic`` removes its temporary file), and ``raise_if_stopped`` raises it again
    until the block ends. The previous handlers are restored afterwards (``legsim.cli.main`` may
    be called from a program or a test). Outside the main thread signals cannot be handled, and
    nothing changes."""
    global _received
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received = None
    previous_hook = sys.unraisablehook

    def quiet_when_stopping(unraisable: sys.UnraisableHookArgs) -> None:
        if not (_received is not None and isinstance(unraisable.exc_value, KeyboardInterrupt)):
            previous_hook(unraisable)

    previous = {signum: signal.signal(signum, _stop) for signum in (signal.SIGINT, signal.SIGTERM)}
    sys.unraisablehook = quiet_when_stopping
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        _received = None
