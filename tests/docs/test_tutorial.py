"""The README, the tutorial and the how-to run as shown, and print what they show.

Each document's fenced blocks run in order, in a temporary folder that is the working
directory: a ```python block in one namespace per document (a tutorial builds on its earlier
blocks), its output compared with the ```text block right after it; each ``$ legsim ...`` line
of a ```console block through the command line, its output compared with the lines under it. In
a shown output a line ``...`` stands for any number of lines, and what changes from run to run
(a wall time's value, the bundled scenes' folder, shown as ``/…/``) is left aside."""

from __future__ import annotations

import os
import re
import shlex
import tempfile
from pathlib import Path

import pytest

from helpers.doc_blocks import comparable
from legsim.cli import main

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = ["README.md", "docs/tutorial.md", "docs/howto-compiled.md"]
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```\s*$", re.S | re.M)


def steps(document: str) -> list[tuple[str, str, list[str] | None]]:
    """(kind, code, shown output or None) in the document's order: ("python", block, the
    ```text block after it), and ("console", command, the lines under it) for each ``$`` line."""
    found = [(m.group(1), m.group(2)) for m in FENCE.finditer((ROOT / document).read_text(encoding="utf-8"))]
    out: list[tuple[str, str, list[str] | None]] = []
    for i, (language, body) in enumerate(found):
        if language == "python":
            after = found[i + 1] if i + 1 < len(found) else None
            shown = after[1].splitlines() if after is not None and after[0] == "text" else None
            out.append(("python", body, shown))
        elif language == "console":
            for line in body.splitlines():
                if line.startswith("$ "):
                    out.append(("console", line[2:], []))
                elif line.strip():
                    out[-1][2].append(line)  # type: ignore[union-attr]
    return out


def matches(printed: list[str], shown: list[str]) -> bool:
    """Whether ``printed`` is ``shown`` line for line, a shown ``...`` matching any lines."""
    printed, shown = comparable(printed), comparable(shown)
    pattern = "".join(r"(?:.*\n)*?" if line == "..." else re.escape(line) + r"\n" for line in shown)
    return re.fullmatch(pattern, "".join(line + "\n" for line in printed)) is not None


def test_matches_takes_ellipsis_for_any_lines():
    assert matches(["a", "b", "c", "d"], ["a", "...", "d"])
    assert matches(["a", "d"], ["a", "...", "d"])
    assert not matches(["a", "b", "c"], ["a", "...", "d"])
    assert not matches(["a", "b"], ["a", "c"])
    assert matches(["x wall time 0.5 s"], ["x wall time 9 s"])


def test_the_documents_have_blocks_with_outputs():
    # Guards the next test against passing on documents whose blocks it no longer finds.
    for document in DOCUMENTS:
        kinds = [(kind, shown is not None and len(shown) > 0) for kind, _, shown in steps(document)]
        assert ("python", True) in kinds, document
    assert ("console", True) in [(k, bool(s)) for k, _, s in steps("docs/tutorial.md")]


def test_the_readme_shows_what_make_demo_runs():
    recipe = (ROOT / "Makefile").read_text(encoding="utf-8").split("\ndemo:", 1)[1].split("\n\n", 1)[0]
    command = next(line.strip() for line in recipe.splitlines() if "legsim run" in line)
    shown = [code for kind, code, _ in steps("README.md") if kind == "console"]
    assert shown == [command.replace("$(BIN)/", "")]
    assert "rerun out/pronk.rrd" in recipe and "out/pronk.html in a browser" in recipe  # how to look


@pytest.mark.parametrize("document", DOCUMENTS)
def test_every_block_runs_and_prints_what_is_shown(document, tmp_path, monkeypatch, capsys):
    from legsim.robots import _native

    if document != "docs/howto-compiled.md" and _native.status() != "available":
        pytest.skip(f"{document} shows the compiled robots' path and counters; native library: {_native.status()}")
    monkeypatch.chdir(tmp_path)  # a block that writes files writes them here
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # and its temporary folders too
    namespace: dict[str, object] = {"__name__": f"doc_{Path(document).stem.replace('-', '_')}"}
    for number, (kind, code, shown) in enumerate(steps(document), start=1):
        where = f"{document} step {number}"
        if kind == "python":
            exec(compile(code, where, "exec"), namespace)
        else:
            words = shlex.split(code)
            assert words[0] == "legsim", where
            assert main(words[1:]) == 0, f"{where}: {code}"
        printed = capsys.readouterr().out.splitlines()
        if shown is not None:
            assert matches(printed, shown), f"{where}: printed\n" + "\n".join(printed)
    assert os.getcwd() == str(tmp_path)
    if document == "docs/tutorial.md":
        assert namespace["folder"].parent == tmp_path  # the stool's folder was made in tmp_path


def test_the_readme_lists_every_command_and_links_the_guides():
    from legsim.cli import discover_commands

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    listed = re.findall(r"^\| `legsim (\w+)", text, re.M)
    commands, broken = discover_commands()
    assert sorted(listed) == sorted([*commands, *broken])
    for guide in ["tutorial", "howto-compiled", "glossary", "references", "packaging"]:
        assert f"(docs/{guide}.md)" in text, guide
