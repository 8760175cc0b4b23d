"""``legsim scenes``: list the scenes a name can reach (bundled, and in ``LEGSIM_SCENE_PATH``)."""

from __future__ import annotations

import argparse
import json

NAME = "scenes"
HELP = "list the bundled scenes (name, robot, description)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print a JSON list of {name, robot, description, path}")
    parser.add_argument(
        "--check",
        action="store_true",
        help="also load and validate each scene (builds its model); exit 2 if any is invalid",
    )


def run(args: argparse.Namespace) -> int:
    from ..errors import LegsimError
    from ..scene import load_scene, scene_files, scene_info

    rows = []
    for path in scene_files().values():
        info = scene_info(path)
        if args.check and "error" not in info:
            try:
                load_scene(path)
            except LegsimError as exc:
                info["error"] = str(exc)
        rows.append(info)
    if args.json:
        print(json.dumps(rows))
    elif rows:
        print(format_rows(rows))
    else:
        from ..scene import search_dirs

        print(f"no scenes found in {[str(d) for d in search_dirs()]}")
    return 2 if any("error" in r for r in rows) else 0


def format_rows(rows: list[dict]) -> str:
    """One line per scene: name, robot, description (or why the file is invalid). Every field
    comes from a file someone may have sent: control characters and line breaks are escaped,
    so a description cannot clear the terminal or forge lines of the listing."""
    from ..output.untrusted import printable

    cells = [
        (
            printable(r["name"], newlines=False),
            printable(r["robot"] or "?", newlines=False),
            printable(r["description"] if "error" not in r else f"INVALID: {r['error']}", newlines=False),
        )
        for r in rows
    ]
    wn = max(len(name) for name, _, _ in cells)
    wr = max(len(robot) for _, robot, _ in cells)
    return "\n".join(f"{name:<{wn}}  {robot:<{wr}}  {text}".rstrip() for name, robot, text in cells)
