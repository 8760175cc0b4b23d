"""Jacobians of the return map and the Floquet multipliers they give.

Jacobians
---------
Two ways, compared in the tests:

* ``jacobian="saltation"`` (default): along the relaxed execution, the derivative of each
  Runge-Kutta step (the variational equation integrated with the same tableau on the same
  steps, with the field's Jacobian from ``Mode.jacobian`` or central differences, ~1e-10
  relative; on a mode written as compiled model functions, in compiled code from the mode's
  field, ``variational``) and, at each
  transition with guard point q, the saltation matrix
  ``Xi = DR + (f+ - DR f-) grad_g^T / (grad_g . f-)`` from the reset Jacobian DR(q), the guard
  gradient (``Transition.reset_jacobian``/``guard_gradient`` or central differences) and the
  fields either side. The return itself is not taken at a fixed time but where the
  trajectory meets the section, so the product ends with a projection along the flow: for a
  crossing section ``I - f grad_s^T / (grad_s . f)``; for a section after a transition the
  returning transition contributes ``DR (I - f- grad_g^T / (grad_g . f-))`` (the derivative of
  the reset image R(q)) instead of its saltation matrix. One simulation in all.
  A Newton step needs the Jacobian only to well below the residual it reduces (an error eta in
  the Jacobian adds about eta times the residual to the next one), so Newton's iterations ask
  for less (``jacobian_saltation(..., newton=True)``): forward differences (~1e-8), and on the
  compiled path the field Jacobian interpolated linearly between the stored step points where
  it changes slowly (~1e-6 on the compass gait, a quarter of the evaluations); the Jacobian at
  the converged orbit, reported with its multipliers, is the accurate one.
* ``jacobian="fd"``: central differences of the return map, 2 simulations per coordinate.
  Step ``delta_j = fd_step * max(1, |x_j|)``. The central difference error is about
  ``eta / delta + delta**2 |P'''| / 6`` with eta the return map's own noise as a function of x
  (rounding, and the O(h^p) jumps as the step that lands in a strip changes with x). For fixed
  steps eta is tiny (about 3e-15 on the compass gait, with |P'''| ~ 5e3), so the optimum
  (3 eta / |P'''|)^(1/3) is near 1e-6, the default. With error-controlled steps (rtol/atol)
  the step sequence itself changes with x, eta ~ the tolerance, and the default becomes
  tolerance^(1/3). ``docs/orbits.md`` has the measurements.

  The Jacobian whose multipliers are reported (``jacobian_fd_checked``) is also checked for
  differentiability: each column's forward and backward differences must agree to what the
  map's curvature explains (``legsim.orbits.kinks``; one more return per column, at half the
  step). Where they do not, a kink of the return map lies inside the stencil (transitions that
  switch order there) and the central difference is an average of two slopes: the result
  reports both sides' multipliers and no stability verdict. Newton's iterations use the
  unchecked ``jacobian_fd``.

Derivatives with respect to free parameters are always central differences of the return map
(the system is rebuilt for each value). Where the simulation on one side of a difference fails
(a model that refuses states on one side, such as a runner whose flight foot would start below
the ground just off a symmetric gait), the one-sided difference on the other side is used.

Multipliers
-----------
The return map extended off the section by the flow satisfies DP f(x*) = 0 (a start moved
along the flow returns to the same point), so the n x n Jacobian DP has the trivial eigenvalue
0 along f. In an orthonormal basis B of the complement f^perp, ``M = B^T DP B`` is the Jacobian
of the return map restricted to a section, whatever the section's shape, and its n - 1
eigenvalues are the Floquet multipliers. Cyclic coordinates (positions along a translation
symmetry, such as a runner's x) are removed first: P(x + a e_c) = P(x) + a e_c, so they only add
trivial multipliers 1. Multipliers known to be 1 because of a conserved quantity (the energy of a
passive runner) are reported but can be excluded from the stability verdict with
``trivial_multipliers``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..derivatives import gradient, jacobian
from ..execution import Segment
from ..hybrid import HybridSystem, Mode, Transition
from ..methods import Tableau
from .errors import OrbitError
from .kinks import CheckedJacobian, ColumnStencil, Surroundings, kinked_columns
from .problem import OrbitProblem, Return
from .returns import ReturnMap
from .section_points import evaluator
from .variational import segment_sensitivity

#: Largest relative finite-difference step: beyond it a difference is no derivative at all
#: (the default is 1e-6, see ``default_fd_step``).
MAX_FD_STEP = 0.1

Control = Callable[[float, np.ndarray], Any] | None


# -- the variational equation along the relaxed execution ---------------------------------------
def _input(control: Control, t: float, x: np.ndarray) -> Any:
    """The control's input at (t, x), None without control."""
    return None if control is None else control(t, x)


def field_at(mode: Mode, control: Control, t: float, x: np.ndarray) -> np.ndarray:
    """The closed-loop field f(t, x, u(t, x)) of ``mode``, shape (n,)."""
    return np.asarray(mode.field(t, x, None if control is None else control(t, x)), dtype=float)


def _segment_sensitivity(
    system: HybridSystem, control: Control, tableau: Tableau, seg: Segment, t_stop: float | None, newton: bool
) -> np.ndarray:
    """d x(end) / d x(start) along one stored segment, stepping the variational equation on the
    segment's own steps (each from its stored start point); ``t_stop`` cuts the last step;
    ``newton``: to the accuracy of a Newton step (module docstring). Compiled when the mode's
    functions are (``variational``)."""
    Phi = segment_sensitivity(evaluator(system, control, tableau), seg, t_stop, newton)
    if Phi is None:
        raise OrbitError(
            f"the variational equation along mode '{seg.mode}' from t={seg.t[0]:.6g} s is not finite: a "
            f"perturbed stage left the model's range",
            "singular_jacobian",
        )
    return Phi


# -- transitions ---------------------------------------------------------------------------------
def _transition_pieces(
    system: HybridSystem,
    transition: Transition,
    q: np.ndarray,
    x_plus: np.ndarray,
    t_minus: float,
    t_plus: float,
    control: Control,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """(DR, grad g, f-, f+, grad g . f-) of a transition at its guard point q; DR and grad g by
    central differences where the transition does not give them."""
    src = system.mode(transition.source)
    tgt = system.mode(transition.target)
    q = np.asarray(q, dtype=float)
    x_plus = np.asarray(x_plus, dtype=float)
    if transition.reset_jacobian is not None:
        DR = np.asarray(transition.reset_jacobian(q), dtype=float).reshape(tgt.dim, src.dim)
    elif transition.reset is None:
        DR = np.eye(src.dim)
    else:
        DR = jacobian(transition.reset, q).reshape(tgt.dim, src.dim)
    if transition.guard_gradient is not None:
        grad = np.asarray(transition.guard_gradient(q), dtype=float).reshape(src.dim)
    else:
        # guard_value: a guard of (t, x, u) (a mode's model functions) needs the time and input too
        grad = gradient(lambda x: transition.guard_value(x, t_minus, _input(control, t_minus, x)), q)
    f_minus = field_at(src, control, t_minus, q)
    f_plus = field_at(tgt, control, t_plus, x_plus)
    rate = float(grad @ f_minus)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus))
    if scale == 0.0 or abs(rate) <= 1e-10 * scale:
        raise OrbitError(
            f"transition {transition.name}: the flow is tangent to the guard at q = "
            f"{np.round(q, 8).tolist()} (grad g . f = {rate:.3g}): grazing, no saltation matrix",
            "singular_jacobian",
        )
    return DR, grad, f_minus, f_plus, rate


def saltation_matrix(
    system: HybridSystem,
    transition: Transition,
    q: np.ndarray,
    x_plus: np.ndarray,
    t_minus: float = 0.0,
    t_plus: float = 0.0,
    control: Control = None,
) -> np.ndarray:
    """The saltation matrix ``Xi = DR + (f+ - DR f-) grad_g^T / (grad_g . f-)`` of a transition
    at its guard point q, shape (n_target, n_source): it maps a perturbation just before the
    nominal transition time to the perturbation just after it (both at the same time).

    DR is ``transition.reset_jacobian(q)`` (central differences of the reset when absent, the
    identity for an identity reset), grad_g ``transition.guard_gradient(q)`` (central
    differences when absent), f- the source field at (t_minus, q) and f+ the target field at
    (t_plus, x_plus); times in s. Raises OrbitError when the flow is tangent to the guard
    (grazing).
    """
    DR, grad, f_minus, f_plus, rate = _transition_pieces(system, transition, q, x_plus, t_minus, t_plus, control)
    return DR + np.outer(f_plus - DR @ f_minus, grad) / rate


def reset_on_guard_jacobian(
    system: HybridSystem,
    transition: Transition,
    q: np.ndarray,
    x_plus: np.ndarray,
    t_minus: float = 0.0,
    t_plus: float = 0.0,
    control: Control = None,
) -> np.ndarray:
    """Derivative of the reset image R(q) itself (not of the state at a fixed time) with respect
    to a perturbation just before the transition: ``DR (I - f- grad_g^T / (grad_g . f-))``, the
    reset Jacobian after projecting onto the guard along the flow, shape (n_target, n_source).
    This ends the Jacobian of the return map of a section ``after`` this transition (the
    saltation matrix would add f+ dt)."""
    DR, grad, f_minus, _, rate = _transition_pieces(system, transition, q, x_plus, t_minus, t_plus, control)
    return DR @ (np.eye(len(grad)) - np.outer(f_minus, grad) / rate)


# -- the return map's Jacobian -------------------------------------------------------------------
def jacobian_saltation(problem: OrbitProblem, ret: Return, newton: bool = False) -> np.ndarray:
    """The n x n Jacobian of the return map at ``ret.x_start``, through the variational equation
    on the relaxed execution and the saltation matrix of each transition (module docstring):
    to about 1e-10 relative, or with ``newton`` to the accuracy a Newton step needs (~1e-6) at
    a fraction of the cost. Not for a problem with a controller (its memory changes at
    transitions, which saltation matrices do not follow): OrbitError, use ``jacobian_fd``."""
    if problem.controller is not None:
        raise OrbitError(
            "the saltation Jacobian does not follow a controller's memory across transitions: use jacobian='fd'",
            key="jacobian",
        )
    system, control = problem.instantiate(ret.parameters)
    ex = ret.execution
    crossing = problem.section.kind == "crossing"
    Phi = np.eye(problem.dim)
    last = ret.segment
    for k in range(last + 1):
        stop = ret.t_return if (k == last and crossing) else None
        Phi = _segment_sensitivity(system, control, problem.tableau, ex.segments[k], stop, newton) @ Phi
        if k == last and crossing:
            break
        rec = ex.transitions[k]
        tr = system.taken(rec.source, rec.index, rec.name)
        # Synchronous saltation inside the period; the returning transition of an "after"
        # section maps onto the reset image itself.
        jump = reset_on_guard_jacobian if k == last else saltation_matrix
        Phi = jump(system, tr, rec.state_before, rec.state_after, rec.time, rec.exit_time, control) @ Phi
    if crossing:
        Phi = _onto_section(problem, system, control, ret) @ Phi
    return Phi


def _onto_section(problem: OrbitProblem, system: HybridSystem, control: Control, ret: Return) -> np.ndarray:
    """The projection ``I - f grad_s^T / (grad_s . f)`` along the flow onto a crossing section
    at the return, shape (n, n)."""
    f = field_at(system.mode(problem.bound.mode), control, ret.t_return, ret.x_end)
    grad = problem.bound.grad(ret.x_end)
    rate = float(grad @ f)
    if abs(rate) <= 1e-10 * float(np.linalg.norm(grad) * np.linalg.norm(f) + 1e-300):
        raise OrbitError(
            f"the flow is tangent to the section {problem.section.label} at the return (grad s . f = {rate:.3g})",
            "singular_jacobian",
        )
    return np.eye(problem.dim) - np.outer(f, grad) / rate


def _sides(
    fn: Callable[[float], np.ndarray], d: float
) -> tuple[np.ndarray | None, np.ndarray | None, list[OrbitError]]:
    """(fn(d), fn(-d), the OrbitErrors raised), None for a side whose simulation failed."""
    values: list[np.ndarray | None] = []
    errors: list[OrbitError] = []
    for delta in (d, -d):
        try:
            values.append(fn(delta))
        except OrbitError as exc:
            values.append(None)
            errors.append(exc)
    return values[0], values[1], errors


def _from_sides(
    plus: np.ndarray | None,
    minus: np.ndarray | None,
    errors: list[OrbitError],
    d: float,
    base: Callable[[], np.ndarray],
    label: str,
) -> np.ndarray:
    """The central difference of two sides, or the one-sided one where a side failed (``difference``)."""
    if plus is not None and minus is not None:
        return (plus - minus) / (2 * d)
    if plus is None and minus is None:
        raise OrbitError(
            f"finite difference in {label}: the simulations on both sides failed: {errors[0]}", errors[0].status
        )
    if plus is not None:
        return (plus - base()) / d
    return (base() - minus) / d


def difference(fn: Callable[[float], np.ndarray], d: float, base: Callable[[], np.ndarray], label: str) -> np.ndarray:
    """Central difference (fn(d) - fn(-d)) / 2d of a map that runs simulations; when the
    simulation on one side fails (a model that refuses states on one side, e.g. a runner whose
    flight foot would start below the ground), the one-sided difference against ``base()`` on
    the other side, accurate to O(d) instead of O(d^2). ``label`` names the variable in the
    error raised when both sides fail."""
    plus, minus, errors = _sides(fn, d)
    return _from_sides(plus, minus, errors, d, base, label)


def check_fd_step(step: Any) -> float:
    """A relative finite-difference step in (0, ``MAX_FD_STEP``], or an OrbitError with key
    ``fd_step``."""
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not 0.0 < step <= MAX_FD_STEP:
        raise OrbitError(f"fd_step must be a relative step in (0, {MAX_FD_STEP:g}], got {step!r}", key="fd_step")
    return float(step)


def default_fd_step(problem: OrbitProblem) -> float:
    """Relative finite-difference step of the return map: 1e-6 for fixed steps, the cube root
    of the tolerance with error-controlled steps (module docstring)."""
    tols = [t for t in (problem.rtol, problem.atol) if t is not None]
    return max(1e-6, max(tols) ** (1.0 / 3.0)) if tols else 1e-6


def jacobian_fd(
    problem: OrbitProblem,
    x: np.ndarray,
    parameters: Mapping[str, float] | None = None,
    step: float | None = None,
    columns: Sequence[int] | None = None,
    rmap: ReturnMap | None = None,
    memory: np.ndarray | None = None,
) -> np.ndarray:
    """The Jacobian of the return map at x by central differences (columns of cyclic
    coordinates are e_c by symmetry; one-sided where one side's simulation fails), n x n, or
    with a controller the (n + m) x (n + m) Jacobian of the augmented map on (x, memory) from
    ``memory`` (default the problem's guess). ``step``: relative step, default
    ``default_fd_step`` (module docstring); ``columns``: only these columns of the augmented
    state (the others are left 0); ``rmap``: the return map to evaluate (a new one by default)."""
    return _FiniteDifferences(problem, x, parameters, step, rmap, memory).jacobian(columns, check=False).central


def jacobian_fd_checked(
    problem: OrbitProblem,
    x: np.ndarray,
    parameters: Mapping[str, float] | None = None,
    step: float | None = None,
    rmap: ReturnMap | None = None,
    memory: np.ndarray | None = None,
    base: np.ndarray | None = None,
) -> CheckedJacobian:
    """``jacobian_fd`` (every column) with its differentiability check (``legsim.orbits.kinks``):
    the central Jacobian, identical to ``jacobian_fd``'s, and the forward and backward ones, and
    the columns whose one-sided differences disagree (a kink of the return map inside the
    stencil). Costs one more return per checked column (at half the step) and P(x) itself
    unless ``base`` (the augmented return from x, shape (n + m,)) is given."""
    return _FiniteDifferences(problem, x, parameters, step, rmap, memory, base).jacobian(None, check=True)


class _FiniteDifferences:
    """The return map's evaluations around one point of the augmented state (x, memory)."""

    def __init__(
        self,
        problem: OrbitProblem,
        x: np.ndarray,
        parameters: Mapping[str, float] | None,
        step: float | None,
        rmap: ReturnMap | None,
        memory: np.ndarray | None,
        base: np.ndarray | None = None,
    ) -> None:
        self.p = problem
        self.parameters = parameters
        self.rmap = rmap or ReturnMap(problem)
        self.step = default_fd_step(problem) if step is None else check_fd_step(step)
        self.start = np.concatenate([x, problem.memory_guess if memory is None else memory])
        self.names = list(problem.names) + list(problem.memory_names)
        self._base = None if base is None else np.asarray(base, dtype=float)
        # The transitions each evaluation took, by the step from the point (0.0: the point).
        self.orders: dict[tuple[int, float], tuple[str, ...]] = {}

    def at(self, z: np.ndarray, key: tuple[int, float] = (-1, 0.0)) -> np.ndarray:
        """The augmented return from the augmented state z, shape (n + m,); the transitions it
        took are kept under ``key`` (column, step)."""
        end, self.orders[key] = self.order_at(z)
        return end

    def base(self) -> np.ndarray:
        """P at the point itself, evaluated once."""
        if self._base is None:
            self._base = self.at(self.start)
        return self._base

    def shifted(self, j: int) -> Callable[[float], np.ndarray]:
        """delta -> P(start + delta e_j)."""

        def along(delta: float) -> np.ndarray:
            z = self.start.copy()
            z[j] += delta
            return self.at(z, (j, delta))

        return along

    def jacobian(self, columns: Sequence[int] | None, check: bool) -> CheckedJacobian:
        """The central (and, with ``check``, one-sided) Jacobians in ``columns`` (all by default).
        With all columns, the held values with a unit come last, so that a parameter among them
        (``_is_parameter``) is known from the others' columns and not simulated."""
        size = len(self.start)
        J = np.zeros((size, size))
        forward, backward = J.copy(), J.copy()
        stencils: dict[int, ColumnStencil] = {}
        orders: dict[int, tuple[tuple[str, ...], tuple[str, ...]]] = {}
        held = self.held_memory()
        quantities = self.held_quantities() if columns is None else set()
        steps = self.steps()
        asked = range(size) if columns is None else columns
        for j in [j for j in asked if j not in quantities] + sorted(quantities):
            if j in self.p.cyclic_idx:
                J[j, j] = forward[j, j] = backward[j, j] = 1.0
                continue
            if j in held or (j in quantities and self._is_parameter(J, j)):
                held.add(j)
                continue
            d = float(steps[j])
            kind = "coordinate" if j < self.p.dim else "controller memory"
            plus, minus, errors = _sides(self.shifted(j), d)
            J[:, j] = forward[:, j] = backward[:, j] = _from_sides(
                plus, minus, errors, d, self.base, f"{kind} {self.names[j]}"
            )
            if check and plus is not None and minus is not None:
                stencil = self._stencil(j, d, plus, minus)
                if stencil is not None:
                    stencils[j] = stencil
                    forward[:, j], backward[:, j] = stencil.forward, stencil.backward
                    orders[j] = (self.orders[(j, d)], self.orders[(j, -d)])
        skipped = set(self.p.cyclic_idx) | held
        unchecked = tuple(j for j in range(J.shape[1]) if check and j not in stencils and j not in skipped)
        around = Surroundings(self.order_at, self.start, self.base(), steps) if check else None
        return CheckedJacobian(
            J, forward, backward, tuple(sorted(stencils)), kinked_columns(stencils, J), unchecked, orders, around
        )

    def steps(self) -> np.ndarray:
        """Each column's difference step (state units), shape (N,)."""
        return self.step * np.maximum(1.0, np.abs(self.start))

    def order_at(self, z: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
        """The augmented return from z, shape (N,), and the event order it took."""
        n = self.p.dim
        ret = self.rmap(z[:n], self.parameters, z[n:])
        return ret.end, tuple(tr.name for tr in ret.transitions)

    def held_memory(self) -> set[int]:
        """Columns of the memory values the problem holds fixed that are flags (no unit), such as
        which leg lands next: no perturbation moves them continuously (a flag read as nonzero
        jumps the return at any step), so their columns stay zero and are not checked for kinks."""
        return self._held(with_unit=False)

    def held_quantities(self) -> set[int]:
        """Columns of the held memory values with a unit, such as a thrust or bias that picks one
        gait of a family: quantities the map moves, whose columns are differentiated, as the
        multipliers of the whole map (its family's 1 among them, ``trivial_multipliers``) need
        them."""
        return self._held(with_unit=True)

    def _held(self, with_unit: bool) -> set[int]:
        """Columns of the held memory values with a unit (``with_unit``) or without."""
        p = self.p
        return {
            p.dim + i
            for i, (name, unit) in enumerate(zip(p.memory_names, p.memory_units, strict=True))
            if name in p.fixed and bool(unit) == with_unit
        }

    def _is_parameter(self, J: np.ndarray, j: int) -> bool:
        """Whether held value j is one the map never changes (e.g. a bound's apex target change
        in a pronk): the return reads it back exactly from the start and from every perturbed
        start (its row of J, from the columns computed so far, is 0 off the diagonal). It then
        acts as a parameter, not a state: its multiplier 1 is no motion of the gait, and its
        column is left out like a flag's."""
        off_diagonal = np.delete(J[j], j)
        return bool(self.base()[j] == self.start[j] and not np.any(off_diagonal))

    def _stencil(self, j: int, d: float, plus: np.ndarray, minus: np.ndarray) -> ColumnStencil | None:
        """The column's stencil with its half step, None when that simulation fails (unchecked)."""
        try:
            half = self.shifted(j)(0.5 * d)
        except OrbitError:
            return None
        return ColumnStencil(self.base(), plus, minus, half, d)


def floquet_multipliers(DP: np.ndarray, f: np.ndarray, cyclic: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Floquet multipliers from the full return-map Jacobian ``DP`` (n x n) and the field ``f``
    (n,) at the fixed point: removes cyclic coordinates, restricts to f^perp (DP f = 0 there) and
    returns (multipliers sorted by decreasing modulus, the restricted matrix M)."""
    keep = [i for i in range(DP.shape[0]) if i not in set(cyclic)]
    D = DP[np.ix_(keep, keep)]
    fk = np.asarray(f, dtype=float)[keep]
    if np.linalg.norm(fk) == 0.0:
        if np.linalg.norm(f) == 0.0:
            raise OrbitError(
                "the field vanishes at the fixed point: it is an equilibrium, not a periodic orbit", "singular_jacobian"
            )
        # The multipliers live on f's orthogonal complement among the non-cyclic coordinates: with
        # f wholly along cyclic ones that complement is undefined, and so is the stability verdict.
        raise OrbitError(
            "the field at the fixed point is zero off the cyclic coordinates: the Jacobian restricted to the "
            "section is singular (the flow has no direction across it outside the cyclic coordinates), so "
            "there are no multipliers to judge stability by",
            "singular_jacobian",
        )
    # Orthonormal basis of f^perp: the last columns of a complete QR of f.
    Q, _ = np.linalg.qr(fk.reshape(-1, 1), mode="complete")
    B = Q[:, 1:]
    M = B.T @ D @ B
    mu = np.linalg.eigvals(M) if M.size else np.empty(0, dtype=complex)
    order = np.argsort(-np.abs(mu), kind="stable")
    return mu[order].astype(complex), M
