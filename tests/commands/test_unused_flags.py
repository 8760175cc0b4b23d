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


def test_an_interrupt_while_a_later_output_is_written_leaves_every_older_file(tmp_path, monkeypatch, capsys):
    """The outputs take their names together once all are written: Ctrl-C while the plot is
    drawn, after the animation is complete, must not leave a new animation beside an old plot."""
    from legsim.commands import run as run_command

    find_writer = run_command.find_writer

    def interrupted_plot(kind, source):
        writer = find_writer(kind, source)
        if kind != "plot":
            return writer

        def plot(execution, scene, path, **extra):
            written = [p for p in tmp_path.iterdir() if p.name.startswith(".a.") and p.suffix == ".html"]
            assert written and written[0].stat().st_size > 3  # the animation is complete, under its temporary name
            raise KeyboardInterrupt

        return plot

    monkeypatch.setattr(run_command, "find_writer", interrupted_plot)
    page, figure = tmp_path / "a.html", tmp_path / "a.png"
    page.write_text("<!DOCTYPE html> OLD")
    figure.write_bytes(b"\x89PNG OLD")
    argv = ["run", "oscillator_ex1", "--set", "integrator.t_final=1", "--quiet"]
    assert main([*argv, "--html", str(page), "--plot", str(figure)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert page.read_text() == "<!DOCTYPE html> OLD" and figure.read_bytes() == b"\x89PNG OLD"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.html", "a.png"]  # no temporary left


def test_json_with_another_table_format_is_refused_by_stress(capsys):
    assert main(["stress", "--quick", "--case", "grazing_tangent", "--json", "--format", "csv"]) == 2
    assert "--json prints JSON; it cannot be given with --format csv" in capsys.readouterr().err
