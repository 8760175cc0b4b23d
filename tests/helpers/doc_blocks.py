"""Shell sessions shown in the docs, read back for the tests that run them: each ``$ COMMAND``
line of a fenced block and the lines printed under it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def session(document: str, heading: str) -> list[tuple[str, list[str]]]:
    """(command, printed lines) of each ``$`` line in the first fenced block after the line
    ``heading`` of ``document`` (a path relative to the repository); blank lines left out."""
    lines = (ROOT / document).read_text(encoding="utf-8").splitlines()
    start = lines.index(heading)
    opening = next(i for i in range(start, len(lines)) if lines[i].startswith("```"))
    closing = next(i for i in range(opening + 1, len(lines)) if lines[i].startswith("```"))
    found: list[tuple[str, list[str]]] = []
    for line in lines[opening + 1 : closing]:
        if line.startswith("$ "):
            found.append((line[2:], []))
        elif line.strip():
            found[-1][1].append(line)
    return found


def comparable(lines: list[str]) -> list[str]:
    """``lines`` without what changes from run to run or machine to machine: a wall time's
    value, and the folder of the bundled scenes (shown as ``/…/``)."""
    out = []
    for line in lines:
        line = re.sub(r"wall time [0-9.e+-]+ s", "wall time … s", line)
        out.append(re.sub(r"(?<![\w.])/\S*/(scenarios/)", r"/…/\1", line))
    return out
