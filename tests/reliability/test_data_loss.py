"""Issue 16, "data lost" and file permissions: an output never replaces the run's input, a
device, a FIFO, a file outside a scene's folder, or another output of the same run; outputs
get the permissions of any file the user creates.

Each test reproduces a reported failure with the real writers (Rerun, meshcat, matplotlib) and
checks that the command refuses before writing (exit 2, the output and the file named) and
that nothing changed on disk."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from helpers.reliability import run_cli, snapshot, temporaries, write_ball
from legsim import save_execution


# -- 1. an output never overwrites the scene --------------------------------------------------------
@pytest.mark.parametrize("flag", ["--rrd", "--html", "--plot"])
def test_an_output_never_overwrites_the_scene(tmp_path, flag):
    scene = write_ball(tmp_path)
    before = scene.read_bytes()
    code, out, err = run_cli("run", scene, flag, scene, "-q")
    assert code == 2 and out == ""
    assert err.startswith(f"legsim: error: {flag} {scene}: ") and err.count("\n") == 1
    assert scene.read_bytes() == before and temporaries(tmp_path) == []


@pytest.mark.parametrize("link", ["hard", "symbolic"])
def test_a_link_to_the_scene_is_the_scene(tmp_path, link):
    # Named .rrd, so only its identity with the input can refuse it.
    scene = write_ball(tmp_path)
    alias = tmp_path / "alias.rrd"
    (os.link if link == "hard" else os.symlink)(scene, alias)
    before = scene.read_bytes()
    code, _, err = run_cli("run", scene, "--rrd", alias, "-q")
    assert (
        code == 2
        and err == f"legsim: error: --rrd {alias}: is an input of this run ({scene}); refusing to overwrite it\n"
    )
    assert scene.read_bytes() == before


# -- 2. the final rename never replaces a device or a FIFO ----------------------------------------
def special_files(folder: Path) -> dict[str, Path]:
    """A FIFO, a symbolic link to /dev/null and, where this user may make one, a character
    device (1, 3) like /dev/null."""
    made = {"fifo": folder / "fifo.png", "link to /dev/null": folder / "null.rrd"}
    os.mkfifo(made["fifo"])
    os.symlink("/dev/null", made["link to /dev/null"])
    try:
        os.mknod(folder / "fakenull.rrd", 0o600 | stat.S_IFCHR, os.makedev(1, 3))
        made["character device"] = folder / "fakenull.rrd"
    except PermissionError:
        pass
    return made


def test_a_device_fifo_or_link_to_a_device_is_never_replaced(tmp_path):
    scene = write_ball(tmp_path / "scene")
    out = tmp_path / "out"
    out.mkdir()
    made = special_files(out)
    before = snapshot(out)
    for what, path in made.items():
        flag = "--plot" if path.suffix == ".png" else "--rrd"
        code, _, err = run_cli("run", scene, flag, path, "-q")
        assert code == 2 and "is not a regular file" in err and "refusing to replace it" in err, what
    assert snapshot(out) == before


# -- 3. a scene's [output] never leaves the scene's folder ----------------------------------------
@pytest.fixture
def neighbourhood(tmp_path):
    """(scene folder, the folders around it that a scene must not touch): a PNG next to the
    scene folder, and a link inside it that points out."""
    scenes = tmp_path / "downloads" / "scene"
    outside = tmp_path / "downloads" / "victim"
    outside.mkdir(parents=True)
    (outside / "holiday.png").write_bytes(b"\x89PNG precious")
    scenes.mkdir()
    os.symlink(outside, scenes / "shortcut")
    return scenes, tmp_path


@pytest.mark.parametrize(
    "target, reason",
    [
        ("{outside}/holiday.png", "is an absolute path"),
        ("../victim/holiday.png", "leaves the scene's folder"),
        ("out/../../victim/holiday.png", "leaves the scene's folder"),
        ("shortcut/holiday.png", "through a symbolic link"),
    ],
)
def test_scene_outputs_stay_in_the_scene_folder(neighbourhood, monkeypatch, target, reason):
    scenes, root = neighbourhood
    target = target.format(outside=root / "downloads" / "victim")
    scene = write_ball(scenes, extra=f'\n[output]\nplot = "{target}"\n')
    before = snapshot(root)
    monkeypatch.chdir(scenes)
    code, out, err = run_cli("run", scene, "-q")
    assert code == 2 and out == ""
    assert err.startswith(f"legsim: error: {scene}: output.plot: ") and reason in err
    assert snapshot(root) == before


def test_scene_outputs_are_relative_to_the_scene_not_the_working_folder(neighbourhood, monkeypatch):
    scenes, root = neighbourhood
    scene = write_ball(scenes, extra='\n[output]\nplot = "out/ball.png"\n')
    elsewhere = root / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    code, out, _ = run_cli("run", scene)
    assert code == 0 and f"wrote {scenes / 'out' / 'ball.png'} (plot)" in out
    assert (scenes / "out" / "ball.png").read_bytes()[:4] == b"\x89PNG"
    assert list(elsewhere.iterdir()) == []
    # --out-dir moves them elsewhere; a path on the command line is the user's own.
    code, out, _ = run_cli("run", scene, "--out-dir", root / "results", "-q")
    assert code == 0 and (root / "results" / "out" / "ball.png").is_file()
    code, _, _ = run_cli("run", scene, "--plot", root / "mine.png", "-q")
    assert code == 0 and (root / "mine.png").is_file()


# -- 4. two outputs of one run never share a file -------------------------------------------------
def test_two_outputs_never_share_a_file(tmp_path):
    scene = write_ball(tmp_path)
    out = tmp_path / "out"
    code, _, err = run_cli("run", scene, "--rrd", out / "same.html", "--html", out / "same.html", "-q")
    assert code == 2 and err.startswith(f"legsim: error: --rrd {out / 'same.html'}: ")
    assert not out.exists()


# -- 12. outputs honour the umask -----------------------------------------------------------------
def test_every_output_honours_the_umask(tmp_path):
    from legsim.bench.work_precision import write_csv
    from legsim.scene import load_scene

    scene = write_ball(tmp_path)
    old = os.umask(0o027)
    try:
        code, _, _ = run_cli(
            "run", scene, "--rrd", tmp_path / "a.rrd", "--html", tmp_path / "a.html", "--plot", tmp_path / "a.png", "-q"
        )
        save_execution(load_scene(scene).simulate(), tmp_path / "a.npz")
        write_csv([], tmp_path / "a.csv")
    finally:
        os.umask(old)
    assert code == 0
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir() if p.name != scene.name}
    assert modes == dict.fromkeys(["a.rrd", "a.html", "a.png", "a.npz", "a.csv"], 0o640)


@pytest.mark.parametrize("which", ["urdf", "terrain csv"])
def test_a_link_to_a_file_the_scene_reads_is_an_input_too(tmp_path, which):
    """The scene's URDF and its terrain profile's CSV are inputs of the run as the scene file is:
    an output through a hard link to either is refused, naming the file, and nothing changes."""
    from helpers import urdf_robots

    (tmp_path / "ground.csv").write_text("x,z\n-5,0\n5,0\n")
    scene = urdf_robots.monoped(tmp_path, '[terrain]\nkind = "profile"\nfile = "ground.csv"\n')
    source = tmp_path / ("monoped.urdf" if which == "urdf" else "ground.csv")
    alias = tmp_path / "alias.png"
    os.link(source, alias)
    before = source.read_bytes()
    code, _, err = run_cli("run", scene, "--plot", alias, "-q", "--set", "integrator.t_final=0.01")
    assert code == 2, err
    assert err == f"legsim: error: --plot {alias}: is an input of this run ({source}); refusing to overwrite it\n"
    assert source.read_bytes() == before and alias.samefile(source)
