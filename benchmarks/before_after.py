"""Work-precision of two checkouts, compared by their speed ratios to the baselines.

    .venv/bin/python benchmarks/before_after.py --before ../legsim-before [--case pronk ...]
        [--out bench-before-after] [--quick]

``--before`` is another checkout of legsim with its own ``.venv`` (``make install`` there): for
example the commit before a redesign. For every case it runs ``legsim bench work-precision``
in the other checkout and in this one, one after the other, and reads both CSVs. A checkout's
speed at an error level is the wall time of its fastest relaxed run reaching that level; its
ratio is the fastest baseline run (solve_ivp, and PS where the case has it) reaching the level
divided by that time. Both ratios are measured in their own process against a baseline timed in
the same process, so a busy machine scales both sides of each ratio alike; comparing the two
checkouts' ratios (after / before) then says whether the relaxed integrator got slower or faster
relative to a fixed reference. Times alone are printed too, but only the ratios are comparable
across the two runs. A second table compares like with like: over the configurations both
sweeps ran, the median after / before wall time of the relaxed runs, divided by that of the
baseline runs (which did not change) to take out the machine's drift between the two runs.

This is a benchmark, not a test: it prints a Markdown table (for the README) and asserts
nothing.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import subprocess
import sys
from pathlib import Path

CASES = ("oscillator-ex1", "oscillator-ex2", "bouncing-ball", "pronk", "double-pendulum")
LEVELS = (1e-3, 1e-5, 1e-7)
HERE = Path(__file__).resolve().parents[1]


def run_bench(checkout: Path, case: str, out: Path, quick: bool, reuse: bool) -> Path:
    """Run one checkout's work-precision bench on ``case``; the path of its CSV."""
    legsim = checkout / ".venv" / "bin" / "legsim"
    if not legsim.exists():
        raise SystemExit(f"before_after: {legsim} not found: run `make install` in {checkout}")
    if reuse and (out / f"{case}.csv").exists():
        return out / f"{case}.csv"
    out.mkdir(parents=True, exist_ok=True)
    command = [str(legsim), "bench", "work-precision", "--case", case, "--out", str(out), "--quiet"]
    if quick:
        command.append("--quick")
    subprocess.run(command, cwd=checkout, check=True, stdout=subprocess.DEVNULL)
    return out / f"{case}.csv"


def fastest(rows: list[dict[str, str]], level: float, relaxed: bool) -> float:
    """Wall time (s) of the fastest finished run reaching ``level``; inf when none does."""
    times = [
        float(row["wall_s"])
        for row in rows
        if (row["kind"] == "relaxed") == relaxed
        and row["status"] == "finished"
        and row["error"]
        and float(row["error"]) <= level
    ]
    return min(times, default=math.inf)


def ratios(csv_path: Path) -> dict[float, tuple[float, float]]:
    """Per level: (fastest relaxed wall s, baseline / relaxed ratio)."""
    with csv_path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    result = {}
    for level in LEVELS:
        relaxed, baseline = fastest(rows, level, True), fastest(rows, level, False)
        ratio = baseline / relaxed if math.isfinite(relaxed) and math.isfinite(baseline) else math.nan
        result[level] = (relaxed, ratio)
    return result


def config_key(row: dict[str, str]) -> tuple[str, ...]:
    return tuple(row[k] for k in ("method", "h", "eps", "tol", "max_step", "landing"))


def same_configurations(before_csv: Path, after_csv: Path) -> tuple[float, float, int]:
    """Over the configurations both sweeps ran (same method, h, eps, tolerance, largest step,
    landing): the median after / before wall-time ratio of the relaxed runs divided by that of
    the baseline runs (the machine's own drift between the two runs divided out), the same for
    the relaxed runs alone, and how many relaxed configurations were compared."""

    def rows(path: Path) -> dict[tuple[str, ...], dict[str, str]]:
        with path.open(newline="") as handle:
            return {config_key(row): row for row in csv.DictReader(handle) if row["status"] == "finished"}

    before, after = rows(before_csv), rows(after_csv)
    common = sorted(set(before) & set(after))
    changes = {k: float(after[k]["wall_s"]) / float(before[k]["wall_s"]) for k in common}
    relaxed = [change for k, change in changes.items() if after[k]["kind"] == "relaxed"]
    baseline = [change for k, change in changes.items() if after[k]["kind"] != "relaxed"]
    if not relaxed or not baseline:
        return math.nan, math.nan, len(relaxed)
    return statistics.median(relaxed) / statistics.median(baseline), statistics.median(relaxed), len(relaxed)


def cell(value: float, unit: str = "") -> str:
    return "-" if not math.isfinite(value) else f"{value:.3g}{unit}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, required=True, help="the other checkout (with its .venv)")
    parser.add_argument("--case", action="append", choices=CASES, help="cases (default: all five)")
    parser.add_argument("--out", type=Path, default=Path("bench-before-after"))
    parser.add_argument("--quick", action="store_true", help="the benches' short sweeps")
    parser.add_argument("--reuse", action="store_true", help="keep a CSV already in --out instead of running again")
    args = parser.parse_args(argv)
    print("| case | error <= | before: ms, ratio | after: ms, ratio | after / before ratio |")
    print("|---|---|---|---|---|")
    csvs = {}
    for case in args.case or CASES:
        before_csv = run_bench(args.before.resolve(), case, args.out.resolve() / "before", args.quick, args.reuse)
        after_csv = run_bench(HERE, case, args.out.resolve() / "after", args.quick, args.reuse)
        csvs[case] = (before_csv, after_csv)
        before, after = ratios(before_csv), ratios(after_csv)
        for level in LEVELS:
            (t0, r0), (t1, r1) = before[level], after[level]
            change = r1 / r0 if math.isfinite(r0) and math.isfinite(r1) else math.nan
            print(
                f"| {case} | {level:g} | {cell(t0 * 1e3)}, {cell(r0, 'x')} | {cell(t1 * 1e3)}, {cell(r1, 'x')} "
                f"| {cell(change)} |",
                flush=True,
            )
    print("\n| case | relaxed configurations | after / before wall time, relaxed | the same over the baseline's |")
    print("|---|---|---|---|")
    for case, (before_csv, after_csv) in csvs.items():
        normalised, raw, n = same_configurations(before_csv, after_csv)
        print(f"| {case} | {n} | {cell(raw)} | {cell(normalised)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
