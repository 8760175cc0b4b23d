"""``legsim bench``: work-precision sweeps, the robots, the orbit search against scipy, integrator overhead."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..bench.names import CASE_NAMES, ROBOT_CASES, ROBOT_CONTROLLED
from ..tables import add_format_argument

NAME = "bench"
HELP = "benchmarks: work-precision against Paoli-Schatzman and solve_ivp, robots, orbit search, integrator overhead"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bench", metavar="BENCH", required=True)
    wp = sub.add_parser(
        "work-precision",
        help="error against wall time for every method on one case (or every case's short form)",
        description="Sweep h, eps, tolerances and methods on one case, measure the error against "
        "the reference and the wall time, write CASE.csv and CASE.png, print a table "
        "and the speed targets: MET or MISSED by the ratio measured at the target's "
        "error, NOT COMPARABLE where the baseline never reaches it (its sweep is "
        "extended first, within --extend-budget). With --quick and no --case: every case's "
        "short form, one after the other.",
    )
    wp.add_argument(
        "--case",
        choices=CASE_NAMES,
        default=None,
        help="the case (required without --quick: a full sweep takes minutes per case)",
    )
    wp.add_argument("--out", default=None, help="folder for CASE.csv and CASE.png (default: bench-out)")
    wp.add_argument(
        "--quick", action="store_true", help="short run, small sweep (seconds; for CI); without --case, every case"
    )
    wp.add_argument(
        "--repeats", type=int, default=None, help="timed repeats per run, median kept (default 3, 1 with --quick)"
    )
    wp.add_argument(
        "--rho-points",
        type=int,
        default=None,
        help="times of the rho grid (default 400, 40 with --quick, 0 for pronk and double-pendulum; 0 skips rho)",
    )
    wp.add_argument(
        "--methods",
        default=None,
        help="comma-separated CSV method names to keep (e.g. relaxed-rk4,relaxed-rk4-zeno,ps; "
        "-zeno: Zeno continuation, oscillator-ex2 only)",
    )
    wp.add_argument(
        "--extend-budget",
        type=float,
        default=None,
        metavar="SECONDS",
        help="wall time the bench may spend refining a baseline's sweep (PS's step, solve_ivp's "
        "tolerance) towards a target level it never reached (default 60, 3 with --quick; 0: none)",
    )
    wp.add_argument("--no-figure", action="store_true", help="write the CSV only")
    wp.add_argument("--quiet", action="store_true", help="print only the table and the targets")
    add_format_argument(wp)
    tg = sub.add_parser(
        "targets",
        help="the table and the targets again, from a CSV written before",
        description="Read OUT/CASE.csv and print its table and the speed targets (no run).",
    )
    tg.add_argument("--case", required=True, choices=CASE_NAMES, help="the case whose CSV to read")
    tg.add_argument("--out", default="bench-out", help="folder holding CASE.csv (default: bench-out)")
    tg.add_argument(
        "--quick", action="store_true", help="judge the quick form's targets (a CSV of `work-precision --quick`)"
    )
    add_format_argument(tg)
    rb = sub.add_parser(
        "robots",
        help="the robots on the compiled path against solve_ivp, and the cost limit",
        description="Compass gait and rimless wheel (Drake's parameters, on their limit cycles), "
        "pronk and double pendulum: compiled relaxed runs, the Python path's best and "
        "solve_ivp over their knobs; the fastest of each below errors 1e-4, 1e-6, 1e-8 "
        "and their ratios; the cost of a field evaluation against a bare C++ aba. "
        "The controlled runners slip-raibert and quadruped-run run only when named "
        "(--case): controlled runs take the Python path, so they have no compiled family. "
        "Writes OUT/robots-CASE.csv and .png.",
    )
    rb.add_argument(
        "--case",
        action="append",
        choices=ROBOT_CASES + ROBOT_CONTROLLED,
        default=None,
        help=f"a robot case (repeatable; default: the uncontrolled {', '.join(ROBOT_CASES)}; "
        f"the controlled {', '.join(ROBOT_CONTROLLED)} run only when named)",
    )
    rb.add_argument("--out", default="bench-out", help="folder for the CSV files and figures (default: bench-out)")
    rb.add_argument("--quick", action="store_true", help="short runs, small sweep (for CI)")
    rb.add_argument("--repeats", type=int, default=5, help="timed repeats per run, median kept (default 5)")
    rb.add_argument("--no-figure", action="store_true", help="write the CSV files only")
    rb.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    add_format_argument(rb)
    ob = sub.add_parser(
        "orbit",
        help="legsim orbit against a scipy Newton iteration at the same accuracy",
        description="The scene's orbit search (what `legsim orbit SCENE` runs) against Newton's "
        "method on a solve_ivp DOP853 step map with events (forward-difference "
        "Jacobian), both measured against a reference fixed point at rtol = atol = "
        "1e-12; the baseline at the loosest tolerance reaching legsim's error; median "
        "wall times of interleaved repeats and their ratio.",
    )
    ob.add_argument("--scene", default="compass_gait", help="a scene with an orbit section (default: compass_gait)")
    ob.add_argument("--repeats", type=int, default=7, help="interleaved timed repeats, median kept (default 7)")
    ob.add_argument("--json", action="store_true", help="print the measurements as JSON")
    ob.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    ov = sub.add_parser(
        "overhead",
        help="integrator cost per step beyond the model's own evaluations",
        description="Steps per second, shares of time in fields, guards and resets, overhead per "
        "step in field evaluations, and evaluations per transition for halve vs aim.",
    )
    ov.add_argument("--quick", action="store_true", help="shorter runs")
    ov.add_argument("--json", action="store_true", help="print the measurements as JSON")
    # Its report is a paragraph of measurements around one table: no csv or markdown form.
    ov.add_argument("--format", choices=("text", "json"), default="text", help="text (default) or json, as --json")


def run(args: argparse.Namespace) -> int:
    runners = {"overhead": _overhead, "orbit": _orbit, "robots": _robots, "targets": _targets}
    return runners.get(args.bench, _work_precision)(args)


def _log(args: argparse.Namespace) -> Any:
    """Progress lines on stderr, or None with --quiet."""
    return None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))


def _overhead(args: argparse.Namespace) -> int:
    from ..bench import overhead

    return overhead.main(quick=args.quick, as_json=args.json, fmt=args.format)


def _orbit(args: argparse.Namespace) -> int:
    from ..bench import orbit
    from ..bench.cases import BenchError

    if args.repeats < 1:
        raise BenchError(f"--repeats must be >= 1, got {args.repeats}")
    return orbit.main(args.scene, repeats=args.repeats, as_json=args.json, log=_log(args))


def _robots(args: argparse.Namespace) -> int:
    from ..bench import robots
    from ..bench.cases import BenchError

    cases = args.case or list(robots.CASES)
    unknown = [c for c in cases if c not in robots.ALL_CASES]
    if unknown:
        raise BenchError(f"--case must name {', '.join(robots.ALL_CASES)} (got {unknown})")
    if args.repeats < 1:
        raise BenchError(f"--repeats must be >= 1, got {args.repeats}")
    return robots.main(cases, quick=args.quick, out=args.out, repeats=args.repeats, figure=not args.no_figure,
                       log=_log(args), fmt=args.format)  # fmt: skip


def _targets(args: argparse.Namespace) -> int:
    from ..bench.cases import BenchError, targets_for
    from ..bench.targets import evaluate_targets, format_targets
    from ..bench.work_precision import read_rows, rows_table
    from ..tables import print_report

    path = Path(args.out) / f"{args.case}.csv"
    rows = read_rows(path)
    others = sorted({row.case for row in rows} - {args.case})
    if others:
        raise BenchError(
            f"{path}: holds rows of case(s) {others}, not of --case {args.case}; its targets would not apply"
        )
    verdicts = format_targets(evaluate_targets(rows, targets_for(args.case, args.quick))) or "- none for this case"
    print_report([replace(rows_table(rows), title=args.case), "", "targets:", verdicts], args.format)
    return 0


def _check_work_precision(args: argparse.Namespace) -> None:
    from ..bench.cases import BenchError

    if args.repeats is not None and args.repeats < 1:
        raise BenchError(f"--repeats must be >= 1, got {args.repeats}")
    if args.rho_points is not None and args.rho_points < 0:
        raise BenchError(f"--rho-points must be >= 0, got {args.rho_points}")
    if args.extend_budget is not None and not 0 <= args.extend_budget < float("inf"):
        raise BenchError(f"--extend-budget must be a finite number of seconds >= 0, got {args.extend_budget}")
    if args.case is None and not args.quick:
        raise BenchError(
            f"bench work-precision needs --case CASE ({', '.join(CASE_NAMES)}): a full sweep takes minutes "
            f"per case; --quick without --case runs every case's short form"
        )


def _work_precision(args: argparse.Namespace) -> int:
    from ..bench.cases import BenchError
    from ..bench.targets import format_targets
    from ..bench.work_precision import rows_table, run_case
    from ..tables import Table, print_report

    _check_work_precision(args)
    methods = None if args.methods is None else [m.strip() for m in args.methods.split(",") if m.strip()]
    cases = [args.case] if args.case is not None else list(CASE_NAMES)
    report: list[str | Table] = []
    for name in cases:
        result = run_case(name, quick=args.quick, out=args.out or "bench-out", repeats=args.repeats,
                          rho_points=args.rho_points, figure=not args.no_figure, log=_log(args), methods=methods,
                          extension_budget=args.extend_budget)  # fmt: skip
        if not result.rows:
            continue
        report += [
            *([""] if report else []),
            f"# {result.case.name}: {result.case.description}",
            f"# reference: {result.case.reference_note}",
            replace(rows_table(result.rows), title=result.case.name),
            "",
            "targets:",
            format_targets(result.targets) or "- none for this case",
            "",
            f"wrote {result.csv_path}" + (f" and {result.figure_path}" if result.figure_path else ""),
        ]
    if not report:
        raise BenchError(f"no run of case {' or '.join(cases)} matches --methods {args.methods}")
    print_report(report, args.format)
    return 0
