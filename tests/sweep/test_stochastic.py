"""``legsim stochastic`` on the sweep engine: every execution has its own random stream, so
any subset, any batching and any cluster give the executions, and the numbers, of the serial
run."""

from __future__ import annotations

import json

import numpy as np

from legsim.cli import main
from legsim.scene import load_scene
from legsim.scene.stochastic import ensemble_from_scene
from legsim.stochastic import sample_ensemble, sample_generator
from legsim.sweep.engine import Engine
from legsim.sweep.stochastic import ensemble_on_engine
from legsim.systems.two_tanks import make_system as two_tanks


def same(a, b) -> bool:
    return (
        a.status == b.status
        and a.modes == b.modes
        and np.array_equal(a.times, b.times)
        and np.array_equal(a.final_state, b.final_state)
    )


def test_any_subset_of_an_ensemble_draws_the_same_executions():
    args = (two_tanks(), "q1", [1.0, 1.0], 6.3, 0.04, "euler")
    whole = sample_ensemble(*args, samples=12, seed=3, floor=1.0)
    part = sample_ensemble(*args, samples=12, seed=3, floor=1.0, indices=[11, 4, 7])
    assert all(same(p, whole.executions[k]) for p, k in zip(part.executions, [11, 4, 7], strict=True))
    # Independent streams: distinct executions differ, and the same seed gives the same draws.
    assert not np.array_equal(whole.executions[0].times, whole.executions[1].times)
    assert sample_generator(3, 5).random() == sample_generator(3, 5).random() != sample_generator(3, 6).random()


def test_batches_on_the_engine_give_the_serial_ensemble():
    scene = load_scene("two_tanks", ["stochastic.t_final=6.3"])
    serial = ensemble_from_scene(scene, {"samples": 10, "seed": 2})
    with Engine(in_process=True, batch_size=3) as engine:
        batched = ensemble_on_engine(scene, "two_tanks", {"samples": 10, "seed": 2}, engine)
    assert all(same(a, b) for a, b in zip(serial.executions, batched.executions, strict=True))
    assert batched.summary() == serial.summary()


def test_the_command_on_a_dask_cluster_prints_the_serial_numbers(capsys, tmp_path):
    argv = ["stochastic", "grazing", "--samples", "40", "--seed", "4", "--json"]
    assert main(argv) == 0
    serial = json.loads(capsys.readouterr().out)
    assert main([*argv, "--workers", "2", "--plot", str(tmp_path / "switching.png")]) == 0
    on_dask = json.loads(capsys.readouterr().out)
    assert on_dask.pop("outputs") == {"plot": str(tmp_path / "switching.png")}
    assert on_dask == serial
    assert (tmp_path / "switching.png").read_bytes()[:4] == b"\x89PNG"


def test_a_bad_plot_path_is_refused_before_sampling(capsys, tmp_path):
    assert main(["stochastic", "grazing", "--samples", "5", "--plot", str(tmp_path / "h.txt")]) == 2
    assert "--plot" in capsys.readouterr().err
