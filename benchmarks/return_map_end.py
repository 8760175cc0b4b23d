"""Orbit searches whose return-map runs end soon after the return, against runs to the map's
whole horizon, interleaved in one process.

``legsim.orbits.ReturnMap`` passes ``simulate`` an ``until`` that ends each run at the loop's
first hand-back after the return; without it a run goes on to the horizon (1.5 times the last
return time). This script runs a scene's orbit search (as ``legsim orbit SCENE`` does) both ways,
alternating which goes first, prints each search's wall time (s), the ratio of the medians
(> 1: ending at the return is faster) and whether the two searches' JSON reports are identical.
Print ``uptime`` beside the numbers.

    .venv/bin/python benchmarks/return_map_end.py quadruped_pronk_forward [--pairs 2]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

from legsim.orbits import find_orbit
from legsim.orbits.returns import ReturnMap
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene

HERE = Path(__file__).resolve().parents[1]
WHOLE, ENDED = "whole horizon", "ends at the return"


def search(scene: Any, ended: bool, returned: Any) -> tuple[float, dict[str, Any]]:
    """One orbit search (wall time in s, its JSON report), the runs ended at the return or not."""
    ReturnMap._returned = returned if ended else (lambda self, so_far: False)  # type: ignore[method-assign]
    try:
        settings = problem_from_scene(scene)
        start = time.perf_counter()
        result = find_orbit(settings.problem, settings.guess, **settings.solver)
        return time.perf_counter() - start, result.to_json()
    finally:
        ReturnMap._returned = returned  # type: ignore[method-assign]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="a bundled scene with an [orbit] section")
    parser.add_argument("--pairs", type=int, default=2, help="searches each way (default 2)")
    args = parser.parse_args()
    scene = load_scene(HERE / "scenarios" / f"{args.scene}.toml")
    returned = ReturnMap._returned
    times: dict[str, list[float]] = {WHOLE: [], ENDED: []}
    reports: dict[str, dict[str, Any]] = {}
    for pair in range(args.pairs):
        for label in (WHOLE, ENDED) if pair % 2 == 0 else (ENDED, WHOLE):
            wall, report = search(scene, label == ENDED, returned)
            times[label].append(wall)
            reports.setdefault(label, report)
    for label, walls in times.items():
        print(f"{label:20s} " + " ".join(f"{w:.2f}" for w in walls) + " s")
    ratio = statistics.median(times[WHOLE]) / statistics.median(times[ENDED])
    print(f"{args.scene}: whole horizon / ended at the return, medians: {ratio:.3f}")
    print(f"identical reports: {reports[WHOLE] == reports[ENDED]}")


if __name__ == "__main__":
    main()
