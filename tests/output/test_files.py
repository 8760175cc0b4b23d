"""Atomic output writes: complete or absent, never a temporary file left, never a non-file replaced."""

import os
import stat
import tempfile
from pathlib import Path

import pytest

from legsim.errors import OutputError
from legsim.output.files import temporary_folder, write_atomic, write_bytes_atomic


def test_a_written_file_is_complete_and_honours_the_umask(tmp_path):
    old = os.umask(0o022)
    try:
        path = write_bytes_atomic(tmp_path / "sub" / "a.bin", b"abc", what="--rrd")
    finally:
        os.umask(old)
    assert path.read_bytes() == b"abc"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert sorted(p.name for p in path.parent.iterdir()) == ["a.bin"]


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")

    def fail(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, fail)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_writer_that_writes_nothing_is_an_error(tmp_path):
    with pytest.raises(OutputError, match="without writing"):
        write_atomic(tmp_path / "a.png", lambda tmp: tmp.unlink(), what="--plot")
    assert list(tmp_path.iterdir()) == []


def test_a_fifo_or_directory_target_is_refused(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match="not a regular file"):
        write_bytes_atomic(fifo, b"x", what="--plot")
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    with pytest.raises(OutputError, match="is a directory"):
        write_bytes_atomic(tmp_path, b"x")


# -- what a run may write where ------------------------------------------------------------------
def test_a_target_with_the_wrong_suffix_or_an_input_is_refused(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text("precious")
    with pytest.raises(OutputError, match=r"^--rrd .*a\.png: unsupported format '\.png'; use one of \['\.rrd'\]$"):
        write_bytes_atomic(tmp_path / "a.png", b"x", what="--rrd", suffixes=(".rrd",))
    # Suffixes compare without case; an input is refused whatever its suffix says.
    assert write_bytes_atomic(tmp_path / "A.RRD", b"x", suffixes=(".rrd",)).read_bytes() == b"x"
    with pytest.raises(OutputError, match=r"is an input of this run .*scene\.toml\); refusing to overwrite it"):
        write_bytes_atomic(tmp_path / "sub" / ".." / "scene.toml", b"x", what="--html", inputs=[scene])
    assert scene.read_text() == "precious" and not (tmp_path / "sub").exists()


def test_an_output_plan_refuses_two_outputs_on_one_file_before_writing_any(tmp_path):
    from legsim.output.files import OutputPlan

    plan = OutputPlan()
    first = plan.add("plot", tmp_path / "out" / "a.png", what="--plot", suffixes=(".png",))
    with pytest.raises(OutputError, match=r"^--figure .*a\.png: --plot writes the same file; give each output its "):
        plan.add("figure", tmp_path / "out" / "." / "a.png", what="--figure")
    # Planning creates nothing; writing through the plan does.
    assert list(plan) == ["plot"] and not (tmp_path / "out").exists()
    assert plan.write("plot", lambda tmp: tmp.write_bytes(b"png")) == first and first.read_bytes() == b"png"
    assert sorted(p.name for p in first.parent.iterdir()) == ["a.png"]


def test_a_folder_that_cannot_be_made_is_named_with_the_reason(tmp_path):
    from legsim.output.files import check_folder

    blocker = tmp_path / "afile"
    blocker.write_text("x")
    with pytest.raises(OutputError, match=rf"^--plot {blocker}/a/b.png: {blocker} is not a directory$"):
        check_folder(blocker / "a" / "b.png", "--plot")
    os.symlink(tmp_path / "gone", tmp_path / "dangling")
    with pytest.raises(OutputError, match="dangling is a broken symbolic link"):
        check_folder(tmp_path / "dangling" / "b.png", "--plot")
    check_folder(tmp_path / "new" / "deeper" / "b.png", "--plot")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "dangling"]


@pytest.mark.parametrize("moment", ["just after it is made", "inside the block"])
def test_a_temporary_folder_is_removed_when_ctrl_c_lands_at_any_moment(tmp_path, monkeypatch, moment):
    # A Ctrl-C right after the folder is made (before the block is entered) is the moment that
    # tempfile.TemporaryDirectory misses; the command line then leaves without garbage collection.
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    made = Path.mkdir

    def interrupted_after(self, *args, **kwargs):
        made(self, *args, **kwargs)
        if moment == "just after it is made":
            raise KeyboardInterrupt

    monkeypatch.setattr(Path, "mkdir", interrupted_after)
    with pytest.raises(KeyboardInterrupt), temporary_folder("legsim-test-") as folder:
        (folder / "recording.rrd").write_bytes(b"x")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_a_read_only_file_is_not_replaced(tmp_path):
    """Its owner made it read-only to keep it; a rename in a writable folder would not ask."""
    mine = tmp_path / "mine.rrd"
    mine.write_bytes(b"RRF2 an old recording")
    mine.chmod(0o444)
    with pytest.raises(OutputError, match=r"^--rrd .*mine\.rrd: is read-only; refusing to replace it"):
        write_bytes_atomic(mine, b"RRF2 new", what="--rrd", suffixes=(".rrd",))
    assert mine.read_bytes() == b"RRF2 an old recording" and stat.S_IMODE(mine.stat().st_mode) == 0o444
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.rrd"]


@pytest.mark.parametrize(
    ("name", "earlier"),
    [
        ("a.rrd", b"RRF2\x00\x29"),
        ("a.html", b"<!DOCTYPE html>\n<html>"),
        ("a.png", b"\x89PNG\r\n"),
        ("a.svg", b"<?xml v"),
        ("a.htm", b"<!DOCTYPE html>\n<html>"),
        ("a.jpg", b"\xff\xd8\xff\xe0"),
        ("a.jpeg", b"\xff\xd8\xff\xe0"),
        ("a.pdf", b"%PDF-1.4"),
        ("a.npz", b"PK\x03\x04"),
    ],
)
def test_a_file_of_another_kind_is_kept_and_an_earlier_output_or_an_empty_file_replaced(tmp_path, name, earlier):
    target = tmp_path / name
    target.write_text("precious notes")
    with pytest.raises(OutputError, match=rf"{name}: holds no \.\w+ file \(it begins b'precious'\); refusing"):
        write_bytes_atomic(target, earlier + b" new", what="--out")
    assert target.read_text() == "precious notes"
    for before in (earlier + b" old", b""):
        target.write_bytes(before)
        assert write_bytes_atomic(target, earlier + b" new", what="--out").read_bytes() == earlier + b" new"


def test_every_suffix_legsim_writes_has_a_signature():
    """A suffix without one was never checked: a user's notes.htm or photo.jpg was replaced."""
    from legsim.viz.plots import FORMATS

    from legsim.commands.run import KIND_SUFFIXES
    from legsim.output.files import SIGNATURES

    written = {s for suffixes in KIND_SUFFIXES.values() for s in suffixes} | {f".{f}" for f in FORMATS}
    assert written <= set(SIGNATURES), written - set(SIGNATURES)
