"""A copy of the checkout to build from: setuptools writes its ``*.egg-info`` and ``build/``
next to the sources it builds, and tests write only in temporary folders."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from importlib.metadata import version
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


def source_copy(target: Path, prebuilt: bool = False) -> Path:
    """The checkout's sources copied to ``target`` (made here), which is returned; with
    ``prebuilt``, also the compiled code `legsim.prebuild` left in ``legsim/_prebuilt``, as
    `make wheel` ships it."""
    skipped = [name for name in NOT_SOURCES if not (prebuilt and name == "_prebuilt")]
    shutil.copytree(ROOT, target, ignore=shutil.ignore_patterns(*skipped), symlinks=True)
    return target


#: Build requirements that only the native extension's compilation reads (its headers). The
#: packaging tests build without it (``LEGSIM_BUILD_NATIVE=0``); installing them (about 400 MB)
#: into each of the three isolated environments the builds made took most of these tests' time.
HEADER_REQUIREMENTS = ("libpinocchio", "cmeel-eigen")


def build_requirements() -> list[str]:
    """``pyproject.toml``'s build requirements but the headers, and the ``build`` front end at
    this environment's version."""
    with (ROOT / "pyproject.toml").open("rb") as file:
        requires = tomllib.load(file)["build-system"]["requires"]
    kept = [r for r in requires if not r.startswith(HEADER_REQUIREMENTS)]
    return [*kept, f"build=={version('build')}"]


def build_environment(folder: Path) -> Path:
    """A fresh virtual environment at ``folder`` holding ``build_requirements()``; returns its
    interpreter. The tests build in it without isolation, as ``python -m build`` would in a
    fresh environment holding the same packages."""
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True, capture_output=True)
    python = folder / "bin" / "python"
    install = [str(python), "-m", "pip", "install", "--quiet", *build_requirements()]
    subprocess.run(install, check=True, capture_output=True, timeout=600)
    return python
