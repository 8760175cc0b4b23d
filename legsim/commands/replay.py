"""``legsim replay FILE.rrd``: print a recording's summary, open it, or animate it."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

NAME = "replay"
HELP = "load a .rrd recording: print its summary (--json), open the Rerun viewer (--spawn), write --html/--plot"

#: Transitions listed in the text summary before eliding the middle.
SHOWN = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="a recording written by `legsim run SCENE --rrd FILE.rrd`")
    parser.add_argument(
        "--json", action="store_true", help="print the summary as JSON (the keys of `legsim run --json`)"
    )
    parser.add_argument("--spawn", action="store_true", help="open the recording in the Rerun viewer (needs a display)")
    parser.add_argument(
        "--html", metavar="OUT.html", help="write a self-contained meshcat animation of the recorded robot"
    )
    parser.add_argument(
        "--html-camera",
        choices=("fixed", "follow"),
        help="the animation's camera: fixed on the whole run (default) or following the robot",
    )
    parser.add_argument(
        "--plot", metavar="OUT.png", help="write the recorded state against time, strips shaded (matplotlib)"
    )


def _fmt_vec(values) -> str:
    return "[" + ", ".join(f"{float(v):.6g}" for v in values) + "]"


def format_summary(path: Path, data: dict[str, Any]) -> str:
    """The human-readable summary printed by ``legsim replay``: the lines of ``legsim run``
    followed by the transitions (edge, times, states before and after the reset)."""
    from .run import format_summary as run_lines

    s = data["summary"]
    lines = [f"recording {path}" + (f" of {s['scene_file']}" if s.get("scene_file") else "")]
    lines += ["  " + line for line in run_lines(s).splitlines()]
    trs = data["transitions"]
    lines.append(f"  transitions ({len(trs)}):")
    if len(trs) <= 2 * SHOWN:
        keep = list(range(len(trs)))
    else:
        keep = list(range(SHOWN)) + list(range(len(trs) - SHOWN, len(trs)))
    for j, k in enumerate(keep):
        if j and k != keep[j - 1] + 1:
            lines.append(f"    ... {k - keep[j - 1] - 1} more ...")
        tr = trs[k]
        lines.append(
            f"    t = {tr['time']:.9g} s  {tr['name']}: {tr['source']} -> {tr['target']}, "
            f"reset at {tr['exit_time']:.9g} s: {_fmt_vec(tr['state_before'])} -> "
            f"{_fmt_vec(tr['state_after'])}"
        )
    seq = data["mode_sequence"]
    if len(seq) <= 2 * SHOWN:
        shown = " -> ".join(seq)
    else:
        shown = " -> ".join(seq[:SHOWN]) + f" -> ... ({len(seq) - 2 * SHOWN} more) -> " + " -> ".join(seq[-SHOWN:])
    lines.append(f"  mode sequence ({len(seq)} segments): {shown}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from ..output.rrd import read_rrd
    from ..output.rrd.live import check_display, open_in_viewer
    from ..output.untrusted import printable
    from .run import html_options, plan_outputs, write_output

    path = Path(args.file)
    if args.spawn:
        check_display("--spawn", f"copy {path} to a machine with a display and run `rerun {path.name}` there")
    # Every requested output is checked before any is written, so a bad --plot does not leave
    # a fresh --html behind it; none may overwrite the recording it is drawn from.
    wanted = {kind: (Path(target), f"--{kind}") for kind in ("html", "plot") if (target := getattr(args, kind))}
    plan, writers = plan_outputs(wanted, inputs=[path])
    options = html_options(args, wanted)
    data = read_rrd(path)
    if not data["verified"]:
        print(
            printable(
                f"legsim: warning: {path} holds no digest of its data (written by an earlier legsim): "
                f"a damaged file cannot be told from a sound one"
            ),
            file=sys.stderr,
        )
    outputs = {
        kind: str(write_output(plan, kind, writers[kind], None, None, recording=data, **options.get(kind, {})))
        for kind in plan
    }
    # The recorded run_summary, with the files this command wrote, as `legsim run --json` has them.
    summary = {**data["summary"], "outputs": outputs}
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
    else:
        # Names and messages come from the file, which may come from someone else.
        print(printable(format_summary(path, data)))
        for kind, out in outputs.items():
            print(printable(f"wrote {out} ({kind})"))
    if args.spawn:
        open_in_viewer(path)
        print(printable(f"opened {path} in the Rerun viewer"), file=sys.stderr)
    return 0
