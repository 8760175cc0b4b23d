"""The source distribution holds what the wheel needs: ``python -m build`` (docs/packaging.md)
makes the sdist, then the wheel from the unpacked sdist alone; that wheel holds every file of
the package as the checkout has it, byte for byte, and nothing else.

The build runs on a copy of the checkout in a temporary folder (setuptools writes its
``*.egg-info`` and ``build/`` next to the sources), without the native extension's compilation
(its source is checked to be in the sdist), in one fresh environment holding the build
requirements instead of the two isolated ones ``python -m build`` makes
(``helpers.packaging.build_environment``)."""

from __future__ import annotations

import os
import subprocess
import tarfile
import zipfile
from pathlib import Path

import pytest

from helpers.packaging import source_copy

ROOT = Path(__file__).resolve().parents[2]
#: Where each folder of the checkout goes in the wheel (setup.py's FOLDERS).
FOLDERS = {"legsim": "legsim", "robots": "legsim/robots", "viz": "legsim/viz", "scenarios": "legsim/scenarios"}


@pytest.fixture(scope="module")
def built(tmp_path_factory, build_python):
    """(sdist, wheel) made by ``python -m build`` from a copy of the checkout, in a fresh
    environment holding the build requirements but the headers the native extension reads
    (helpers.packaging.HEADER_REQUIREMENTS): the dependency check is skipped for them."""
    tmp = tmp_path_factory.mktemp("build")
    source = source_copy(tmp / "legsim")
    build = [str(build_python), "-m", "build", "--no-isolation", "--skip-dependency-check"]
    result = subprocess.run(
        [*build, "--outdir", str(tmp / "dist"), str(source)],
        capture_output=True,
        text=True,
        cwd=tmp,  # a `build` folder where the test runs would shadow the build module
        env={**os.environ, "LEGSIM_BUILD_NATIVE": "0"},
        timeout=1200,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return next((tmp / "dist").glob("legsim-*.tar.gz")), next((tmp / "dist").glob("legsim-*.whl"))


def package_files() -> dict[str, Path]:
    """The checkout's files that the wheel installs, by their path in the wheel."""
    found = {}
    for folder, target in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*")):
            source = path.suffix in (".py", ".toml", ".urdf") or path.name == "py.typed"
            made = "__pycache__" in path.parts or "_prebuilt" in path.parts
            if path.is_file() and source and not made:
                found[f"{target}/{path.relative_to(ROOT / folder).as_posix()}"] = path
    return found


def test_the_wheel_built_from_the_sdist_holds_the_package_as_checked_out(built):
    _, wheel = built
    expected = package_files()
    with zipfile.ZipFile(wheel) as archive:
        held = {name: archive.read(name) for name in archive.namelist() if ".dist-info/" not in name}
        entry_points = next(n for n in archive.namelist() if n.endswith(".dist-info/entry_points.txt"))
        assert "legsim = legsim.cli:entry" in archive.read(entry_points).decode()
    assert sorted(held) == sorted(expected)
    assert [name for name, data in held.items() if data != expected[name].read_bytes()] == []


def test_the_sdist_holds_the_build_files_and_no_checkout_clutter(built):
    sdist, _ = built
    with tarfile.open(sdist) as archive:
        names = {name.split("/", 1)[1] for name in archive.getnames() if "/" in name}
    needed = {"pyproject.toml", "setup.py", "README.md", "LICENSE", "robots/_native/pinlegsim.cpp"}
    assert needed <= names
    assert not {name for name in names if name.split("/")[0] in (".venv", ".git", "out", "dist", "build")}
