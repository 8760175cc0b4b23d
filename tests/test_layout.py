"""The architecture, checked: module sizes, the integrator's loop and functions short enough to
read whole, and imports that point one way (the core knows nothing of Pinocchio, Rerun, meshcat,
the robots or the pictures)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCES = [
    p
    for folder in ("legsim", "robots", "viz", "scenarios", "tests", "benchmarks")
    for p in sorted((ROOT / folder).rglob("*.py"))
]


def code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of a function without its docstring."""
    lines = node.end_lineno - node.lineno + 1
    body = node.body
    if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant):
        lines -= body[0].end_lineno - body[0].lineno + 1
    return lines


def test_no_module_is_longer_than_700_lines():
    long = {str(p.relative_to(ROOT)): n for p in SOURCES if (n := len(p.read_text().splitlines())) > 700}
    assert long == {}


def test_the_integrators_loop_fits_in_one_file_and_its_functions_on_one_screen():
    # The loop of paper 000 Fig. 12 reads whole in one file; every function of the loop and of
    # the kernel that compiles it fits on one screen.
    assert len((ROOT / "legsim/relaxed/loop.py").read_text().splitlines()) <= 300
    long = {}
    for path in sorted([*(ROOT / "legsim/relaxed").glob("*.py"), *(ROOT / "legsim/compiled").glob("*.py")]):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and code_lines(node) > 60:
                long[f"{path.name}:{node.name}"] = code_lines(node)
    assert long == {}


def imported_modules(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = path.relative_to(ROOT).parent.parts
                package = parts[: len(parts) - node.level + 1]
                base = ".".join(("legsim",) + package[1:] + ((base,) if base else ()))
            names.add(base)
    return names


def test_the_core_imports_neither_robots_nor_pictures_nor_their_libraries():
    forbidden = ("pinocchio", "meshcat", "legsim.robots", "legsim.viz")
    found = {}
    for path in sorted((ROOT / "legsim").rglob("*.py")):
        rel = path.relative_to(ROOT)
        allowed_rerun = rel.parts[:3] == ("legsim", "output", "rrd")
        bad = sorted(
            m
            for m in imported_modules(path)
            if m.startswith(forbidden) or (m.startswith("rerun") and not allowed_rerun)
        )
        if bad:
            found[str(rel)] = bad
    assert found == {}
