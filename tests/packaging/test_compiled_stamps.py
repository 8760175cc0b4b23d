"""The stamps of legsim's compiled code (``legsim.compiled.cache``): the scan of a file's imports
that decides which sources a stamp covers, checked against Python's own parser."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from legsim.compiled.cache import import_statements

ROOT = Path(__file__).resolve().parents[2]
PACKAGE_FILES = sorted(path for folder in ("legsim", "robots", "viz") for path in (ROOT / folder).rglob("*.py"))


def parsed_imports(source: str) -> set[tuple[int, str | None, str | None]]:
    """The reference: every import statement Python's parser finds, at any depth."""
    found: set[tuple[int, str | None, str | None]] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            found.update((node.level, node.module, alias.name) for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update((0, alias.name, None) for alias in node.names)
    return found


def test_the_import_scan_finds_what_pythons_parser_finds_in_every_package_file():
    # A file the scan read differently would be stamped without a module it imports: its
    # compiled code would outlive an edit of that module.
    assert len(PACKAGE_FILES) > 150
    differing = {
        path.relative_to(ROOT).as_posix(): (parsed_imports(text) ^ import_statements(text))
        for path in PACKAGE_FILES
        if parsed_imports(text := path.read_text()) != import_statements(text)
    }
    assert differing == {}


TRICKY = '''
"""A docstring showing an example, which imports nothing:

    from legsim import simulate
    import legsim.sweep
"""
import os, legsim.relaxed.layout as layout  # two modules
from . import (
    cache,  # a comment, with a comma
    functions as named,
)
from ..relaxed.strip import cross; import sys


def inside():
    if True:
        from .kernel import address, on_compile as said
    text = \'\'\'
    from .not_code import nothing
    \'\'\'
    return text
'''


@pytest.mark.parametrize("source", [TRICKY], ids=["tricky"])
def test_the_import_scan_reads_every_form_ruff_leaves_and_skips_docstrings(source):
    assert import_statements(source) == parsed_imports(source)
    assert (1, None, "functions") in import_statements(source)
    assert not any(module == "legsim" or name == "nothing" for _, module, name in import_statements(source))
