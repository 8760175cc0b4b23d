"""The documents' code blocks run, and print what the documents show.

In each document listed, the ```python blocks run in order in one namespace (a tutorial builds
on its earlier blocks); a ```text block right after a python block is the output that block
prints, compared line by line. Blocks fenced as ```python no-run are shown, not run."""

from __future__ import annotations

import contextlib
import io
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = ["docs/models.md", "docs/method.md"]
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```\s*$", re.S | re.M)


def blocks(document: str) -> list[tuple[str, str | None]]:
    """(code, the output shown after it or None) of every runnable python block."""
    found = [(m.group(1), m.group(2).strip(), m.group(3)) for m in FENCE.finditer((ROOT / document).read_text())]
    out: list[tuple[str, str | None]] = []
    for i, (language, options, body) in enumerate(found):
        if language != "python" or "no-run" in options:
            continue
        shown = found[i + 1][2] if i + 1 < len(found) and found[i + 1][0] == "text" else None
        out.append((body, shown))
    return out


@pytest.mark.parametrize("document", DOCUMENTS)
def test_every_code_block_runs_and_prints_what_is_shown(document, tmp_path):
    namespace: dict[str, object] = {"__name__": f"doc_{Path(document).stem}"}
    cwd = os.getcwd()
    os.chdir(tmp_path)  # a block that writes files writes them here
    try:
        for number, (code, shown) in enumerate(blocks(document), start=1):
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                exec(compile(code, f"{document} block {number}", "exec"), namespace)
            if shown is not None:
                assert printed.getvalue().rstrip().splitlines() == shown.rstrip().splitlines(), (
                    f"{document} block {number}"
                )
    finally:
        os.chdir(cwd)
