"""The command line: run (summary, --json, exit codes, outputs), scenes, errors, discovery."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

import legsim.commands
from helpers.scenes import TINY_SCENE, register_tiny, write_scene
from legsim import simulate
from legsim.cli import main
from legsim.scene import bundled_dir, load_scene

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable


@pytest.fixture(autouse=True)
def tiny(monkeypatch):
    register_tiny(monkeypatch)


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


# -- legsim run --------------------------------------------------------------------------------
REQUIRED_KEYS = {
    "status",
    "t_final",
    "final_mode",
    "final_state",
    "state_names",
    "mode_sequence",
    "transitions",
    "steps",
    "halvings",
    "wall_time_s",
    "field_evals",
    "guard_evals",
    "reset_evals",
    "energy_initial",
    "energy_final",
    "drag_evals",
    "scene",
}


def test_run_json_matches_a_direct_simulate_call(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--json")
    assert code == 0 and err == ""
    summary = json.loads(out)
    assert set(summary) >= REQUIRED_KEYS
    system = load_scene(path).model.system
    direct = simulate(system, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, "rk4")
    assert summary["status"] == "finished" and summary["t_final"] == 1.0
    assert summary["final_state"] == direct.final_state.tolist()
    assert summary["final_mode"] == direct.final_mode and summary["state_names"] == ["z", "zd"]
    assert summary["mode_sequence"] == direct.mode_sequence
    assert summary["transitions"] == len(direct.transitions)
    for key in ("steps", "halvings", "field_evals", "guard_evals", "reset_evals"):
        assert summary[key] == direct.counters[key], key
    # Energy g z + zd^2 / 2 at the initial and final states.
    assert summary["energy_initial"] == pytest.approx(9.81)
    z, zd = direct.final_state
    assert summary["energy_final"] == pytest.approx(9.81 * z + 0.5 * zd**2, rel=1e-12)
    assert summary["drag_evals"] == 0 and summary["scene"] == "tiny" and summary["outputs"] == {}


def test_run_human_summary_names_the_state(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--set", "effects.floor=false")
    assert code == 0 and err == ""
    z = 1.0 - 9.81 / 2  # free fall without the floor
    assert f"final mode flight: z = {z:.6g}, zd = {-9.81:.6g}" in out
    assert "tiny: finished at t = 1 s (rk4, h = 0.001 s, eps = 0.001)" in out
    assert "transitions 0: flight (1 visit)" in out
    assert "guard 0, reset 0" in out


def test_run_set_overrides_reach_the_simulation(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, _ = run_cli(
        capsys, "run", str(path), "--json", "--set", "integrator.t_final=0.25", "--set", "effects.floor=false"
    )
    summary = json.loads(out)
    assert code == 0 and summary["t_final"] == 0.25 and summary["guard_evals"] == 0
    # Free fall z(t) = 1 - g t^2 / 2: RK4 is exact on a cubic.
    assert summary["final_state"][0] == pytest.approx(1 - 9.81 * 0.25**2 / 2, abs=1e-13)


def test_run_bad_override_exits_2_with_one_line(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--set", "integrator.h=-1")
    assert code == 2 and out == ""
    assert err == f"legsim: error: {path}: integrator.h: -1.0 is out of range, allowed: float in (0, inf) s\n"
    code, _, err = run_cli(capsys, "run", str(path), "--set", "integrator.h")
    assert code == 2 and err.startswith("legsim: error: --set 'integrator.h': expected key.path=value")


def test_bad_scene_has_no_traceback_unless_debug(tmp_path, capsys):
    path = write_scene(tmp_path, TINY_SCENE.replace("tinyball", "nobot"))
    code, _, err = run_cli(capsys, "run", str(path))
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert err.startswith(f"legsim: error: {path}: robot.name: unknown robot 'nobot'")
    code, _, err = run_cli(capsys, "--debug", "run", str(path))
    assert code == 2 and "Traceback (most recent call last)" in err and "SceneError" in err
    code, _, err2 = run_cli(capsys, "run", str(path), "--debug")
    assert code == 2 and "Traceback" in err2


def test_missing_scene_and_usage_errors_exit_2(tmp_path, capsys):
    code, _, err = run_cli(capsys, "run", str(tmp_path / "no.toml"))
    assert code == 2 and err == f"legsim: error: {tmp_path / 'no.toml'}: no such scene file\n"
    code, _, err = run_cli(capsys, "run")
    assert code == 2 and "required: SCENE" in err
    code, _, err = run_cli(capsys, "frobnicate")
    assert code == 2 and "invalid choice: 'frobnicate'" in err
    code, _, err = run_cli(capsys)
    assert code == 2 and "usage: legsim" in err


def test_run_stopped_early_exits_3_with_the_message(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--json", "--set", "integrator.max_transitions=1")
    summary = json.loads(out)
    assert code == 3 and summary["status"] == "max_transitions" and summary["transitions"] == 1
    assert err.startswith("legsim: run stopped early (max_transitions): transition budget max_transitions=1")
    code, out, err = run_cli(capsys, "run", str(path), "--set", "integrator.max_transitions=1")
    assert code == 3 and "max_transitions at t = " in out and "stopped: transition budget" in out


def test_quiet_prints_nothing_and_non_tty_shows_no_progress(tmp_path, capsys):
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--quiet")
    assert (code, out, err) == (0, "", "")


# -- outputs -----------------------------------------------------------------------------------
def _fake_writers(monkeypatch, calls, fail=()):
    import legsim.commands.run as run_module

    def make(kind):
        def writer(execution, scene, path):
            calls.append((kind, Path(path), execution.status, scene.name))
            Path(path).write_text(f"{kind} partial")
            if kind in fail:
                raise RuntimeError(f"{kind} writer broke")
            Path(path).write_text(f"{kind} of {scene.name}: {len(execution.transitions)}")

        return writer

    monkeypatch.setattr(run_module, "find_writer", lambda kind, source="": make(kind))


def test_outputs_from_flags_and_scene_are_written_atomically(tmp_path, capsys, monkeypatch):
    calls = []
    _fake_writers(monkeypatch, calls)
    out_dir = tmp_path / "out"
    # A scene's [output] paths are relative to its own folder (tmp_path).
    path = write_scene(tmp_path, TINY_SCENE + '\n[output]\nrrd = "out/scene.rrd"\nplot = "out/s.png"\n')
    code, out, _ = run_cli(
        capsys, "run", str(path), "--json", "--plot", str(out_dir / "flag.png"), "--html", str(out_dir / "a.html")
    )
    assert code == 0
    summary = json.loads(out)
    # A flag wins over the scene's [output]; the scene's other outputs are kept.
    assert summary["outputs"] == {
        "rrd": str(out_dir / "scene.rrd"),
        "html": str(out_dir / "a.html"),
        "plot": str(out_dir / "flag.png"),
    }
    assert not (out_dir / "s.png").exists()
    for kind, target in summary["outputs"].items():
        assert Path(target).read_text() == f"{kind} of tiny: {summary['transitions']}"
    # Each writer wrote a temporary file in the target's directory with the target's suffix.
    for kind, tmp, status, _ in calls:
        assert tmp.parent == out_dir and tmp.suffix == Path(summary["outputs"][kind]).suffix
        assert tmp.name.startswith(".") and not tmp.exists() and status == "finished"
    assert sorted(p.name for p in out_dir.iterdir()) == ["a.html", "flag.png", "scene.rrd"]


def test_failed_writer_leaves_no_partial_file(tmp_path, capsys, monkeypatch):
    calls = []
    _fake_writers(monkeypatch, calls, fail=("html",))
    path = write_scene(tmp_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    (out_dir / "old.html").write_text("<!DOCTYPE html> previous")
    code, _out, err = run_cli(capsys, "run", str(path), "--html", str(out_dir / "old.html"))
    assert code == 2
    assert err == f"legsim: error: --html {out_dir / 'old.html'}: writing failed: RuntimeError: html writer broke\n"
    # The earlier file is untouched and no temporary file is left behind.
    assert sorted(p.name for p in out_dir.iterdir()) == ["old.html"]
    assert (out_dir / "old.html").read_text() == "<!DOCTYPE html> previous"


def test_failed_run_writes_nothing(tmp_path, capsys, monkeypatch):
    calls = []
    _fake_writers(monkeypatch, calls)
    path = write_scene(tmp_path)
    out_dir = tmp_path / "out"
    # The initial state lies past the floor: rejected before anything runs.
    code, _, err = run_cli(
        capsys,
        "run",
        str(path),
        "--rrd",
        str(out_dir / "a.rrd"),
        "--set",
        "initial.state.z=-1",
        "--set",
        "initial.state.zd=-1",
    )
    assert code == 2 and "lies past the guard of transition bounce" in err
    assert calls == [] and not out_dir.exists()


def test_failed_writer_after_an_early_stop_keeps_exit_3_and_the_other_outputs(tmp_path, capsys, monkeypatch):
    # The run's status is the result: a writer that cannot draw a run which stopped early is
    # reported on one line, leaves no file, costs the other outputs nothing, and the exit code
    # stays 3 (2 would say the input was bad).
    calls = []
    _fake_writers(monkeypatch, calls, fail=("plot",))
    path = write_scene(tmp_path)
    out_dir = tmp_path / "out"
    code, out, err = run_cli(
        capsys,
        "run",
        str(path),
        "--json",
        "--set",
        "integrator.max_transitions=1",
        "--plot",
        str(out_dir / "p.png"),
        "--html",
        str(out_dir / "a.html"),
    )
    assert code == 3
    assert json.loads(out)["outputs"] == {"html": str(out_dir / "a.html")}
    lines = err.splitlines()
    assert lines[0] == f"legsim: error: --plot {out_dir / 'p.png'}: writing failed: RuntimeError: plot writer broke"
    assert lines[1].startswith("legsim: run stopped early (max_transitions): ") and len(lines) == 2
    assert sorted(p.name for p in out_dir.iterdir()) == ["a.html"]


DIVERGING = [
    "oscillator_ex1",
    "-q",
    "--set",
    "effects.stop=false",
    "--set",
    "effects.damping=false",
    "--set",
    'integrator.method="euler"',
    "--set",
    "integrator.h=0.5",
    "--set",
    "integrator.t_final=5000",
]


def test_diverged_run_writes_its_outputs_quietly_and_exits_3(tmp_path):
    # Explicit Euler at h = 0.5 on the undamped oscillator grows until the state is not finite
    # (t = 750.5 s, |x| ~ 1e308). A real process, so that stderr is exactly what a user sees
    # (pytest would otherwise catch the warnings before they reach stderr).
    from matplotlib.image import imread

    from legsim.record import read_rrd

    out_dir = tmp_path / "o"
    done = subprocess.run(
        [
            PYTHON,
            "-m",
            "legsim",
            "run",
            *DIVERGING,
            "--plot",
            str(out_dir / "div.png"),
            "--html",
            str(out_dir / "div.html"),
            "--rrd",
            str(out_dir / "div.rrd"),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode == 3, done.stderr
    # The undamped field is in no bundled scene's modes, so not prebuilt: where no earlier run
    # cached it, the run first says, in its one line, that it compiles it.
    lines = [line for line in done.stderr.splitlines() if not line.startswith("legsim: compiling ")]
    assert len(done.stderr.splitlines()) - len(lines) <= 1
    stderr = "\n".join(lines)
    assert "Warning" not in stderr and "error" not in stderr, done.stderr
    assert stderr.startswith("legsim: run stopped early (non_finite): ")
    assert len(lines) == 1 and done.stdout == ""
    # Complete files only, no temporaries left behind.
    assert sorted(p.name for p in out_dir.iterdir()) == ["div.html", "div.png", "div.rrd"]
    img = imread(out_dir / "div.png")
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    # The lines are drawn (dark pixels beyond the axes' frame and text).
    assert (img[..., :3].max(axis=-1) < 0.2).sum() > 1000
    html = (out_dir / "div.html").read_text()
    assert html.rstrip().endswith("</html>") and "diverged: not drawn past t = " in html
    assert read_rrd(out_dir / "div.rrd")["summary"]["status"] == "non_finite"


def test_missing_writers_fail_for_their_flag_only(tmp_path, capsys, monkeypatch):
    from importlib import metadata

    import legsim.commands.run as run_module

    path = write_scene(tmp_path)
    monkeypatch.delattr("legsim.output.rrd.write_rrd")  # a recorder without its writer
    code, _, err = run_cli(capsys, "run", str(path), "--rrd", str(tmp_path / "a.rrd"))
    assert code == 2 and err.startswith("legsim: error: --rrd: Rerun recordings are not available: ")
    assert "write_rrd" in err
    monkeypatch.setattr(metadata, "entry_points", lambda **kw: [])
    code, _, err = run_cli(capsys, "run", str(path), "--html", str(tmp_path / "a.html"))
    assert code == 2 and err == (
        "legsim: error: --html: no 'html' writer is registered in the legsim.writers entry points\n"
    )
    # Without the flags the same run succeeds, and nothing was written.
    code, _, _ = run_cli(capsys, "run", str(path), "--quiet")
    assert code == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["tiny.toml"]
    assert run_module.requested_outputs(types.SimpleNamespace(rrd=None, html=None, plot=None), {}) == {}


def test_rrd_uses_the_recorders_write_rrd(tmp_path, capsys, monkeypatch):
    calls = []

    def write_rrd(execution, scene, path):
        calls.append(Path(path))
        Path(path).write_bytes(b"RRF2")

    monkeypatch.setattr("legsim.output.rrd.write_rrd", write_rrd)
    code, out, _ = run_cli(capsys, "run", str(write_scene(tmp_path)), "--rrd", str(tmp_path / "x.rrd"))
    assert code == 0 and (tmp_path / "x.rrd").read_bytes() == b"RRF2" and len(calls) == 1
    assert f"wrote {tmp_path / 'x.rrd'} (rrd)" in out


# -- legsim scenes -----------------------------------------------------------------------------
BUNDLED = sorted(p.stem for p in bundled_dir().glob("*.toml"))


def test_scenes_lists_every_bundled_file(capsys, monkeypatch):
    monkeypatch.delenv("LEGSIM_SCENE_PATH", raising=False)
    code, out, _ = run_cli(capsys, "scenes", "--json")
    rows = json.loads(out)
    assert [r["name"] for r in rows] == BUNDLED
    code_text, text, _ = run_cli(capsys, "scenes")
    assert code == code_text
    if BUNDLED:
        lines = text.splitlines()
        assert [line.split()[0] for line in lines] == BUNDLED
        for row, line in zip(rows, lines, strict=True):
            assert row["robot"] in line.split() and row["description"] in line


def test_scenes_lists_scene_path_entries_and_flags_invalid_ones(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LEGSIM_SCENE_PATH", str(tmp_path))
    write_scene(tmp_path, name="zz_tiny")
    write_scene(tmp_path, TINY_SCENE.replace("h = 1e-3", "h = 0"), name="zz_bad_value")
    write_scene(tmp_path, "[scene\n", name="zz_bad_syntax")
    code, out, _ = run_cli(capsys, "scenes", "--json", "--check")
    rows = {r["name"]: r for r in json.loads(out)}
    assert code == 2
    assert rows["zz_tiny"]["robot"] == "tinyball" and rows["zz_tiny"]["description"] == "a tiny ball"
    assert "error" not in rows["zz_tiny"]
    assert "integrator.h: 0.0 is out of range" in rows["zz_bad_value"]["error"]
    assert "TOML syntax error" in rows["zz_bad_syntax"]["error"]
    code, out, _ = run_cli(capsys, "scenes")
    line = next(line for line in out.splitlines() if line.startswith("zz_tiny "))
    assert line.split()[:2] == ["zz_tiny", "tinyball"] and line.endswith("a tiny ball")


# -- discovery and errors ----------------------------------------------------------------------
def test_commands_are_discovered_from_modules(tmp_path, capsys, monkeypatch):
    (tmp_path / "zz_hello.py").write_text(
        "NAME = 'hello'\nHELP = 'say hello'\n"
        "def add_arguments(p):\n    p.add_argument('--code', type=int, default=0)\n"
        "def run(args):\n    print('hello'); return args.code\n"
    )
    (tmp_path / "zz_broken.py").write_text("import not_a_module_anywhere\n")
    (tmp_path / "zz_crash.py").write_text(
        "NAME = 'crash'\nHELP = 'crash'\ndef add_arguments(p): pass\ndef run(args):\n    raise RuntimeError('boom')\n"
    )
    monkeypatch.setattr(legsim.commands, "__path__", [*legsim.commands.__path__, str(tmp_path)])
    for name in ("zz_hello", "zz_broken", "zz_crash"):
        monkeypatch.delitem(sys.modules, f"legsim.commands.{name}", raising=False)
    assert run_cli(capsys, "hello", "--code", "5")[:2] == (5, "hello\n")
    code, _, err = run_cli(capsys, "zz_broken")
    assert code == 2 and err.startswith(
        "legsim: error: command 'zz_broken' is unavailable: its module failed "
        "to load (ModuleNotFoundError: No module named 'not_a_module_anywhere')"
    )
    code, _, err = run_cli(capsys, "crash")
    assert code == 1 and err == "legsim: internal error: RuntimeError: boom (run with --debug for the traceback)\n"
    code, _, err = run_cli(capsys, "crash", "--debug")
    assert code == 1 and "Traceback" in err and err.endswith("legsim: internal error: RuntimeError: boom\n")
    for name in ("zz_hello", "zz_broken", "zz_crash"):
        sys.modules.pop(f"legsim.commands.{name}", None)


def test_python_m_legsim_and_startup_imports_nothing_heavy():
    code = (
        "import sys; from legsim.cli import build_parser; build_parser(); "
        "print(sorted(m for m in ('rerun', 'matplotlib', 'scipy', 'pinocchio', 'meshcat') if m in sys.modules))"
    )
    out = subprocess.run([PYTHON, "-c", code], capture_output=True, text=True, cwd=REPO, check=True).stdout
    assert out.strip() == "[]"
    done = subprocess.run([PYTHON, "-m", "legsim", "--version"], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0 and done.stdout.startswith("legsim ")


# -- progress ----------------------------------------------------------------------------------
def test_scene_simulate_calls_progress_on_long_runs(tmp_path):
    # A run of a few tenths of a second reports progress (simulate reports every ~0.2 s);
    # the reported times increase within [t0, t_final].
    scene = load_scene(
        write_scene(tmp_path), overrides=["effects.floor=false", "integrator.h=5e-6", "integrator.method=euler"]
    )
    seen = []
    scene.simulate(progress=lambda t, t0, t1: seen.append((t, t0, t1)))
    assert seen, "no progress reported on a run of 200000 steps"
    times = [t for t, _, _ in seen]
    assert times == sorted(times) and all(0.0 <= t <= 1.0 and t1 == 1.0 for t, _, t1 in seen)


def test_unwritable_output_fails_before_the_run(tmp_path, capsys, monkeypatch):
    calls = []
    _fake_writers(monkeypatch, calls)
    path = write_scene(tmp_path)
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    code, out, err = run_cli(capsys, "run", str(path), "--plot", str(blocker / "sub" / "p.png"))
    assert code == 2 and out == "" and calls == []
    assert err == f"legsim: error: --plot {blocker / 'sub' / 'p.png'}: {blocker} is not a directory\n"
    code, _, err = run_cli(capsys, "run", str(path), "--html", str(tmp_path))
    assert code == 2 and err == f"legsim: error: --html {tmp_path}: is a directory\n" and calls == []
    # A folder whose permission bits say yes (to root) but where no file can be created: the
    # probe finds it before the run, not the writer after it.
    if Path("/proc/self").is_dir():
        code, out, err = run_cli(capsys, "run", str(path), "--rrd", "/proc/x.rrd")
        assert code == 2 and out == "" and calls == []
        assert err.startswith("legsim: error: --rrd /proc/x.rrd: cannot write in /proc (")


def test_a_bad_plot_format_fails_before_the_run(tmp_path, capsys, monkeypatch):
    # The real plot writer declares its suffixes: a wrong one costs no simulation and writes
    # no other output.
    import legsim.scene as scene_module

    ran = []
    original = scene_module.Scene.simulate
    monkeypatch.setattr(scene_module.Scene, "simulate", lambda self, **kw: ran.append(1) or original(self, **kw))
    path = write_scene(tmp_path)
    out_dir = tmp_path / "out"
    code, out, err = run_cli(
        capsys, "run", str(path), "--rrd", str(out_dir / "a.rrd"), "--plot", str(out_dir / "a.rrd")
    )
    assert code == 2 and out == "" and ran == [] and not out_dir.exists()
    assert err == (
        f"legsim: error: --plot {out_dir / 'a.rrd'}: unsupported format '.rrd'; "
        f"use one of ['.png', '.pdf', '.svg', '.jpg', '.jpeg']\n"
    )


def test_a_diverging_run_prints_its_summary_without_numpy_warnings(capsys):
    # Damping a = 1e6 with h = 1e-2 makes explicit RK4 blow up: the run ends non_finite, the
    # summary is printed (the final energy, which overflows, as null), the reason on stderr,
    # and numpy's overflow warnings do not bury it.
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any RuntimeWarning leaking from the run fails the test
        code, out, err = run_cli(capsys, "run", "oscillator_ex1", "--json", "--set", "effects.damping.a=1e6")
    summary = json.loads(out)
    assert code == 3 and summary["status"] == "non_finite" and summary["energy_final"] is None
    assert summary["energy_initial"] == pytest.approx(0.5 * (31.4**2 + 2.5**2 * 11.36**2))
    assert err.startswith("legsim: run stopped early (non_finite): the step from t=") and err.count("\n") == 1
    code, out, _ = run_cli(capsys, "run", "oscillator_ex1", "--set", "effects.damping.a=1e6")
    assert code == 3 and "energy 896.26 J -> n/a J" in out


def test_replay_checks_every_output_before_writing_any(tmp_path, capsys, monkeypatch):
    from legsim.record import write_rrd

    scene = load_scene(write_scene(tmp_path))
    rrd = write_rrd(scene.simulate(), scene, tmp_path / "tiny.rrd")
    code, out, err = run_cli(
        capsys, "replay", str(rrd), "--html", str(tmp_path / "a.html"), "--plot", str(tmp_path / "a.gif")
    )
    assert code == 2 and out == "" and "--plot " in err and "unsupported format '.gif'" in err
    assert not (tmp_path / "a.html").exists()
    # --spawn without a display fails at once, before printing a summary it cannot follow up.
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code, out, err = run_cli(capsys, "replay", str(rrd), "--spawn")
    assert code == 2 and out == "" and err.startswith("legsim: error: --spawn needs a display")


def test_progress_bar_is_drawn_on_a_terminal_and_erased(tmp_path):
    # `legsim run` with stderr on a pseudo-terminal (stdout a pipe): the bar is drawn on stderr
    # with carriage returns, its fraction grows, it is erased at the end, and stdout carries
    # only the summary. 150000 Euler steps (1 s here) take well over the 0.2 s after which simulate
    # reports progress.
    import pty

    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [
            PYTHON,
            "-m",
            "legsim",
            "run",
            "oscillator_ex1",
            "--set",
            "effects.stop=false",
            "--set",
            "integrator.method=euler",
            "--set",
            # 3e6 compiled steps: long enough for the bar to be drawn
            "integrator.h=5e-7",
            "--set",
            "integrator.t_final=1.5",
        ],
        stdout=subprocess.PIPE,
        stderr=slave,
        cwd=REPO,
    )
    os.close(slave)
    received = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        received += chunk
    out = proc.stdout.read().decode()
    assert proc.wait(timeout=60) == 0
    os.close(master)
    err = received.decode()
    plain = [re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", part) for part in err.split("\r")]
    bars = [part for part in plain if part.startswith("oscillator_ex1 ")]
    assert bars, f"no progress bar drawn: {err!r}"
    fractions = [float(re.search(r" (\d+)% ", b).group(1)) for b in bars]
    assert fractions == sorted(fractions) and fractions[0] >= 0.0 and fractions[-1] <= 100.0
    assert all(" ETA " in b for b in bars)
    assert err.endswith("\x1b[1A\x1b[2K")  # erased: the cursor goes up to the bar's line and clears it
    assert "\r" not in out and out.startswith("oscillator_ex1: finished at t = 1.5 s (euler, h = 5e-07 s")


def test_ctrl_c_while_writing_leaves_no_temporary(tmp_path, capsys, monkeypatch):
    import legsim.commands.run as run_module

    def interrupted(execution, scene, path):
        Path(path).write_text("half a plot")
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "find_writer", lambda kind, source="": interrupted)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code, _, err = run_cli(capsys, "run", str(write_scene(tmp_path)), "--plot", str(out_dir / "p.png"))
    assert code == 130 and err == "legsim: interrupted\n"
    assert list(out_dir.iterdir()) == []


def test_html_of_a_model_without_geometry_fails_before_the_run(tmp_path, capsys):
    # The tiny ball defines no geometry; the real html writer says it needs one.
    path = write_scene(tmp_path)
    code, out, err = run_cli(capsys, "run", str(path), "--html", str(tmp_path / "a.html"))
    assert code == 2 and out == "" and not (tmp_path / "a.html").exists()
    assert err == (
        f"legsim: error: --html {tmp_path / 'a.html'}: this output draws the robot, and tinyball defines "
        f"no geometry (Model.geometry is None); use --plot or --rrd for it\n"
    )


def test_the_first_compile_of_a_run_says_so_in_one_line_on_stderr(tmp_path, capsys, monkeypatch):
    # Without prebuilt or cached code a first run compiles for tens of seconds: the command line
    # says so once, in one line, whatever else compiles after it in the process.
    import numba

    from legsim.compiled import kernel

    monkeypatch.setattr(kernel, "on_compile", None)
    monkeypatch.setattr(kernel._FirstCompile, "said", False)
    code, _, err = run_cli(capsys, "run", str(write_scene(tmp_path)))
    assert code == 0 and err == ""  # the tiny scene compiles nothing

    def first(x):
        return x + 1.0

    def second(x):
        return x * 2.0

    assert numba.njit(first)(1.0) == 2.0 and numba.njit(second)(1.0) == 2.0
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("legsim: compiling ")
    assert f"{first.__module__}.{first.__qualname__}" in lines[0]
    # numba.njit without cache=True compiles in every process: the line must not promise "once".
    assert "for this run (not cached: every run compiles it)" in lines[0] and "once" not in lines[0]
