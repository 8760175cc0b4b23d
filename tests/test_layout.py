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


#: The layers of the package, lowest first: a module imports only from its own layer or those
#: below (imports inside functions included). The core knows nothing of files, scenes, Rerun,
#: Pinocchio or the compiled path; the compiled path registers itself with the core; the ground
#: (terrain and its heights, which model functions read) sits on both and knows nothing of scene
#: files; outputs (files, recordings, summaries) above it; the tools above them; robots and
#: pictures on top.
LAYERS = {
    "core": (
        "errors",
        "interrupts",
        "model",
        "hybrid",
        "execution",
        "methods",
        "relaxed",
        "control",
        "derivatives",
        "arguments",
        "builders",
        "registry",
        "version",
    ),
    "compiled": ("compiled",),
    "ground": ("heights", "terrain"),
    "outputs": ("output",),
}
RANK = {"core": 0, "compiled": 1, "ground": 2, "outputs": 3, "tools": 4, "robots": 5, "viz": 5}


def layer_of(module: str) -> str | None:
    """The layer of a legsim module name (``legsim.relaxed.loop``), None for other packages."""
    parts = module.split(".")
    if parts[0] != "legsim" or len(parts) < 2:
        return None
    top = parts[1]
    if top in ("robots", "viz"):
        return top
    for layer, tops in LAYERS.items():
        if top in tops:
            return layer
    return "tools"


def package_modules() -> dict[str, Path]:
    """Every module of the installed package by its dotted name (robots/ and viz/ as
    legsim.robots and legsim.viz)."""
    out = {}
    for folder, package in (("legsim", "legsim"), ("robots", "legsim.robots"), ("viz", "legsim.viz")):
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT / folder).with_suffix("").parts
            rel = rel[:-1] if rel[-1] == "__init__" else rel
            out[".".join((package, *rel))] = path
    return out


def test_imports_point_down_the_layers_inside_functions_too():
    upward = {}
    for name, path in package_modules().items():
        own = layer_of(name)
        if own is None or name in ("legsim", "legsim.cli", "legsim.__main__"):
            continue
        for module in imported_modules_named(path, name):
            target = layer_of(module)
            if target is not None and RANK[target] > RANK[own]:
                upward.setdefault(name, []).append(module)
    assert upward == {}


def imported_modules_named(path: Path, name: str) -> set[str]:
    """The modules ``path`` (module ``name``) imports, relative imports resolved."""
    is_package = path.name == "__init__.py"
    package = name.split(".") if is_package else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            found.add(module)
            found |= {f"{module}.{alias.name}" for alias in node.names}
    return found
