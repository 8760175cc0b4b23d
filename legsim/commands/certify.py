"""``legsim certify SCENE``: certify the transitions of a scene's execution (paper 004 Sec. V).

Settings come from the scene's ``[certify]`` section (``legsim.scene.certify.section_schema``: h,
method, pair, floor, alpha, max_refinements, t_final, max_transitions), with h, method and
t_final defaulting to ``[integrator]``. ``--json`` prints the list of verdicts, one object per
transition with ``source``, ``target``, ``time``, ``certified`` and ``reason`` (null, or one of
grazing, intersecting_guards, zeno, refinement_limit, t_final), and more.

Exit codes: 0 when every transition up to t_final is certified; 3 when one is refused (the
verdicts say why) or when ``max_transitions`` were certified before t_final (the rest is not
examined); 2 for errors in the scene or the arguments. Long runs draw a progress bar on a
terminal's stderr (not with --quiet).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from ..errors import LegsimError

NAME = "certify"
HELP = "certify that the true execution of a scene takes the computed transitions, or say why not"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene file (.toml) or bundled scene name")
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a scene field, e.g. --set certify.h=0.01 --set certify.max_refinements=8",
    )
    parser.add_argument("--json", action="store_true", help="print the list of per-transition verdicts as JSON")
    parser.add_argument(
        "--max-refinements",
        type=int,
        metavar="R",
        help="most refinements h := h / alpha (default: certify.max_refinements, else 6)",
    )
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from ..progress import progress_for
    from ..scene import load_scene
    from ..scene.certify import certify_scene

    if args.max_refinements is not None and args.max_refinements < 0:
        raise LegsimError(f"--max-refinements must be an integer >= 0, got {args.max_refinements}")
    scene = load_scene(args.scene, overrides=args.overrides)
    bar = progress_for(sys.stderr, enabled=not args.quiet, label=scene.name)
    try:
        cert = certify_scene(
            scene,
            {"max_refinements": args.max_refinements},
            progress=None if bar is None else _level_progress(bar, scene),
        )
    finally:
        if bar is not None:
            bar.close()
    if args.json:
        print(json.dumps(cert.to_list(), allow_nan=False))
    else:
        print(format_certificate(cert.summary()))
    if not cert.certified:
        refused = [tr for tr in cert.transitions if not tr.certified]
        if refused:
            print(
                f"legsim: transition {refused[0].index} ({refused[0].name}) not certified: {refused[0].reason}",
                file=sys.stderr,
            )
        else:
            print(f"legsim: certification incomplete: {cert.message}", file=sys.stderr)
        return 3
    return 0


def _level_progress(bar, scene):
    """progress(level, h, t) drawing the bar of the current refinement level, a few times a
    second once the run has lasted half a second."""
    import time

    from ..scene.certify import scene_settings
    from ..scene.error_bounds import start_time

    t0 = start_time(scene)
    t_final = scene_settings(scene)["t_final"]
    started = time.perf_counter()
    last = [0.0]

    def progress(level: int, h: float, t: float) -> None:
        now = time.perf_counter()
        if now - started < 0.5 or now - last[0] < 0.2:
            return
        last[0] = now
        bar.label = f"{scene.name} level {level} (h = {h:.3g})"
        bar(min(t, t_final), t0, t_final)

    return progress


def format_certificate(s: dict[str, Any]) -> str:
    """Human-readable verdicts (the text output of ``legsim certify``)."""
    hs = ", ".join(f"{lv['h']:g}" for lv in s["levels"])
    lines = [
        f"{s.get('scene', s['system'])}: certification to t = {s['t_final']:g} s with {s['method']} "
        f"(pair {s['pair']}, floor {s['floor']:g}), h = {hs}"
    ]
    if not s["transitions"]:
        lines.append("no transition up to t_final, and the error cone meets no guard")
    else:
        lines.append("   #  transition            source -> target            time (s)   verdict")
    for tr in s["transitions"]:
        verdict = "certified" if tr["certified"] else f"REFUSED: {tr['reason']}"
        if not tr["taken"]:
            verdict += " (not taken by the computed trajectory)"
        time = tr["time"] if tr["time"] is not None else math.nan
        lines.append(
            f"  {tr['index']:2d}  {tr['name']:<20s}  {tr['source'] + ' -> ' + tr['target']:<24s} "
            f"{time:12.9g}   {verdict}"
        )
    refused = [tr for tr in s["transitions"] if not tr["certified"]]
    if refused:
        lines.append(f"why: {refused[0]['detail']}")
        lines.append("later transitions are not examined: they would be certified only on an uncertain branch")
    elif not s.get("complete", True):
        lines.append(f"incomplete: {s['message']}")
    else:
        lines.append("all transitions certified" if s["transitions"] else "certified")
    return "\n".join(lines)
