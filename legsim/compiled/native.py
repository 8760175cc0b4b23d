"""Calls from compiled code to a compiled model function by its address, and the addresses
themselves (``address``).

The step loop is compiled once (``legsim.compiled.kernel``) and calls every model's functions
through the run's function table, an array of addresses: the address of a numba-compiled
function's machine code for one signature, called with numba's own calling convention (the
arguments as numba passes them between its functions). A kernel compiled this way knows no
model, so one cached compilation serves every system, and a call costs an indirect call (a few
nanoseconds), where numba's first-class function values cost ~70 ns through a function boundary.

Three call shapes cover every kind of model function (``legsim.model``,
``legsim.relaxed.calls``): ``(t, a, b, c, out)``, ``(e, t, a, b, c, out)`` and the joint
resolution ``(rest, t, q, u, p, crossed, out) -> int``; every array is float64, one-dimensional
and contiguous.
"""

from __future__ import annotations

from typing import Any

import numba
from numba import types
from numba.core import cgutils
from numba.core.extending import intrinsic

#: The arrays of every call: float64, 1-d, contiguous.
ARRAY = types.Array(types.float64, 1, "C")
#: The signatures a model function is compiled for, by call shape.
STATE_SIGNATURE = types.void(types.float64, ARRAY, ARRAY, ARRAY, ARRAY)
INDEXED_SIGNATURE = types.void(types.int64, types.float64, ARRAY, ARRAY, ARRAY, ARRAY)
JOINT_SIGNATURE = types.int64(types.int64, types.float64, ARRAY, ARRAY, ARRAY, ARRAY, ARRAY)
SIGNATURES = {"state": STATE_SIGNATURE, "indexed": INDEXED_SIGNATURE, "joint": JOINT_SIGNATURE}


def _codegen(signature: Any):
    """The lowering of a call to the function at an address compiled for ``signature``: the
    arguments cast to its scalar types (arrays of any 1-d float64 layout share one data model)."""
    callee_args = signature.args

    def codegen(context, builder, sig, llargs):
        values = []
        for value, given, wanted in zip(llargs[1:], sig.args[1:], callee_args, strict=True):
            values.append(value if isinstance(wanted, types.Array) else context.cast(builder, value, given, wanted))
        fnty = context.call_conv.get_function_type(signature.return_type, callee_args)
        pointer = builder.inttoptr(llargs[0], fnty.as_pointer())
        status, result = context.call_conv.call_function(builder, pointer, signature.return_type, callee_args, values)
        # An exception the model function raised (a raise, an assert, an index past an array's end
        # under boundscheck) is passed on to the kernel's caller, as numba passes it between its
        # own functions: the run then fails naming the mode and time, as the Python loop does,
        # instead of going on with whatever the function left in its output.
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        if signature.return_type == types.void:
            return context.get_dummy_value()
        return result

    return codegen


def _typed(signature: Any, address: Any, args: tuple[Any, ...]) -> Any:
    """The intrinsic's signature for these argument types, or None when they do not fit."""
    if not isinstance(address, types.Integer):
        return None
    for given, wanted in zip(args, signature.args, strict=True):
        if isinstance(wanted, types.Array):
            if not (isinstance(given, types.Array) and given.dtype == types.float64 and given.ndim == 1):
                return None
        elif not isinstance(given, (types.Integer, types.Float, types.Boolean)):
            return None
    return signature.return_type(address, *args)


@intrinsic
def call_state_at(typingctx, address, t, a, b, c, out):
    """``fn(t, a, b, c, out)`` for the function at ``address``."""
    return _typed(STATE_SIGNATURE, address, (t, a, b, c, out)), _codegen(STATE_SIGNATURE)


@intrinsic
def call_indexed_at(typingctx, address, e, t, a, b, c, out):
    """``fn(e, t, a, b, c, out)`` for the function at ``address``."""
    return _typed(INDEXED_SIGNATURE, address, (e, t, a, b, c, out)), _codegen(INDEXED_SIGNATURE)


@intrinsic
def call_joint_at(typingctx, address, rest, t, q, u, p, crossed, out):
    """``fn(rest, t, q, u, p, crossed, out) -> int`` for the function at ``address``."""
    return _typed(JOINT_SIGNATURE, address, (rest, t, q, u, p, crossed, out)), _codegen(JOINT_SIGNATURE)


_ADDRESSES: dict[tuple[int, str], tuple[Any, int]] = {}


def address(function: Any, kind: str) -> int:
    """The address of ``function`` (a numba-compiled model function) compiled for the call
    shape ``kind`` (``native.SIGNATURES``); compiled (or loaded from its cache) on first use."""
    key = (id(function), kind)
    found = _ADDRESSES.get(key)
    if found is not None and found[0] is function:
        return found[1]
    signature = SIGNATURES[kind]
    function.compile(signature)
    result = function.overloads[signature.args]
    pointer = int(result.library.get_pointer_to_function(result.fndesc.llvm_func_name))
    _ADDRESSES[key] = (function, pointer)  # holding the function keeps its code and id alive
    return pointer


def compiles(function: Any) -> bool:
    """Whether the kernel can call ``function``: a numba dispatcher."""
    return isinstance(function, numba.core.registry.CPUDispatcher)
