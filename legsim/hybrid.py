"""The hybrid-system model: modes, transitions and the system that ties them together.

A controlled hybrid system (paper 000, Def. 7) is a set of modes ``j``, each with a domain
``D_j`` in R^{n_j} and a vector field ``f_j(t, x, u)``, and a set of transitions ``e = (j, j')``,
each with a guard ``G_e`` on the boundary of ``D_j`` and a reset map ``R_e: G_e -> D_j'``.

Conventions (they are the whole contract between models and the integrator):

* ``guard(x) >= 0`` inside the source domain and ``< 0`` past the guard. A domain is the set
  where every guard of its outgoing transitions is >= 0. Write "and" conditions with ``max``:
  a stop at ``x_max`` reached while moving towards it is ``max(x_max - x, -v)``.
* The guard's value is the *transverse coordinate* of the relaxation strip: the strip of a
  transition is ``-eps <= guard(x) < 0``, so ``eps`` is measured in the guard's own units
  (metres for a height, radians for an angle). Each model documents its guard units.
* ``field(t, x, u) -> dx/dt`` and ``reset(x) -> x'`` take and return float64 arrays of shape
  ``(n,)``; ``u`` is whatever the control returns (``None`` without control).

The system is immutable once built. Modes can also be produced lazily by an ``expand``
callback, for models whose contact subsets are too many to enumerate up front.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from .errors import ModelError
from .model import GuardOf, ModeFunctions, ResetOf, evaluate_field, guard_values_of

FieldFn = Callable[[float, np.ndarray, Any], np.ndarray]
#: ``guard(x) -> float``, or ``guard(t, x, u) -> float`` for a transition declared with
#: ``guard_args="t,x,u"`` (which of the two is known only from that field, at run time).
GuardFn = Callable[..., float]
ResetFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True, init=False)
class Mode:
    """One discrete mode: a state dimension, a vector field and optional coordinate names.

    Parameters
    ----------
    dim:
        State dimension n_j (>= 1).
    field:
        ``field(t, x, u) -> dx/dt``, x of shape (n_j,), returns shape (n_j,).
    names:
        Names of the state coordinates (length n_j); default ``x0, x1, ...``.
    jacobian:
        Optional ``jacobian(t, x, u) -> df/dx`` of shape (n_j, n_j); finite differences
        are used where it is missing (error bounds, periodic orbits).
    units:
        Optional unit of each coordinate (``"m"``, ``"rad"``, ``"m/s"``, ...; ``""`` for none),
        for plots and recordings; default all ``""``.
    functions:
        The mode as model functions (``legsim.model.ModeFunctions``), which every path evaluates:
        ``field`` is made from them (giving both is refused), and outgoing transitions take their
        guards and resets from them, in their order, unless they give their own.
    """

    dim: int
    field: FieldFn
    names: tuple[str, ...]
    jacobian: Callable[[float, np.ndarray, Any], np.ndarray] | None
    units: tuple[str, ...]
    functions: ModeFunctions | None

    # A hand-written __init__ (the dataclass still gives eq, hash, repr and replace): names and
    # units may be omitted, but once built a mode always has both, so the fields are typed so.
    def __init__(
        self,
        dim: int,
        field: FieldFn | None = None,
        names: Iterable[str] | None = None,
        jacobian: Callable[[float, np.ndarray, Any], np.ndarray] | None = None,
        units: Iterable[str] | None = None,
        functions: ModeFunctions | None = None,
    ) -> None:
        if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1:
            raise ModelError(f"Mode dim must be a positive integer, got {dim!r}")
        dim = int(dim)
        if functions is not None and not isinstance(functions, ModeFunctions):
            raise ModelError(f"Mode functions must be a legsim.ModeFunctions, got {type(functions).__name__}")
        if isinstance(field, _FieldOf):  # a mode's own, passed back by dataclasses.replace: made anew
            field = None
        if functions is not None and field is not None:  # runs evaluate the functions, tools Mode.field
            raise ModelError("Mode takes a field or functions, not both: a field beside them is a second model")
        if field is None and functions is not None:
            field = _FieldOf(functions, dim)
        if not callable(field):
            raise ModelError(f"Mode field must be callable f(t, x, u), got {type(field).__name__}")
        if jacobian is not None and not callable(jacobian):
            raise ModelError("Mode jacobian must be callable jacobian(t, x, u) or None")
        name_tuple = tuple(f"x{i}" for i in range(dim)) if names is None else tuple(str(n) for n in names)
        if len(name_tuple) != dim:
            raise ModelError(f"Mode has dim {dim} but {len(name_tuple)} coordinate names {name_tuple}")
        if len(set(name_tuple)) != len(name_tuple):
            raise ModelError(f"Mode coordinate names must be unique, got {name_tuple}")
        unit_tuple = ("",) * dim if units is None else tuple(str(u) for u in units)
        if len(unit_tuple) != dim:
            raise ModelError(f"Mode has dim {dim} but {len(unit_tuple)} units {unit_tuple}")
        for key, value in (
            ("dim", dim),
            ("field", field),
            ("names", name_tuple),
            ("jacobian", jacobian),
            ("units", unit_tuple),
            ("functions", functions),
        ):
            object.__setattr__(self, key, value)


class _TargetDim:
    """The dimension of a system's mode, asked when first needed (``ResetOf``): a lazily
    expanded target is built then. Holds the system weakly (the system holds its transitions)."""

    def __init__(self, system: HybridSystem, mode: str) -> None:
        self._system = weakref.ref(system)
        self._mode = mode

    def __call__(self) -> int:
        system = self._system()
        assert system is not None, "a transition outlived its system"
        return system.mode(self._mode).dim


@dataclass(frozen=True)
class _FieldOf:
    """The field of a mode written as model functions, as ``field(t, x, u)``."""

    functions: ModeFunctions
    dim: int

    def __call__(self, t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return evaluate_field(self.functions, self.dim, t, x, u)


def _identity(x: np.ndarray) -> np.ndarray:
    return x.copy()


@dataclass(frozen=True)
class Continuation:
    """What follows when the crossings of a transition accumulate (a Zeno point ahead): the
    transition is replaced, at its crossing, by one into ``target`` with ``reset`` (identity if
    None). For an impact this is the plastic impact into the constrained (resting, sticking)
    mode, left again by that mode's own guards (where the constraint force changes sign).

    Past an accumulation point the relaxed execution is only guaranteed up to the Zeno time
    (paper 000, Thm. 26): without a continuation it holds the state in the strip instead of
    moving it. The integrator decides when crossings accumulate (``legsim.relaxed.zeno``).
    """

    target: str
    reset: ResetFn | None = None
    #: Empty: ``"<transition>_continued"``, given by the transition it continues.
    name: str = ""

    def __post_init__(self) -> None:
        label = self.name or None  # not named yet
        if not isinstance(self.target, str):
            raise ModelError(f"continuation {label}: target must be a mode name (str), got {self.target!r}")
        if self.reset is not None and not callable(self.reset):
            raise ModelError(f"continuation {label}: reset must be callable reset(x) -> x' or None")


@dataclass(frozen=True)
class Transition:
    """A transition ``source -> target``: guard and reset map.

    Parameters
    ----------
    source, target:
        Mode names; ``source == target`` is a self-transition (e.g. an impact with bounce).
    guard:
        ``guard(x) -> float``: >= 0 inside the source domain, < 0 past the guard, in units of
        the transverse coordinate (the strip width eps is measured in these units). None for a
        transition of a mode written as model functions: its guard is then the mode's, at this
        transition's place among the mode's outgoing transitions (and so is its reset).
    reset:
        ``reset(x) -> x'`` from the source's state space to the target's; identity if None
        (allowed only when the dimensions agree).
    name:
        A readable name for messages and recordings; empty (the default) or None: ``"source->target"``.
    guard_gradient, reset_jacobian:
        Optional derivatives (shape (n_source,) and (n_target, n_source)); finite
        differences are used where they are missing.
    guard_args:
        ``"x"`` (default): ``guard(x)``. ``"t,x,u"``: ``guard(t, x, u)``, for a guard that
        depends on time or on the input, e.g. the release guard of a constraint force under a
        time-varying torque; the integrator then evaluates it, and the control, at the trial
        time of every step and along the step's interpolant when locating the crossing.
    continuation:
        Optional ``Continuation``: the transition taken instead when this one's crossings
        accumulate (see ``Continuation``); its name defaults to ``"<name>_continued"``.
    """

    source: str
    target: str
    guard: GuardFn | None = None
    reset: ResetFn | None = None
    name: str = ""
    guard_gradient: Callable[[np.ndarray], np.ndarray] | None = None
    reset_jacobian: Callable[[np.ndarray], np.ndarray] | None = None
    guard_args: str = "x"
    continuation: Continuation | None = None

    def __post_init__(self) -> None:
        label = self.name or f"{self.source}->{self.target}"
        object.__setattr__(self, "name", label)
        if self.guard_args not in ("x", "t,x,u"):
            raise ModelError(f"transition {label}: guard_args must be 'x' or 't,x,u', got {self.guard_args!r}")
        if not isinstance(self.source, str) or not isinstance(self.target, str):
            raise ModelError(f"transition {label}: source and target must be mode names (str)")
        if self.guard is not None and not callable(self.guard):
            raise ModelError(f"transition {label}: guard must be callable guard(x) -> float")
        if self.reset is not None and not callable(self.reset):
            raise ModelError(f"transition {label}: reset must be callable reset(x) -> x' or None")
        for attr in ("guard_gradient", "reset_jacobian"):
            if getattr(self, attr) is not None and not callable(getattr(self, attr)):
                raise ModelError(f"transition {label}: {attr} must be callable or None")
        if self.continuation is not None:
            if not isinstance(self.continuation, Continuation):
                raise ModelError(f"transition {label}: continuation must be a legsim.Continuation or None")
            if not self.continuation.name:
                object.__setattr__(
                    self,
                    "continuation",
                    Continuation(self.continuation.target, self.continuation.reset, f"{label}_continued"),
                )

    @property
    def edge(self) -> tuple[str, str]:
        """The (source, target) pair."""
        return (self.source, self.target)

    def guard_fn(self) -> GuardFn:
        """The guard callable; ModelError for a transition whose guard its mode's model
        functions give only once it is part of a ``HybridSystem``."""
        if self.guard is None:
            raise ModelError(f"transition {self.name}: no guard (a mode's functions give it in a HybridSystem)")
        return self.guard

    def guard_value(self, x: np.ndarray, t: float = 0.0, u: Any = None) -> float:
        """The guard at x (and t, u for a ``guard_args="t,x,u"`` guard), as a float."""
        guard = self.guard_fn()
        if self.guard_args == "x":
            return float(guard(x))
        return float(guard(t, x, u))

    def image(self, x: np.ndarray, t: float = 0.0, u: Any = None) -> np.ndarray:
        """The reset's image of x (a copy of x without a reset); a reset written as model
        functions takes t (s) and the input u applied before the transition (an impact law
        with friction chooses its outcome by the forces after it, which the input changes)."""
        if self.reset is None:
            return np.array(x, dtype=float)
        if isinstance(self.reset, ResetOf):
            return np.asarray(self.reset.under(x, t, u), dtype=float)
        return np.asarray(self.reset(x), dtype=float)


@dataclass(frozen=True)
class JointCrossing:
    """Several transitions of one mode crossed in the same landing, resolved at once by the model
    (simultaneous impacts under one impact law): the name recorded, the target mode and the
    image of the strip point there."""

    name: str
    target: str
    state: np.ndarray


#: ``joint(mode, transition names, q, rest) -> JointCrossing | None``: how a model resolves
#: transitions crossed in the same landing step together (None: one after the other); ``rest``:
#: these crossings accumulate, resolve them by their continuation (every impact plastic).
JointFn = Callable[[str, tuple[str, ...], np.ndarray, bool], "JointCrossing | None"]


@dataclass(frozen=True)
class ModeData:
    """What the integrator needs about one mode, gathered once (internal)."""

    name: str
    mode: Mode
    transitions: tuple[Transition, ...]
    guards: tuple[GuardFn, ...]
    resets: tuple[ResetFn, ...]
    targets: tuple[str, ...]
    continuations: tuple[Continuation | None, ...] = ()


class HybridSystem:
    """A hybrid system: named modes and the transitions between them.

    Parameters
    ----------
    modes:
        Mapping of mode name to ``Mode``.
    transitions:
        The transitions; their source and target must be modes of the system (or modes that
        ``expand`` can produce).
    name:
        A readable name.
    expand:
        Optional ``expand(mode_name) -> (Mode, [Transition, ...])`` producing a mode and its
        outgoing transitions on first use, for models with many reachable modes.
    dims:
        Optional ``dims(mode_name) -> int``: the state dimension of a mode without expanding it
        (a run registers every mode a transition may reach, and expands only those it enters).
    energy:
        Optional ``energy(mode_name, x) -> float`` (J), reported in run summaries of
        mechanical systems.
    initial:
        Optional ``(mode_name, x)`` on which fields, guards and resets are evaluated once
        at construction to check their dimensions.
    joint:
        Optional ``joint(mode, names, q, rest) -> JointCrossing | None``: resolves transitions
        whose guards are crossed in the same landing step (their strips entered together:
        simultaneous impacts) at once, from the strip point q of the first; ``rest`` when such
        joint crossings accumulate (their continuation: every impact plastic). Without it, or
        when it returns None, they are crossed one after the other, and the run warns where the
        two orders of two self-transitions' resets give different states.

    Raises
    ------
    ModelError
        naming the mode or transition at fault.
    """

    def __init__(
        self,
        modes: Mapping[str, Mode],
        transitions: Sequence[Transition] = (),
        *,
        name: str = "hybrid system",
        expand: Callable[[str], tuple[Mode, Sequence[Transition]]] | None = None,
        dims: Callable[[str], int] | None = None,
        energy: Callable[[str, np.ndarray], float] | None = None,
        initial: tuple[str, Any] | None = None,
        joint: JointFn | None = None,
    ) -> None:
        if not isinstance(modes, Mapping):
            raise ModelError(f"{name}: modes must be a mapping name -> Mode, got {type(modes).__name__}")
        if not modes and expand is None:
            raise ModelError(f"{name}: a hybrid system needs at least one mode")
        for key, mode in modes.items():
            if not isinstance(key, str) or not key:
                raise ModelError(f"{name}: mode names must be non-empty strings, got {key!r}")
            if not isinstance(mode, Mode):
                raise ModelError(f"{name}: mode '{key}' must be a legsim.Mode, got {type(mode).__name__}")
        if expand is not None and not callable(expand):
            raise ModelError(f"{name}: expand must be callable expand(mode_name) -> (Mode, transitions)")
        if dims is not None and not callable(dims):
            raise ModelError(f"{name}: dims must be callable dims(mode_name) -> int")
        if joint is not None and not callable(joint):
            raise ModelError(f"{name}: joint must be callable joint(mode, names, q, rest) -> JointCrossing | None")
        if energy is not None and not callable(energy):
            raise ModelError(f"{name}: energy must be callable energy(mode, x) -> float")
        self._name = name
        self._modes: dict[str, Mode] = dict(modes)
        self._outgoing: dict[str, list[Transition]] = {key: [] for key in self._modes}
        self._expand = expand
        self._dims = dims
        self._energy = energy
        self._joint = joint
        self._transitions: list[Transition] = []
        # each transition's place in _transitions (by id), so that binding a mode's transitions
        # replaces them in place rather than rebuilding the list for every mode built
        self._place: dict[int, int] = {}
        for tr in transitions:
            self._add_transition(tr)
        if expand is None:
            for tr in self._transitions:
                if tr.target not in self._modes:
                    raise ModelError(
                        f"{name}: transition {tr.name} targets unknown mode '{tr.target}' "
                        f"(modes: {sorted(self._modes)})"
                    )
                if tr.continuation is not None and tr.continuation.target not in self._modes:
                    raise ModelError(
                        f"{name}: continuation {tr.continuation.name} of transition {tr.name} targets unknown mode "
                        f"'{tr.continuation.target}' (modes: {sorted(self._modes)})"
                    )
        for key in self._modes:
            self._bind_functions(key)
        self._compiled: dict[str, ModeData] = {}
        #: The integrator's scratch between runs of this system, never part of its definition:
        #: the tables of a finished run, its modes ready, for the next run under the same law
        #: (``legsim.relaxed.tables.kept_tables``).
        self.run_scratch: dict[Any, Any] = {}
        self._turn = threading.RLock()
        self._continued: dict[tuple[str, int], Transition] = {}
        if initial is not None:
            mode0, x0 = initial
            self.check_state(mode0, x0, label="initial state")

    # -- construction helpers -------------------------------------------------------------
    def _add_transition(self, tr: Transition) -> None:
        if not isinstance(tr, Transition):
            raise ModelError(f"{self._name}: transitions must be legsim.Transition, got {type(tr).__name__}")
        if tr.source not in self._modes:
            raise ModelError(
                f"{self._name}: transition {tr.name} leaves unknown mode '{tr.source}' (modes: {sorted(self._modes)})"
            )
        functions = self._modes[tr.source].functions
        if tr.guard is None and functions is None:
            raise ModelError(
                f"{self._name}: transition {tr.name} has no guard, and its mode '{tr.source}' is not written as "
                f"model functions (Mode(functions=...)) to give it one"
            )
        if (
            tr.reset is None
            and (functions is None or functions.reset is None)
            and self._expand is None
            and tr.target in self._modes
            and self._modes[tr.source].dim != self._modes[tr.target].dim
        ):
            raise ModelError(
                f"{self._name}: transition {tr.name} has no reset but changes dimension "
                f"{self._modes[tr.source].dim} -> {self._modes[tr.target].dim}"
            )
        self._place[id(tr)] = len(self._transitions)
        self._transitions.append(tr)
        self._outgoing[tr.source].append(tr)

    def _ensure(self, mode: str) -> None:
        if mode in self._modes:
            return
        if self._expand is None:
            raise ModelError(f"{self._name}: unknown mode '{mode}' (modes: {sorted(self._modes)})")
        try:
            produced = self._expand(mode)
        except ModelError:
            raise
        except Exception as exc:  # the user's callback failed: say which mode it was asked for
            raise ModelError(f"{self._name}: expand('{mode}') failed: {type(exc).__name__}: {exc}") from exc
        if not (isinstance(produced, tuple) and len(produced) == 2 and isinstance(produced[0], Mode)):
            raise ModelError(f"{self._name}: expand('{mode}') must return (Mode, [Transition, ...])")
        new_mode, new_transitions = produced
        self._modes[mode] = new_mode
        self._outgoing[mode] = []
        for tr in new_transitions:
            if tr.source != mode:
                raise ModelError(f"{self._name}: expand('{mode}') returned transition {tr.name} from '{tr.source}'")
            self._add_transition(tr)
        self._bind_functions(mode)

    def _check_names(self, mode: str, outgoing: Sequence[Transition]) -> None:
        """Records, recordings and messages name a transition: two of one mode with one name
        would make an execution's record ambiguous."""
        names = [tr.name for tr in outgoing]
        if len(set(names)) < len(names):
            twice = sorted({n for n in names if names.count(n) > 1})
            raise ModelError(
                f"{self._name}: mode '{mode}' has several transitions named {twice}; give each its own name"
            )

    def _bind_functions(self, mode: str) -> None:
        """Give the transitions of a mode written as model functions their guards and resets
        from those functions, each at its place among the mode's outgoing transitions."""
        functions = self._modes[mode].functions
        outgoing = self._outgoing[mode]
        self._check_names(mode, outgoing)
        if functions is None or not outgoing:
            return
        if functions.guards is None:
            raise ModelError(
                f"{self._name}: mode '{mode}' has {len(outgoing)} outgoing transitions but its functions no guards"
            )
        count = len(outgoing)
        bound = [self._bound(functions, e, count, tr) for e, tr in enumerate(outgoing)]
        self._outgoing[mode] = bound
        for old, new in zip(outgoing, bound, strict=True):
            place = self._place.pop(id(old))
            self._transitions[place] = new
            self._place[id(new)] = place

    def _bound(self, functions: ModeFunctions, e: int, count: int, tr: Transition) -> Transition:
        """Transition ``tr`` (the e-th of ``count``) with the mode's guard and resets."""
        guard, args = (tr.guard, tr.guard_args) if tr.guard is not None else (GuardOf(functions, e, count), "t,x,u")
        reset, continuation = tr.reset, tr.continuation
        if functions.reset is not None:
            if reset is None:
                reset = ResetOf(functions, e, _TargetDim(self, tr.target))
            if continuation is not None and continuation.reset is None:
                continuation = Continuation(
                    continuation.target,
                    ResetOf(functions, count + e, _TargetDim(self, continuation.target)),
                    continuation.name,
                )
        return replace(tr, guard=guard, reset=reset, guard_args=args, continuation=continuation)

    # -- public read-only view ------------------------------------------------------------
    @property
    def name(self) -> str:
        """Readable name of the system."""
        return self._name

    @property
    def modes(self) -> Mapping[str, Mode]:
        """The modes built so far (all of them for an eagerly built system)."""
        return MappingProxyType(self._modes)

    @property
    def transitions(self) -> tuple[Transition, ...]:
        """The transitions built so far."""
        return tuple(self._transitions)

    @property
    def joint(self) -> JointFn | None:
        """``joint(mode, names, q)`` resolving simultaneous transitions at once, or None."""
        return self._joint

    @property
    def energy(self) -> Callable[[str, np.ndarray], float] | None:
        """``energy(mode, x)`` in J, or None when the model does not define one."""
        return self._energy

    def turn(self) -> threading.RLock:
        """The lock that runs of this system take turns with (``with system.turn(): ...``): its
        model functions may keep scratch of their own (a robot's Pinocchio data) that two runs
        at once would share. Re-entrant, for a run started from inside another's callback;
        systems built apart run at once."""
        return self._turn

    def mode(self, name: str) -> Mode:
        """The mode called ``name`` (expanded on first use for lazy systems)."""
        self._ensure(name)
        return self._modes[name]

    def dim(self, name: str) -> int:
        """The state dimension of mode ``name``, without expanding it where the system knows it
        (``dims``)."""
        if name in self._modes or self._dims is None:
            return self.mode(name).dim
        return int(self._dims(name))

    def outgoing(self, name: str) -> tuple[Transition, ...]:
        """The transitions leaving mode ``name``; its domain is where all their guards are >= 0."""
        self._ensure(name)
        return tuple(self._outgoing[name])

    def state_names(self, name: str) -> tuple[str, ...]:
        """Coordinate names of mode ``name``."""
        return self.mode(name).names

    def mode_data(self, name: str) -> ModeData:
        """Everything the integrator needs about mode ``name``, gathered once and cached."""
        data = self._compiled.get(name)
        if data is None:
            mode = self.mode(name)
            trs = tuple(self._outgoing[name])
            for tr in trs:
                self._check_target(mode, tr.name, tr.target, tr.reset)
                if tr.continuation is not None:
                    self._check_target(mode, tr.continuation.name, tr.continuation.target, tr.continuation.reset)
            data = ModeData(
                name=name,
                mode=mode,
                transitions=trs,
                guards=tuple(tr.guard_fn() for tr in trs),
                resets=tuple(tr.reset if tr.reset is not None else _identity for tr in trs),
                targets=tuple(tr.target for tr in trs),
                continuations=tuple(tr.continuation for tr in trs),
            )
            self._compiled[name] = data
        return data

    def _check_target(self, mode: Mode, name: str | None, target: str, reset: ResetFn | None) -> None:
        """The target exists, and a transition without reset keeps the dimension."""
        dim = self.dim(target)
        if reset is None and dim != mode.dim:
            raise ModelError(f"{self._name}: transition {name} has no reset but changes dimension {mode.dim} -> {dim}")

    def taken(self, source: str, index: int, name: str) -> Transition:
        """The transition a ``TransitionRecord`` (source, index, name) took: outgoing transition
        ``index`` of ``source``, or, when the record carries its continuation's name, that
        continuation as a transition (the same guard, the continuation's target and reset)."""
        tr = self.outgoing(source)[index]
        if tr.name == name or tr.continuation is None or tr.continuation.name != name:
            return tr
        key = (source, index)
        if key not in self._continued:
            cont = tr.continuation
            self._continued[key] = Transition(
                source, cont.target, tr.guard, cont.reset, cont.name, tr.guard_gradient, None, tr.guard_args
            )
        return self._continued[key]

    def guard_values(self, mode: str, x: np.ndarray, t: float = 0.0, u: Any = None) -> np.ndarray:
        """All guard values of ``mode`` at ``x`` (shape (number of outgoing transitions,));
        t and u matter only for guards declared with ``guard_args="t,x,u"``."""
        return guard_values_of(self.mode_data(mode).transitions, t, x, u)

    def in_domain(self, mode: str, x: np.ndarray, eps: float = 0.0, t: float = 0.0, u: Any = None) -> bool:
        """True when every guard of ``mode`` is >= -eps at ``x`` (the relaxed domain for eps > 0)."""
        values = self.guard_values(mode, x, t, u)
        return bool(np.all(values >= -eps))

    # -- validation -----------------------------------------------------------------------
    def check_state(self, mode: str, x: Any, *, t: float = 0.0, u: Any = None, label: str = "state") -> np.ndarray:
        """Check ``x`` as a state of ``mode`` and evaluate the mode's field, guards and resets
        once on it, so that dimension and type errors surface here with the mode or
        transition named, rather than deep inside a run. Returns x as a float64 array.
        """
        if not isinstance(mode, str):
            raise ModelError(f"{self._name}: {label}: mode must be a mode name (str), got {mode!r}")
        m = self.mode(mode)
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{self._name}: {label} in mode '{mode}' is not a numeric vector: {exc}") from exc
        if arr.shape != (m.dim,):
            raise ModelError(
                f"{self._name}: {label} in mode '{mode}' has shape {arr.shape}, expected ({m.dim},) "
                f"with coordinates {m.names}"
            )
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"{self._name}: {label} in mode '{mode}' is not finite: {arr}")
        check_field_output(self._name, mode, m, t, arr, u)
        for tr in self.outgoing(mode):
            check_guard_output(self._name, tr, arr, t, u)
            self._ensure(tr.target)
            if tr.reset is not None:
                check_reset_output(self._name, tr, self._modes[tr.target].dim, arr)
        return arr


def check_field_output(system: str, mode_name: str, mode: Mode, t: float, x: np.ndarray, u: Any) -> np.ndarray:
    """Evaluate a field once and check its output's shape and finiteness."""
    try:
        out = np.asarray(mode.field(t, x, u), dtype=float)
    except Exception as exc:
        raise ModelError(f"{system}: field of mode '{mode_name}' failed at t={t}: {type(exc).__name__}: {exc}") from exc
    if out.shape != (mode.dim,):
        raise ModelError(f"{system}: field of mode '{mode_name}' returned shape {out.shape}, expected ({mode.dim},)")
    return out


def real_number(value: Any) -> float | None:
    """``value`` as a float when it is a real number (a Python or numpy int or float, or a 0-d
    numeric array), else None (a bool, None, an array of numbers, anything else)."""
    if isinstance(value, float):
        return float(value)
    if isinstance(value, (bool, np.bool_)):
        return None
    if isinstance(value, (int, np.integer, np.floating)):
        return float(value)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return float(value)
    return None


def describe_value(value: Any) -> str:
    """A model output as a message shows it: its type (and shape), then its value, shortened."""
    shape = f" of shape {value.shape}" if isinstance(value, np.ndarray) else ""
    text = repr(value)
    return f"{type(value).__name__}{shape} {text[:60] + '...' if len(text) > 60 else text}"


def not_a_number(value: Any) -> str:
    """What is wrong with a guard's value that ``real_number`` refused, for a message."""
    if isinstance(value, np.ndarray):
        return f"must return a scalar, got shape {value.shape}"
    return f"must return a real number (a float), got {describe_value(value)}"


def check_guard_output(system: str, tr: Transition, x: np.ndarray, t: float = 0.0, u: Any = None) -> float:
    """Evaluate a guard once and check that it returns a real number, not nan."""
    try:
        value = tr.guard_fn()(x) if tr.guard_args == "x" else tr.guard_fn()(t, x, u)
    except Exception as exc:
        raise ModelError(f"{system}: guard of transition {tr.name} failed: {type(exc).__name__}: {exc}") from exc
    out = real_number(value)
    if out is None:
        raise ModelError(f"{system}: guard of transition {tr.name} {not_a_number(value)} at t={t}, x={x}")
    if math.isnan(out):
        raise ModelError(f"{system}: guard of transition {tr.name} returned nan at x={x}")
    return out


def check_reset_output(system: str, tr: Transition, target_dim: int, x: np.ndarray) -> np.ndarray:
    """Evaluate a reset once and check the dimension of its image."""
    try:
        out = np.asarray(x if tr.reset is None else tr.reset(x), dtype=float)
    except Exception as exc:
        raise ModelError(f"{system}: reset of transition {tr.name} failed: {type(exc).__name__}: {exc}") from exc
    if out.shape != (target_dim,):
        raise ModelError(
            f"{system}: reset of transition {tr.name} returned shape {out.shape}, "
            f"expected ({target_dim},) for mode '{tr.target}'"
        )
    return out
