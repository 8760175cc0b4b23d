"""Preloaded by the embedded cluster's worker processes (Dask's ``preload``): they ignore SIGINT
and SIGTERM.

Ctrl-C at a terminal reaches every process of its group, the workers included, and each would
print a KeyboardInterrupt traceback; SIGTERM sent to the group (``timeout``, a service manager)
would kill them, and their nannies would start new ones while the sweep stops. The client alone
stops the sweep: it cancels what is queued, merges the rows finished so far and closes the
cluster, whose nannies end the workers (with SIGKILL when they do not stop in time).
"""

from __future__ import annotations

import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:
    """Called by Dask in each worker process as it starts (on its main thread)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
