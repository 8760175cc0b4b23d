"""Python models and controllers as the step loop calls them: adapters to the signatures of
``legsim.model`` (and ``legsim.relaxed.calls``).

A mode written as plain Python callables (``Mode.field``, ``Transition.guard`` and ``reset``, a
``HybridSystem(joint=...)``), a plain ``control(t, x)`` and a ``legsim.control.Controller`` are
wrapped here so that the one loop steps them. Their values are checked as they come (a field of
the wrong shape, a guard that is not a number): ``ContractError``, which the driver reports with
the mode, time and state. A ``ModelBreakdown`` they raise is written as nan and flagged in the
run's workspace (``layout.I_BREAKDOWN``), so the loop shortens the step as it does for a model
function's nan; the exception is kept for the run's message (``Breakdowns``).

The input u of a Python controller may be any value its plant's callables take (None, a number,
an array, a record): the adapters hand it from the controller to the plant in ``InputCell``; the
loop's numeric u array is filled too when a compiled plant needs it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..control import Bound
from ..errors import ContractError, LegsimError, ModelBreakdown, ModelError
from ..hybrid import JointCrossing, Mode, ModeData, not_a_number, real_number
from .layout import I_BREAKDOWN


def field_value(k: Any, x: np.ndarray) -> np.ndarray:
    """A field's output k at a state x, checked to be an array of x's shape (a field that returns
    another shape would be broadcast silently into the step)."""
    value = k if isinstance(k, np.ndarray) else np.asarray(k, dtype=float)
    if value.shape != x.shape:
        raise ContractError(f"field returned shape {value.shape}, expected {x.shape}")
    return value


class InputCell:
    """The input u last evaluated by a Python controller (any value), for the plant's callables."""

    __slots__ = ("u",)

    def __init__(self) -> None:
        self.u: Any = None


class Breakdowns:
    """The last ``ModelBreakdown`` a Python model raised in a run, and the workspace to flag."""

    __slots__ = ("last", "ws")

    def __init__(self) -> None:
        self.last: ModelBreakdown | None = None
        self.ws: Any = None

    def note(self, exc: ModelBreakdown) -> None:
        self.last = exc
        if self.ws is not None:
            self.ws.iv[I_BREAKDOWN] = 1


def field_adapter(mode: Mode, cell: InputCell, breakdowns: Breakdowns) -> Callable[..., None]:
    """``field(t, x, u, p, dx)`` of a Python mode."""
    field = mode.field

    def adapted(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
        try:
            value = field(t, x, cell.u)
        except ModelBreakdown as exc:
            breakdowns.note(exc)
            out[:] = np.nan
            return
        if value.__class__ is not np.ndarray or value.shape != x.shape:
            value = field_value(value, x)
        out[:] = value

    return adapted


def guards_adapter(data: ModeData, cell: InputCell, breakdowns: Breakdowns) -> Callable[..., None]:
    """``guards(t, x, u, p, g)`` of a Python mode: each transition's guard, checked to be a real
    number."""
    calls = [(tr.guard_fn(), tr.guard_args == "x", tr.name) for tr in data.transitions]

    def adapted(t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
        try:
            for e, (guard, plain, name) in enumerate(calls):
                value = guard(x) if plain else guard(t, x, cell.u)
                if value.__class__ is not float:
                    number = real_number(value)
                    if number is None:
                        raise ContractError(f"guard of transition {name} {not_a_number(value)}")
                    value = number
                out[e] = value
        except ModelBreakdown as exc:
            breakdowns.note(exc)
            out[:] = np.nan

    return adapted


def reset_adapter(system: Any, data: ModeData, breakdowns: Breakdowns) -> Callable[..., None]:
    """``reset(e, t, x, u, p, x_new)`` of a Python mode: transition e's reset, or for
    e >= the transition count the continuation's (identity when it has none)."""
    count = len(data.transitions)

    def adapted(e: int, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
        tr = data.transitions[e % count]
        reset: Callable[[np.ndarray], np.ndarray] | None
        if e < count:
            reset, name, target = data.resets[e], tr.name, tr.target
        else:
            continuation = tr.continuation
            assert continuation is not None, "the loop continues only a transition with a continuation"
            reset, name, target = continuation.reset, continuation.name, continuation.target
        try:
            image = x.copy() if reset is None else np.asarray(reset(x.copy()), dtype=float)
        except ModelBreakdown as exc:
            breakdowns.note(exc)
            out[:] = np.nan
            return
        except LegsimError:
            raise
        except Exception as exc:
            raise ModelError(
                f"{system.name}: reset of transition {name} failed at t={t:.17g}, q={x.tolist()}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        dim = system.mode(target).dim
        if image.shape != (dim,):
            raise ModelError(
                f"{system.name}: reset of transition {name} returned shape {image.shape}, expected ({dim},) "
                f"for mode '{target}'"
            )
        out[:dim] = image

    return adapted


def joint_adapter(system: Any, data: ModeData, outcomes: Callable[[str, str], int]) -> Callable[..., int]:
    """``joint(rest, t, q, u, p, crossed, x_new) -> k`` of a system with a Python ``joint``
    function: its ``JointCrossing`` registered as the mode's outcome k by ``outcomes(name,
    target)``."""
    joint = system.joint
    names = [tr.name for tr in data.transitions]

    def adapted(
        rest: int, t: float, q: np.ndarray, u: np.ndarray, p: np.ndarray, crossed: np.ndarray, out: np.ndarray
    ) -> int:
        order = sorted((rank, e) for e, rank in enumerate(crossed.tolist()) if rank > 0.0)
        found = joint(data.name, tuple(names[e] for _, e in order), q.copy(), bool(rest))
        if found is None:
            return -1
        if not isinstance(found, JointCrossing):
            raise ModelError(
                f"{system.name}: joint function returned {type(found).__name__}, expected a JointCrossing or None"
            )
        image = np.asarray(found.state, dtype=float)
        dim = system.mode(found.target).dim
        if image.shape != (dim,):
            raise ModelError(
                f"{system.name}: joint crossing {found.name} returned shape {image.shape}, expected ({dim},) for "
                f"mode '{found.target}'"
            )
        out[:dim] = image
        return outcomes(found.name, found.target)

    return adapted


def control_adapter(control: Any, mode: str, cell: InputCell, reads: int) -> Callable[..., None]:
    """``control(t, x, m, p, u)`` of a Python control in ``mode``: a ``Bound`` controller asked
    in that mode, or a plain ``control(t, x)``; the value kept in ``cell`` (and, when the loop's
    input array has entries, written there for compiled plant functions). ``reads``: the entries
    the mode's own functions read; a mode that reads none may be given None."""
    if isinstance(control, Bound):

        def evaluate(t: float, x: np.ndarray) -> Any:
            return control.input_in(mode, t, x)
    else:
        evaluate = control

    def adapted(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, u: np.ndarray) -> None:
        value = evaluate(t, x)
        cell.u = value
        if value is None and reads == 0:
            u[:] = np.nan  # read by no function of this mode
        elif u.shape[0]:
            u[:] = input_entries(value, u.shape[0], control)

    return adapted


def input_entries(value: Any, count: int, control: Any) -> np.ndarray:
    """A Python controller's input as the ``count`` numbers a compiled plant reads; a value of
    another size or not numeric is the controller's ContractError (numpy would otherwise report it
    as a failure of the mode's field, where the loop writes the input)."""
    if value is None:  # numpy would read it as one nan
        raise ContractError(f"{_who(control)} returned None, expected {count} numbers")
    try:
        entries = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ContractError(
            f"{_who(control)} returned {type(value).__name__} {value!r:.60}, expected {count} numbers"
        ) from exc
    if entries.shape[0] != count:
        raise ContractError(f"{_who(control)} returned {entries.shape[0]} input entries, the plant takes {count}")
    return entries


def _who(control: Any) -> str:
    """A control as an error names it."""
    return f"controller {type(control.controller).__name__}" if isinstance(control, Bound) else "control"


def enter_adapter(control: Bound, mode: str) -> Callable[..., None]:
    """``enter(t, x, m, p, m_new)`` of a Python ``Controller`` entering ``mode``: its ``reset``,
    then its memory as the state's memory entries."""

    def adapted(t: float, x: np.ndarray, m: np.ndarray, p: np.ndarray, m_new: np.ndarray) -> None:
        control.reset_in(mode, t, x.copy())
        if m_new.shape[0]:
            m_new[:] = np.asarray(control.controller.memory(), dtype=float).reshape(-1)

    return adapted


__all__ = [
    "Breakdowns",
    "InputCell",
    "control_adapter",
    "enter_adapter",
    "field_adapter",
    "guards_adapter",
    "joint_adapter",
    "reset_adapter",
]
