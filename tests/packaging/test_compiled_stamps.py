"""The stamps of legsim's compiled code (``legsim.compiled.cache``): the scan of a file's imports
that decides which sources a stamp covers, checked against Python's own parser."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from legsim.compiled import cache
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


def test_a_file_compiled_under_another_is_stamped_with_it(tmp_path):
    """The loop's modules are compiled under the kernel's module (its calls into the function
    table, what it inlines): an edit of the kernel's module alone must make their cached code
    stale, though they do not import it."""
    source, compiler = tmp_path / "loop_like.py", tmp_path / "kernel_like.py"
    source.write_text("def step():\n    return 1\n")
    compiler.write_text('INLINED = frozenset({"step"})\n')
    alone = cache.stamp(source)
    cache.compiled_under([source], [compiler])
    try:
        under = cache.stamp(source)
        compiler.write_text("INLINED = frozenset()\n")
        cache.source_digest.cache_clear()
        edited = cache.stamp(source)
    finally:
        cache._COMPILED_UNDER.pop(source.resolve(), None)
        cache.source_digest.cache_clear()
    assert len({alone, under, edited}) == 3
    assert cache.stamp(source) == alone


def test_the_kernel_inlines_functions_that_exist_and_stamps_the_loop_with_itself():
    # An entry naming no function (a renamed one) would silently stop being inlined.
    from legsim.compiled import kernel

    for name in kernel.INLINED:
        module, function = name.rsplit(".", 1)
        assert callable(getattr(importlib.import_module(module), function, None)), name
    kernel_file = Path(kernel.__file__).resolve()
    assert all(cache._COMPILED_UNDER[Path(m.__file__).resolve()] == (kernel_file,) for m in kernel.LOOP_MODULES)
