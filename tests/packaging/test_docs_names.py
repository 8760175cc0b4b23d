"""The glossary and the reference list name only what exists: every ``legsim...`` name in
backticks imports, every file they cite is in the repository, and every document they link to
is there."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = ["docs/glossary.md", "docs/references.md"]


def _resolves(dotted: str) -> bool:
    """Whether ``dotted`` is a module, or an attribute of one, of the installed legsim."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            target = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            if not hasattr(target, name):
                return False
            target = getattr(target, name)
        return True
    return False


@pytest.mark.parametrize("document", DOCUMENTS)
def test_what_the_document_names_exists(document):
    text = (ROOT / document).read_text(encoding="utf-8")
    names = set(re.findall(r"`(legsim(?:\.\w+)+)`", text))
    files = set(re.findall(r"`((?:tests|scenarios|legsim|robots|viz|docs)/[\w/.-]+\.(?:py|md|toml))`", text))
    links = set(re.findall(r"\]\(([\w/.-]+\.md)(?:#[\w-]*)?\)", text))
    assert names and [n for n in sorted(names) if not _resolves(n)] == []
    assert [f for f in sorted(files) if not (ROOT / f).exists()] == []
    assert [f for f in sorted(links) if not (ROOT / document).parent.joinpath(f).exists()] == []


def test_the_readme_cites_no_file_outside_the_repository():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "shared/" not in text and "docs/references.md" in text
