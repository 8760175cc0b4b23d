"""The wheel as a user installs it: only the ``legsim`` name in site-packages, the bundled
scenes found from any directory, and a local folder called ``robots/`` shadowing nothing.

The wheel is built from a copy of this checkout and installed with ``pip --target`` into a temporary
folder. It runs with ``python -S`` (no site processing, so the checkout's editable install is
not seen), its dependencies taken from this environment's site-packages minus everything of
legsim's own."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from helpers.packaging import source_copy

ROOT = Path(__file__).resolve().parents[2]
SITE = Path(sysconfig.get_paths()["purelib"])

LAUNCHER = """
import runpy, sys
import cmeel_pth  # what cmeel.pth does at startup: put Pinocchio's prefix on the path
sys.argv = ["legsim"] + sys.argv[1:]
runpy.run_module("legsim", run_name="__main__")
"""


@pytest.fixture(scope="module")
def installed(tmp_path_factory, build_python):
    tmp = tmp_path_factory.mktemp("wheel")
    # With the compiled code `legsim.prebuild` made for this checkout, as `make wheel` ships it.
    source = source_copy(tmp / "legsim", prebuilt=True)
    # The layout is what is tested here: the native extension's compilation is left out, and
    # so are the headers it reads (helpers.packaging.HEADER_REQUIREMENTS).
    wheel_command = [str(build_python), "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation"]
    subprocess.run(
        [*wheel_command, "-w", str(tmp / "dist"), str(source)],
        check=True,
        capture_output=True,
        env={**os.environ, "LEGSIM_BUILD_NATIVE": "0"},
    )
    wheel = next((tmp / "dist").glob("legsim-*.whl"))
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(tmp / "site"), str(wheel)],
        check=True,
        capture_output=True,
    )
    deps = tmp / "deps"
    deps.mkdir()
    for entry in SITE.iterdir():
        if not (entry.name.startswith(("legsim", "__editable__")) or entry.suffix == ".pth"):
            (deps / entry.name).symlink_to(entry)
    (tmp / "launch.py").write_text(LAUNCHER)
    work = tmp / "empty"
    (work / "robots").mkdir(parents=True)
    (work / "robots" / "__init__.py").write_text("raise ImportError('a user folder was imported')\n")
    return wheel, tmp, work


def run(installed, *args: str) -> subprocess.CompletedProcess:
    _, tmp, work = installed
    env = {**os.environ, "PYTHONPATH": f"{tmp / 'site'}{os.pathsep}{tmp / 'deps'}"}
    env.pop("LEGSIM_SCENE_PATH", None)
    return subprocess.run(
        [sys.executable, "-S", str(tmp / "launch.py"), *args],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_wheel_installs_only_the_legsim_name(installed):
    wheel, _, _ = installed
    with zipfile.ZipFile(wheel) as archive:
        tops = {name.split("/")[0] for name in archive.namelist()}
        scenes = [
            name for name in archive.namelist() if name.startswith("legsim/scenarios/") and name.endswith(".toml")
        ]
    assert tops == {"legsim", wheel.name.split("-")[0] + "-" + wheel.name.split("-")[1] + ".dist-info"}
    assert "legsim/scenarios/pronk.toml" in scenes and len(scenes) == len(list((ROOT / "scenarios").glob("*.toml")))


def test_an_installed_legsim_lists_and_runs_the_bundled_scenes_from_any_directory(installed):
    listing = run(installed, "scenes")
    assert listing.returncode == 0, listing.stderr
    for name in (p.stem for p in (ROOT / "scenarios").glob("*.toml")):
        assert name in listing.stdout
    result = run(installed, "run", "bouncing_ball", "--json")
    assert result.returncode == 0, result.stderr
    # The first run after installing loads the compiled code the wheel ships: nothing compiles.
    assert "legsim: compiling" not in result.stderr
    summary = json.loads(result.stdout)
    assert summary["status"] == "finished" and summary["scene"] == "bouncing_ball"
    assert str(installed[1] / "site") in summary["scene_file"]


def test_a_robot_scene_without_the_native_extension_says_what_is_missing(installed):
    # This wheel was built without the native extension (LEGSIM_BUILD_NATIVE=0): a robot scene
    # stops before running, naming the scene, the robot and how to get the extension.
    result = run(installed, "run", "pronk")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "pronk.toml" in result.stderr and "robot 'pronk' could not be built" in result.stderr
    assert "legsim.robots._native._pinlegsim was not built" in result.stderr and "compiler" in result.stderr


DIGESTS = """
import json
from legsim.compiled.cache import PACKAGE_ROOT, source_digest
files = sorted((PACKAGE_ROOT / "robots").rglob("*.py"))
print(json.dumps({path.relative_to(PACKAGE_ROOT).as_posix(): source_digest(path) for path in files}))
"""


def test_compiled_code_is_stamped_alike_installed_and_in_a_checkout(installed):
    # The prebuilt code a wheel ships is made in a checkout, where robots/ sits beside legsim/;
    # installed, it sits inside. A stamp depending on that layout would make every first run
    # after `pip install` compile for minutes.
    from legsim.compiled.cache import source_digest

    _, tmp, work = installed
    (tmp / "digests.py").write_text(DIGESTS)
    env = {**os.environ, "PYTHONPATH": f"{tmp / 'site'}{os.pathsep}{tmp / 'deps'}"}
    done = subprocess.run(
        [sys.executable, "-S", str(tmp / "digests.py")], cwd=work, env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    installed_digests = json.loads(done.stdout)
    assert len(installed_digests) > 20
    assert installed_digests == {name: source_digest(ROOT / name) for name in installed_digests}
