"""The native library: Pinocchio's rigid-body algorithms behind a plain C ABI (``pinlegsim.cpp``),
built at install time as the optional extension ``legsim.robots._native._pinlegsim``.

numba-compiled code calls its functions by symbol name (``CALLS``: ``numba.types.ExternalFunction``
declarations), which the process resolves once ``load()`` has loaded the library; compiled
functions that call them cache on disk like any other. Python calls ``create_model`` through
ctypes. Without the library (no C++ compiler at install time, or ``LEGSIM_NATIVE=0``), ``load()``
returns False and ``status()`` says why: every robot's model functions call this library, so a
robot cannot be built without it (``robots.bridge.native.handle_for`` raises a ``ModelError``
naming the robot and the reason); the analytic systems need none of it.
"""

from __future__ import annotations

import ctypes
import importlib.machinery
import os
from pathlib import Path
from typing import cast

import numpy as np

#: The C interface version this module speaks (``lsn_version()`` of the library).
INTERFACE_VERSION = 13
#: Environment variable that switches the native path off when set to 0.
SWITCH = "LEGSIM_NATIVE"

_state: dict[str, object] = {"loaded": None, "reason": "", "lib": None}


def library_path() -> Path | None:
    """The built extension's file, or None when the install built none."""
    here = Path(__file__).parent
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = here / f"_pinlegsim{suffix}"
        if path.exists():
            return path
    return None


def load() -> bool:
    """Load the library into the process (once); True when its functions can be called."""
    if _state["loaded"] is not None:
        return bool(_state["loaded"])
    _state["loaded"] = False
    if os.environ.get(SWITCH, "1") == "0":
        _state["reason"] = f"switched off by {SWITCH}=0"
        return False
    path = library_path()
    if path is None:
        _state["reason"] = (
            "the extension legsim.robots._native._pinlegsim was not built at install time (no C++ "
            "compiler, or no Pinocchio/Eigen headers); reinstall with a compiler to build it"
        )
        return False
    try:
        import llvmlite.binding as llvm

        lib = ctypes.CDLL(str(path))
        version = int(lib.lsn_version())
        if version != INTERFACE_VERSION:
            raise OSError(f"interface version {version}, expected {INTERFACE_VERSION}: rebuild it (make install)")
        llvm.load_library_permanently(str(path))  # numba's JIT resolves the lsn_* symbols from here
    except OSError as exc:
        _state["reason"] = f"{path} could not be loaded: {exc}"
        return False
    lib.lsn_create.restype = ctypes.c_long
    lib.lsn_create.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_long]
    lib.lsn_time_aba.restype = ctypes.c_double
    lib.lsn_time_aba.argtypes = [ctypes.c_long] + [ctypes.POINTER(ctypes.c_double)] * 3 + [ctypes.c_long]
    lib.lsn_planar.restype = ctypes.c_long
    lib.lsn_planar.argtypes = [ctypes.c_long]
    lib.lsn_counts.restype = None
    lib.lsn_counts.argtypes = [ctypes.c_long, ctypes.POINTER(ctypes.c_double), ctypes.c_long]
    _state["lib"], _state["loaded"] = lib, True
    return True


def library() -> ctypes.CDLL:
    """The loaded library, for calls from Python (``calls``); RuntimeError when unavailable."""
    if not load():
        raise RuntimeError(f"native library unavailable: {_state['reason']}")
    return cast(ctypes.CDLL, _state["lib"])


def status() -> str:
    """'available', or why the native path is not."""
    return "available" if load() else str(_state["reason"])


def create_model(description: np.ndarray) -> int:
    """Build a model in the library from its flat description (``pinlegsim.cpp``, lsn_create)
    and return its handle; ValueError on a description the library refuses."""
    if not load():
        raise RuntimeError(f"native library unavailable: {_state['reason']}")
    desc = np.ascontiguousarray(description, dtype=np.float64)
    lib = cast(ctypes.CDLL, _state["lib"])  # load() succeeded
    handle = int(lib.lsn_create(desc.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), desc.size))
    if handle < 0:
        raise ValueError("the native library refused the model description")
    return handle


#: How many counters each robot of the library keeps (``lsn_counts``).
COUNTER_SLOTS = 16


def counts(handle: int, reset: bool = False) -> np.ndarray:
    """The evaluation counters of the library's model ``handle`` (``COUNTER_SLOTS`` values; the
    robots name them), set back to 0 afterwards with ``reset``."""
    if not load():
        raise RuntimeError(f"native library unavailable: {_state['reason']}")
    out = np.zeros(COUNTER_SLOTS)
    lib = cast(ctypes.CDLL, _state["lib"])  # load() succeeded
    lib.lsn_counts(int(handle), out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), int(reset))
    return out


def planar(handle: int) -> bool:
    """Whether the library's model ``handle`` moves in the x-z plane, its M and h then computed
    from its planar bodies (``planar_dynamics`` in ``pinlegsim.cpp``) rather than by Pinocchio's
    crba and RNEA."""
    if not load():
        raise RuntimeError(f"native library unavailable: {_state['reason']}")
    lib = cast(ctypes.CDLL, _state["lib"])  # load() succeeded
    return bool(lib.lsn_planar(int(handle)))


def time_aba(handle: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, reps: int) -> float:
    """Seconds per call of bare C++ ABA on the model ``handle`` at (q, v, tau), timed inside
    the library (no Python, no numba around it): the best of 5 batches of ``reps`` calls, as
    other timings on a shared machine take the best of repeats."""
    if not load():
        raise RuntimeError(f"native library unavailable: {_state['reason']}")
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (q, v, tau)]
    pointers = [a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in arrays]
    lib = cast(ctypes.CDLL, _state["lib"])  # load() succeeded
    return min(float(lib.lsn_time_aba(handle, *pointers, int(reps))) for _ in range(5))
