"""Issue 16, "half-written or left behind": SIGTERM during an output write ends the command
like Ctrl-C (exit 143, no temporary file, the older file intact); SIGKILL, which nothing can
catch, leaves a temporary file that the next write of the same output removes.

Each case runs a real process that signals itself while its writer is half-way through the
file, so the signal lands inside the write, every time."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest

from helpers.reliability import temporaries, write_ball
from legsim import load_execution

# A `legsim run` whose --plot writer writes half a file, sends itself SIGNAL, then finishes.
RUN_WITH_SIGNAL = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    import legsim.commands.run as run_module

    real = run_module.find_writer
    def find_writer(kind, source=""):
        writer = real(kind, source)
        def half_then_signal(execution, scene, path, **kw):
            Path(path).write_bytes(b"\\x89PNG" + b"half a figure" * 1000)
            os.kill(os.getpid(), getattr(signal, sys.argv[1]))
            writer(execution, scene, path, **kw)
        half_then_signal.suffixes = writer.suffixes
        return half_then_signal
    run_module.find_writer = find_writer
    from legsim.cli import main
    sys.exit(main(sys.argv[2:]))
""")

# save_execution whose numpy writer writes half the archive, then the process is killed.
SAVE_WITH_SIGNAL = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    from legsim import save_execution
    from legsim.scene import load_scene

    execution = load_scene(sys.argv[2]).simulate()
    real = np.savez_compressed
    def half_then_signal(fh, **arrays):
        fh.write(b"PK half an archive" * 1000)
        fh.flush()
        os.kill(os.getpid(), getattr(signal, sys.argv[1]))
        real(fh, **arrays)
    if sys.argv[1] != "none":
        np.savez_compressed = half_then_signal
    save_execution(execution, sys.argv[3])
""")


def run(script: str, *argv, cwd) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", script, *map(str, argv)], capture_output=True, text=True, timeout=300, cwd=cwd
    )


def test_sigterm_while_writing_is_a_clean_shutdown(tmp_path):
    scene = write_ball(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "ball.png").write_bytes(b"\x89PNG yesterday's figure")
    done = run(RUN_WITH_SIGNAL, "SIGTERM", "run", scene, "--plot", out / "ball.png", "-q", cwd=tmp_path)
    assert done.returncode == 128 + signal.SIGTERM, done.stderr
    assert done.stderr == "legsim: terminated\n"
    assert temporaries(tmp_path) == []
    assert (out / "ball.png").read_bytes() == b"\x89PNG yesterday's figure"


def test_the_temporary_of_a_killed_run_is_removed_by_the_next_write(tmp_path):
    scene = write_ball(tmp_path)
    target = tmp_path / "out" / "ball.png"
    killed = run(RUN_WITH_SIGNAL, "SIGKILL", "run", scene, "--plot", target, "-q", cwd=tmp_path)
    assert killed.returncode == -signal.SIGKILL
    left = temporaries(tmp_path)
    assert [p.parent for p in left] == [target.parent] and not target.exists()  # SIGKILL cannot be caught
    done = run(
        RUN_WITH_SIGNAL.replace("os.kill(os.getpid(), getattr(signal, sys.argv[1]))", "pass"),
        "SIGKILL",
        "run",
        scene,
        "--plot",
        target,
        "-q",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert temporaries(tmp_path) == [] and target.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGKILL"])
def test_a_killed_save_leaves_nothing_after_the_next_save(tmp_path, sig):

    scene = write_ball(tmp_path)
    target = tmp_path / "run.npz"
    killed = run(SAVE_WITH_SIGNAL, sig, scene, target, cwd=tmp_path)
    assert killed.returncode == -getattr(signal, sig) and not target.exists()
    # A program using the library keeps Python's own SIGTERM handling (the process ends at
    # once): what it leaves is removed by the next save of that file.
    done = run(SAVE_WITH_SIGNAL, "none", scene, target, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert temporaries(tmp_path) == [] and load_execution(target).status == "finished"


def test_a_live_writers_temporary_is_left_alone(tmp_path):
    # Another process writing the same target right now: its file is not a leftover.
    from legsim.output.files import remove_stale_temporaries, temporary_name

    target = tmp_path / "a.png"
    ours = temporary_name(target)
    ours.write_bytes(b"being written")
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        theirs = tmp_path / ours.name.replace(f".{os.getpid()}-", f".{sleeper.pid}-")
        theirs.write_bytes(b"being written elsewhere")
        assert remove_stale_temporaries(target) == []
    finally:
        sleeper.kill()
        sleeper.wait()
    assert remove_stale_temporaries(target) == [theirs] and ours.exists()


class Signalled(KeyboardInterrupt):
    """What a signal handler raises, landing at one line of ``write_atomic``."""


def test_a_signal_at_any_line_of_write_atomic_leaves_no_temporary(tmp_path):
    """A Ctrl-C (or SIGTERM turned into one) can land between any two lines. A trace function
    raises it at the k-th line event of ``write_atomic`` (and of what it calls in its module),
    for every k up to the end of the write: no case may leave a temporary file, and the target
    holds the older content or the whole newer one."""
    import legsim.output.files as files

    target = tmp_path / "out.txt"
    target.write_text("older")
    module = files.__file__
    k = 0
    while True:
        seen = 0

        def trace(frame, event, arg, k=k):
            nonlocal seen
            if frame.f_code.co_filename != module:
                return None
            if event == "line":
                if seen == k:
                    raise Signalled(f"line {frame.f_lineno}")
                seen += 1
            return trace

        sys.settrace(trace)
        try:
            files.write_atomic(target, lambda tmp: tmp.write_text("newer"))
        except Signalled:
            interrupted = True
        else:
            interrupted = False
        finally:
            sys.settrace(None)
        assert temporaries(tmp_path) == [], f"a signal at line event {k} left a temporary file"
        if not interrupted:
            break
        assert target.read_text() in ("older", "newer"), f"a signal at line event {k} damaged the file"
        k += 1
    assert target.read_text() == "newer" and k > 10
