"""The kernel's source, generated per set of twin functions, and the machine code numba caches
for it.

A module is written per tuple of *function sets* (a set: the module-level twin functions
field, guards and resets of some modes; every mode of a bridge robot shares one), holding the
constants and functions of ``legsim.relaxed.rules``, ``legsim.compiled.transit`` and
``legsim.compiled.kernel`` as globals, and ``_twin_field/_guards/_resets(fid, ...)`` that
dispatch on a mode's set. A module-level global is a compile-time constant numba can inline
and cache on disk, whereas passing the twin's functions as arguments would recompile the whole
loop in every process (5 s). The built-in methods' stages are unrolled into straight-line code (twice as fast
for RK4 as the loop over a tableau's arrays, which stays for other tableaux), generated from the
same grouping of terms as the Python stepper (``methods.stepper.stage_groups``).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numba
import numpy as np

from ..methods import METHODS, Tableau, stage_groups
from ..methods.stepper import DOT_TERMS
from ..relaxed import rules
from . import kernel, transit

#: Built-in methods with straight-line stage code in the kernel, by method id; the methods whose
#: long rows the Python stepper combines by matrix products (DOP853) run the generic loop.
UNROLLED = tuple(
    t
    for t in METHODS.values()
    if all(np.count_nonzero(t.A[i, :i]) < DOT_TERMS for i in range(t.stages)) and np.count_nonzero(t.b) < DOT_TERMS
)


@dataclass(frozen=True)
class Plan:
    """A tableau as the kernel's arrays: nodes c (s,), and per row (s rows of A, then b) its
    groups of equal weights: counts (s + 1,), weights (s + 1, G), member counts (s + 1, G) and
    members (s + 1, G, s); b_err (2, s): the error weights and the blended low-order ones (zeros
    where the method has none)."""

    c: np.ndarray
    n_groups: np.ndarray
    weights: np.ndarray
    n_members: np.ndarray
    members: np.ndarray
    b_err: np.ndarray
    fsal: bool
    stages: int
    method_id: int


_PLANS: dict[int, tuple[Tableau, Plan]] = {}  # by id, holding the tableau so an id is never reused


def plan_for(tableau: Tableau) -> Plan:
    """The tableau as the kernel's arrays (cached per tableau object)."""
    entry = _PLANS.get(id(tableau))
    if entry is not None and entry[0] is tableau:
        return entry[1]
    s = tableau.stages
    rows = [stage_groups(tableau.A[i, :i]) if i > 0 else [] for i in range(s)] + [stage_groups(tableau.b)]
    width = max(1, max(len(r) for r in rows))
    n_groups = np.zeros(s + 1, dtype=np.int64)
    weights = np.zeros((s + 1, width))
    n_members = np.zeros((s + 1, width), dtype=np.int64)
    members = np.zeros((s + 1, width, s), dtype=np.int64)
    for i, row in enumerate(rows):
        n_groups[i] = len(row)
        for g, (w, js) in enumerate(row):
            weights[i, g] = w
            n_members[i, g] = len(js)
            members[i, g, : len(js)] = js
    b_err = np.zeros((2, s))
    if tableau.b_err is not None:
        b_err[0] = tableau.b_err
    if tableau.b_err_low is not None:
        b_err[1] = tableau.b_err_low
    method_id = next((i for i, t in enumerate(UNROLLED) if t is tableau), -1)
    plan = Plan(
        np.asarray(tableau.c, dtype=float),
        n_groups,
        weights,
        n_members,
        members,
        b_err,
        bool(tableau.fsal),
        s,
        method_id,
    )
    _PLANS[id(tableau)] = (tableau, plan)
    return plan


def _sum_source(base: str, weights: np.ndarray) -> str:
    """``base + (hk * w) * (K[j, d] + ...) + ...`` in the Python stepper's grouping and order."""
    out = base
    for w, js in stage_groups(weights):
        terms = " + ".join(f"K[{j}, d]" for j in js)
        out += f" + (hk * {w!r}) * " + (f"({terms})" if len(js) > 1 else terms)
    return out


def _stage_source(tableau: Tableau, indent: str) -> list[str]:
    """Straight-line stage code of one tableau (the body of kernel._k_stages, unrolled)."""
    lines = []
    for i in range(1, tableau.stages):
        lines += [
            "for d in range(n):",
            f"    XS[d] = {_sum_source('x[d]', tableau.A[i, :i])}",
            f"ki = _twin_field(fid, t + {float(tableau.c[i])!r} * hk, XS, p)",
            "for d in range(n):",
            f"    K[{i}, d] = ki[d]",
        ]
    last = "XS[d]" if tableau.fsal else _sum_source("x[d]", tableau.b)
    lines += ["for d in range(n):", f"    x_new[d] = {last}"]
    return [indent + line for line in lines]


def _unrolled_stages(indent: str) -> str:
    lines = []
    for method_id, tableau in enumerate(UNROLLED):
        lines.append(f"{indent}{'if' if method_id == 0 else 'elif'} method_id == {method_id}:  # {tableau.name}")
        lines += _stage_source(tableau, indent + "    ")
    lines += [f"{indent}else:", f"{indent}    {kernel.STAGES_CALL}"]
    return "\n".join(lines)


def _constants(module: ModuleType) -> list[str]:
    return [
        f"{name} = {value!r}" for name, value in vars(module).items() if name.isupper() and type(value) in (int, float)
    ]


def _function_source(fn: Any) -> str:
    source = inspect.getsource(fn).rstrip()
    if fn is kernel._k_mode_loop:
        marker = source.index(kernel.STAGES_CALL)
        indent = source[source.rindex("\n", 0, marker) + 1 : marker]
        source = source[: marker - len(indent)] + _unrolled_stages(indent) + source[marker + len(kernel.STAGES_CALL) :]
    return source


#: The twin functions of a function set, and their arguments.
TWIN_KINDS = (("field", "t, x, p"), ("guards", "x, p"), ("resets", "x, p, e"))


def _dispatch_source(count: int) -> list[str]:
    """``_twin_<kind>(fid, ...)``: the function of set fid, for sets 0 .. count - 1 bound as
    ``_f<set>_<kind>`` (a single set needs no branch)."""
    lines = []
    for kind, args in TWIN_KINDS:
        lines += ["", "", "@_inline", f"def _twin_{kind}(fid, {args}):"]
        for k in range(count - 1):
            lines += [f"    if fid == {k}:", f"        return _f{k}_{kind}({args})"]
        lines.append(f"    return _f{count - 1}_{kind}({args})")
    return lines


def kernel_source(imports: list[str], cache: bool, count: int = 1) -> str:
    """The generated module's text: the twins' functions imported as ``_f<set>_<kind>``
    (``imports``, ``count`` sets), their dispatchers, then the rules' and the kernel's constants
    and functions, each jitted."""
    lines = [
        "# Generated by legsim.compiled.generate from legsim.relaxed.rules and legsim.compiled.kernel;",
        "# edit those, not this file.",
        "import math",
        "",
        "import numba",
        "",
    ]
    lines += imports
    # The scalar rules of every step are inlined where they are called; the functions of landings
    # and aims stay calls, which keeps the step loop small.
    lines += [
        "",
        f"_njit = numba.njit(cache={cache}, fastmath=False, nogil=True)",
        f"_inline = numba.njit(cache={cache}, fastmath=False, nogil=True, inline='always')",
        "",
    ]
    lines += _constants(rules) + _constants(transit) + _constants(kernel)
    lines += _dispatch_source(count)
    for fn in dict.fromkeys(kernel.RULES + kernel.KERNEL_FUNCTIONS):
        decorator = "@_inline" if fn in kernel.EVERY_STEP else "@_njit"
        lines += ["", "", decorator, _function_source(fn)]
    return "\n".join(lines) + "\n"


def cache_dir() -> Path:
    """Where generated kernel modules and numba's compiled code for them live:
    ``$LEGSIM_CACHE_DIR``, else ``$XDG_CACHE_HOME/legsim/kernels`` (``~/.cache/legsim/kernels``)."""
    env = os.environ.get("LEGSIM_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "legsim" / "kernels"


@numba.njit(cache=True)
def no_resets(x, p, e):
    """The kernel's reset for twins without compiled resets (never called: such twins hand
    every transition to Python)."""
    return x.copy()


def importable(fn: Any) -> str | None:
    """``module:qualname`` of a module-level jitted function, or None (closures, __main__)."""
    py = getattr(fn, "py_func", None)
    module, qualname = getattr(py, "__module__", None), getattr(py, "__qualname__", "")
    if py is None or module in (None, "__main__") or "<" in qualname or "." in qualname:
        return None
    try:
        if getattr(importlib.import_module(module), qualname) is fn:
            return f"{module}:{qualname}"
    except Exception:
        return None
    return None


#: A function set: a twin's (field, guards, resets).
FunctionSet = tuple[Any, Any, Any]
_KERNELS: dict[tuple[int, ...], tuple[tuple[FunctionSet, ...], Any]] = {}


def get_kernel(sets: tuple[FunctionSet, ...]) -> Any:
    """The jitted step loop bound to the function sets ``sets`` (``no_resets`` for twins
    without resets), set k being ``fid`` k. For twins defined at module level the kernel is
    generated once into ``cache_dir()`` and numba caches its machine code there, so later
    processes load it in milliseconds; other twins (closures) get a kernel compiled in this
    process only."""
    key = tuple(id(fn) for functions in sets for fn in functions)
    found = _KERNELS.get(key)
    if found is not None:
        return found[1]
    names = [importable(fn) for functions in sets for fn in functions]
    kernel_fn = _cached_kernel(names, len(sets)) if None not in names else None
    if kernel_fn is None:
        namespace: dict[str, Any] = {
            f"_f{k}_{kind}": fn
            for k, functions in enumerate(sets)
            for (kind, _), fn in zip(TWIN_KINDS, functions, strict=True)
        }
        exec(compile(kernel_source([], cache=False, count=len(sets)), "<legsim kernel>", "exec"), namespace)
        kernel_fn = namespace["_k_step_loop"]
    _KERNELS[key] = (sets, kernel_fn)  # holding the functions keeps their ids from being reused
    return kernel_fn


def _twin_sources(names: Sequence[str | None]) -> str:
    """The source of the twins' modules and of the modules of the jitted functions they use:
    numba links the twins' machine code into the cached kernel, and checks only the generated
    module's own file, so a changed twin must change the kernel's name."""
    modules: dict[str, ModuleType] = {}
    for name in names:
        module = importlib.import_module(str(name).split(":")[0])
        modules[module.__name__] = module
        for value in vars(module).values():
            used = getattr(value, "py_func", None)
            if used is not None and getattr(used, "__module__", None) in sys.modules:
                modules.setdefault(used.__module__, sys.modules[used.__module__])
    sources = []
    for module_name in sorted(modules):
        try:
            sources.append(inspect.getsource(modules[module_name]))
        except (OSError, TypeError):
            sources.append(module_name)
    return "".join(sources)


def _cached_kernel(names: list[str | None], count: int) -> Any:
    imports = []
    for k in range(count):
        for (kind, _), name in zip(TWIN_KINDS, names[3 * k : 3 * k + 3], strict=True):
            module_name, qualname = str(name).split(":")
            imports.append(f"from {module_name} import {qualname} as _f{k}_{kind}")
    text = kernel_source(imports, cache=True, count=count)
    digest = hashlib.sha256((text + numba.__version__ + _twin_sources(names)).encode()).hexdigest()[:20]
    try:
        directory = cache_dir()
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f"legsim_kernel_{digest}.py"
        if not path.exists() or path.read_text() != text:
            fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=directory)
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
            os.replace(tmp, path)
        spec = importlib.util.spec_from_file_location(f"legsim_kernel_{digest}", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        # numba's cache finds a function's module by name when it loads compiled code.
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
        return module._k_step_loop
    except OSError:
        return None  # no writable cache: compile in memory instead
