"""A copy of the checkout to build from: setuptools writes its ``*.egg-info`` and ``build/``
next to the sources it builds, and tests write only in temporary folders."""

from __future__ import annotations

import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: Made by a build, a run or `legsim.prebuild`, not sources.
NOT_SOURCES = (
    ".venv",
    ".git",
    "build",
    "dist",
    "out",
    "bench-out",
    "__pycache__",
    "*.egg-info",
    "*.so",
    ".*_cache",
    "_prebuilt",
)


def source_copy(target: Path) -> Path:
    """The checkout's sources copied to ``target`` (made here), which is returned."""
    shutil.copytree(ROOT, target, ignore=shutil.ignore_patterns(*NOT_SOURCES), symlinks=True)
    return target
