"""How accurate is each bundled scene's default run, and what does it cost?

    .venv/bin/python benchmarks/scene_accuracy.py [SCENE ...] [--markdown] [--repeat 3]

For every bundled scene (or the ones named) it prints the integrator settings, the wall time of
one run (the median of ``--repeat`` runs after a first one, which loads the model's compiled
code and is not counted), the estimated relative error of the final state that ``legsim run
SCENE --check-accuracy`` reports (against eps / 10 and h / 2, or tolerances / 10), and the same
error measured against a much finer run (the refinement applied twice: eps / 100, and h / 4 or
tolerances / 100), which checks that the estimate is honest. ``--markdown`` prints the table
as Markdown (the README's "Accuracy of the bundled scenes").

Relative errors are ``legsim.accuracy.ErrorEstimate.final_state_relative``: the largest
coordinate error over that coordinate's size along the run; "-" where the two runs end in
different modes (no state to compare). The status and the warnings are the default run's.

This is a benchmark, not a test: it prints numbers and asserts nothing
(tests/scenarios/test_default_accuracy.py asserts the bound).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from typing import Any

from legsim.accuracy import compare, refined
from legsim.scene import bundled_dir, load_scene


def settings_text(integrator: dict[str, Any]) -> str:
    """The settings that decide the accuracy, in one short string."""
    parts = [integrator["method"], f"h = {integrator['h']:g}", f"eps = {integrator['eps']:g}"]
    if integrator.get("rtol") is not None:
        parts.append(f"rtol = {integrator['rtol']:g}")
    if integrator.get("atol") is not None:
        parts.append(f"atol = {integrator['atol']:g}")
    if integrator.get("landing", "halve") != "halve":
        parts.append(f"landing {integrator['landing']}")
    if not integrator.get("continuation", True):
        parts.append("no continuation")
    return ", ".join(parts)


def measure(name: str, repeat: int) -> dict[str, Any]:
    """One row: settings, wall time (s), estimated and measured relative final-state error."""
    scene = load_scene(name)
    scene.simulate()  # loads the compiled code and warms the caches
    walls, run = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        run = scene.simulate()
        walls.append(time.perf_counter() - start)
    once = refined(scene.integrator)
    fine = dataclasses.replace(scene, integrator=once).simulate()
    finest = dataclasses.replace(scene, integrator=refined(once)).simulate()
    return {
        "scene": name,
        "settings": settings_text(scene.integrator),
        "wall_s": statistics.median(walls),
        "estimate": compare(run, fine).final_state_relative,
        "measured": compare(run, finest).final_state_relative,
        "status": run.status,
        "warnings": sorted({w.kind for w in run.warnings}),
    }


def _relative(value: float | None) -> str:
    return "-" if value is None else f"{value:.2g}"


def _cells(row: dict[str, Any]) -> list[str]:
    notes = ", ".join([*([] if row["status"] == "finished" else [str(row["status"])]), *row["warnings"]])
    return [
        row["scene"],
        row["settings"],
        f"{row['wall_s']:.3f}",
        _relative(row["estimate"]),
        _relative(row["measured"]),
        notes or "-",
    ]


HEADERS = ["scene", "settings", "wall (s)", "estimated rel. error", "vs eps/100", "status, warnings"]


def print_markdown(rows: list[dict[str, Any]]) -> None:
    print("| " + " | ".join(HEADERS) + " |")
    print("|" + "---|" * len(HEADERS))
    for row in rows:
        cells = _cells(row)
        print("| " + " | ".join([f"`{cells[0]}`", *cells[1:]]) + " |")


def print_table(rows: list[dict[str, Any]]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(*HEADERS)
    for row in rows:
        table.add_row(*_cells(row))
    Console().print(table)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", help="bundled scene names (default: all)")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per scene (default 3)")
    args = parser.parse_args(argv)
    names = args.scenes or sorted(p.stem for p in bundled_dir().glob("*.toml"))
    rows = [measure(name, max(1, args.repeat)) for name in names]
    (print_markdown if args.markdown else print_table)(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
