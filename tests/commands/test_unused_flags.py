"""Flags that would have nothing to act on are refused before the run (exit 2, naming what
they need), never left unused: a user who asked for a following camera or an output folder
must not get a result without them and no word."""

from __future__ import annotations

from legsim.cli import main

SHORT = ["bouncing_ball", "--set", "integrator.t_final=0.5", "--quiet"]


def test_a_camera_without_an_animation_is_refused_by_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", *SHORT, "--html-camera", "follow"]) == 2
    assert "--html-camera sets the animation's camera: give --html OUT.html with it" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_camera_without_an_animation_is_refused_by_replay(tmp_path, capsys):
    recording = tmp_path / "ball.rrd"
    assert main(["run", *SHORT, "--rrd", str(recording)]) == 0
    capsys.readouterr()
    assert main(["replay", str(recording), "--html-camera", "follow"]) == 2
    assert "--html-camera sets the animation's camera" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ball.rrd"]


def test_an_output_folder_for_a_scene_without_outputs_is_refused(tmp_path, capsys):
    folder = tmp_path / "od"
    assert main(["run", *SHORT, "--out-dir", str(folder)]) == 2
    err = capsys.readouterr().err
    assert f"--out-dir {folder}: places the scene's own [output] files" in err and "no [output] section" in err
    assert not folder.exists()
