"""Results computed on a batch of a run's points, kept while the batch's array lives: the checks
over a run (``legsim.relaxed.watches.PointsByMode``) hand every watch the very same arrays of
each mode in turn, and several watches read the same quantity of them.
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np


class KeptWhileAlive:
    """Values by batch array, looked up by the array's identity; an entry goes when its array is
    freed (so that nothing outlives the run, and a reused id never finds a stale entry)."""

    def __init__(self) -> None:
        self._kept: dict[int, tuple[weakref.ref[np.ndarray], Any]] = {}

    def __len__(self) -> int:
        return len(self._kept)

    def get(self, batch: Any) -> Any:
        """The value kept for ``batch`` (that very array), or None."""
        if not isinstance(batch, np.ndarray):
            return None
        kept = self._kept.get(id(batch))
        return kept[1] if kept is not None and kept[0]() is batch else None

    def keep(self, batch: Any, value: Any) -> None:
        """Keep ``value`` for ``batch`` until the array is freed: a batch of several rows only,
        which several checks are handed in turn (nothing for one point located between two, nor
        for another sequence, which a later call cannot hand back as the same object)."""
        if not isinstance(batch, np.ndarray) or batch.ndim != 2 or batch.shape[0] < 2:
            return
        key = id(batch)

        def forget(ref: weakref.ref[np.ndarray]) -> None:
            if self._kept.get(key, (None,))[0] is ref:
                del self._kept[key]

        self._kept[key] = (weakref.ref(batch, forget), value)

    def clear(self) -> None:
        """Forget every value."""
        self._kept.clear()
