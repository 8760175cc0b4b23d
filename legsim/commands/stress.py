"""``legsim stress``: run the stress suite (``legsim.stress``) and print its table.

Each case runs one of the hard cases of hybrid simulation (Zeno, grazing, simultaneous guards,
resting contact, extremes) and checks invariants that can fail. ``--quick`` runs the short form
(the one CI runs); without it the full form runs longer horizons and more refinements.
``--json`` prints a list of objects with at least ``name`` and ``passed``; ``--format`` prints
the table as text, CSV, Markdown or JSON (``legsim.tables``).

Exit codes: 0 when every selected case passes, 1 when one fails (the table says which check
and why), 2 for a usage error (no case matches the selection).
"""

from __future__ import annotations

import argparse
import json
import sys

from ..tables import add_format_argument

NAME = "stress"
HELP = "run the stress suite (Zeno, grazing, simultaneous guards, resting contact, extremes) and check its invariants"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="the short form of every case (the one CI runs)")
    parser.add_argument("--json", action="store_true", help="print a JSON list of results (name, passed, checks, ...)")
    add_format_argument(parser)
    parser.add_argument(
        "--case",
        dest="cases",
        metavar="NAME",
        action="append",
        default=[],
        help="run only the cases whose name contains NAME, or the group NAME "
        "(zeno, grazing, simultaneous, resting, extremes); repeatable",
    )
    parser.add_argument("--list", action="store_true", help="list the cases and exit")


def run(args: argparse.Namespace) -> int:
    from ..errors import LegsimError
    from ..progress import counting
    from ..stress import CASES, report, run_suite, select
    from ..tables import output_width, print_report

    if args.json and args.format not in ("text", "json"):
        raise LegsimError(f"--json prints JSON; it cannot be given with --format {args.format}")
    chosen = select(args.cases)
    if not chosen:
        raise LegsimError(f"no stress case matches {args.cases}; cases: {[c.name for c in CASES]}")
    if args.list:
        width = max(len(c.name) for c in chosen)
        for c in chosen:
            print(f"{c.name:<{width}}  {c.group:<12}  {c.description}")
        return 0
    show = sys.stderr.isatty() and not args.json
    with counting(len(chosen), "stress", enabled=show) as advance:

        def progress(case, result) -> None:
            if show:
                print(
                    f"  {case.name}: {'pass' if result.passed else 'FAIL'} ({result.wall_time:.1f} s)", file=sys.stderr
                )
            advance(1)

        results = run_suite(quick=args.quick, names=args.cases, progress=progress)
    if args.json:
        print(json.dumps([r.to_dict() for r in results], allow_nan=False))
    else:
        title = f"legsim stress ({'quick' if args.quick else 'full'} form, {len(results)} cases)"
        print_report([title, *report(results, output_width(sys.stdout))], args.format)
    return 0 if all(r.passed for r in results) else 1
