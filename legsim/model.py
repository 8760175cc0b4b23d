"""Models written once: a mode's field, guards and resets as functions over plain arrays, which
the Python loop and the compiled kernel both evaluate.

A mode written this way carries ``ModeFunctions``; its ``Mode.field`` and its transitions'
``guard`` and ``reset`` callables are made from the same functions (``legsim.hybrid``), so every
tool that reads a ``HybridSystem`` (orbits, metric, bounds, recordings) sees the one source.
Decorated with ``legsim.model_function`` (numba's ``njit``), the functions are compiled, and a
run whose modes and controller are all written so runs in the compiled kernel; undecorated, they
run in Python. The signatures (float64 arrays, one-dimensional and contiguous; each function
writes its result into its last argument and returns nothing, except ``joint``):

* ``field(t, x, u, p, dx)``: dx/dt at (t, x) under the input u; x and dx of the mode's dim;
* ``guards(t, x, u, p, g)``: every outgoing transition's guard, in their order (>= 0 inside the
  domain, < 0 past the guard, in the guard's own units: the strip width eps is in them);
* ``reset(e, t, x, u, p, x_new)``: the image of outgoing transition e at the guard point x, of
  the target's dim; for ``e >= len(g)`` the continuation of transition ``e - len(g)``;
* ``joint(rest, t, q, u, p, crossed, x_new) -> k``: for a mode whose model resolves transitions
  crossed in the same step together (simultaneous impacts): ``crossed[e] > 0`` for each one
  crossed (1 for the first on the step's curve, 2, 3, ... for the others), ``rest`` 1 when these
  joint crossings accumulate (their continuation: every impact plastic); returns the index of
  the outcome in ``ModeFunctions.joint_outcomes`` with the image in x_new, or -1 to cross them
  one after the other.

``p`` is the mode's parameter array (``ModeFunctions.params``): parameters travel as data, so
that one compilation serves every parameter set. A model function signals a state past the
model's range (a robot's hip below the ground) by writing nan, and declares ``nan_breaks``: the
step there is shortened, as for a Python model's ``ModelBreakdown``.

A mode whose functions choose a crossing's outcome by the contact forces after it (a robot's
impact with friction: stuck, slipping or lifted off) needs the input the controller applies
*there*, in the outcome's mode at its image, which the functions cannot evaluate; it declares
``previewed``: the loop then resolves each crossing of the mode with that input
(``legsim.relaxed.crossing.previewed_choice``): it takes the outcome chosen under the input
before the crossing, evaluates the controller in its target at its image (entered on a copy of
the memory), and asks the mode's guards (or its joint function) again under that input, until
the choice repeats.

A mode whose guards may jump, discontinuous in the state by design (a robot's contact forces and
slip velocities where a sliding point passes a corner of the terrain, or where the controller
switches), declares ``crosses_jumps``: where a guard jumps past its strip within a rounding of
the state, so that no step can land in the strip, the loop crosses it there
(``legsim.relaxed.stepping.land_at_jump``), from the point just past the jump, located to
rounding (closer than any strip), and counts it (``Execution.counters["guard_jumps"]``, present
where the run crossed one); a state entering such a mode past a guard by more than eps crosses
it at once. Without the flag such a run ends with ``halving_exhausted``
(``reset_outside_domain`` at an entry): a guard that should be continuous and is not is a
model's error, which the run must not step over.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import ModelError


@dataclass(frozen=True)
class ModeFunctions:
    """A mode written as model functions (module docstring).

    Attributes
    ----------
    field, guards, reset, joint: the functions (guards None: no outgoing transition; reset None:
        every transition keeps the state; joint None: crossings one after the other).
    params: the parameter array p (any length, one-dimensional): numbers, stored as a read-only float64 array
        (typed ``Any`` because it is given as any sequence of numbers and kept as an ndarray).
    inputs: the number of entries of the input u the field expects (0: none).
    joint_outcomes: (name, target mode) of each outcome ``joint`` may return, by index.
    nan_breaks: a nan from these functions means the state is past the model's range.
    range_note: what such a nan means, in words (e.g. "the hip is below the slope: the walker
        fell"), for the run's message; "" says only that the state left the range. Or a
        function ``note(x) -> str`` of the last state before the nan (the mode's dimension),
        which can name the part of the robot nearest its range's edge there.
    previewed: the functions choose a crossing's outcome under the input applied after it
        (module docstring).
    crosses_jumps: a guard that jumps past its strip is crossed where it jumps (module
        docstring).
    call_params: params as a writable array, for the calls from Python (set, not given).
    """

    field: Any
    guards: Any = None
    reset: Any = None
    joint: Any = None
    params: Any = field(default_factory=lambda: np.zeros(0))
    inputs: int = 0
    joint_outcomes: tuple[tuple[str, str], ...] = ()
    nan_breaks: bool = False
    range_note: str | Callable[[np.ndarray], str] = ""
    previewed: bool = False
    crosses_jumps: bool = False
    #: A writable copy of params, which the Python path passes to the functions (__post_init__).
    call_params: Any = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("field", "guards", "reset", "joint"):
            value = getattr(self, name)
            if value is not None and not callable(value):
                raise ModelError(f"ModeFunctions.{name} must be a function, got {type(value).__name__}")
        if not callable(self.field):
            raise ModelError("ModeFunctions.field is required")
        try:
            params = np.ascontiguousarray(self.params, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"ModeFunctions.params must be numbers: {exc}") from exc
        if params.ndim > 1:  # flattening a table would hand the functions its rows run together
            raise ModelError(f"ModeFunctions.params must be a flat sequence of numbers, got shape {params.shape}")
        params = params.reshape(-1)
        params.flags.writeable = False
        object.__setattr__(self, "params", params)
        # The functions are compiled for writable arrays, as the kernel passes them; a call with
        # the read-only params would make numba compile each function and all it calls a second
        # time, for a read-only p (tens of seconds for a robot's model).
        object.__setattr__(self, "call_params", params.copy())
        if isinstance(self.inputs, bool) or not isinstance(self.inputs, (int, np.integer)) or self.inputs < 0:
            raise ModelError(f"ModeFunctions.inputs must be an integer >= 0, got {self.inputs!r}")
        outcomes = tuple((str(name), str(target)) for name, target in self.joint_outcomes)
        object.__setattr__(self, "joint_outcomes", outcomes)
        if self.joint is not None and not outcomes:
            raise ModelError(
                "ModeFunctions.joint needs joint_outcomes, the (name, target mode) of each index it may return"
            )

    @property
    def compiled(self) -> bool:
        """Whether every function is compiled (numba), so the kernel can call them."""
        return all(fn is None or hasattr(fn, "py_func") for fn in (self.field, self.guards, self.reset, self.joint))


def as_input(u: Any, inputs: int) -> np.ndarray:
    """A control value as the writable float64 input array of ``inputs`` entries a model
    function takes (an empty array for None; writable for the reason of ``call_params``)."""
    if u is None:
        return np.zeros(inputs)
    return _writable(np.ascontiguousarray(u, dtype=np.float64).reshape(-1))


def as_state(x: Any) -> np.ndarray:
    """A state as the writable float64 array a model function takes (see ``call_params``)."""
    return _writable(np.ascontiguousarray(x, dtype=np.float64))


def _writable(arr: np.ndarray) -> np.ndarray:
    """arr, or a copy of it where it is read-only (a model's functions are compiled for
    writable arrays: ``ModeFunctions.call_params``)."""
    return arr if arr.flags.writeable else arr.copy()


def evaluate_field(functions: ModeFunctions, dim: int, t: float, x: np.ndarray, u: Any) -> np.ndarray:
    """The mode's field at (t, x) under u, shape (dim,)."""
    out = np.empty(dim)
    functions.field(float(t), as_state(x), as_input(u, functions.inputs),
                    functions.call_params, out)  # fmt: skip
    return out


def evaluate_guards(functions: ModeFunctions, count: int, t: float, x: np.ndarray, u: Any) -> np.ndarray:
    """Every guard of the mode at (t, x) under u, shape (count,)."""
    out = np.empty(count)
    if count:
        functions.guards(float(t), as_state(x), as_input(u, functions.inputs),
                         functions.call_params, out)  # fmt: skip
    return out


def evaluate_reset(
    functions: ModeFunctions, e: int, target_dim: int, x: np.ndarray, t: float = 0.0, u: Any = None
) -> np.ndarray:
    """The image of transition e (or a continuation, ``e >= guards``) at x, shape (target_dim,)."""
    out = np.empty(target_dim)
    functions.reset(int(e), float(t), as_state(x), as_input(u, functions.inputs),
                    functions.call_params, out)  # fmt: skip
    return out


@dataclass(frozen=True)
class GuardOf:
    """Transition e's guard of a mode written as model functions, as ``guard(t, x, u)``."""

    functions: ModeFunctions
    index: int
    count: int

    def __call__(self, t: float, x: np.ndarray, u: Any = None) -> float:
        return float(evaluate_guards(self.functions, self.count, t, x, u)[self.index])


def guard_values_of(transitions: Sequence[Any], t: float, x: np.ndarray, u: Any) -> np.ndarray:
    """Each transition's guard at (t, x) under u (``Transition.guard_value``), shape
    (len(transitions),): one call of the mode's guards function when every guard is a
    ``GuardOf`` of that one mode's functions."""
    own = [tr.guard for tr in transitions if isinstance(tr.guard, GuardOf)]
    first = own[0] if own else None
    if first is None or len(own) != len(transitions) or any(g.functions is not first.functions for g in own):
        return np.array([tr.guard_value(x, t, u) for tr in transitions], dtype=float)
    return evaluate_guards(first.functions, first.count, t, x, u)[[g.index for g in own]]


@dataclass(frozen=True)
class ResetOf:
    """Transition e's reset (or continuation's, e >= guard count) of a mode written as model
    functions, as ``reset(x)``; ``target_dim()`` gives the target's dimension (a lazily built
    target is built when first asked)."""

    functions: ModeFunctions
    index: int
    target_dim: Callable[[], int]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return evaluate_reset(self.functions, self.index, self.target_dim(), x)

    def under(self, x: np.ndarray, t: float, u: Any) -> np.ndarray:
        """The image at x at time t (s) under the input u (an impact law with friction chooses
        its outcome by the forces after it, which the input changes); ``__call__`` takes u = 0."""
        return evaluate_reset(self.functions, self.index, self.target_dim(), x, t, u)


def check_outcomes(outcomes: Sequence[tuple[str, str]], modes: Sequence[str], where: str) -> None:
    """Every joint outcome's target must be a mode (of those given, for an eager system)."""
    for name, target in outcomes:
        if modes and target not in modes:
            raise ModelError(f"{where}: joint outcome {name} targets unknown mode '{target}'")
