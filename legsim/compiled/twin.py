"""The compiled twin of a mode: numba-jitted functions computing the same field, guards and
(optionally) resets as its Python callables, which remain the reference and serve everything
else.

* ``field(t, x, p) -> dx/dt``, shape (n,);
* ``guards(x, p) -> values``, shape (n_guards,), in the order of the mode's outgoing transitions;
* ``resets(x, p, e) -> x'``, optional: the reset of outgoing transition e, into its target's
  state (for e >= n_guards, with ``continued``: the reset of transition e - n_guards's
  continuation);

with ``p`` a float64 parameter array. Parameters travel as data rather than as closure constants
so that one compilation of the kernel serves every parameter set of a model (numba treats
closure variables as constants and would compile the kernel again for each).

A twin may compute a controller's input itself (``controls``): the controller's values (gains,
and what its ``reset`` decided: a planned foot placement, a measured stance time) travel in p
too, written by Python at every entry of the mode after the controller's reset. Such a run
hands every transition back to Python (``visit.Table``), so that each entry resets the
controller as on the Python path; the steps between transitions stay compiled.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ModelBreakdown, ModelError
from ..hybrid import HybridSystem, ModeData


@dataclass(frozen=True)
class CompiledMode:
    """The compiled twin of a mode.

    Attributes
    ----------
    field: numba-jitted ``field(t, x, p) -> (n,)`` (the control, if any, computed from p).
    guards: numba-jitted ``guards(x, p) -> (n_guards,)``, ordered like the mode's outgoing
        transitions, >= 0 inside the domain (same values as the Python guards).
    n_guards: number of guards (the mode's outgoing transitions).
    params: float64 parameter array ``p`` passed to all three.
    resets: optional numba-jitted ``resets(x, p, e) -> x'`` (the reset of outgoing transition e
        into its target's state, same values as the Python reset). With it the kernel also
        crosses the mode's strips and enters the targets that have twins (``table``), so a run
        through many transitions (a gait, chattering, Zeno) stays compiled; Python then only
        turns the recorded transitions into Execution pieces.
    continued: True when ``resets`` also computes the continuations' resets, transition e's at
        ``n_guards + e``, so that the kernel takes a Zeno continuation itself.
    joint_groups: for a system with a ``joint`` function, each transition's group: the model's
        joint function resolves the transitions a landing crossed together exactly when every
        one of them has a group >= 0 and they span two groups or more (the bridge: strikes of
        two rigid contacts); the kernel hands those landings to Python and crosses the others
        itself. None: every landing that crosses two guards or more goes to Python.
    fallback: True when a nan guard means "past the model's range" (a robot's hip below the
        ground, which its Python guards raise as ModelBreakdown): the Python loop then takes
        the rest of the visit from the kernel's last accepted point, shortening that step as it
        does for a breakdown, and says what happened. False: a nan guard ends the run as on the
        Python path.
    controls: optional ``controls(controller) -> write | None``, for a twin that computes a
        controller's input itself. ``controller`` is the run's ``legsim.control.Controller``
        (evaluated at every stage; its ``input_source``) or control function, or None for a run
        without control. It returns
        ``write(p)``, which puts the controller's values now into p (called at every entry of
        the mode, after the controller's reset), or None when the twin cannot compute that
        controller (the run then takes the Python path). The field evaluates the control at each
        stage and the guards at their state, from (x, p): guards take no t, so the twin must
        not accept a controller whose input depends on t. Without ``controls`` a twin runs
        only runs without control.
    """

    field: Any
    guards: Any
    n_guards: int
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    resets: Any = None
    fallback: bool = False
    continued: bool = False
    joint_groups: tuple[int, ...] | None = None
    controls: Any = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", np.ascontiguousarray(self.params, dtype=np.float64).reshape(-1))
        if isinstance(self.n_guards, bool) or not isinstance(self.n_guards, (int, np.integer)) or self.n_guards < 0:
            raise ModelError(f"CompiledMode n_guards must be an integer >= 0, got {self.n_guards!r}")
        object.__setattr__(self, "n_guards", int(self.n_guards))
        if self.joint_groups is not None:
            groups = tuple(int(g) for g in self.joint_groups)
            if len(groups) != self.n_guards:
                raise ModelError(f"CompiledMode joint_groups has {len(groups)} entries for {self.n_guards} guards")
            object.__setattr__(self, "joint_groups", groups)


def check_twin(
    system_name: str, data: ModeData, t: float, x: np.ndarray, k0: np.ndarray, guards: Sequence[float] | None = None
) -> bool:
    """The twin of ``data``'s mode must return the Python callables' shapes and values at
    (t, x), where the Python field is k0 and the Python guards ``guards`` (default: the mode's
    guards of x alone): field, guards, and the resets (and continuation resets) it computes.
    Raises ModelError naming what disagrees. Returns whether every guard was compared (False
    where a fallback twin's nan guards hand the step to Python: check again at another state)."""
    twin = data.mode.compiled
    if not isinstance(twin, CompiledMode):
        raise ModelError(
            f"{system_name}: mode '{data.name}'.compiled must be a legsim.compiled.CompiledMode, "
            f"got {type(twin).__name__}"
        )
    if twin.n_guards != len(data.guards):
        raise ModelError(
            f"{system_name}: compiled twin of mode '{data.name}' declares {twin.n_guards} guards, the "
            f"mode has {len(data.guards)} outgoing transitions"
        )
    f, g, images = _evaluate(system_name, data, twin, t, x)
    if f.shape != (data.mode.dim,) or g.shape != (twin.n_guards,):
        raise ModelError(
            f"{system_name}: compiled twin of mode '{data.name}' returned field shape {f.shape} and "
            f"guards shape {g.shape}, expected ({data.mode.dim},) and ({twin.n_guards},)"
        )
    g_py = np.array([float(guard(x)) for guard in data.guards] if guards is None else guards, dtype=float)
    # A fallback twin's nan guards hand their step to the Python loop: nothing of theirs is used.
    used = ~np.isnan(g) if twin.fallback else np.ones(g.shape, dtype=bool)
    if not (
        np.all(np.abs(f - k0) <= 1e-9 * (1.0 + np.abs(k0))) and np.allclose(g[used], g_py[used], rtol=1e-9, atol=1e-12)
    ):
        raise ModelError(
            f"{system_name}: compiled twin of mode '{data.name}' disagrees with the Python callables at "
            f"t={t}, x={x.tolist()}: field {f.tolist()} vs {k0.tolist()}, guards {g.tolist()} vs "
            f"{g_py.tolist()}"
        )
    for name, reset, image in images:
        try:
            expected = np.asarray(reset(x.copy()), dtype=float)
        except ModelBreakdown:
            # The reset is past its model's range at this state (a foot below the ground), where
            # no run applies it: nothing to compare, and no reason to end the run.
            continue
        if image.shape != expected.shape or not np.allclose(image, expected, rtol=1e-9, atol=1e-12, equal_nan=True):
            raise ModelError(
                f"{system_name}: compiled reset of {name} of mode '{data.name}' disagrees with its Python "
                f"reset at x={x.tolist()}: {image.tolist()} vs {expected.tolist()}"
            )
    return bool(np.all(used))


def _evaluate(
    system_name: str, data: ModeData, twin: CompiledMode, t: float, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[tuple[str, Any, np.ndarray]]]:
    """The twin's field and guards at (t, x), and (name, Python reset, twin image) of every reset
    it computes."""
    xc = np.ascontiguousarray(x, dtype=float)
    ng = twin.n_guards
    try:
        f = np.asarray(twin.field(float(t), xc, twin.params), dtype=float)
        g = np.asarray(twin.guards(xc, twin.params), dtype=float)
        images = []
        if twin.resets is not None:
            for e, (tr, reset) in enumerate(zip(data.transitions, data.resets, strict=True)):
                image = np.asarray(twin.resets(xc, twin.params, e), dtype=float)
                images.append((f"transition {tr.name}", reset, image))
                cont = tr.continuation
                if twin.continued and cont is not None:
                    python = cont.reset if cont.reset is not None else np.copy
                    image = np.asarray(twin.resets(xc, twin.params, ng + e), dtype=float)
                    images.append((f"continuation {cont.name}", python, image))
    except Exception as exc:
        raise ModelError(
            f"{system_name}: compiled twin of mode '{data.name}' failed at t={t}: {type(exc).__name__}: {exc}"
        ) from exc
    return f, g, images


def without_compiled(system: HybridSystem) -> HybridSystem:
    """The same system with its modes' compiled twins removed, so ``simulate`` runs the Python
    step loop (for comparisons of the two paths). Eagerly built systems only."""
    modes = {name: dataclasses.replace(mode, compiled=None) for name, mode in system.modes.items()}
    return HybridSystem(modes, system.transitions, name=system.name, energy=system.energy, joint=system.joint)
