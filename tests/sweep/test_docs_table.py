"""docs/sweep.md reads a sweep's table with pyarrow (the library legsim installs, pandas is
not one): its example runs as shown and prints the lines shown under it."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _blocks_after(heading: str) -> tuple[str, list[str]]:
    """The Python block after ``heading`` in docs/sweep.md and the lines of the block after it."""
    text = (ROOT / "docs" / "sweep.md").read_text(encoding="utf-8")
    rest = text[text.index(heading) :]
    code = rest.split("```python\n", 1)[1].split("```", 1)[0]
    shown = rest.split("```python\n", 1)[1].split("```", 1)[1].split("```\n", 1)[1].split("```", 1)[0]
    return code, shown.splitlines()


def test_the_table_example_prints_what_the_docs_show(tmp_path, monkeypatch):
    code, shown = _blocks_after("### Reading the table")
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "docs/sweep.md", "exec"), {"__name__": "docs_sweep"})
    assert printed.getvalue().splitlines() == shown
    assert "pandas" not in code  # what legsim does not install
