"""Issue 16, misleading messages (the ones outside the integrator): a device or FIFO given as
the scene, save_execution's raw OS errors, a read-only file system called "permission denied",
and terminal escape sequences from a scene printed raw."""

from __future__ import annotations

import errno
import os

import pytest

from helpers.reliability import run_cli, write_ball
from legsim import save_execution
from legsim.errors import OutputError


@pytest.mark.parametrize("kind", ["character device", "FIFO"])
def test_a_device_or_fifo_as_the_scene_is_named_for_what_it_is(tmp_path, kind):
    if kind == "FIFO":
        path = tmp_path / "pipe.toml"
        os.mkfifo(path)  # nobody writes to it: reading it would wait for ever
    else:
        path = "/dev/zero"  # reading it would never end
    code, out, err = run_cli("run", path)
    assert (code, out) == (2, "")
    assert err == f"legsim: error: {path}: not a scene file (it is a {kind})\n"


@pytest.fixture(scope="module")
def execution():
    from legsim.scene import load_scene

    return load_scene("bouncing_ball", ["integrator.t_final=0.2"]).simulate()


def test_execution_save_reports_what_is_wrong_as_an_output_error(execution, tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    cases = {
        blocker / "run.npz": f"{blocker} is not a directory",
        tmp_path: "is a directory",
        tmp_path / "run.toml": "unsupported format '.toml'; use one of ['.npz']",
    }
    for target, reason in cases.items():
        with pytest.raises(OutputError, match=r"^execution file .*: ") as caught:
            save_execution(execution, target)
        assert reason in str(caught.value), str(caught.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_a_read_only_file_system_is_not_called_permission_denied(tmp_path, monkeypatch, execution):
    # What a read-only mount does: access(2) and every file creation fail with EROFS. Emulated,
    # because a test may not mount file systems.
    import tempfile

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    real_access = os.access
    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: False if mode & os.W_OK else real_access(path, mode))
    scene = write_ball(tmp_path / "scene")
    code, _, err = run_cli("run", scene, "--plot", tmp_path / "ro" / "ball.png")
    assert code == 2 and "Read-only file system" in err and "ermission denied" not in err
    with pytest.raises(OutputError, match="Read-only file system"):
        save_execution(execution, tmp_path / "ro" / "run.npz")


ESCAPES = {
    "erase the screen": "\\u001b[2J",
    "recolour": "\\u001b[31m",
    "return to line start": "\\r",
    "operating system command": "\\u001b]0;owned\\u0007",
    "right-to-left override": "\\u202e",
}


@pytest.mark.parametrize("what", sorted(ESCAPES))
def test_terminal_escapes_from_a_scene_are_printed_escaped(tmp_path, monkeypatch, what):
    code = ESCAPES[what]
    scene = write_ball(tmp_path, "hostile.toml")
    text = scene.read_text()
    text = text.replace(text.splitlines()[1], f'description = "before {code} after\\nforged line"')
    scene.write_text(text.replace('name = "bouncing_ball"', f'name = "ro{code}bot"'))
    monkeypatch.setenv("LEGSIM_SCENE_PATH", str(tmp_path))
    _, listing, _ = run_cli("scenes")
    _, _, error = run_cli("run", scene)
    hostile = next(line for line in listing.splitlines() if line.startswith("hostile"))
    # One line, the escape shown as text: nothing a terminal would act on.
    assert "forged line" in hostile and "\\n" in hostile
    for printed in (listing, error):
        assert not any(ch in printed for ch in "\x1b\r\x07\u202e"), repr(printed)
    assert error.startswith(f"legsim: error: {scene}: robot.name: ") and "ro\\" in error
