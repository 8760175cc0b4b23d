"""Writing recordings: the file is complete or absent (a failed write leaves no file, keeps
the previous one and no temporary), has ordinary permissions, and bad arguments are named."""

from __future__ import annotations

import os

import pytest

from helpers.recordings import run_hopper
from legsim.builders import Model
from legsim.output.rrd import write_rrd
from legsim.output.rrd.digest import FOOTER_MAGIC
from legsim.output.trace import RecordingError


def _broken_geometry(model: Model, after: float) -> Model:
    def geometry(mode, x):
        if x[0] < after:
            raise ValueError("boom")
        return model.geometry(mode, x)

    return Model(model.system, model.initial_mode, model.initial_state, geometry=geometry, scenery=model.scenery)


def test_failing_write_leaves_no_file(tmp_path):
    model, ex = run_hopper(t_final=0.8)
    out = tmp_path / "out"
    with pytest.raises(Exception, match="geometry failed in mode"):
        write_rrd(ex, None, out / "x.rrd", model=_broken_geometry(model, 0.1))
    assert not (out / "x.rrd").exists()
    assert list(out.iterdir()) == [] if out.exists() else True


def test_failing_write_keeps_the_previous_file(tmp_path):
    model, ex = run_hopper(t_final=0.8)
    path = write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    before = path.read_bytes()
    with pytest.raises(Exception, match="geometry failed"):
        write_rrd(ex, None, path, model=_broken_geometry(model, 0.1))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]  # no temporary left behind


def test_interrupted_write_removes_the_temporary(tmp_path, monkeypatch):
    model, ex = run_hopper(t_final=0.5)

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(RecordingError, match=r"x\.rrd: cannot write the recording: disk full"):
        write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    assert list(tmp_path.iterdir()) == []


def test_a_recording_rerun_could_not_finish_is_refused_and_the_previous_file_kept(tmp_path, monkeypatch):
    """Rerun's SDK only logs a failure to write its file's footer (a disk filling as the stream
    closes) and returns: such a file, cut short, must not take the recording's name."""
    from legsim.output.rrd import write as rrd_write

    model, ex = run_hopper(t_final=0.3)
    path = write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    before = path.read_bytes()
    assert before.endswith(FOOTER_MAGIC + before[-4:])  # the check's premise: a finished file
    closing = rrd_write.recording_stream.__exit__

    def closed_on_a_full_disk(self, *exc):
        closing(self, *exc)
        for partial in tmp_path.glob(".*partial*"):  # the writer's temporary file, cut before its footer
            os.truncate(partial, partial.stat().st_size - 100)

    monkeypatch.setattr(rrd_write.recording_stream, "__exit__", closed_on_a_full_disk)
    with pytest.raises(RecordingError, match=r"x\.rrd: the recording is incomplete.*no footer"):
        write_rrd(ex, None, path, model=model)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]


def test_written_file_has_ordinary_permissions(tmp_path):
    model, ex = run_hopper(t_final=0.3)
    path = write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_write_needs_an_execution_and_a_path(tmp_path):
    with pytest.raises(RecordingError, match="needs a legsim Execution"):
        write_rrd({"not": "an execution"}, None, tmp_path / "x.rrd")
    _, ex = run_hopper(t_final=0.2)
    with pytest.raises(RecordingError, match="needs a path"):
        write_rrd(ex, None)
