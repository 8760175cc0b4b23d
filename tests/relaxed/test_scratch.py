"""``legsim.compiled.functions.scratch``: a model function's small work arrays, on the stack
when compiled and ``np.empty`` when interpreted. The robots' model functions take theirs from it,
and a model function must give the same numbers on both paths
(``tests/robots/test_compiled_robots.py`` runs whole scenes both ways to the bit)."""

import ast
from pathlib import Path

import numba
import numpy as np

from legsim.compiled.functions import STACK_ALIGNMENT, scratch


@numba.njit
def _weighted_sum(x):
    """sum_i (i + 1) x_i through a work array: written once, compiled or interpreted."""
    work = scratch(x.shape[0])
    for i in range(x.shape[0]):
        work[i] = (i + 1) * x[i]
    total = 0.0
    for i in range(x.shape[0]):
        total += work[i]
    return total


@numba.njit
def _offset(n):
    """Where a work array of n entries starts, modulo the alignment (bytes)."""
    work = scratch(n)
    work[0] = 0.0
    return work.ctypes.data % STACK_ALIGNMENT


@numba.njit
def _offsets_below(n, depth):
    """``_offset`` from ``depth`` frames down, each holding a work array of its own of an odd
    length, so that the stack stands at another place each time."""
    if depth == 0:
        return _offset(n)
    mine = scratch(2 * depth + 1)
    mine[0] = 1.0
    return max(_offsets_below(n, depth - 1), mine.ctypes.data % STACK_ALIGNMENT)


def test_compiled_and_interpreted_give_the_same_numbers():
    x = np.linspace(-1.0, 2.0, 7)
    expected = float(np.dot(np.arange(1, 8), x))
    assert _weighted_sum(x) == _weighted_sum.py_func(x) == expected


def test_interpreted_it_is_a_fresh_array_of_that_length():
    a, b = scratch(3), scratch(3)
    assert a.shape == (3,) and a.dtype == np.float64 and not np.shares_memory(a, b)


def test_compiled_it_allocates_nothing_and_is_aligned_wherever_the_stack_stands():
    """No call into numba's allocator in the compiled function (a heap array would show
    ``NRT_MemInfo_alloc``), and every work array starts on a ``STACK_ALIGNMENT`` boundary at
    every depth."""
    _weighted_sum(np.ones(3))
    code = next(iter(_weighted_sum.inspect_llvm().values()))
    assert "NRT_MemInfo_alloc" not in code
    assert all(_offsets_below(n, depth) == 0 for n in (1, 4, 9) for depth in range(4))


def _scratch_misuses(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, what) of each ``scratch`` array taken inside a loop, or returned, in a module."""
    found: list[tuple[int, str]] = []
    for function in ast.walk(tree):
        if not isinstance(function, ast.FunctionDef):
            continue
        held: set[str] = set()
        for node in ast.walk(function):
            if isinstance(node, (ast.For, ast.While)):
                found += [(call.lineno, "in a loop") for call in ast.walk(node) if _is_scratch(call)]
            if isinstance(node, ast.Assign) and _is_scratch(node.value):
                held |= {target.id for target in node.targets if isinstance(target, ast.Name)}
        for node in ast.walk(function):
            if isinstance(node, ast.Return) and node.value is not None:
                values = node.value.elts if isinstance(node.value, ast.Tuple) else [node.value]
                # the array itself (its entries are numbers, free to return)
                arrays = [v for v in values if (isinstance(v, ast.Name) and v.id in held) or _is_scratch(v)]
                found += [(node.lineno, "returned")] if arrays else []
    return found


def _is_scratch(node: ast.AST) -> bool:
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "scratch"


def test_no_function_takes_one_in_a_loop_or_returns_it():
    """Compiled, a work array taken in a loop grows the stack at every turn, and one returned
    points into a frame that is gone: the package's and the robots' sources do neither (and the
    check finds both in a bad example)."""
    bad = "def f(n):\n    for i in range(n):\n        a = scratch(3)\n    b = scratch(2)\n    return b\n"
    assert [what for _, what in _scratch_misuses(ast.parse(bad))] == ["in a loop", "returned"]
    root = Path(__file__).resolve().parents[2]
    sources = sorted([*root.joinpath("legsim").rglob("*.py"), *root.joinpath("robots").rglob("*.py")])
    users = [path for path in sources if "import model_function, scratch" in path.read_text()]
    assert len(users) >= 5  # the bridge's modules and the controllers
    for path in users:
        assert _scratch_misuses(ast.parse(path.read_text())) == [], path
