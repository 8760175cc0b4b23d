"""Named plug-ins found through entry points: robots (``legsim.builders``), controllers
(``legsim.controllers``). A third-party package adds one by declaring an entry point."""

from __future__ import annotations

import functools
from importlib import metadata
from typing import TypeVar

from .errors import SceneError

T = TypeVar("T")


def registered(group: str) -> dict[str, metadata.EntryPoint]:
    """The entry points of ``group`` by name (not yet imported), as installed when the process
    first asked: reading every distribution's metadata costs milliseconds, and a scene's
    controller is made anew for every run (an orbit search makes dozens)."""
    return {ep.name: ep for ep in _scan(group)}


@functools.cache
def _scan(group: str) -> tuple[metadata.EntryPoint, ...]:
    return tuple(metadata.entry_points(group=group))


def load_registered(found: dict[str, metadata.EntryPoint], name: str, kind: str, expected: type[T]) -> T:
    """Load the plug-in ``name`` of ``found`` (a group's ``registered`` entry points), which must
    be an ``expected``; SceneError names the known ones when it is unknown (``kind``: "robot",
    "controller"), and says what failed when it cannot be loaded."""
    if name not in found:
        raise SceneError(f"unknown {kind} '{name}'; available: {sorted(found)}")
    try:
        plugin = found[name].load()
    except Exception as exc:
        raise SceneError(
            f"{kind} '{name}' could not be loaded from {found[name].value}: {type(exc).__name__}: {exc}"
        ) from exc
    if not isinstance(plugin, expected):
        raise SceneError(
            f"entry point '{name}' ({found[name].value}) is not a {expected.__module__}.{expected.__qualname__}"
        )
    return plugin
