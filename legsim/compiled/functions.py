"""The decorator of model functions, ``model_function``: numba's ``njit`` with legsim's options and
cache. A leaf module: a model's file imports it without the kernel, so the stamp of the model's
compiled code (``cache.source_digest``, over the files it imports) does not change with the
kernel's or the package's other modules."""

from __future__ import annotations

import os
from typing import Any

import numba
import numpy as np
from numba import types
from numba.core import errors
from numba.core.registry import CPUDispatcher
from numba.extending import intrinsic, overload

from .cache import use_legsim_cache

#: numba options of every compiled function of legsim's: cached on disk, no fast-math (results
#: equal to the interpreted loop's to the bit), numpy's error model (nan, not exceptions).
JIT_OPTIONS: dict[str, Any] = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}


def model_function(fn: Any = None, /, **options: Any) -> Any:
    """Compile a model function (``legsim.model``) or a helper it calls, with numba: plain
    Python over arrays and scalars, in the subset numba compiles. A mode whose functions are all
    compiled, under a controller whose functions are too, runs in the compiled kernel; from
    Python the same function is called as it is. ``options`` are numba's ``njit`` options on
    top of legsim's (``JIT_OPTIONS``: cached, no fast-math, numpy's error model).

    Usable as ``@model_function`` or ``@model_function(inline="always")``. A function defined
    where numba cannot cache it (a notebook, an interactive session) is compiled in the process
    only."""

    def compile_one(function: Any) -> Any:
        where = getattr(getattr(function, "__code__", None), "co_filename", "")
        cachable = bool(where) and os.path.isfile(where)
        dispatcher = numba.njit(**{**JIT_OPTIONS, "cache": cachable, **options})(function)
        # njit takes no dispatcher class: the dispatcher it built becomes a OneSpecialization.
        dispatcher.__class__ = OneSpecialization
        return use_legsim_cache(dispatcher)

    return compile_one if fn is None else compile_one(fn)


class OneSpecialization(CPUDispatcher):
    """numba's dispatcher, except that a call from compiled code with constant arguments
    compiles the function for their types, not for their values. numba would compile one
    specialization per constant a caller passes (``f(x, 0)`` and ``f(x, 1)`` twice, then again
    for every function those pass it on to): a quarter or more of a robot's compile time went
    to such copies. The arithmetic is the same; a function that only types for a constant's
    value (a tuple of mixed items indexed by it) still gets that value."""

    def get_call_template(self, args: Any, kws: Any) -> Any:
        plain_args = tuple(types.unliteral(a) for a in args)
        plain_kws = {name: types.unliteral(a) for name, a in kws.items()}
        if plain_args == tuple(args) and plain_kws == kws:
            return super().get_call_template(args, kws)
        try:
            return super().get_call_template(plain_args, plain_kws)
        except errors.TypingError:
            return super().get_call_template(args, kws)


#: Bytes to which ``scratch`` aligns its arrays.
STACK_ALIGNMENT = 64


@intrinsic
def _stack_floats(typingctx: Any, count: Any) -> Any:
    """A pointer to ``count`` float64 values allocated on the stack of the function the call is
    compiled into."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        values = builder.alloca(context.get_value_type(types.float64), size=args[0])
        # Aligned as a cache line whatever the stack's depth, so that vectorised native code
        # reading the array never meets an alignment that depends on where the stack stands.
        values.align = STACK_ALIGNMENT
        return values

    return types.CPointer(types.float64)(types.intp), codegen


def scratch(count: int) -> np.ndarray:
    """A float64 array of ``count`` uninitialised entries, for the small work arrays of a model
    function called at every evaluation. Interpreted, ``np.empty(count)``; compiled, an array on
    the calling function's stack: no allocation and no reference counting. It lives until that
    function returns: never return it or keep it, and never take one inside a loop (compiled,
    each call grows the stack until the function returns)."""
    return np.empty(count)


@overload(scratch, inline="always")
def _compiled_scratch(count):  # numba compares the implementation's annotations with these: none
    def on_the_stack(count):
        return numba.carray(_stack_floats(count), count)

    return on_the_stack
