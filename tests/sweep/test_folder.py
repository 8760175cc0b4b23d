"""A sweep owns its folder (legsim.sweep.table): a second sweep started into it, the same or
another, is refused while the first runs; ``--resume`` continues only a table this sweep wrote
(manifest digest, schema, indices), refusing anything else by name with exit 2; grids are
counted before their values are made."""

from __future__ import annotations

import io
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import legsim
from helpers.reliability import run_cli
from legsim.sweep.table import LOCK, TIMING_COLUMNS

#: A bouncing-ball sweep of a few seconds in this process: long enough for a second one to start.
BALL = ["sweep", "bouncing_ball", "--set", "integrator.t_final=0.3", "--in-process", "--batch", "20", "--quiet"]
GRIDS = {"a": "initial.state.z=0.5:2:240", "b": "initial.state.z=0.6:1.9:240"}


def without_timing(table: pa.Table) -> bytes:
    """The table's rows but for their wall times, as Parquet bytes (the rows' digest in the
    metadata leaves the wall times out too)."""
    sink = io.BytesIO()
    pq.write_table(table.drop_columns(list(TIMING_COLUMNS)).combine_chunks(), sink)
    return sink.getvalue()


def reference(grid: str, folder: Path) -> bytes:
    """The table of the sweep over ``grid`` run alone in ``folder``."""
    assert run_cli(*BALL, "--grid", grid, "--out", folder)[0] == 0
    return without_timing(pq.read_table(folder / "results.parquet"))


def start(grid: str, out: Path) -> subprocess.Popen:
    """The sweep over ``grid`` on an embedded Dask cluster of one worker, started in a new process:
    the cluster's start-up is the window in which the second sweep used to slip in."""
    argv = [a for a in BALL if a != "--in-process"]
    return subprocess.Popen(
        [sys.executable, "-m", "legsim.cli", *argv, "--workers", "1", "--grid", grid, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_two_different_sweeps_started_at_once_into_one_folder_one_is_refused(tmp_path):
    # Both passed the "already holds a sweep" check before either wrote sweep.json, and mixed
    # their rows: 388 of 600 wrong, exit 0 for both.
    out = tmp_path / "shared"
    runs = {name: start(grid, out) for name, grid in GRIDS.items()}
    ends = {name: proc.communicate(timeout=300) for name, proc in runs.items()}
    codes = {name: proc.returncode for name, proc in runs.items()}
    assert sorted(codes.values()) == [0, 2], ends
    winner = next(name for name, code in codes.items() if code == 0)
    loser = next(name for name, code in codes.items() if code == 2)
    assert "another sweep is running in this folder" in ends[loser][1] or "already holds a sweep" in ends[loser][1], (
        ends[loser]
    )
    assert without_timing(pq.read_table(out / "results.parquet")) == reference(GRIDS[winner], tmp_path / "alone")
    assert sorted(p.name for p in out.iterdir()) == ["results.parquet", "sweep.json"]


def test_two_identical_sweeps_started_at_once_give_the_sweeps_table(tmp_path):
    out = tmp_path / "shared"
    runs = [start(GRIDS["a"], out), start(GRIDS["a"], out)]
    ends = [proc.communicate(timeout=300) for proc in runs]
    codes = sorted(proc.returncode for proc in runs)
    assert codes in ([0, 0], [0, 2]), ends
    for proc, (_, err) in zip(runs, ends, strict=True):
        if proc.returncode == 2:
            assert "another sweep is running in this folder" in err or "already holds a sweep" in err, err
    assert without_timing(pq.read_table(out / "results.parquet")) == reference(GRIDS["a"], tmp_path / "alone")


def test_a_running_sweep_holds_its_folder_and_leaves_no_lock_behind(tmp_path):
    out = tmp_path / "s"
    seen = []

    def batch(spec, items):
        from legsim.sweep.tasks import run_batch

        if not seen:
            seen.append(run_cli(*BALL, "--grid", GRIDS["b"], "--out", out))
            seen.append(run_cli(*BALL, "--grid", GRIDS["a"], "--out", out, "--resume"))
        return run_batch(spec, items)

    import legsim.sweep.runner as runner

    real, runner.run_batch = runner.run_batch, batch
    try:
        assert run_cli(*BALL, "--grid", GRIDS["a"], "--out", out)[0] == 0
    finally:
        runner.run_batch = real
    for code, _, err in seen:
        assert code == 2 and f"--out {out}: another sweep is running in this folder (process {os.getpid()})" in err
    assert not (out / LOCK).exists()


def test_a_sweep_whose_engine_cannot_start_leaves_no_folder(tmp_path):
    argv = [a for a in BALL if a != "--in-process"]
    code, _, err = run_cli(*argv, "--grid", GRIDS["a"], "--out", tmp_path / "a" / "b", "--scheduler", "x:1:2")
    assert code == 2 and "--scheduler 'x:1:2': not a Dask scheduler address" in err
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def finished(tmp_path) -> Path:
    """A finished 240-row sweep's folder."""
    out = tmp_path / "done"
    assert run_cli(*BALL, "--grid", GRIDS["a"], "--out", out)[0] == 0
    return out


def resume(out: Path) -> tuple[int, str]:
    code, _, err = run_cli(*BALL, "--grid", GRIDS["a"], "--out", out, "--resume")
    return code, err


def rewrite(path: Path, table: pa.Table) -> None:
    pq.write_table(table, path)


def test_resume_accepts_the_sweeps_own_table_and_runs_nothing(finished):
    before = pq.read_table(finished / "results.parquet")
    code, _, _ = run_cli(*BALL, "--grid", GRIDS["a"], "--out", finished, "--resume", "--json")
    assert code == 0 and pq.read_table(finished / "results.parquet").equals(before)


def test_resume_refuses_a_foreign_table_with_only_an_index_column(finished):
    # It was taken for 240 finished rows, all null, exit 0.
    rewrite(finished / "results.parquet", pa.table({"index": pa.array(range(240), pa.int64())}))
    code, err = resume(finished)
    assert code == 2 and f"--resume: {finished / 'results.parquet'} was not written by this sweep" in err


@pytest.mark.parametrize(
    "change, message",
    [
        ("other_sweep", "was not written by this sweep"),
        ("drop_column", "lacks or changes this sweep's columns ['final_state']"),
        ("out_of_range", "has row index 240, outside 0..239"),
        ("negative", "has row index -1, outside 0..239"),
        ("repeated", "repeats row 3"),
        ("edited", "was changed after this sweep wrote it: its rows do not match their digest"),
    ],
)
def test_resume_refuses_a_table_of_another_schema_sweep_or_indices(finished, change, message):
    path = finished / "results.parquet"
    table = pq.read_table(path)
    index = table.column("index").to_pylist()
    if change == "other_sweep":
        table = table.replace_schema_metadata({"legsim.sweep": "0" * 64})
    elif change == "drop_column":
        table = table.drop_columns(["final_state"])
    elif change == "edited":  # same schema, one value changed (found by the tables' fuzzer)
        status = table.column("status").to_pylist()
        status[5] = "max_transitions"
        table = table.set_column(table.column_names.index("status"), "status", pa.array(status, pa.string()))
    elif change in ("out_of_range", "negative", "repeated"):
        index[5] = {"out_of_range": 240, "negative": -1, "repeated": 3}[change]
        table = table.set_column(0, pa.field("index", pa.int64(), nullable=False), pa.array(index, pa.int64()))
    rewrite(path, table)
    code, err = resume(finished)
    assert code == 2 and f"--resume: {path} " in err and message in err, err


def test_a_table_with_a_flipped_bit_is_refused_or_read_unchanged(finished, tmp_path):
    """40 bits flipped at random positions, one at a time: each copy is refused naming the table
    (page checksums, the rows' digest, Parquet's own structure), or resumed to the same rows."""
    import random
    import shutil

    reference = without_timing(pq.read_table(finished / "results.parquet"))
    raw = (finished / "results.parquet").read_bytes()
    rng = random.Random(11)
    refused = 0
    for k in range(40):
        copy = tmp_path / f"copy{k}"
        shutil.copytree(finished, copy)
        data = bytearray(raw)
        data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        (copy / "results.parquet").write_bytes(bytes(data))
        code, err = resume(copy)
        if code == 2:
            assert err.startswith(f"legsim: error: --resume: {copy / 'results.parquet'} ") and err.count("\n") == 1
            refused += 1
        else:
            assert code == 0 and without_timing(pq.read_table(copy / "results.parquet")) == reference, err
    assert refused >= 20


@pytest.mark.parametrize(
    "text, message",
    [
        # 10,000 deep is past Python's recursion limit, and within the bound on a manifest's size.
        ("[" * 10_000 + "]" * 10_000, "nested more than 64 levels deep"),
        ('{"scene": "bouncing_ball"}', "lacks ['format', 'digest', 'spec']"),
        ("not json", "Expecting value"),
        ('{"format": "legsim-sweep-0", "digest": "", "spec": {}}', "its format is 'legsim-sweep-0'"),
    ],
)
def test_resume_refuses_a_manifest_that_is_no_manifest_of_this_legsim(finished, text, message):
    # A manifest nested 100,000 deep raised RecursionError: an internal error.
    (finished / "sweep.json").write_text(text)
    code, err = resume(finished)
    assert code == 2 and f"--resume: {finished / 'sweep.json'} is not a sweep manifest of this legsim" in err
    assert message in err and "internal error" not in err


def test_resume_refuses_a_manifest_whose_content_does_not_match_its_digest(finished):
    manifest = json.loads((finished / "sweep.json").read_text())
    manifest["spec"]["seed"] = 1
    (finished / "sweep.json").write_text(json.dumps(manifest))
    code, err = resume(finished)
    assert code == 2 and "sweep.json is damaged: its specification does not match its digest" in err


def test_a_manifest_far_larger_than_this_sweeps_is_refused_unread(finished):
    # A 300 MB manifest holding a list of 150 million numbers was parsed before its grid was
    # counted: 2.9 GB resident and 4 min 45 s to the error. This one is 30 MB.
    manifest = json.loads((finished / "sweep.json").read_text())
    manifest["spec"]["grid"][0]["values"] = "VALUES"
    numbers = ",".join(["0"] * 15_000_000)
    (finished / "sweep.json").write_text(json.dumps(manifest).replace('"VALUES"', f"[{numbers}]"))
    assert (finished / "sweep.json").stat().st_size > 30_000_000
    began = time.monotonic()
    code, err = resume(finished)
    assert code == 2 and f"--resume: {finished / 'sweep.json'}: larger than 65536 bytes" in err, err
    assert time.monotonic() - began < 10


def sweep_table_like(finished: Path, columns: dict[str, pa.Array]) -> pa.Table:
    """A table of the finished sweep's schema and digest whose columns are ``columns`` (the
    others null): what a crafted file may claim to be."""
    own = pq.read_table(finished / "results.parquet")
    rows = len(next(iter(columns.values())))
    arrays = [columns.get(f.name, pa.nulls(rows, f.type)) for f in own.schema]
    return pa.Table.from_arrays(arrays, schema=own.schema)


def test_a_table_of_more_rows_than_variations_is_refused_before_its_rows_are_read(finished):
    # A file of a few kilobytes may hold 10^9 repeated indices (8 GB once read).
    crafted = sweep_table_like(finished, {"index": pa.array(np.zeros(1_000_000, np.int64))})
    pq.write_table(crafted, finished / "results.parquet")
    code, err = resume(finished)
    assert code == 2 and "results.parquet holds 1000000 rows, more than this sweep's 240 variations" in err, err


def test_a_table_whose_rows_unpack_to_more_than_a_rows_bytes_is_refused(finished):
    huge = pa.array(["x" * (8 << 20)], pa.string())
    crafted = sweep_table_like(finished, {"index": pa.array([0], pa.int64()), "error": huge})
    pq.write_table(crafted, finished / "results.parquet", compression="zstd")
    assert (finished / "results.parquet").stat().st_size < 100_000
    code, err = resume(finished)
    assert code == 2 and "results.parquet unpacks to" in err and "more than the 1048576 bytes a row" in err, err


def test_resume_refuses_a_table_that_is_a_folder_or_fifo(finished):
    (finished / "results.parquet").unlink()
    os.mkfifo(finished / "results.parquet")
    code, err = resume(finished)
    assert code == 2 and "results.parquet is a FIFO, not a table this sweep wrote" in err


def test_a_grid_of_a_billion_values_is_refused_at_once_without_its_memory(tmp_path):
    # Its values were made before the count was checked: 7.45 GiB asked for (3 GB in 5 s).
    limit = 2 << 30

    def bounded() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    began = time.monotonic()
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "legsim.cli",
            *BALL,
            "--grid",
            "initial.state.z=0:1:1000000000",
            "--out",
            tmp_path / "x",
        ],
        preexec_fn=bounded,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr == "legsim: error: 1000000000 variations, more than the limit 1e+07: check the grid sizes\n"
    assert time.monotonic() - began < 30
    with pytest.raises(legsim.sweep.spec.SweepError, match="1000 x 1000 x 1000 variations"):
        legsim.sweep("bouncing_ball", grid={f"a.{k}": (0.0, 1.0, 1000) for k in "xyz"}, in_process=True)
