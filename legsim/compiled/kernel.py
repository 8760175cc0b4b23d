"""The step loop compiled: ``legsim.relaxed``'s loop functions made jittable, its model calls
given numba implementations that call compiled model functions by address, and one cached
compilation of the loop's entry that serves every model.

Importing this module registers the kernel with the relaxed driver (``relaxed.driver.KERNEL``):
the core never imports the compiled path.
"""

from __future__ import annotations

import inspect
import sys
import types as pytypes
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from numba.core import event
from numba.core.caching import NullCache
from numba.core.extending import overload, register_jitable

from ..relaxed import calls, crossing, curve, driver, entering, evaluate, loop, rules, stages, stepping
from . import cache
from .functions import JIT_OPTIONS
from .native import address, call_indexed_at, call_joint_at, call_state_at, compiles

#: The loop's modules, whose functions the kernel compiles from their source.
LOOP_MODULES = (rules, stages, evaluate, curve, stepping, crossing, entering, loop)
#: The loop's options: without numba's reference counting (``_nrt``). The loop allocates nothing
#: and its arrays are owned by the driver for the whole call, while counting the references of
#: every array a function receives costs two calls each at every call (~1 us a field
#: evaluation, against ~10 ns without).
LOOP_OPTIONS: dict[str, Any] = {**JIT_OPTIONS, "_nrt": False}
#: The options of the calls into the function table (inlined into the loop, no reference counting).
CALL_OPTIONS: Any = {"error_model": "numpy", "_nrt": False}


#: The loop's functions that numba inlines into their callers. A compiled call passes its tuple
#: arguments flattened, by value: the workspace's arrays, the tables and the method are some 350
#: machine words pushed at each call. The functions every step goes through (the loop's step, its
#: trial, stages and error norm, and the move to its end) are therefore inlined, for about 25 s
#: more of the loop's one compilation; inlining more (crossings, mode entries) gained nothing
#: measurable and doubled it (docs/architecture.md, "The loop").
INLINED = frozenset(
    {
        "legsim.relaxed.loop.step_once",
        "legsim.relaxed.loop.advance",
        "legsim.relaxed.stepping.take_step",
        "legsim.relaxed.stepping.trial",
        "legsim.relaxed.stages.stages",
        "legsim.relaxed.stages.error_norm",
    }
)


def _register(module: pytypes.ModuleType) -> None:
    """Make every function defined in ``module`` callable from compiled code (with the loop's
    options; those of ``INLINED`` inlined where they are called)."""
    options = {k: v for k, v in LOOP_OPTIONS.items() if k != "cache"}
    for value in vars(module).values():
        if isinstance(value, pytypes.FunctionType) and value.__module__ == module.__name__:
            inline = "always" if f"{module.__name__}.{value.__name__}" in INLINED else "never"
            register_jitable(**options, inline=inline)(value)


def _register_loop() -> None:
    """Make every function of the loop's modules callable from compiled code, compiled under
    this module (its calls and inlining are part of their code)."""
    cache.compiled_under([inspect.getfile(module) for module in LOOP_MODULES], [__file__])
    for module in LOOP_MODULES:
        _register(module)


_TOOLS: dict[Any, Any] = {}


def tool(fn: Any) -> Any:
    """``fn`` (a function written like the loop's, taking the run's tables, a visit, the
    workspace and the method first) compiled with the loop's options, the other functions of its
    module made callable from it; compiled once per process (cached on disk)."""
    compiled = _TOOLS.get(fn)
    if compiled is None:
        module = sys.modules[fn.__module__]
        cache.compiled_under([inspect.getfile(module)], [__file__])
        _register(module)
        compiled = _TOOLS[fn] = cache.use_legsim_cache(numba.njit(**LOOP_OPTIONS)(fn))
    return compiled


@overload(calls.call_state, jit_options=CALL_OPTIONS)
def _call_state(functions, i, t, a, b, c, out):
    def impl(functions, i, t, a, b, c, out):
        call_state_at(functions[i], t, a, b, c, out)

    return impl


@overload(calls.call_indexed, jit_options=CALL_OPTIONS)
def _call_indexed(functions, i, e, t, a, b, c, out):
    def impl(functions, i, e, t, a, b, c, out):
        call_indexed_at(functions[i], e, t, a, b, c, out)

    return impl


@overload(calls.call_joint, jit_options=CALL_OPTIONS)
def _call_joint(functions, i, rest, t, q, u, p, crossed, out):
    def impl(functions, i, rest, t, q, u, p, crossed, out):
        return call_joint_at(functions[i], rest, t, q, u, p, crossed, out)

    return impl


#: Called once per process with a one-line message when legsim compiles code for this machine
#: (a cache miss: the first run after installing, or after a change of legsim or numba); the
#: command line prints it on stderr. None: silent.
on_compile: Callable[[str], None] | None = None


class _FirstCompile(event.Listener):
    """Tells ``on_compile`` when the first of legsim's functions (or a model function) starts
    compiling in this process."""

    said = False

    def on_start(self, ev: event.Event) -> None:
        if _FirstCompile.said or on_compile is None:
            return
        dispatcher = ev.data.get("dispatcher")
        py_func = getattr(dispatcher, "py_func", None)
        if py_func is None:
            return
        what = "the step loop" if py_func is loop.run_flat else f"{py_func.__module__}.{py_func.__qualname__}"
        _FirstCompile.said = True
        if isinstance(getattr(dispatcher, "_cache", None), NullCache):  # compiled anew in every process
            on_compile(f"legsim: compiling {what} and what it calls for this run (not cached: every run compiles it)")
            return
        on_compile(
            f"legsim: compiling {what} and what it calls for this machine (once: later runs load it from "
            f"{cache.cache_dir()})"
        )

    def on_end(self, ev: event.Event) -> None:
        pass


event.register("numba:compile", _FirstCompile())
cache.install()
_register_loop()
#: The loop's entry, compiled once per machine and legsim version (cached on disk).
_run = cache.use_legsim_cache(numba.njit(**LOOP_OPTIONS)(loop.run_flat))


class Kernel:
    """What the relaxed driver calls: ``run(tables, ws, method)`` and ``addresses``."""

    @staticmethod
    def run(tables: Any, ws: Any, method: Any) -> int:
        return int(_run(tuple(tables), tuple(ws), tuple(method)))

    @staticmethod
    def addresses(functions: list[Any], kinds: list[str]) -> np.ndarray:
        return np.array([address(fn, kind) for fn, kind in zip(functions, kinds, strict=True)], dtype=np.int64)

    compiles = staticmethod(compiles)
    tool = staticmethod(tool)


driver.KERNEL = Kernel
