"""The documentation shows no one machine's paths: a reader's checkout lives elsewhere, so a
printed ``/work/...`` or ``/home/...`` path in an example output is noise at best and a leak at
worst. Example outputs abbreviate a scene's folder as ``/…/``."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MACHINE_PATH = re.compile(r"(?<![\w.])/(?:work|home|Users|root)/[\w.-]+")


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_the_documents_exist():
    # Guards the next test against passing on an empty list (a moved docs folder).
    assert len(documents()) > 5


def test_no_document_prints_a_machine_specific_absolute_path():
    found = [
        f"{path.relative_to(ROOT)}:{number}: {match.group(0)}"
        for path in documents()
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        for match in MACHINE_PATH.finditer(line)
    ]
    assert found == [], "machine paths in the docs:\n" + "\n".join(found)
