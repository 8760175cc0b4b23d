"""A user's compiled model functions, run once as plain Python when their mode is prepared.

numba does not check indices: a field that writes past ``dx``, guards writing more entries than
the mode has transitions, a reset writing past its target's state, or a read past ``p`` or ``u``
runs on silently compiled, reading and writing memory that is not the model's. The Python source
of the same function (``py_func``), run on numpy arrays of the right sizes, raises IndexError at
that line instead, as the Python loop does on every call. ``probe_indices`` makes that call once
per ``ModeFunctions`` at a zero state, and turns an IndexError into a ``ModelError`` naming the
mode and the function. Any other exception there is the function's own arithmetic at that state
(a division by a zero coordinate), which the run meets where it meets it; the probe says nothing.
Functions of legsim's own models (``legsim.*``) are covered by its tests and not probed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..errors import ModelError
from ..model import ModeFunctions


def probe_indices(mode: str, dim: int, functions: ModeFunctions, guards: int, reset_dims: Mapping[int, int]) -> None:
    """ModelError naming ``mode`` (of dimension ``dim``) where a compiled function of
    ``functions`` indexes past an array when run as Python: its field, its ``guards`` guards (one
    per transition) and its reset for each index e of ``reset_dims`` (e -> the dimension of its
    image: transition e's target below ``guards``, a continuation's from there). Once per
    ``functions`` object."""
    if getattr(functions, "_probed", False) or not functions.compiled or _ours(functions.field):
        return
    t, x, u, p = 0.0, np.zeros(dim), np.zeros(functions.inputs), functions.call_params
    calls: list[tuple[str, Any, Callable[[Any], object]]] = [
        ("field", functions.field, lambda f: f(t, x.copy(), u.copy(), p.copy(), np.zeros(dim)))
    ]
    if functions.guards is not None and guards:
        calls.append(("guards", functions.guards, lambda f: f(t, x.copy(), u.copy(), p.copy(), np.zeros(guards))))
    if functions.reset is not None:
        for e, target_dim in reset_dims.items():

            def reset(f: Any, e: int = e, d: int = target_dim) -> object:
                return f(e, t, x.copy(), u.copy(), p.copy(), np.zeros(d))

            calls.append((f"reset {e}", functions.reset, reset))
    for what, fn, call in calls:
        _probe(mode, what, fn, call)
    # Only a model that passed: a refused one is refused again on every run.
    object.__setattr__(functions, "_probed", True)


def probe_controller(mode: str, dim: int, law: Any, params: np.ndarray) -> None:
    """ModelError naming ``mode`` (plant dimension ``dim``) where the compiled controller ``law``
    (a ``ControlLaw``) indexes past an array when run as Python under the mode's controller
    parameters ``params``: its control and its enter. Once per law and parameter array."""
    if not law.compiled or _ours(law.control):
        return
    seen: set[tuple[int, bytes]] = law.__dict__.setdefault("_probed", set())
    key = (dim, params.tobytes())
    if key in seen:
        return
    t, x, m, p = 0.0, np.zeros(dim), np.zeros(len(law.memory_names)), np.array(params, dtype=float)

    def call(size: int) -> Callable[[Any], object]:
        return lambda f: f(t, x.copy(), m.copy(), p.copy(), np.zeros(size))

    _probe(mode, "controller's control", law.control, call(law.inputs))
    if law.enter is not None:
        _probe(mode, "controller's enter", law.enter, call(m.shape[0]))
    seen.add(key)


def _probe(mode: str, what: str, fn: Any, call: Callable[[Any], object]) -> None:
    try:
        with np.errstate(all="ignore"):
            call(fn.py_func)
    except IndexError as exc:
        raise ModelError(
            f"mode '{mode}': its {what} ({fn.py_func.__qualname__}) indexes past an array when run as Python "
            f"(IndexError: {exc}); compiled, it would read or write memory that is not the model's (check its "
            f"sizes: the mode's dimension, one guard per transition, the target's dimension, params, inputs, memory)"
        ) from None
    except Exception:  # the function's own arithmetic at the zero state: not the probe's to judge
        return


def _ours(fn: Any) -> bool:
    module = getattr(getattr(fn, "py_func", fn), "__module__", "") or ""
    return module == "legsim" or module.startswith("legsim.")
