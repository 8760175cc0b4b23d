"""The sweep engine's scaling and overhead on a compass-gait basin of attraction.

    .venv/bin/python benchmarks/sweep_scaling.py [--cells 10000] [--overhead-cells 1024] [--max-steps 20]

The basin: a square grid of initial states (stance and hip rates, ``initial.state.stanced`` in
[0.6, 1.6] rad/s and ``initial.state.hipd`` in [-2.0, 0.5] rad/s, the angles on the gait) of
the bundled ``compass_gait`` scene, each walked until it falls, stops or converges onto the
gait, at most ``--max-steps`` steps (``legsim sweep --walk``).

Printed, from runs in this one process's lifetime:

* speed-up: wall time of the whole basin on an embedded Dask cluster of 1 worker over that of
  2 workers (cluster start-up excluded, reported apart);
* engine overhead, two ways: (a) the 1-worker Dask sweep's wall time over the same sweep run in
  this process without Dask (``--in-process``), minus 1, on a ``--overhead-cells`` grid; (b)
  within each Dask run, 1 - (sum of the rows' own wall times) / (workers x wall time): the
  share of the workers' time spent on anything but the rows (scheduling, transfers, waiting);
* the machine's load average before and after, since other processes share its cores.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from pathlib import Path

import numpy as np

import legsim


def basin(cells: int, out: Path, max_steps: int, **engine) -> legsim.sweep.runner.SweepResult:
    side = max(2, round(math.sqrt(cells)))
    return legsim.sweep(
        "compass_gait",
        grid={"initial.state.stanced": (0.6, 1.6, side), "initial.state.hipd": (-2.0, 0.5, side)},
        walk=True,
        max_steps=max_steps,
        out=out,
        figures=False,
        **engine,
    )


def busy_share(result, workers: int) -> float:
    """Sum of the rows' wall times over workers x the sweep's wall time."""
    rows = float(np.sum(result.table.column("wall_time_s").to_numpy()))
    return rows / (workers * result.elapsed_s)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def report(label: str, result, workers: int) -> None:
    rows = float(np.sum(result.table.column("wall_time_s").to_numpy()))
    print(
        f"{label:28s} {result.table.num_rows:6d} cells  {result.elapsed_s:8.1f} s  "
        f"(start-up {result.startup_s:4.1f} s)"
        f"  rows' own time {rows:8.1f} s  busy {100 * busy_share(result, workers):5.1f}%  "
        f"outcomes {dict(sorted(result.counts('outcome').items()))}",
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=10_000, help="cells of the basin (a square grid)")
    parser.add_argument("--overhead-cells", type=int, default=1024, help="cells of the overhead comparison")
    parser.add_argument("--max-steps", type=int, default=20)
    args = parser.parse_args()
    print(f"load average before: {load()} (cores: {os.cpu_count()})", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        here = basin(args.overhead_cells, tmp / "o0", args.max_steps, in_process=True)
        report("overhead: in this process", here, 1)
        one_small = basin(args.overhead_cells, tmp / "o1", args.max_steps, workers=1)
        report("overhead: Dask, 1 worker", one_small, 1)
        one = basin(args.cells, tmp / "w1", args.max_steps, workers=1)
        report("basin: Dask, 1 worker", one, 1)
        two = basin(args.cells, tmp / "w2", args.max_steps, workers=2)
        report("basin: Dask, 2 workers", two, 2)
    print(f"load average after: {load()}")
    print(f"speed-up 2 workers / 1 worker: {one.elapsed_s / two.elapsed_s:.2f}x (target >= 1.8x)")
    print(
        "engine overhead (a), Dask 1 worker vs this process: "
        f"{100 * (one_small.elapsed_s / here.elapsed_s - 1):+.1f}% (target < 5%)"
    )
    print(
        f"engine overhead (b), workers' time not in rows: 1 worker {100 * (1 - busy_share(one, 1)):.1f}%, "
        f"2 workers {100 * (1 - busy_share(two, 2)):.1f}% (target < 5%)"
    )


if __name__ == "__main__":
    main()
