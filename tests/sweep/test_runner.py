"""Whole sweeps: rows against closed forms, errors and timeouts as rows, the same table from
this process and from a Dask cluster, resuming an interrupted 1,000-run sweep without
recomputing a finished row, and the command line."""

from __future__ import annotations

import io
import json
import math
import os
import re
import signal
import subprocess
import sys
import time

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import legsim
from legsim.cli import main
from legsim.scene import load_scene
from legsim.scene.files import bundled_dir
from legsim.sweep import runner
from legsim.sweep.spec import SweepError
from legsim.sweep.table import TIMING_COLUMNS
from legsim.sweep.walk import OUTCOMES

G = 9.81
BALL = ["integrator.t_final=0.3"]


def table_bytes(table: pa.Table) -> bytes:
    """The table without its timing column, as Parquet bytes (equal tables, equal bytes)."""
    sink = io.BytesIO()
    pq.write_table(table.drop_columns(list(TIMING_COLUMNS)).combine_chunks(), sink, compression="zstd")
    return sink.getvalue()


def test_rows_hold_each_variations_run_against_the_closed_form(tmp_path):
    result = legsim.sweep(
        "bouncing_ball", grid={"initial.state.z": (0.5, 2.0, 7)}, overrides=BALL, out=tmp_path / "s", in_process=True
    )
    table = pq.read_table(tmp_path / "s" / "results.parquet")
    assert table.equals(result.table) and table.num_rows == 7
    assert table.column("index").to_pylist() == list(range(7))
    for row in table.to_pylist():
        assert row["task_status"] == "done" and row["error"] is None and row["status"] == "finished"
        z0 = row["initial.state.z"]
        # Free fall for 0.3 s (g t^2 / 2 = 0.441 m): above it no bounce yet, z = z0 - 0.441.
        if z0 > 0.5:
            assert row["transitions"] == 0
            assert row["final_state"][0] == pytest.approx(z0 - G * 0.09 / 2, abs=1e-12)
            assert row["final_state"][1] == pytest.approx(-G * 0.3, abs=1e-12)
        assert row["energy_initial"] == pytest.approx(G * z0)
        assert row["wall_time_s"] > 0
    manifest = json.loads((tmp_path / "s" / "sweep.json").read_text())
    assert manifest["spec"]["scene"] == "bouncing_ball" and manifest["digest"] == result.spec.fingerprint()


def test_a_run_the_method_cannot_vouch_for_says_so_in_its_row(tmp_path, capsys):
    """The paper's pronk holds its state in strips at eps = 1e-2 for 3% of its run: that row
    carries the run's own warnings (as ``legsim run`` reports them), the finer run's row none,
    and the report counts the rows with warnings."""
    from legsim.commands.sweep import format_summary
    from legsim.scene import load_scene

    result = legsim.sweep("pronk_paper", grid={"integrator.eps": [1e-2, 1e-6]}, out=tmp_path / "s", in_process=True)
    coarse, fine = result.table.to_pylist()
    expected = load_scene("pronk_paper").simulate().warnings
    assert [w.kind for w in expected] == ["strip_hold"]
    assert coarse["warnings"] == [f"{w.kind}: {w.message}" for w in expected]
    assert coarse["status"] == fine["status"] == "finished" and fine["warnings"] == []
    assert result.summary()["warned"] == {"warnings": 1}
    assert "with warnings (see the column): 1 rows in warnings" in format_summary(result.summary())


def test_a_failing_or_timed_out_variation_is_a_row_with_its_error_and_the_sweep_goes_on(tmp_path):
    # Without its floor the ball falls freely: a long run is all flow, where the deadline is
    # checked a few times a second. 9000 s of dop853 at h = 1e-3 are 9e6 steps of 12 stages,
    # about 2 s of the compiled loop here: four times the timeout (rk4's 5000 s took 0.49 s, and
    # a run that ends just inside the timeout is a row "done", not "timeout"). Each axis's
    # values are valid (checked before anything runs); one pair is not, t_final below t0, and
    # only its variation fails.
    result = legsim.sweep(
        "bouncing_ball",
        grid={"integrator.t0": [0.0, 0.15], "integrator.t_final": [9000.0, 0.1]},
        overrides=["effects.floor=false", "integrator.method=dop853"],
        timeout=0.5,
        in_process=True,
    )
    rows = result.table.to_pylist()
    assert [r["task_status"] for r in rows] == ["timeout", "done", "timeout", "error"]
    for timed_out in (rows[0], rows[2]):
        assert "took longer than --timeout 0.5 s" in timed_out["error"]
        assert 0.5 <= timed_out["wall_time_s"] < 5.0
    assert "integrator.t_final: 0.1 must be > integrator.t0 = 0.15" in rows[3]["error"]
    assert rows[3]["status"] is None and rows[1]["status"] == "finished"
    assert rows[1]["final_state"][1] == pytest.approx(-G * 0.1, abs=1e-12)
    assert result.counts("task_status") == {"done": 1, "timeout": 2, "error": 1}


def test_an_axis_out_of_range_is_refused_before_anything_runs(tmp_path):
    with pytest.raises(legsim.SceneError, match=r"robot.parameters.slope"):
        legsim.sweep(
            "compass_gait", grid={"robot.parameters.slope": (3.0, 40.0, 3)}, out=tmp_path / "s", in_process=True
        )
    assert not (tmp_path / "s").exists()


def test_every_value_of_an_axis_given_out_of_order_is_checked_before_anything_runs(tmp_path):
    # The ends of an axis in order bound its values; a list out of order is checked value by
    # value (its middle value here was a failed row, the other cells run).
    with pytest.raises(legsim.SceneError, match=r"robot.parameters.slope"):
        legsim.sweep(
            "compass_gait", grid={"robot.parameters.slope": [3.0, 40.0, 2.0]}, out=tmp_path / "s", in_process=True
        )
    assert not (tmp_path / "s").exists()


def test_an_override_completed_by_an_axis_is_a_sweep_of_valid_scenes(tmp_path):
    # terrain.kind=slope needs its angle, which the grid gives each variation: the scene with
    # the override alone is incomplete, and no variation is.
    overrides = ["terrain.kind='slope'", "integrator.t_final=0.2"]
    table = legsim.sweep(
        "quadruped_stand", grid={"terrain.angle": [2.0, 4.0]}, overrides=overrides, out=tmp_path / "s",
        in_process=True,
    ).table  # fmt: skip
    rows = table.to_pylist()
    assert [r["task_status"] for r in rows] == ["done", "done"]
    for row in rows:
        alone = load_scene("quadruped_stand", [*overrides, f"terrain.angle={row['terrain.angle']}"]).simulate()
        assert row["status"] == alone.status and row["final_state"] == pytest.approx(alone.final_state, abs=1e-12)


def test_a_local_dask_cluster_gives_the_table_of_this_process(tmp_path):
    kwargs = dict(
        grid={"initial.state.z": (0.5, 2.0, 9), "integrator.method": ["rk4", "heun"]},
        overrides=["integrator.t_final=0.5"],
    )
    here = legsim.sweep("bouncing_ball", in_process=True, **kwargs)
    dask = legsim.sweep("bouncing_ball", workers=2, batch_size=4, out=tmp_path / "d", **kwargs)
    assert dask.where.startswith("an embedded Dask cluster of 2")
    assert table_bytes(dask.table) == table_bytes(here.table)
    assert table_bytes(pq.read_table(tmp_path / "d" / "results.parquet")) == table_bytes(here.table)


RESUME_ARGS = [
    "sweep",
    "bouncing_ball",
    "--grid",
    "initial.state.z=0.5:2.0:1000",
    "--set",
    "integrator.t_final=0.05",
    "--in-process",
    "--batch",
    "50",
    "--quiet",
]


def test_resuming_an_interrupted_1000_run_sweep_recomputes_no_finished_row(tmp_path, monkeypatch):
    out = tmp_path / "s"
    calls = []
    real = runner.run_batch

    def interrupted(spec, items):
        if len(calls) == 7:
            raise KeyboardInterrupt
        calls.append([i for i, _ in items])
        return real(spec, items)

    monkeypatch.setattr(runner, "run_batch", interrupted)
    assert main([*RESUME_ARGS, "--out", str(out)]) == 130
    before = pq.read_table(out / "results.parquet")
    assert before.num_rows == 350 and before.column("index").to_pylist() == list(range(350))

    ran = []

    def spy(spec, items):
        ran.extend(i for i, _ in items)
        return real(spec, items)

    monkeypatch.setattr(runner, "run_batch", spy)
    assert main([*RESUME_ARGS, "--out", str(out), "--resume"]) == 0
    after = pq.read_table(out / "results.parquet")
    assert sorted(ran) == list(range(350, 1000))
    assert after.num_rows == 1000 and after.column("index").to_pylist() == list(range(1000))
    # The finished rows are those of the first run, their wall times included (not recomputed).
    assert after.slice(0, 350).equals(before)
    assert not (out / "results.parts").exists()


def test_a_sweep_whose_scene_file_changed_is_not_resumed(tmp_path, monkeypatch, capsys):
    # The rows on disk were computed from the scene as it was: resuming after an edit would mix
    # two scenes in one table, so --resume refuses, naming the files; put back, it resumes.
    scene = tmp_path / "ball.toml"
    original = (bundled_dir() / "bouncing_ball.toml").read_text()
    scene.write_text(original)
    out = tmp_path / "s"
    args = ["sweep", str(scene), "--grid", "initial.state.z=0.5:2:40", "--set", "integrator.t_final=0.05",
            "--out", str(out), "--in-process", "--batch", "10", "--quiet"]  # fmt: skip
    real = runner.run_batch
    calls = []

    def interrupted(spec, items):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(items)
        return real(spec, items)

    monkeypatch.setattr(runner, "run_batch", interrupted)
    assert main(args) == 130
    monkeypatch.setattr(runner, "run_batch", real)
    scene.write_text(original + "\n# edited\n")
    capsys.readouterr()
    assert main([*args, "--resume"]) == 2
    assert "scene's files" in capsys.readouterr().err
    assert pq.read_table(out / "results.parquet").num_rows == 20  # nothing added
    scene.write_text(original)
    assert main([*args, "--resume"]) == 0
    assert pq.read_table(out / "results.parquet").column("index").to_pylist() == list(range(40))


def test_a_sweep_written_without_its_files_digest_is_not_resumed_blindly(tmp_path, capsys):
    # A folder whose manifest carries no digest of the scene's files (as sweeps wrote before it
    # did): its rows cannot be matched to the files now, and --resume says so.
    import dataclasses

    from legsim.sweep.table import manifest_text

    out = tmp_path / "s"
    grid = {"initial.state.z": (0.5, 2.0, 4)}
    result = legsim.sweep("bouncing_ball", grid=grid, overrides=["integrator.t_final=0.05"], out=out, in_process=True)
    assert result.spec.inputs  # this sweep's files' digest
    (out / "sweep.json").write_bytes(manifest_text(dataclasses.replace(result.spec, inputs="")))
    args = ["sweep", "bouncing_ball", "--grid", "initial.state.z=0.5:2.0:4", "--set", "integrator.t_final=0.05"]
    assert main([*args, "--out", str(out), "--in-process", "--resume"]) == 2
    assert "without the digest of its scene's files" in capsys.readouterr().err


def test_a_sweep_killed_outright_resumes_from_the_batches_it_streamed(tmp_path):
    out = tmp_path / "s"
    proc = subprocess.Popen(
        [sys.executable, "-m", "legsim.cli", *RESUME_ARGS, "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    parts = out / "results.parts"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(list(parts.glob("part-*.parquet"))) < 3 and proc.poll() is None:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    streamed = pa.concat_tables([pq.read_table(p) for p in sorted(parts.glob("part-*.parquet"))]).sort_by("index")
    assert len(list(parts.glob("part-*.parquet"))) >= 3 and streamed.num_rows < 1000
    result = legsim.sweep(
        "bouncing_ball",
        grid={"initial.state.z": (0.5, 2.0, 1000)},
        overrides=["integrator.t_final=0.05"],
        out=out,
        resume=True,
        in_process=True,
        batch_size=50,
    )
    assert result.resumed == streamed.num_rows and result.computed == 1000 - streamed.num_rows
    kept = result.table.filter(pa.compute.is_in(result.table.column("index"), streamed.column("index")))
    assert kept.equals(streamed)  # the streamed rows, wall times and all: none recomputed


def test_the_command_line_reports_rows_without_result_and_refuses_bad_input(tmp_path, capsys):
    out = tmp_path / "s"
    code = main(
        [
            "sweep",
            "bouncing_ball",
            "--grid",
            "integrator.t0=0,0.15",
            "--grid",
            "integrator.t_final=0.2,0.1",
            "--out",
            str(out),
            "--in-process",
            "--json",
        ]
    )
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    # each axis's values are valid; the pair t0 = 0.15, t_final = 0.1 is not: its row has no result
    assert code == 3 and summary["task_status"] == {"done": 3, "error": 1}
    assert summary["variations"] == 4 and summary["results"] == str(out / "results.parquet")
    assert "row 3: " in captured.err and "integrator.t_final" in captured.err
    # The folder holds that sweep: neither a new sweep nor another one's --resume may touch it.
    assert main(["sweep", "bouncing_ball", "--grid", "integrator.h=1e-3,2e-3", "--out", str(out), "--in-process"]) == 2
    assert "already holds a sweep" in capsys.readouterr().err
    assert (
        main(
            [
                "sweep",
                "bouncing_ball",
                "--grid",
                "integrator.h=1e-3,2e-3",
                "--out",
                str(out),
                "--in-process",
                "--resume",
            ]
        )
        == 2
    )
    assert "holds another sweep" in capsys.readouterr().err
    for argv, message in (
        (["--grid", "integrator.h"], "expected KEY=LO:HI:N"),
        (["--grid", "integrator.h=1e-3,-1,2e-3"], "integrator.h: -1.0 is out of range"),
        (["--samples", "3"], "--samples needs a --random"),
        (["--random", "initial.state.z=0.5:2", "--samples", "0"], "--samples must be an integer >= 1, got 0"),
        (["--walk", "--no-run"], "exclude each other"),
        (["--grid", "initial.state.q=0:1:3"], "unknown coordinate"),
        (["--workers", "0"], "--workers must be an integer >= 1"),
    ):
        assert main(["sweep", "bouncing_ball", "--out", str(tmp_path / "x"), *argv]) == 2
        assert message in capsys.readouterr().err


def test_a_walk_sweep_draws_the_basin_and_an_orbit_sweep_the_stability_map(tmp_path):
    basin = legsim.sweep(
        "rimless_wheel",
        grid={"initial.state.theta": [-math.pi / 10, 0.0], "initial.state.thetad": [0.8, 2.6]},
        walk=True,
        out=tmp_path / "b",
        in_process=True,
    )
    rows = basin.table.to_pylist()
    # Just after an impact (theta = -alpha) the step map's closed form gives the steps
    # (tests/sweep/test_walk.py): 15 from 0.8 rad/s, 18 from 2.6 rad/s.
    assert [(r["outcome"], r["steps_to_gait"]) for r in rows[:2]] == [("converges", 15), ("converges", 18)]
    assert all(r["task_status"] == "done" and r["outcome"] in OUTCOMES for r in rows)
    assert (tmp_path / "b" / "basin.png").stat().st_size > 0
    omega = math.sqrt(
        math.cos(math.pi / 5) ** 2
        * 4
        * G
        * math.sin(math.pi / 10)
        * math.sin(math.radians(5))
        / (1 - math.cos(math.pi / 5) ** 2)
    )
    orbits = legsim.sweep(
        "rimless_wheel",
        grid={"robot.parameters.slope": [5.0], "robot.parameters.m": [1.0, 2.0]},
        run=False,
        orbit=True,
        out=tmp_path / "o",
        in_process=True,
    )
    rows = orbits.table.to_pylist()
    assert [r["orbit_status"] for r in rows] == ["converged", "converged"]
    # The wheel's gait is independent of its mass; its multiplier is c^2 (closed form).
    for row in rows:
        assert row["orbit_fixed_point"][1] == pytest.approx(omega, rel=1e-8)
        assert row["orbit_spectral_radius"] == pytest.approx(math.cos(math.pi / 5) ** 2, rel=1e-6)
        assert row["orbit_stable"] is True
    assert (tmp_path / "o" / "stability.png").stat().st_size > 0


def test_orbit_rows_place_the_compass_gaits_period_doubling_where_continuation_does():
    # `legsim orbit compass_gait --continue slope 3 6` locates the period doubling at
    # slope 4.3909 (docs/orbits.md): the sweep's independent orbit searches on either side agree.
    result = legsim.sweep(
        "compass_gait", grid={"robot.parameters.slope": [4.2, 4.6]}, run=False, orbit=True, in_process=True
    )
    below, above = result.table.to_pylist()
    assert below["orbit_status"] == above["orbit_status"] == "converged"
    assert below["orbit_spectral_radius"] < 1 < above["orbit_spectral_radius"]
    assert below["orbit_stable"] is True and above["orbit_stable"] is False
    real = [
        re for re, im in zip(above["orbit_multipliers_re"], above["orbit_multipliers_im"], strict=True) if im == 0.0
    ]
    assert min(real) < -1.0  # through -1: a period doubling


@pytest.mark.parametrize(
    "axes, message",
    [
        ({"random": {"initial.state.theta": (0.1,)}}, "random initial.state.theta: expected (low, high) with finite"),
        ({"random": {"initial.state.theta": "0:1"}}, "random initial.state.theta: expected (low, high)"),
        ({"random": {"initial.state.theta": (0.2, 0.1)}}, "finite low < high, got (0.2, 0.1)"),
        ({"grid": {"initial.state.theta": (-0.1, 0.1)}}, "a tuple is read as a range: give a list for values"),
        ({"grid": {"initial.state.theta": (1, 2, 3, 4)}}, "expected a range (low, high, n) or a non-empty list"),
    ],
)
def test_the_python_api_refuses_a_malformed_axis_naming_its_field(tmp_path, axes, message):
    """legsim.sweep's grid and random axes as docs/sweep.md gives them: a tuple (low, high, n) is
    a range and a list holds values; a random axis is (low, high). Anything else is a SweepError
    naming the field (a raw unpacking error, or a tuple silently read as values, before)."""
    with pytest.raises(SweepError, match=re.escape(message)):
        legsim.sweep("rimless_wheel", out=tmp_path / "s", in_process=True, **axes)


def test_a_folder_holding_a_file_of_a_sweep_figure_s_name_is_refused_and_kept(tmp_path, capsys):
    """A folder without a sweep but with the user's basin.png (the name a walk sweep draws its
    figure to) is refused before anything runs: the sweep would replace the user's file."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "basin.png").write_bytes(b"MY OWN FIGURE")
    (out / "notes.txt").write_text("mine")
    args = ["sweep", "rimless_wheel", "--grid", "initial.state.thetad=0.8,2.6", "--walk", "--max-steps", "2"]
    assert main([*args, "--in-process", "--out", str(out)]) == 2
    assert "holds basin.png" in capsys.readouterr().err
    assert (out / "basin.png").read_bytes() == b"MY OWN FIGURE"
    assert sorted(p.name for p in out.iterdir()) == ["basin.png", "notes.txt"]
