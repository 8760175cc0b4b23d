"""The decorator of model functions, ``model_function``: numba's ``njit`` with legsim's options and
cache. A leaf module: a model's file imports it without the kernel, so the stamp of the model's
compiled code (``cache.source_digest``, over the files it imports) does not change with the
kernel's or the package's other modules."""

from __future__ import annotations

import os
from typing import Any

import numba

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
        return use_legsim_cache(numba.njit(**{**JIT_OPTIONS, "cache": cachable, **options})(function))

    return compile_one if fn is None else compile_one(fn)
