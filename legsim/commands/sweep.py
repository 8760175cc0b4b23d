"""``legsim sweep SCENE``: run variations of a scene on Dask, one Parquet row per variation.

Variations are grids (``--grid KEY=LO:HI:N`` or ``KEY=V1,V2,...``) and random draws
(``--random KEY=LO:HI --samples N --seed S``) over any scene field. Each variation runs the
scene to its t_final (its run summary), or with ``--walk`` step by step until it falls or
converges onto the scene's gait (at most ``--max-steps``), and with ``--orbit`` searches its
periodic orbit. The batches run on an embedded Dask cluster (``--workers N``, default one
process per core), on a running scheduler (``--scheduler ADDRESS`` or
``DASK_SCHEDULER_ADDRESS``), or in this process (``--in-process``). Rows stream to
``--out DIR/results.parquet`` (``--resume`` continues an interrupted sweep); a two-field grid
also draws ``basin.png`` (walks) and ``stability.png`` (orbits).

Exit codes: 0 when every variation has a result; 3 when some failed or timed out (their rows
say why); 2 for errors in the scene, the axes or the options.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

NAME = "sweep"
HELP = "run variations of a scene (grids, random draws) on Dask: basins of attraction, stability maps"
#: Random draws of a --random field when --samples is not given.
RANDOM_SAMPLES = 100


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene file (.toml) or bundled scene name")
    axes = parser.add_argument_group("variations")
    axes.add_argument(
        "--grid",
        metavar="KEY=LO:HI:N",
        action="append",
        default=[],
        help="a grid over a scene field: N values from LO to HI, or KEY=V1,V2,... (repeat for a "
        "product), e.g. --grid initial.state.thetad=-2:2:101",
    )
    axes.add_argument(
        "--random",
        metavar="KEY=LO:HI",
        action="append",
        default=[],
        help="uniform random draws of a scene field in [LO, HI) (with --samples, --seed)",
    )
    axes.add_argument("--samples", type=int, default=None, metavar="N", help=f"random draws (default {RANDOM_SAMPLES})")
    axes.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the random draws (default 0)")
    axes.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a scene field in every variation (as legsim run --set)",
    )
    measures = parser.add_argument_group("measures")
    measures.add_argument(
        "--walk",
        action="store_true",
        help="walk each variation step by step until it falls, stops or converges onto the "
        "scene's gait ([orbit] section) instead of running it to t_final",
    )
    measures.add_argument("--max-steps", type=int, default=20, metavar="K", help="steps of a walk (default 20)")
    measures.add_argument(
        "--tol",
        type=float,
        default=1e-3,
        help="a walk has converged within this distance of the gait (state units, default 1e-3)",
    )
    measures.add_argument(
        "--orbit",
        action="store_true",
        help="search each variation's periodic orbit: period, Floquet multipliers, stability",
    )
    measures.add_argument("--no-run", action="store_true", help="no run to t_final (with --orbit: orbits only)")
    measures.add_argument(
        "--orbit-guess",
        choices=["scene", "run"],
        default="scene",
        help="the orbit search's initial guess: the scene's [initial] state and orbit.guess (default), "
        "or the state and controller memory at the last crossing of the section in the variation's run",
    )
    measures.add_argument(
        "--measure",
        dest="measures",
        metavar="KIND:COORD[:FROM]",
        action="append",
        default=[],
        help="a column measured on each run over [FROM, t_end] (FROM default t0): mean_rate (e.g. "
        "mean_rate:x:5, the mean forward speed after 5 s) or max_abs (e.g. max_abs:pitch); repeatable",
    )
    measures.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds one variation may take; its row then says timeout (default: no limit)",
    )
    engine = parser.add_argument_group("where it runs")
    engine.add_argument(
        "--out", required=True, metavar="DIR", help="folder for results.parquet, sweep.json and the maps"
    )
    engine.add_argument("--resume", action="store_true", help="continue the sweep in --out: run only missing rows")
    engine.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes of the embedded Dask cluster (default: one per core)",
    )
    engine.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="a running Dask scheduler, e.g. tcp://127.0.0.1:8786 (default: $DASK_SCHEDULER_ADDRESS)",
    )
    engine.add_argument(
        "--connect-timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds to wait at each step of reaching --scheduler: connection, first answer, first worker; "
        "during the sweep, without a finished batch before its answer is asked for (default 20)",
    )
    engine.add_argument("--in-process", action="store_true", help="no Dask: run the variations in this process")
    engine.add_argument(
        "--batch", type=int, default=None, metavar="N", help="variations per task (default: sized to about 2 s of work)"
    )
    parser.add_argument("--json", action="store_true", help="print the sweep's summary as one JSON object")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from ..sweep.runner import run_sweep
    from ..sweep.spec import SweepError, SweepSpec, check_count, grid_size, parse_grid, parse_random, scene_reference

    if args.random and args.samples is None:
        args.samples = RANDOM_SAMPLES
    if args.samples is not None and not args.random:
        raise SweepError("--samples needs a --random field to draw")
    if args.samples is not None and args.samples < 1:
        raise SweepError(f"--samples must be an integer >= 1, got {args.samples}")
    if args.walk and args.no_run:
        raise SweepError("--walk and --no-run exclude each other (a walk is the run)")
    # Counted before any grid's values are made: a grid of 10^9 values is refused at once.
    check_count([grid_size(g) for g in args.grid], args.samples if args.random else 1)
    spec = SweepSpec(
        scene=scene_reference(args.scene),
        overrides=tuple(args.overrides),
        grid=tuple(parse_grid(g) for g in args.grid),
        random=tuple(parse_random(r) for r in args.random),
        samples=args.samples if args.random else 1,
        seed=args.seed,
        run="walk" if args.walk else ("none" if args.no_run else "scene"),
        orbit=args.orbit,
        max_steps=args.max_steps,
        tol=args.tol,
        timeout=args.timeout,
        measures=tuple(args.measures),
        orbit_guess=args.orbit_guess,
    )
    log = None if (args.quiet or args.json) else (lambda line: print(f"legsim sweep: {line}", file=sys.stderr))
    result = run_sweep(
        spec,
        out=args.out,
        resume=args.resume,
        workers=args.workers,
        scheduler=args.scheduler,
        in_process=args.in_process,
        batch_size=args.batch,
        progress=not (args.quiet or args.json),
        log=log,
        connect_timeout=args.connect_timeout,
    )
    summary = result.summary()
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(format_summary(summary))
    failed = {k: v for k, v in summary["task_status"].items() if k != "done"}
    if failed:
        example = next(
            r for r in result.table.select(["index", "task_status", "error"]).to_pylist() if r["task_status"] != "done"
        )
        print(
            f"legsim: {sum(failed.values())} of {summary['variations']} variations have no result: {failed}; "
            f"e.g. row {example['index']}: {example['error']}",
            file=sys.stderr,
        )
        return 3
    return 0


def format_summary(s: dict[str, Any]) -> str:
    """The text report of ``legsim sweep``."""
    lines = [
        f"{s['scene']}: {s['variations']} variations ({s['computed']} run now, {s['resumed']} already done) "
        f"in {s['elapsed_s']:.1f} s on {s['where']} (started in {s['startup_s']:.1f} s)",
        "tasks: " + ", ".join(f"{k} {v}" for k, v in sorted(s["task_status"].items())),
    ]
    for column, label in (
        ("outcome", "walks"),
        ("status", "runs"),
        ("orbit_status", "orbit searches"),
        ("orbit_stable", "stable orbits"),
    ):
        if s.get(column):
            lines.append(f"{label}: " + ", ".join(f"{k} {v}" for k, v in sorted(s[column].items())))
    warned = {column: count for column, count in s.get("warned", {}).items() if count}
    if warned:
        lines.append(
            "with warnings (see the column): "
            + ", ".join(f"{count} rows in {column}" for column, count in warned.items())
        )
    if s["results"]:
        lines.append(f"wrote {s['results']}")
    for kind, path in s["figures"].items():
        lines.append(f"wrote {path} ({kind.replace('_', ' ')})")
    return "\n".join(lines)
