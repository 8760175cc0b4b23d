"""The transition graph of a hybrid system."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .hybrid import HybridSystem


def reachable_modes(system: HybridSystem, start: str | Iterable[str]) -> list[str]:
    """Modes reachable from ``start`` through the transition graph (breadth first)."""
    queue = [start] if isinstance(start, str) else list(start)
    seen: list[str] = []
    while queue:
        mode = queue.pop(0)
        if mode in seen:
            continue
        seen.append(mode)
        queue.extend(tr.target for tr in system.outgoing(mode) if tr.target not in seen)
    return seen
